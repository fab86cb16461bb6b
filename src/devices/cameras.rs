//! Which cameras are attached, per backend (`brdf-rig cameras`). A backend that is not compiled
//! in, or whose tool is missing, says so instead of failing the listing.

use std::path::Path;

/// The listing of one backend.
#[derive(Clone, Debug, PartialEq)]
pub struct BackendListing {
    pub backend: &'static str,
    /// `(id to pass on the command line, description)`.
    pub cameras: Vec<(String, String)>,
    /// Why the backend could not list (not compiled in, tool missing, ...).
    pub unavailable: Option<String>,
}

/// Lists the cameras of every backend. `gphoto2` names the gphoto2 program.
pub fn list_all(gphoto2: &Path) -> Vec<BackendListing> {
    let mut out = vec![BackendListing {
        backend: "sim",
        cameras: vec![(
            "sim".into(),
            "simulated camera (renders the virtual scene of the simulated rig)".into(),
        )],
        unavailable: None,
    }];
    out.push(match super::camera_gphoto2::list(gphoto2) {
        Ok(cameras) => BackendListing {
            backend: "gphoto2",
            cameras,
            unavailable: None,
        },
        Err(e) => BackendListing {
            backend: "gphoto2",
            cameras: Vec::new(),
            unavailable: Some(e.to_string()),
        },
    });
    #[cfg(feature = "webcam")]
    out.push(match super::camera_webcam::list() {
        Ok(cameras) => BackendListing {
            backend: "webcam",
            cameras,
            unavailable: None,
        },
        Err(e) => BackendListing {
            backend: "webcam",
            cameras: Vec::new(),
            unavailable: Some(e.to_string()),
        },
    });
    #[cfg(not(feature = "webcam"))]
    out.push(BackendListing {
        backend: "webcam",
        cameras: Vec::new(),
        unavailable: Some("not compiled in (build with --features webcam)".into()),
    });
    #[cfg(feature = "v4l2")]
    out.push(BackendListing {
        backend: "v4l2",
        cameras: super::camera_v4l2::list(),
        unavailable: None,
    });
    #[cfg(not(feature = "v4l2"))]
    out.push(BackendListing {
        backend: "v4l2",
        cameras: Vec::new(),
        unavailable: Some("not compiled in (build with --features v4l2)".into()),
    });
    out
}
