//! Starting a capture: from a rig profile and a plan to the camera, the run options and the
//! session folder a run needs. `brdf-rig capture` and the lab page (`brdf-rig serve`) both start
//! captures through these functions, so they check the same things, open the same cameras and
//! create sessions the same way; each only orders the steps around its own way of talking to
//! the operator (a terminal, a browser) and of holding the rig (per command, for the server's
//! lifetime).
//!
//! An edge: loads the simulated scene, creates and removes session folders, writes the simulated
//! ground truth. The session format is `crate::capture::session`; the run is
//! `crate::capture::runner`. Must not talk to the terminal.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::capture::camera_config::{CameraConfigError, CameraSection, parse_camera_section};
use crate::capture::plan::LabGeometry;
use crate::capture::runner::RunOptions;
use crate::capture::session::SessionHeader;
use crate::capture::{CaptureError, CapturePlan, Operator, Session, Stage};
use crate::devices::Camera;
use crate::profile::Profile;
use crate::sim::SimHandle;
use crate::sim::imaging::{ObjectScene, SceneError};
use crate::sim::scene::{SceneConfig, SceneConfigError, StageState};
use crate::sim::truth::TruthError;

/// Name of the copy of the profile kept in the session folder (a resume uses it).
pub const PROFILE_COPY: &str = "profile.toml";

/// Why a capture cannot start. Each names the file, folder or section concerned.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// `[camera]` of the profile.
    #[error(transparent)]
    Camera(#[from] CameraConfigError),
    /// `[scene]` of the profile.
    #[error(transparent)]
    SceneConfig(#[from] SceneConfigError),
    #[error("the simulated scene is not loaded")]
    SceneNotLoaded,
    #[error("loading the simulated scene of {origin} ([scene] section): {source}")]
    Scene {
        origin: String,
        #[source]
        source: SceneError,
    },
    /// The output folder cannot take a new session.
    #[error("{0}")]
    Folder(String),
    #[error(
        "the simulated camera needs the simulated rig (profile [serial] port = \"sim\"); set [camera] backend for a real camera"
    )]
    SimCameraWithoutSimRig,
    #[error(
        "camera backend `{0}` is not compiled into this binary (build with --features webcam or v4l2)"
    )]
    Backend(String),
    #[error(
        "writing the simulated ground truth (sim/): {source}; nothing was captured; the new session folder {dir} was removed"
    )]
    GroundTruthNew {
        dir: PathBuf,
        #[source]
        source: TruthError,
    },
    #[error("writing the simulated ground truth (sim/): {0}")]
    GroundTruth(#[source] TruthError),
    #[error(transparent)]
    Capture(#[from] CaptureError),
}

/// What a profile gives every capture on its rig: the camera section, the lab geometry (camera
/// placement and light directions) and, for the simulated camera, its scene, loaded once.
pub struct CaptureRig {
    pub profile: Profile,
    pub camera: CameraSection,
    pub scene: SceneConfig,
    pub lab: LabGeometry,
    /// The simulated object, for the simulated camera (`None` for a real camera).
    pub object: Option<Arc<ObjectScene>>,
}

impl CaptureRig {
    /// Reads the profile's `[camera]` and `[scene]` and loads the simulated scene when the
    /// camera is simulated.
    pub fn load(profile: Profile) -> Result<CaptureRig, StartError> {
        let camera = parse_camera_section(&profile.source, &profile.origin)?;
        let scene = SceneConfig::from_profile_text(&profile.source, &profile.origin)?;
        let lab = camera.lab(
            profile
                .light
                .channels
                .iter()
                .map(|c| (c.azimuth_deg, c.elevation_deg))
                .collect(),
        );
        let object = if camera.backend == "sim" {
            Some(Arc::new(ObjectScene::load(&scene).map_err(|source| {
                StartError::Scene {
                    origin: profile.origin.clone(),
                    source,
                }
            })?))
        } else {
            None
        };
        Ok(CaptureRig {
            profile,
            camera,
            scene,
            lab,
            object,
        })
    }

    /// Opens the profile's camera for images of `width` x `height` (the simulated camera renders
    /// that size; a V4L2 device is asked for it; the others use their own). `sim` is the
    /// simulated rig's state, which the simulated camera looks at; `stage` is what stands on
    /// the simulated turntable. `download_dir` is where a DSLR's files land.
    pub fn open_camera(
        &self,
        width: usize,
        height: usize,
        sim: Option<&SimHandle>,
        stage: &StageState,
        download_dir: &Path,
    ) -> Result<Box<dyn Camera>, StartError> {
        let camera = &self.camera;
        Ok(match camera.backend.as_str() {
            "sim" => {
                let Some(handle) = sim else {
                    return Err(StartError::SimCameraWithoutSimRig);
                };
                let Some(renderer) = &self.object else {
                    return Err(StartError::SceneNotLoaded);
                };
                Box::new(crate::sim::camera::SimCamera::new(
                    Box::new(handle.clone()),
                    stage.clone(),
                    self.lab.clone(),
                    self.scene.clone(),
                    width,
                    height,
                    renderer.clone(),
                ))
            }
            "gphoto2" => {
                use crate::devices::camera_gphoto2::{Gphoto2Camera, Gphoto2Config};
                let mut cfg = Gphoto2Config::new(download_dir.to_path_buf());
                cfg.program = PathBuf::from(&camera.gphoto2_program);
                cfg.port = camera.gphoto2_port.clone();
                cfg.shutter_key = camera.shutter_key.clone();
                cfg.iso_key = camera.iso_key.clone();
                cfg.extra_config = camera
                    .extra_config
                    .iter()
                    .filter_map(|kv| kv.split_once('='))
                    .map(|(k, v)| (k.to_string(), v.to_string()))
                    .collect();
                Box::new(Gphoto2Camera::new(cfg))
            }
            #[cfg(feature = "webcam")]
            "webcam" => Box::new(crate::devices::camera_webcam::WebcamCamera::new(
                camera.webcam_index,
            )),
            #[cfg(feature = "v4l2")]
            "v4l2" => Box::new(crate::devices::camera_v4l2::V4l2Camera::new(
                Path::new(&camera.v4l2_device),
                width as u32,
                height as u32,
            )),
            other => return Err(StartError::Backend(other.to_string())),
        })
    }

    /// Options of a run on this rig: its light directions (recorded with each shot) and its
    /// turntable travel (moves take the shorter way round).
    pub fn run_options(&self, snapshot_every: usize) -> RunOptions {
        RunOptions {
            snapshot_every,
            lab: Some(self.lab.clone()),
            angle_range: Some((
                self.profile.turntable.min_angle_deg,
                self.profile.turntable.max_angle_deg,
            )),
            ..RunOptions::default()
        }
    }

    /// Creates the session folder (with a copy of the profile) and, for the simulated camera,
    /// its ground truth. When the ground truth cannot be written the new folder is removed
    /// again (an empty folder the user gave is put back), so the same start can be tried again.
    pub fn create_session(
        &self,
        dir: &Path,
        plan: &CapturePlan,
        plan_text: &str,
        was_empty_folder: bool,
    ) -> Result<Session, StartError> {
        let header = SessionHeader {
            format_version: 0,
            tool: format!("brdf-rig {}", env!("CARGO_PKG_VERSION")),
            plan_name: String::new(),
            planned_shots: 0,
            profile: self.profile.origin.clone(),
            camera_backend: self.camera.backend.clone(),
            created_utc: crate::capture::session::now_utc().1,
            simulated: self.camera.backend == "sim",
        };
        let session = Session::create(
            dir,
            plan,
            plan_text,
            header,
            &[(PROFILE_COPY, self.profile.source.as_bytes())],
        )?;
        if let Err(source) = self.write_ground_truth(dir, plan) {
            drop(session);
            remove_new_session(dir, was_empty_folder)?;
            return Err(StartError::GroundTruthNew {
                dir: dir.to_path_buf(),
                source,
            });
        }
        Ok(session)
    }

    /// Writes the simulated ground truth again into a resumed session (deterministic and cheap;
    /// a kill may have interrupted it). Nothing for a real camera.
    pub fn refresh_ground_truth(&self, dir: &Path, plan: &CapturePlan) -> Result<(), StartError> {
        self.write_ground_truth(dir, plan)
            .map_err(StartError::GroundTruth)
    }

    fn write_ground_truth(&self, dir: &Path, plan: &CapturePlan) -> Result<(), TruthError> {
        match &self.object {
            Some(object) => {
                crate::sim::truth::write_ground_truth(dir, plan, &self.lab, object, &self.scene)
            }
            None => Ok(()),
        }
    }
}

/// The command that continues the session in `dir` from a terminal, with what a resume cannot
/// read from the session: `--port` (a real board's port) and `--unattended` (without a terminal
/// a guided resume refuses to start). Paths are quoted for a POSIX shell where they need it.
pub fn resume_command(dir: &Path, port: Option<&Path>, unattended: bool) -> String {
    let quote = |p: &Path| {
        let s = p.display().to_string();
        if s.contains(|c: char| c.is_whitespace() || "'\"$\\`;&|<>()*?".contains(c)) {
            format!("'{}'", s.replace('\'', r"'\''"))
        } else {
            s
        }
    };
    let mut cmd = format!("brdf-rig capture --resume {}", quote(dir));
    if let Some(port) = port {
        cmd.push_str(&format!(" --port {}", quote(port)));
    }
    if unattended {
        cmd.push_str(" --unattended");
    }
    cmd
}

/// Refuses an output folder that exists and is not empty, or whose nearest existing ancestor is
/// not a writable folder; the error names `dir` as given. Writes nothing that stays.
pub fn check_output_folder(dir: &Path) -> Result<(), StartError> {
    let refuse = |m: String| Err(StartError::Folder(m));
    if dir.exists() {
        if !dir.is_dir() {
            return refuse(format!(
                "{} exists and is not a folder; choose a new --out",
                dir.display()
            ));
        }
        let mut entries = std::fs::read_dir(dir)
            .map_err(|e| StartError::Folder(format!("listing {}: {e}", dir.display())))?;
        if entries.next().is_some() {
            return refuse(format!(
                "{} exists and is not empty; choose a new --out, or continue it with --resume",
                dir.display()
            ));
        }
    }
    // The session is built beside `dir` and renamed into place: its parent (or the nearest
    // folder that exists above it) must take new entries.
    let mut probe = match dir.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    while !probe.exists() {
        match probe.parent() {
            Some(p) if !p.as_os_str().is_empty() => probe = p.to_path_buf(),
            _ => probe = PathBuf::from("."),
        }
    }
    if !probe.is_dir() {
        return refuse(format!(
            "cannot create the session folder {}: {} is not a folder",
            dir.display(),
            probe.display()
        ));
    }
    // A folder made and removed at once: the only sure test of write permission (root, ACLs,
    // read-only mounts and immutable folders all answer differently to a look at the mode bits).
    let test = probe.join(format!(".brdf-rig-write-test-{}", std::process::id()));
    match std::fs::create_dir(&test) {
        Ok(()) => {
            let _ = std::fs::remove_dir(&test);
            Ok(())
        }
        Err(e) => refuse(format!(
            "cannot create the session folder {}: {} does not accept new files ({e})",
            dir.display(),
            probe.display()
        )),
    }
}

/// Removes a session folder a start created (it failed before any shot); puts back the empty
/// folder the user gave, if there was one.
pub fn remove_new_session(dir: &Path, was_empty_folder: bool) -> Result<(), StartError> {
    std::fs::remove_dir_all(dir).map_err(|e| {
        StartError::Folder(format!(
            "removing the new session folder {} after a failed start: {e}",
            dir.display()
        ))
    })?;
    if was_empty_folder {
        std::fs::create_dir(dir).map_err(|e| {
            StartError::Folder(format!(
                "putting back the empty folder {}: {e}",
                dir.display()
            ))
        })?;
    }
    Ok(())
}

/// Sets the simulated scene's stage once the operator (a person, a page, or nobody) has done
/// their part, so the simulated camera sees what a real one would.
pub struct SimStage<'a> {
    pub inner: &'a mut dyn Operator,
    pub stage: StageState,
}

impl Operator for SimStage<'_> {
    fn set_stage(&mut self, from: Option<Stage>, to: Stage) -> Result<(), CaptureError> {
        self.inner.set_stage(from, to)?;
        self.stage.set(to);
        Ok(())
    }
}
