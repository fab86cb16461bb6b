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

use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

use super::render::ObjectScene;
use super::scene::{SceneConfig, SimCameraRig};
use crate::capture::plan::{CapturePlan, LabGeometry, ShotKind};
use crate::capture::session::write_atomic;
use crate::geometry::colmap::{CameraModel, ColmapCamera, ColmapImage, ColmapModel, write_text};
use crate::geometry::mesh_io::{PlyEncoding, write_ply};
use crate::geometry::sfm_like::{SfmLikeParams, sfm_like};

#[derive(Serialize)]
struct ChannelTruth {
    channel: usize,
    azimuth_deg: f64,
    elevation_deg: f64,
    light_dir_lab: [f64; 3],
    light_dir_camera: [f64; 3],
    irradiance_w_m2: f64,
    theta_d_deg: f64,
}

#[derive(Serialize)]
struct Truth<'a> {
    note: &'static str,
    scene: &'a SceneConfig,
    width: usize,
    height: usize,
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
    /// camera_from_lab as COLMAP: quaternion (w, x, y, z) and translation.
    camera_from_lab_qvec: [f64; 4],
    camera_from_lab_tvec: [f64; 3],
    channels: Vec<ChannelTruth>,
    /// Sensor value = radiance * exposure_secs * gain * sensitivity (below saturation at 1.0).
    sensitivity: f64,
    /// Ambient view -> turntable angle, degrees.
    view_angles_deg: BTreeMap<usize, f64>,
}

/// Writes `DIR/sim/` (see the module header).
pub fn write_ground_truth(
    dir: &Path,
    plan: &CapturePlan,
    lab: &LabGeometry,
    scene: &ObjectScene,
    config: &SceneConfig,
) -> Result<(), String> {
    let sim = dir.join("sim");
    std::fs::create_dir_all(&sim).map_err(|e| format!("creating {}: {e}", sim.display()))?;
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
                theta_d_deg: lab.theta_d_deg(ch).unwrap_or(f64::NAN),
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
        note: "simulated capture: the material is a neural fit of a MERL BRDF (Sztrajman et al. 2021), a smooth approximation, not measured MERL data",
        scene: config,
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
    let json = serde_json::to_vec_pretty(&truth).map_err(|e| e.to_string())?;
    write_atomic(&sim.join("truth.json"), &json).map_err(|e| e.to_string())?;
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
    let colmap_dir = sim.join("colmap");
    std::fs::create_dir_all(&colmap_dir)
        .map_err(|e| format!("creating {}: {e}", colmap_dir.display()))?;
    write_text(&colmap_dir, &model).map_err(|e| e.to_string())?;
    write_ply(
        &sim.join("mesh_true.ply"),
        scene.mesh(),
        PlyEncoding::BinaryLittleEndian,
    )
    .map_err(|e| e.to_string())?;
    let sfm = sfm_like(
        scene.mesh(),
        &SfmLikeParams {
            seed: config.seed,
            ..SfmLikeParams::default()
        },
    );
    write_ply(
        &sim.join("mesh_sfm.ply"),
        &sfm,
        PlyEncoding::BinaryLittleEndian,
    )
    .map_err(|e| e.to_string())?;
    Ok(())
}
