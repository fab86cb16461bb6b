//! Capture plans: what to shoot, read from TOML (`capture-plans/`), validated, and expanded into
//! the ordered list of shots a session takes.
//!
//! Conventions: angles in degrees in the file (operators think in degrees), exposures in seconds,
//! settle times in milliseconds, distances in metres. The lab frame (the rig profile's) has the
//! turntable centre at the origin, z up, and the camera at azimuth 0 (towards +x); a light's
//! azimuth is measured about z from the camera's, its elevation up from the turntable plane.
//! Light directions come from the rig profile, not the plan: the plan says which channels.
//!
//! Order of the shots (fixed, so a resumed session takes the same shots): every ambient view
//! (room light on, turntable stepping once round), then the single-light shots of the chosen views
//! (room light off), then the black sphere and the white reference under each channel. Within a
//! view or a calibration target: channel by channel, and the exposure bracket innermost, so the
//! turntable and the light change as rarely as possible.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;
use std::path::Path;

use super::error::CaptureError;

/// The plan used when none is given: the paper's setup (55 ambient views, 11 single-light views).
pub const DEFAULT_PLAN_TOML: &str = include_str!("../../capture-plans/default.toml");

/// The version of the plan format this tool reads; a plan without `format_version` is version 1.
pub const PLAN_FORMAT_VERSION: u32 = 1;

/// A capture plan as written in TOML (this module owns the format; a session keeps its plan
/// verbatim as `capture::session::PLAN_FILE`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CapturePlan {
    /// Absent in plans written before versions were recorded: version 1.
    #[serde(default = "crate::format::version_1")]
    pub format_version: u32,
    pub name: String,
    #[serde(default)]
    pub camera: CameraPlan,
    pub ambient: AmbientPlan,
    pub single_light: SingleLightPlan,
    #[serde(default)]
    pub calibration: CalibrationPlan,
    #[serde(default)]
    pub settle: SettlePlan,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPlan {
    /// Image size of the simulated camera; real cameras use their own.
    pub width: usize,
    pub height: usize,
    pub gain: f64,
}

impl Default for CameraPlan {
    fn default() -> Self {
        Self {
            width: 320,
            height: 240,
            gain: 1.0,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AmbientPlan {
    /// Number of views, evenly spaced over one turn starting at `start_deg`.
    pub views: usize,
    #[serde(default)]
    pub start_deg: f64,
    pub exposures_secs: Vec<f64>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SingleLightPlan {
    /// Every `every`-th ambient view gets single-light shots (views 0, every, 2 every, ...).
    #[serde(default)]
    pub every: Option<usize>,
    /// Or an explicit list of ambient view indices.
    #[serde(default)]
    pub views: Option<Vec<usize>>,
    pub channels: Vec<usize>,
    #[serde(default = "one")]
    pub level: f64,
    pub exposures_secs: Vec<f64>,
}

fn one() -> f64 {
    1.0
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrationPlan {
    pub sphere: bool,
    pub white: bool,
    /// Defaults to the single-light bracket when empty.
    #[serde(default)]
    pub exposures_secs: Vec<f64>,
}

impl Default for CalibrationPlan {
    fn default() -> Self {
        Self {
            sphere: true,
            white: true,
            exposures_secs: Vec::new(),
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SettlePlan {
    /// Wait after the turntable reports at rest (vibration dies out).
    pub turntable_millis: u64,
    /// Wait after a light reports stable.
    pub light_millis: u64,
}

impl Default for SettlePlan {
    fn default() -> Self {
        Self {
            turntable_millis: 200,
            light_millis: 100,
        }
    }
}

/// Nominal rig geometry in the lab frame (see the module header): from the rig profile's light
/// channels and the camera placement.
#[derive(Clone, Debug, PartialEq)]
pub struct LabGeometry {
    pub camera_distance_m: f64,
    pub camera_elevation_deg: f64,
    pub vertical_fov_deg: f64,
    /// `(azimuth_deg, elevation_deg)` of each light channel, by channel number.
    pub lights: Vec<(f64, f64)>,
}

/// Unit vector for an azimuth about z from +x and an elevation above the xy plane.
pub fn unit_from_angles(azimuth_deg: f64, elevation_deg: f64) -> Vector3<f64> {
    let (az, el) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    Vector3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
}

impl LabGeometry {
    /// Unit vector from the turntable centre towards the camera (lab frame).
    pub fn camera_dir_lab(&self) -> Vector3<f64> {
        unit_from_angles(0.0, self.camera_elevation_deg)
    }

    /// Unit vector from the turntable centre towards light `channel` (lab frame).
    pub fn light_dir_lab(&self, channel: usize) -> Option<Vector3<f64>> {
        self.lights
            .get(channel)
            .map(|&(az, el)| unit_from_angles(az, el))
    }

    /// theta_d of a far light and camera at the turntable centre: half the angle between the
    /// light and view directions. The same for every pixel and every turntable angle.
    pub fn theta_d_deg(&self, channel: usize) -> Option<f64> {
        let l = self.light_dir_lab(channel)?;
        let v = self.camera_dir_lab();
        Some(0.5 * l.dot(&v).clamp(-1.0, 1.0).acos().to_degrees())
    }
}

/// What a shot photographs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ShotKind {
    /// The object under room light, for photogrammetry.
    Ambient,
    /// The object under one light channel, room light off.
    SingleLight,
    /// The black glossy sphere under one channel (light direction).
    Sphere,
    /// The white reference under one channel (irradiance).
    White,
}

impl ShotKind {
    /// What must be on the turntable and whether the room light is on.
    pub fn stage(self) -> Stage {
        match self {
            ShotKind::Ambient => Stage {
                target: Target::Object,
                room_light: true,
            },
            ShotKind::SingleLight => Stage {
                target: Target::Object,
                room_light: false,
            },
            ShotKind::Sphere => Stage {
                target: Target::Sphere,
                room_light: false,
            },
            ShotKind::White => Stage {
                target: Target::White,
                room_light: false,
            },
        }
    }
}

/// What stands on the turntable.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Target {
    Object,
    Sphere,
    White,
}

/// The state of the scene a shot needs, which only the operator can set.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct Stage {
    pub target: Target,
    pub room_light: bool,
}

/// One shot of the expanded plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlannedShot {
    /// Position in the plan (0-based).
    pub index: usize,
    /// Stable identifier, unique in the plan: e.g. `light/v005/ch1/e2`.
    pub id: String,
    pub kind: ShotKind,
    /// Ambient view index (ambient and single-light shots).
    pub view: Option<usize>,
    pub angle_deg: f64,
    /// Lit channel (single-light and calibration shots); none = all rig lights off.
    pub channel: Option<usize>,
    pub level: f64,
    pub exposure_secs: f64,
    /// Position in the exposure bracket.
    pub bracket: usize,
    pub gain: f64,
    /// Image file relative to the session folder.
    pub file: String,
}

/// Reads and validates a plan file.
pub fn load_plan(path: &Path) -> Result<CapturePlan, CaptureError> {
    let text = std::fs::read_to_string(path).map_err(|source| CaptureError::Io {
        what: "reading the capture plan".into(),
        path: path.to_path_buf(),
        source,
    })?;
    parse_plan(&text, &path.display().to_string())
}

/// Parses and validates a plan; `origin` names it in errors.
pub fn parse_plan(text: &str, origin: &str) -> Result<CapturePlan, CaptureError> {
    let plan: CapturePlan = toml::from_str(text).map_err(|e| CaptureError::Plan {
        origin: origin.to_string(),
        reason: e.to_string(),
    })?;
    if plan.format_version != PLAN_FORMAT_VERSION {
        return Err(CaptureError::Plan {
            origin: origin.to_string(),
            reason: format!(
                "format_version {}, but this brdf-rig reads plan version {PLAN_FORMAT_VERSION}",
                plan.format_version
            ),
        });
    }
    plan.validate().map_err(|e| CaptureError::Plan {
        origin: origin.to_string(),
        reason: e.to_string(),
    })?;
    Ok(plan)
}

/// The embedded default plan.
#[allow(clippy::expect_used)] // an invariant: the embedded file is checked by a unit test
pub fn default_plan() -> CapturePlan {
    // The embedded file is checked by a unit test; a failure here is a build defect.
    parse_plan(DEFAULT_PLAN_TOML, "capture-plans/default.toml (embedded)")
        .expect("the embedded default plan is valid")
}

/// What is wrong with a plan, named by its field (`single_light.views[2]`); the file is named
/// by the caller ([`CaptureError::Plan`]).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlanError {
    #[error("{field}: at least one exposure is needed")]
    NoExposure { field: &'static str },
    #[error("{field}[{index}] = {value}: an exposure must be in (0, 60] seconds")]
    Exposure {
        field: &'static str,
        index: usize,
        value: f64,
    },
    #[error("camera.width/height = {width}x{height}: must be between 8 and 20000 pixels")]
    ImageSize { width: usize, height: usize },
    #[error("camera.gain = {0}: must be positive")]
    Gain(f64),
    #[error("ambient.views = {0}: must be between 1 and 3600")]
    Views(usize),
    #[error("ambient.start_deg: must be a finite angle")]
    StartAngle,
    #[error("single_light: give either `every` or `views`, not both")]
    EveryAndViews,
    #[error("single_light.every = 0: must be at least 1")]
    EveryZero,
    #[error(
        "single_light.views[{index}] = {view}: there are only {views} ambient views (0..{last})"
    )]
    View {
        index: usize,
        view: usize,
        views: usize,
        last: usize,
    },
    #[error("single_light.level = {0}: must be in (0, 1]")]
    Level(f64),
    #[error("single_light.channels[{index}] = {channel}: channel listed twice")]
    ChannelTwice { index: usize, channel: usize },
    #[error("single_light.channels: at least one light channel is needed")]
    NoChannel,
    #[error("single_light.channels contains {channel}, but the light reports {count} channel(s)")]
    MissingChannel { channel: usize, count: usize },
}

fn check_exposures(field: &'static str, values: &[f64]) -> Result<(), PlanError> {
    if values.is_empty() {
        return Err(PlanError::NoExposure { field });
    }
    for (i, e) in values.iter().enumerate() {
        if !(e.is_finite() && *e > 0.0 && *e <= 60.0) {
            return Err(PlanError::Exposure {
                field,
                index: i,
                value: *e,
            });
        }
    }
    Ok(())
}

impl CapturePlan {
    /// Checks the plan on its own (the rig's channel count is checked by [`Self::check_rig`]).
    pub fn validate(&self) -> Result<(), PlanError> {
        let c = &self.camera;
        if c.width < 8 || c.height < 8 || c.width > 20_000 || c.height > 20_000 {
            return Err(PlanError::ImageSize {
                width: c.width,
                height: c.height,
            });
        }
        if !(c.gain.is_finite() && c.gain > 0.0) {
            return Err(PlanError::Gain(c.gain));
        }
        if self.ambient.views == 0 || self.ambient.views > 3600 {
            return Err(PlanError::Views(self.ambient.views));
        }
        if !self.ambient.start_deg.is_finite() {
            return Err(PlanError::StartAngle);
        }
        check_exposures("ambient.exposures_secs", &self.ambient.exposures_secs)?;
        let sl = &self.single_light;
        match (sl.every, &sl.views) {
            (Some(_), Some(_)) => return Err(PlanError::EveryAndViews),
            (Some(0), None) => return Err(PlanError::EveryZero),
            (_, Some(v)) => {
                for (i, &view) in v.iter().enumerate() {
                    if view >= self.ambient.views {
                        return Err(PlanError::View {
                            index: i,
                            view,
                            views: self.ambient.views,
                            last: self.ambient.views - 1,
                        });
                    }
                }
            }
            _ => {}
        }
        if !(sl.level > 0.0 && sl.level <= 1.0) {
            return Err(PlanError::Level(sl.level));
        }
        for (i, &ch) in sl.channels.iter().enumerate() {
            if sl.channels[..i].contains(&ch) {
                return Err(PlanError::ChannelTwice {
                    index: i,
                    channel: ch,
                });
            }
        }
        let needs_light = !self.single_light_views().is_empty()
            || self.calibration.sphere
            || self.calibration.white;
        if needs_light {
            if sl.channels.is_empty() {
                return Err(PlanError::NoChannel);
            }
            check_exposures("single_light.exposures_secs", &sl.exposures_secs)?;
        }
        if !self.calibration.exposures_secs.is_empty() {
            check_exposures(
                "calibration.exposures_secs",
                &self.calibration.exposures_secs,
            )?;
        }
        Ok(())
    }

    /// Checks the plan against the rig: every planned channel must exist.
    pub fn check_rig(&self, channel_count: usize) -> Result<(), PlanError> {
        if let Some(&ch) = self
            .single_light
            .channels
            .iter()
            .find(|&&ch| ch >= channel_count)
        {
            return Err(PlanError::MissingChannel {
                channel: ch,
                count: channel_count,
            });
        }
        Ok(())
    }

    /// Turntable angle of ambient view `view`, in [0, 360).
    pub fn view_angle_deg(&self, view: usize) -> f64 {
        let step = 360.0 / self.ambient.views as f64;
        (self.ambient.start_deg + step * view as f64).rem_euclid(360.0)
    }

    /// The ambient views that also get single-light shots, ascending.
    pub fn single_light_views(&self) -> Vec<usize> {
        let mut v = match (&self.single_light.views, self.single_light.every) {
            (Some(v), _) => v.clone(),
            (None, Some(every)) if every > 0 => (0..self.ambient.views).step_by(every).collect(),
            _ => Vec::new(),
        };
        v.sort_unstable();
        v.dedup();
        v
    }

    fn calibration_exposures(&self) -> &[f64] {
        if self.calibration.exposures_secs.is_empty() {
            &self.single_light.exposures_secs
        } else {
            &self.calibration.exposures_secs
        }
    }

    /// Expands the plan into the ordered list of shots (see the module header).
    pub fn shots(&self) -> Vec<PlannedShot> {
        let mut shots = Vec::new();
        let gain = self.camera.gain;
        let mut push =
            |kind, view, angle_deg, channel, level, exposure_secs, bracket, id: String| {
                let file = format!("{}.exr", id.replace('/', "_").replacen('_', "/", 1));
                shots.push(PlannedShot {
                    index: shots.len(),
                    id,
                    kind,
                    view,
                    angle_deg,
                    channel,
                    level,
                    exposure_secs,
                    bracket,
                    gain,
                    file,
                });
            };
        for view in 0..self.ambient.views {
            let angle = self.view_angle_deg(view);
            for (b, &e) in self.ambient.exposures_secs.iter().enumerate() {
                let id = format!("ambient/v{view:03}/e{b}");
                push(ShotKind::Ambient, Some(view), angle, None, 0.0, e, b, id);
            }
        }
        let level = self.single_light.level;
        for view in self.single_light_views() {
            let angle = self.view_angle_deg(view);
            for &ch in &self.single_light.channels {
                for (b, &e) in self.single_light.exposures_secs.iter().enumerate() {
                    let id = format!("light/v{view:03}/ch{ch}/e{b}");
                    push(
                        ShotKind::SingleLight,
                        Some(view),
                        angle,
                        Some(ch),
                        level,
                        e,
                        b,
                        id,
                    );
                }
            }
        }
        let calib = self.calibration_exposures().to_vec();
        for (enabled, kind, name) in [
            (self.calibration.sphere, ShotKind::Sphere, "sphere"),
            (self.calibration.white, ShotKind::White, "white"),
        ] {
            if !enabled {
                continue;
            }
            for &ch in &self.single_light.channels {
                for (b, &e) in calib.iter().enumerate() {
                    let id = format!("calib/{name}/ch{ch}/e{b}");
                    push(kind, None, 0.0, Some(ch), level, e, b, id);
                }
            }
        }
        shots
    }

    /// `(channel, theta_d in degrees)` of each single-light channel on a rig of this geometry
    /// (channels the rig lacks are left out; [`Self::check_rig`] refuses them).
    pub fn theta_d(&self, lab: &LabGeometry) -> Vec<(usize, f64)> {
        self.single_light
            .channels
            .iter()
            .filter_map(|&ch| Some((ch, lab.theta_d_deg(ch)?)))
            .collect()
    }

    /// The theta_d range `(lowest, highest)` the single-light channels cover, in degrees.
    pub fn theta_d_range(&self, lab: &LabGeometry) -> Option<(f64, f64)> {
        self.theta_d(lab)
            .into_iter()
            .fold(None, |range, (_, td)| match range {
                None => Some((td, td)),
                Some((lo, hi)) => Some((f64::min(lo, td), f64::max(hi, td))),
            })
    }

    /// A human summary: shot counts, the theta_d each channel gives, and the covered range.
    pub fn summary(&self, lab: &LabGeometry) -> String {
        let shots = self.shots();
        let count = |k: ShotKind| shots.iter().filter(|s| s.kind == k).count();
        let mut s = String::new();
        let _ = writeln!(
            s,
            "plan `{}`: {} shots ({} ambient over {} views, {} single-light over {} views, {} sphere, {} white), images {}x{}",
            self.name,
            shots.len(),
            count(ShotKind::Ambient),
            self.ambient.views,
            count(ShotKind::SingleLight),
            self.single_light_views().len(),
            count(ShotKind::Sphere),
            count(ShotKind::White),
            self.camera.width,
            self.camera.height,
        );
        for (ch, td) in self.theta_d(lab) {
            if let Some(&(az, el)) = lab.lights.get(ch) {
                let _ = writeln!(
                    s,
                    "  channel {ch}: light at azimuth {az:.1} deg, elevation {el:.1} deg -> theta_d = {td:.1} deg"
                );
            }
        }
        if let Some((lo, hi)) = self.theta_d_range(lab) {
            let _ = writeln!(
                s,
                "  theta_d covered: {lo:.1} .. {hi:.1} deg (of 0 .. 90; one value per channel, nominal geometry)"
            );
        }
        s
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn a_plan_of_another_version_is_refused_by_name() {
        let v1 = format!("format_version = 1\n{DEFAULT_PLAN_TOML}");
        assert_eq!(parse_plan(&v1, "p.toml").unwrap(), default_plan());
        let v2 = format!("format_version = 2\n{DEFAULT_PLAN_TOML}");
        let e = parse_plan(&v2, "p.toml").unwrap_err().to_string();
        assert!(
            e.contains("p.toml") && e.contains("format_version 2"),
            "{e}"
        );
    }

    #[test]
    fn default_plan_is_the_papers_setup() {
        let plan = default_plan();
        assert_eq!(plan.ambient.views, 55);
        assert_eq!(plan.single_light_views().len(), 11);
        let shots = plan.shots();
        let ids: HashSet<_> = shots.iter().map(|s| s.id.clone()).collect();
        let files: HashSet<_> = shots.iter().map(|s| s.file.clone()).collect();
        assert_eq!(ids.len(), shots.len(), "ids unique");
        assert_eq!(files.len(), shots.len(), "files unique");
        assert_eq!(shots[0].file, "ambient/v000_e0.exr");
        assert!(shots.iter().all(|s| s.index < shots.len()));
        let light: Vec<_> = shots
            .iter()
            .filter(|s| s.kind == ShotKind::SingleLight)
            .collect();
        assert_eq!(light.len(), 11 * 3 * 3);
        assert_eq!(light[0].file, "light/v000_ch0_e0.exr");
        assert!(plan.summary(&test_lab()).contains("theta_d covered"));
    }

    #[test]
    fn quick_plan_parses() {
        let text = include_str!("../../capture-plans/quick.toml");
        let plan = parse_plan(text, "quick.toml").unwrap();
        assert!(plan.shots().len() < 80);
    }

    fn test_lab() -> LabGeometry {
        LabGeometry {
            camera_distance_m: 0.6,
            camera_elevation_deg: 0.0,
            vertical_fov_deg: 30.0,
            lights: vec![(20.0, 0.0), (60.0, 0.0), (110.0, 0.0)],
        }
    }

    #[test]
    fn theta_d_matches_a_closed_form() {
        let mut lab = test_lab();
        // camera and light both in the turntable plane: theta_d is half the azimuth
        assert!((lab.theta_d_deg(1).unwrap() - 30.0).abs() < 1e-9);
        // light straight up, camera at 0 elevation: 45
        lab.lights[0] = (0.0, 90.0);
        assert!((lab.theta_d_deg(0).unwrap() - 45.0).abs() < 1e-9);
        assert!(lab.theta_d_deg(7).is_none());
    }

    #[test]
    fn errors_name_the_field_and_line() {
        let bad = DEFAULT_PLAN_TOML.replace("channels = [0, 1, 2]", "channels = [0, 0]");
        let err = parse_plan(&bad, "x.toml").unwrap_err().to_string();
        assert!(
            err.contains("x.toml") && err.contains("single_light.channels[1] = 0"),
            "{err}"
        );
        let bad = DEFAULT_PLAN_TOML.replace("views = 55", "views = \"many\"");
        let err = parse_plan(&bad, "x.toml").unwrap_err().to_string();
        assert!(err.contains("line") && err.contains("views"), "{err}");
        let bad = DEFAULT_PLAN_TOML.replace("exposures_secs = [0.02]", "exposures_secs = [-1.0]");
        let err = parse_plan(&bad, "x.toml").unwrap_err().to_string();
        assert!(err.contains("ambient.exposures_secs[0]"), "{err}");
        let plan = default_plan();
        assert!(
            plan.check_rig(2)
                .unwrap_err()
                .to_string()
                .contains("2 channel")
        );
        assert!(plan.check_rig(3).is_ok());
    }
}
