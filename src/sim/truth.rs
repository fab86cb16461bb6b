//! What a simulated capture knows that a real one does not, written to `DIR/sim/` so the
//! calibrate and reconstruct steps (and their tests) can run without photogrammetry and be
//! scored against the truth:
//!
//! ```text
//! sim/truth.json        scene, material (a neural MERL fit, not measured data), camera intrinsics
//!                       and lab pose, each channel's light direction (lab and camera frames) and
//!                       irradiance, sensor constants
//! sim/colmap/           what photogrammetry would give: COLMAP text model (cameras.txt,
//!                       images.txt, empty points3D.txt), one image per ambient view, named by the
//!                       view's first ambient file (e.g. `ambient/v003_e0.exr`); single-light
//!                       shots of view N use that view's pose
//! sim/mesh_true.ply     the object as placed on the turntable (object frame)
//! sim/mesh_sfm.ply      what SfM/MVS would give: the true mesh smoothed and noised
//!                       (`geometry::sfm_like`, default parameters, seeded by the scene seed)
//! ```
//!
//! This module owns `sim/truth.json`: [`Truth`] is its serde type (version
//! [`TRUTH_FORMAT_VERSION`]), written here and read through [`read_truth`], never as untyped
//! JSON. The paths above are relative to the session folder ([`TRUTH_FILE`], [`COLMAP_DIR`],
//! [`MESH_SFM_FILE`]).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

use super::imaging::ObjectScene;
use super::scene::{SceneConfig, SimCameraRig};
use crate::capture::plan::{CapturePlan, LabGeometry, ShotKind};
use crate::format::{FormatError, Versioned, version_1};
use crate::geometry::colmap::{
    CameraModel, ColmapCamera, ColmapError, ColmapImage, ColmapModel, write_text,
};
use crate::geometry::mesh_io::{MeshIoError, PlyEncoding, write_ply};
use crate::geometry::sfm_like::{SfmLikeParams, sfm_like};

/// `sim/truth.json`, relative to the session folder.
pub const TRUTH_FILE: &str = "sim/truth.json";
/// What photogrammetry would give: the COLMAP model, relative to the session folder.
pub const COLMAP_DIR: &str = "sim/colmap";
/// What SfM/MVS would give: the smoothed, noised mesh, relative to the session folder.
pub const MESH_SFM_FILE: &str = "sim/mesh_sfm.ply";
/// The version of `sim/truth.json` written, and the only one read.
pub const TRUTH_FORMAT_VERSION: u32 = 1;

const FORMAT: Versioned = Versioned {
    what: "simulated ground truth",
    version: TRUTH_FORMAT_VERSION,
    remedy: "capture the simulated session again with this brdf-rig",
};

/// One light channel as simulated.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChannelTruth {
    pub channel: usize,
    pub azimuth_deg: f64,
    pub elevation_deg: f64,
    pub light_dir_lab: [f64; 3],
    /// Unit vector towards the light, camera axes.
    pub light_dir_camera: [f64; 3],
    /// At light level 1.
    pub irradiance_w_m2: f64,
    /// `None` when the channel's geometry gives none.
    pub theta_d_deg: Option<f64>,
}

/// `sim/truth.json`: what the simulator knew.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Truth {
    #[serde(default = "version_1")]
    pub format_version: u32,
    pub note: String,
    pub scene: SceneConfig,
    pub width: usize,
    pub height: usize,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// camera_from_lab as COLMAP: quaternion (w, x, y, z) and translation.
    pub camera_from_lab_qvec: [f64; 4],
    pub camera_from_lab_tvec: [f64; 3],
    pub channels: Vec<ChannelTruth>,
    /// Sensor value = radiance * exposure_secs * gain * sensitivity (below saturation at 1.0).
    pub sensitivity: f64,
    /// Ambient view -> turntable angle, degrees.
    pub view_angles_deg: BTreeMap<usize, f64>,
}

/// Reads `SESSION/sim/truth.json`.
pub fn read_truth(session_dir: &Path) -> Result<Truth, FormatError> {
    FORMAT.read(&session_dir.join(TRUTH_FILE))
}

/// Why the simulated ground truth could not be written; each names its file or folder.
#[derive(Debug, thiserror::Error)]
pub enum TruthError {
    #[error("creating {}: {source}", path.display())]
    CreateDir {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Truth(#[from] FormatError),
    #[error(transparent)]
    Colmap(#[from] ColmapError),
    #[error(transparent)]
    Mesh(#[from] MeshIoError),
}

fn create_dir(path: &Path) -> Result<(), TruthError> {
    std::fs::create_dir_all(path).map_err(|source| TruthError::CreateDir {
        path: path.to_owned(),
        source,
    })
}

/// Writes `DIR/sim/` (see the module header).
pub fn write_ground_truth(
    dir: &Path,
    plan: &CapturePlan,
    lab: &LabGeometry,
    scene: &ObjectScene,
    config: &SceneConfig,
) -> Result<(), TruthError> {
    let sim = dir.join("sim");
    create_dir(&sim)?;
    let rig = SimCameraRig::new(lab, plan.camera.width, plan.camera.height);
    let k = rig.intrinsics;
    let q = rig.camera_from_lab.rotation;
    let t = rig.camera_from_lab.translation;
    let channels = lab
        .lights
        .iter()
        .enumerate()
        .filter_map(|(ch, &(az, el))| {
            let l = lab.light_dir_lab(ch)?;
            let lc = rig.camera_from_lab.dir_to_camera(&l);
            Some(ChannelTruth {
                channel: ch,
                azimuth_deg: az,
                elevation_deg: el,
                light_dir_lab: [l.x, l.y, l.z],
                light_dir_camera: [lc.x, lc.y, lc.z],
                irradiance_w_m2: config.light_irradiance,
                theta_d_deg: lab.theta_d_deg(ch),
            })
        })
        .collect();
    let shots = plan.shots();
    let mut view_angles = BTreeMap::new();
    let mut images = Vec::new();
    for s in shots
        .iter()
        .filter(|s| s.kind == ShotKind::Ambient && s.bracket == 0)
    {
        let Some(view) = s.view else { continue };
        view_angles.insert(view, s.angle_deg);
        images.push(ColmapImage {
            id: view as u32 + 1,
            camera_id: 1,
            name: s.file.clone(),
            pose: rig.camera_from_object(s.angle_deg),
        });
    }
    let truth = Truth {
        format_version: TRUTH_FORMAT_VERSION,
        note: "simulated capture: the material is a neural fit of a MERL BRDF (Sztrajman et al. 2021), a smooth approximation, not measured MERL data".into(),
        scene: config.clone(),
        width: k.width,
        height: k.height,
        fx: k.fx,
        fy: k.fy,
        cx: k.cx,
        cy: k.cy,
        camera_from_lab_qvec: [q.w, q.i, q.j, q.k],
        camera_from_lab_tvec: [t.x, t.y, t.z],
        channels,
        sensitivity: config.sensitivity,
        view_angles_deg: view_angles,
    };
    FORMAT.write(&dir.join(TRUTH_FILE), &truth)?;
    let mut cameras = BTreeMap::new();
    cameras.insert(
        1,
        ColmapCamera {
            id: 1,
            model: CameraModel::simplest_for(&k),
            intrinsics: k,
        },
    );
    let model = ColmapModel { cameras, images };
    let colmap_dir = dir.join(COLMAP_DIR);
    create_dir(&colmap_dir)?;
    write_text(&colmap_dir, &model)?;
    write_ply(
        &sim.join("mesh_true.ply"),
        scene.mesh(),
        PlyEncoding::BinaryLittleEndian,
    )?;
    let sfm = sfm_like(
        scene.mesh(),
        &SfmLikeParams {
            seed: config.seed,
            ..SfmLikeParams::default()
        },
    );
    write_ply(
        &dir.join(MESH_SFM_FILE),
        &sfm,
        PlyEncoding::BinaryLittleEndian,
    )?;
    Ok(())
}
