//! Calibrating a capture session: from the session folder's bracketed calibration and
//! single-light shots to linear HDR images, a light direction and an irradiance per light
//! channel, and the reconstruction job that the `reconstruct` step reads.
//!
//! This is an edge: it reads the session (manifest, EXR images) and writes `hdr/`,
//! `calibration.json` and `job.toml` into it. It knows nothing of simulation: the photogrammetry
//! model, the mesh and the white board's albedo come in [`SessionCalibOptions`], and so does a
//! truth to score against (`pipeline::sim_session` fills them for a simulated session). Every image the
//! manifest lists is checked against its size and SHA-256 first (the same check as `session
//! verify`), and a damaged one is refused by name before anything is written. While it writes it
//! holds `.calibrate.lock`, and it removes the temporaries a killed run left (`.NAME.tmp-*` in
//! `hdr/` and beside `job.toml`). The measuring
//! itself is `crate::calib` (pure); the formats are owned by `capture::session` (manifest),
//! `pipeline::calibration_file` (`calibration.json`) and `reconstruct::job` (`job.toml`).
//!
//! Conventions:
//! - Radiance unit: an HDR image holds `value / (exposure_secs * gain)`, the same unit for every
//!   shot of a session, so the irradiance measured on the white board and the single-light
//!   images share it and cancel in r = I / (E cos theta_i).
//! - The camera does not move in the lab, so one light direction per channel (camera axes)
//!   serves every view; the turntable's rotation reaches the object frame through each view's
//!   photogrammetry pose.
//! - The white board stands at the turntable centre facing the camera at turntable angle 0 and
//!   turns with the table (the capture runner turns it by half the channel's azimuth). Its normal
//!   in camera axes is `(0, 0, -1)` turned about the turntable axis by the white shot's measured
//!   angle; the axis in camera axes is the rotation axis between the photogrammetry poses of the
//!   ambient views (`turntable_axis_camera`), so it holds for a tilted camera and for lights at
//!   any elevation. Without two views at different angles the board is assumed to face the
//!   bisector of light and camera, `normalize(l + v)`, which is right only for a light at the
//!   camera's elevation.

use nalgebra::Vector3;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::calibration_file::{CALIBRATION_FILE, CALIBRATION_FORMAT_VERSION};
pub use super::calibration_file::{ChannelCalibration, SessionCalibration};
use crate::calib::hdr::{Exposure, MergeOptions, MergedHdr, merge_linear};
use crate::calib::light::{OutlineInput, SphereShot, calibrate_light};
use crate::calib::sphere::SphereOptions;
use crate::calib::white::{BoardRegion, WhiteOptions, calibrate_irradiance};
use crate::capture::plan::ShotKind;
use crate::capture::session::{Manifest, ShotRecord, read_manifest};
use crate::geometry::camera::Intrinsics;
use crate::geometry::colmap;
use crate::imageio::{ExrPrecision, read_linear, write_exr};
use crate::reconstruct::job::{JOB_FILE, Job, LightImageSpec};
use crate::render::image::LinearImage;

/// What went wrong, naming the file or shot.
#[derive(Debug, thiserror::Error)]
pub enum SessionCalibError {
    #[error("{path}: {reason}")]
    File { path: PathBuf, reason: String },
    #[error("session {dir}: {reason}")]
    Session { dir: PathBuf, reason: String },
    #[error("channel {channel}: {reason}")]
    Channel { channel: usize, reason: String },
}

/// What photogrammetry gives, the white board's albedo, and (simulations) the truth.
#[derive(Clone, Debug, Default)]
pub struct SessionCalibOptions {
    /// COLMAP model folder (required).
    pub cameras: Option<PathBuf>,
    /// Mesh from photogrammetry (required).
    pub mesh: Option<PathBuf>,
    /// Albedo of the white reference (required).
    pub white_albedo: Option<f64>,
    /// The true light of each channel, when it is known: the calibration is scored against it
    /// (`truth_dir_error_deg`, `truth_irradiance_error`).
    pub truth: Option<LightTruth>,
}

/// The true light per channel, in the units the calibration measures.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LightTruth {
    /// channel -> (unit vector towards the light in camera axes, irradiance in the session's
    /// radiance unit)
    pub channels: BTreeMap<usize, (Vector3<f64>, f64)>,
}

/// Groups of shots that form one bracket: (kind, view, channel) -> records.
type Brackets<'a> = BTreeMap<(u8, Option<usize>, Option<usize>), Vec<&'a ShotRecord>>;

fn kind_key(k: ShotKind) -> u8 {
    match k {
        ShotKind::Ambient => 0,
        ShotKind::SingleLight => 1,
        ShotKind::Sphere => 2,
        ShotKind::White => 3,
    }
}

fn manifest(dir: &Path) -> Result<Manifest, SessionCalibError> {
    read_manifest(dir).map_err(|e| SessionCalibError::Session {
        dir: dir.into(),
        reason: format!("{e}; is this a capture session folder?"),
    })
}

/// Checks every image the manifest lists against its size and SHA-256; the first damaged or
/// missing one is an error naming it.
fn verify_images(dir: &Path, manifest: &Manifest) -> Result<(), SessionCalibError> {
    for s in &manifest.shots {
        if let (_, Some(problem)) = crate::capture::verify::check_record(dir, s) {
            return Err(SessionCalibError::File {
                path: dir.join(&s.file),
                reason: format!(
                    "{} (shot {}): the image is not the one the capture recorded; `brdf-rig \
                     capture --resume {}` takes it again (the damaged file is kept aside)",
                    problem.what(),
                    s.id,
                    dir.display()
                ),
            });
        }
    }
    Ok(())
}

/// Takes `.calibrate.lock` (two calibrations of one session would write the same files) and
/// removes what a killed calibration left: temporaries of atomic writes in `hdr/` and beside
/// `job.toml` and `calibration.json`. The lock is held while the returned file lives.
fn lock_and_clean(dir: &Path, hdr_dir: &Path) -> Result<std::fs::File, SessionCalibError> {
    let path = dir.join(".calibrate.lock");
    let file_err = |path: &Path, e: std::io::Error| SessionCalibError::File {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    let lock = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&path)
        .map_err(|e| file_err(&path, e))?;
    if fs4::FileExt::try_lock(&lock).is_err() {
        return Err(SessionCalibError::Session {
            dir: dir.into(),
            reason: "another `brdf-rig calibrate` is writing to this session".into(),
        });
    }
    crate::atomic::remove_stray_temporaries(hdr_dir, None).map_err(|e| file_err(hdr_dir, e))?;
    crate::atomic::remove_stray_temporaries(dir, Some(&[JOB_FILE, CALIBRATION_FILE]))
        .map_err(|e| file_err(dir, e))?;
    Ok(lock)
}

/// Merges one bracket into an HDR image in the session's radiance unit, with where it clips.
fn merge(dir: &Path, shots: &[&ShotRecord]) -> Result<MergedHdr, SessionCalibError> {
    let mut images = Vec::with_capacity(shots.len());
    for s in shots {
        let path = dir.join(&s.file);
        let img = read_linear(&path, 1.0).map_err(|e| SessionCalibError::File {
            path: path.clone(),
            reason: e.to_string(),
        })?;
        images.push(img);
    }
    let first = shots.first().ok_or_else(|| SessionCalibError::Session {
        dir: dir.into(),
        reason: "an empty bracket".into(),
    })?;
    // value / exposure is what merge_linear gives; dividing by the gain too makes shots with
    // different gains comparable.
    let brackets: Vec<Exposure> = images
        .iter()
        .zip(shots)
        .map(|(image, s)| Exposure {
            image,
            exposure_secs: s.exposure_secs * s.gain.max(f64::MIN_POSITIVE),
        })
        .collect();
    let noise_floor = first.saturation * 2e-3;
    let merged = merge_linear(&brackets, &MergeOptions::new(first.saturation, noise_floor))
        .map_err(|e| SessionCalibError::Session {
            dir: dir.into(),
            reason: format!("merging the bracket of {}: {e}", first.id),
        })?;
    Ok(merged)
}

/// What a session calibration needs besides the session's images: the photogrammetry model and
/// mesh, the camera's intrinsics and the white board's albedo.
struct Inputs {
    cameras: PathBuf,
    mesh: PathBuf,
    model: colmap::ColmapModel,
    intr: Intrinsics,
    albedo: f64,
}

fn inputs(dir: &Path, opts: &SessionCalibOptions) -> Result<Inputs, SessionCalibError> {
    let missing = |what: &str| SessionCalibError::Session {
        dir: dir.into(),
        reason: format!("{what} (a simulated session has its own under sim/)"),
    };
    let cameras = opts.cameras.clone().ok_or_else(|| {
        missing("the photogrammetry model is not given: give the COLMAP model with --cameras")
    })?;
    let mesh = opts.mesh.clone().ok_or_else(|| {
        missing("the mesh is not given: give the photogrammetry mesh with --mesh")
    })?;
    let model = colmap::read_model(&cameras).map_err(|e| SessionCalibError::File {
        path: cameras.clone(),
        reason: format!("{e} (give the photogrammetry model with --cameras)"),
    })?;
    let intr: Intrinsics = *model
        .cameras
        .values()
        .next()
        .map(|c| &c.intrinsics)
        .ok_or_else(|| SessionCalibError::File {
            path: cameras.clone(),
            reason: "the COLMAP model has no camera".into(),
        })?;
    let albedo = opts
        .white_albedo
        .ok_or_else(|| missing("the white reference's albedo is unknown: give it with --albedo"))?;
    Ok(Inputs {
        cameras,
        mesh,
        model,
        intr,
        albedo,
    })
}

/// The merged sphere and white-reference brackets, per light channel.
struct CalibrationShots {
    sphere: BTreeMap<usize, MergedHdr>,
    white: BTreeMap<usize, MergedHdr>,
}

fn merge_calibration_shots(
    dir: &Path,
    brackets: &Brackets<'_>,
    progress: &mut impl FnMut(&str),
) -> Result<CalibrationShots, SessionCalibError> {
    let sphere_key = kind_key(ShotKind::Sphere);
    let white_key = kind_key(ShotKind::White);
    let mut sphere = BTreeMap::new();
    let mut white = BTreeMap::new();
    for ((k, _view, ch), shots) in brackets {
        let Some(ch) = ch else { continue };
        if *k == sphere_key {
            progress(&format!("merging the sphere bracket of channel {ch}"));
            sphere.insert(*ch, merge(dir, shots)?);
        } else if *k == white_key {
            progress(&format!(
                "merging the white-reference bracket of channel {ch}"
            ));
            white.insert(*ch, merge(dir, shots)?);
        }
    }
    if sphere.is_empty() {
        return Err(SessionCalibError::Session {
            dir: dir.into(),
            reason: "no sphere shots: the plan must have [calibration] sphere = true".into(),
        });
    }
    Ok(CalibrationShots { sphere, white })
}

/// One channel's light direction (from its sphere image, the outline found in `outline_img`
/// when given) and irradiance (from its white-reference image, whose normal is turned about
/// the turntable `axis` by the white shot's measured angle `white_angle`), scored against the
/// truth when it is known.
#[allow(clippy::too_many_arguments)]
fn calibrate_channel(
    ch: usize,
    shots: &CalibrationShots,
    outline_img: Option<&LinearImage>,
    white_angle: Option<f64>,
    axis: Option<nalgebra::Unit<Vector3<f64>>>,
    inputs: &Inputs,
    truth: Option<&LightTruth>,
    progress: &mut impl FnMut(&str),
) -> Result<ChannelCalibration, SessionCalibError> {
    let sphere = shots
        .sphere
        .get(&ch)
        .ok_or_else(|| SessionCalibError::Channel {
            channel: ch,
            reason: "no sphere shot for this channel".into(),
        })?;
    // The clip level is the merged bracket's, never guessed from the pixels: the outline
    // image (a per-pixel maximum over the channels) clips no lower than its least one.
    let clip_min = shots
        .sphere
        .values()
        .filter_map(|m| m.clip.value)
        .fold(f32::INFINITY, f32::min);
    let sphere_opts = SphereOptions {
        saturation: sphere.clip.value.map(|v| v.min(clip_min)),
        ..SphereOptions::default()
    };
    let outline = match outline_img {
        Some(o) => OutlineInput::Image(o),
        None => OutlineInput::FromLightImage,
    };
    let light = calibrate_light(
        &[SphereShot {
            light: &sphere.image,
            outline,
        }],
        &inputs.intr,
        &sphere_opts,
    )
    .map_err(|e| SessionCalibError::Channel {
        channel: ch,
        reason: format!("light direction from the sphere: {e}"),
    })?;
    let l = light.dir_camera;
    let white = shots
        .white
        .get(&ch)
        .ok_or_else(|| SessionCalibError::Channel {
            channel: ch,
            reason: "no white-reference shot for this channel".into(),
        })?;
    let normal = match (axis, white_angle) {
        (Some(axis), Some(a)) => {
            nalgebra::UnitQuaternion::from_axis_angle(&axis, a.to_radians())
                * Vector3::new(0.0, 0.0, -1.0)
        }
        _ => (l + Vector3::new(0.0, 0.0, -1.0)).normalize(),
    };
    let irr = calibrate_irradiance(
        &white.image,
        [inputs.albedo; 3],
        &l,
        Some(&normal),
        &BoardRegion::Detect,
        &WhiteOptions {
            saturation: white.clip.value,
            ..WhiteOptions::default()
        },
    )
    .map_err(|e| SessionCalibError::Channel {
        channel: ch,
        reason: format!("irradiance from the white reference: {e}"),
    })?;
    let (mut dir_err, mut irr_err) = (None, None);
    if let Some(&(t_dir, t_irr)) = truth.and_then(|t| t.channels.get(&ch)) {
        dir_err = Some(l.angle(&t_dir).to_degrees());
        let mean = irr.irradiance.iter().sum::<f64>() / 3.0;
        irr_err = Some((mean - t_irr).abs() / t_irr);
    }
    progress(&format!(
        "channel {ch}: light ({:.4}, {:.4}, {:.4}) +- {:.2} deg, irradiance ({:.4}, {:.4}, {:.4}); \
         clip level of the sphere image {}, of the white image {}",
        l.x,
        l.y,
        l.z,
        light.uncertainty_deg,
        irr.irradiance[0],
        irr.irradiance[1],
        irr.irradiance[2],
        sphere.clip,
        white.clip
    ));
    Ok(ChannelCalibration {
        channel: ch,
        light: light.summary(),
        irradiance: irr.irradiance,
        irradiance_std_error: irr.std_error,
        flat_field_spread: irr.flat_field.spread,
        sphere_clip: sphere.clip,
        white_clip: white.clip,
        warnings: irr.warnings.clone(),
        truth_dir_error_deg: dir_err,
        truth_irradiance_error: irr_err,
    })
}

/// Merges each single-light bracket, writes it to `hdr_dir` and lists it for the job with its
/// channel's calibration and its clip level; warns of values clipped in every exposure.
fn write_light_images(
    dir: &Path,
    hdr_dir: &Path,
    manifest: &Manifest,
    brackets: &Brackets<'_>,
    channels: &[ChannelCalibration],
    inputs: &Inputs,
    progress: &mut impl FnMut(&str),
) -> Result<Vec<LightImageSpec>, SessionCalibError> {
    let ambient_names = ambient_names(manifest);
    let mut light_images = Vec::new();
    let mut clipped = Vec::new();
    let single = kind_key(ShotKind::SingleLight);
    for ((k, view, ch), shots) in brackets {
        if *k != single {
            continue;
        }
        let (Some(view), Some(ch)) = (view, ch) else {
            continue;
        };
        let Some(cal) = channels.iter().find(|c| c.channel == *ch) else {
            return Err(SessionCalibError::Channel {
                channel: *ch,
                reason: "single-light shots but no calibration shots for this channel".into(),
            });
        };
        let camera =
            ambient_names
                .get(view)
                .cloned()
                .ok_or_else(|| SessionCalibError::Session {
                    dir: dir.into(),
                    reason: format!("view {view} has single-light shots but no ambient image"),
                })?;
        if inputs.model.view(&camera).is_none() {
            return Err(SessionCalibError::File {
                path: inputs.cameras.clone(),
                reason: format!("the COLMAP model has no image named {camera:?}"),
            });
        }
        let merged = merge(dir, shots)?;
        let img = merged.image;
        let file = hdr_dir.join(format!("light_v{view:03}_ch{ch}.exr"));
        if merged.clipped_everywhere > 0 {
            clipped.push((file.clone(), merged.clipped_everywhere, merged.clip));
        }
        write_exr(&file, &img, ExrPrecision::F32).map_err(|e| SessionCalibError::File {
            path: file.clone(),
            reason: e.to_string(),
        })?;
        let d = cal.light.dir_camera;
        light_images.push(LightImageSpec {
            file,
            camera,
            light_dir_camera: Vector3::new(d[0], d[1], d[2]),
            irradiance: cal.irradiance,
            mask: None,
            labels: None,
            // where even the shortest exposure clipped: the reconstruction must not fit it
            saturation: merged.clip.value.map(f64::from),
        });
    }
    if light_images.is_empty() {
        return Err(SessionCalibError::Session {
            dir: dir.into(),
            reason: "no single-light shots to reconstruct from".into(),
        });
    }
    if let Some((file, most, clip)) = clipped.iter().max_by_key(|c| c.1) {
        progress(&format!(
            "warning: {} of {} light images have channel values clipped in every exposure \
             ({} values; the most, {most}, in {}; clip level {clip}): the reconstruction \
             leaves those pixels out (a specular peak's brightest); a shorter exposure in the \
             plan's [single_light] bracket keeps them",
            clipped.len(),
            light_images.len(),
            clipped.iter().map(|c| c.1).sum::<usize>(),
            file.display(),
        ));
    }
    Ok(light_images)
}

/// Writes `job.toml` and then `calibration.json` (atomically, each).
fn write_job_and_calibration(
    dir: &Path,
    inputs: Inputs,
    light_images: Vec<LightImageSpec>,
    channels: Vec<ChannelCalibration>,
) -> Result<SessionCalibration, SessionCalibError> {
    let n_light = light_images.len();
    let job_name = Path::new(JOB_FILE);
    let job_path = dir.join(job_name);
    let job = Job {
        source: job_path.clone(),
        mesh: inputs.mesh,
        cameras: inputs.cameras,
        light_images,
        warnings: Vec::new(),
    };
    let text = job.to_toml(dir).map_err(|e| SessionCalibError::File {
        path: job_path.clone(),
        reason: e.to_string(),
    })?;
    crate::atomic::write_atomic(&job_path, text.as_bytes()).map_err(|e| {
        SessionCalibError::File {
            path: job_path.clone(),
            reason: e.to_string(),
        }
    })?;
    let out = SessionCalibration {
        format_version: CALIBRATION_FORMAT_VERSION,
        channels,
        light_images: n_light,
        job: job_name.to_path_buf(),
    };
    super::calibration_file::write(dir, &out).map_err(|e| SessionCalibError::File {
        path: dir.join(CALIBRATION_FILE),
        reason: e.to_string(),
    })?;
    Ok(out)
}

/// Calibrates a session and writes `hdr/`, `calibration.json` and `job.toml` into it: reads
/// the inputs, checks every image, merges the calibration brackets, calibrates each channel,
/// writes the single-light images and then the job and the calibration.
pub fn calibrate_session(
    dir: &Path,
    opts: &SessionCalibOptions,
    mut progress: impl FnMut(&str),
) -> Result<SessionCalibration, SessionCalibError> {
    let manifest = manifest(dir)?;
    if manifest.status != "complete" {
        progress(&format!(
            "warning: the session is `{}`; calibrating the shots it has (resume the capture to finish it)",
            manifest.status
        ));
    }
    let inputs = inputs(dir, opts)?;
    let mut brackets: Brackets = BTreeMap::new();
    for s in &manifest.shots {
        brackets
            .entry((kind_key(s.kind), s.view, s.channel))
            .or_default()
            .push(s);
    }
    verify_images(dir, &manifest)?;
    let hdr_dir = dir.join("hdr");
    let _lock = lock_and_clean(dir, &hdr_dir)?;
    std::fs::create_dir_all(&hdr_dir).map_err(|e| SessionCalibError::File {
        path: hdr_dir.clone(),
        reason: e.to_string(),
    })?;

    let shots = merge_calibration_shots(dir, &brackets, &mut progress)?;
    // The black sphere in a dark room shows only its lit side, so its outline is found in the
    // brightest-of image over every channel's shot (lit from several sides) when there are
    // several, which keeps the outline fit away from the terminator.
    let outline_img = union_max(shots.sphere.values().map(|m| &m.image));
    let axis = turntable_axis_camera(&manifest, &inputs.model);
    if axis.is_none() {
        progress(
            "warning: fewer than two ambient views at different angles in the photogrammetry \
             model: the white reference is assumed to face the bisector of light and camera",
        );
    }
    let white_key = kind_key(ShotKind::White);
    let mut channels = Vec::new();
    for &ch in shots.sphere.keys() {
        let white_angle = brackets
            .get(&(white_key, None, Some(ch)))
            .and_then(|s| s.first())
            .map(|s| s.measured_angle_deg);
        channels.push(calibrate_channel(
            ch,
            &shots,
            outline_img.as_ref(),
            white_angle,
            axis,
            &inputs,
            opts.truth.as_ref(),
            &mut progress,
        )?);
    }
    let light_images = write_light_images(
        dir,
        &hdr_dir,
        &manifest,
        &brackets,
        &channels,
        &inputs,
        &mut progress,
    )?;
    write_job_and_calibration(dir, inputs, light_images, channels)
}

/// The turntable's axis in camera axes, from the photogrammetry poses of the ambient views: the
/// camera stands still while the table turns, so `R_i R_j^T` (camera from object) is a rotation
/// about that axis by the difference of the views' measured angles, which also fixes the axis's
/// sign. Averaged over the pairs with the first view whose angles differ by 10 to 170 degrees.
fn turntable_axis_camera(
    manifest: &Manifest,
    model: &colmap::ColmapModel,
) -> Option<nalgebra::Unit<Vector3<f64>>> {
    let mut views: Vec<(f64, nalgebra::UnitQuaternion<f64>)> = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for s in &manifest.shots {
        if s.kind == ShotKind::Ambient
            && let Some(v) = s.view
            && seen.insert(v)
            && let Some((_, pose)) = model.view(&s.file)
        {
            views.push((s.measured_angle_deg, pose.rotation));
        }
    }
    let (a0, r0) = *views.first()?;
    let mut sum = Vector3::zeros();
    for (a, r) in &views[1..] {
        let turn = (a - a0 + 180.0).rem_euclid(360.0) - 180.0;
        if !(10.0..=170.0).contains(&turn.abs()) {
            continue;
        }
        let (axis, angle) = (r * r0.inverse()).axis_angle()?;
        // axis_angle returns a positive angle; the measured turn says which way the axis points
        sum += if (angle > 0.0) == (turn > 0.0) {
            axis.into_inner()
        } else {
            -axis.into_inner()
        };
    }
    (sum.norm() > 0.0).then(|| nalgebra::Unit::new_normalize(sum))
}

/// View -> the file name of its first ambient shot (the image's NAME in the COLMAP model).
fn ambient_names(m: &Manifest) -> BTreeMap<usize, String> {
    let mut names = BTreeMap::new();
    for s in &m.shots {
        if s.kind == ShotKind::Ambient
            && let Some(v) = s.view
        {
            names.entry(v).or_insert_with(|| s.file.clone());
        }
    }
    names
}

/// Per-pixel maximum over several images of one size; `None` for fewer than two.
fn union_max<'a>(imgs: impl Iterator<Item = &'a LinearImage>) -> Option<LinearImage> {
    let imgs: Vec<&LinearImage> = imgs.collect();
    if imgs.len() < 2 {
        return None;
    }
    let mut out = imgs[0].clone();
    for img in &imgs[1..] {
        if img.width() != out.width() || img.height() != out.height() {
            return None;
        }
        for (o, v) in out.data_mut().iter_mut().zip(img.data()) {
            *o = o.max(*v);
        }
    }
    Some(out)
}
