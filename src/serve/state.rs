//! What the lab page shows, as one serialisable value: the rig, the plans and sessions on
//! offer, the capture under way, who controls, the preview settings and a short log. The server
//! keeps one [`PageState`] and pushes it whole to every page when it changes (a page never
//! patches its copy, so a page that missed updates is right after the next one).
//!
//! Plain data and the small computations on it (time left, plan summaries); no I/O except
//! [`PlanInfo::from_file`] and [`SessionInfo::scan`], which read the files they describe.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::capture::plan::{CapturePlan, LabGeometry, load_plan, parse_plan};
use crate::capture::session_format::{
    JOURNAL_FILE, PLAN_FILE, current_records, read_header, read_journal, read_manifest,
};
use crate::capture::{ShotKind, VerifyReport};

/// Lines of log kept for the page.
pub const LOG_LINES: usize = 60;

#[derive(Clone, Debug, Default, Serialize)]
pub struct PageState {
    pub server: ServerInfo,
    pub rig: RigState,
    pub plans: Vec<PlanInfo>,
    pub sessions: Vec<SessionInfo>,
    pub capture: CaptureState,
    pub control: ControlInfo,
    pub preview: PreviewSettings,
    pub log: VecDeque<LogLine>,
}

impl PageState {
    /// Adds a line to the log (the oldest goes when it is full).
    pub fn log(&mut self, level: &str, text: impl Into<String>) {
        if self.log.len() >= LOG_LINES {
            self.log.pop_front();
        }
        self.log.push_back(LogLine {
            time_utc: crate::capture::session::now_utc().1,
            level: level.to_string(),
            text: text.into(),
        });
    }
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct ServerInfo {
    pub version: String,
    /// The address the server listens on.
    pub bind: String,
    /// Acting requests need `Authorization: Bearer TOKEN` (bound beyond localhost, or
    /// `--token-file` given).
    pub token_required: bool,
    pub profile: String,
    pub sessions_dir: String,
    /// A page whose connection is silent this long is gone (its capture pauses).
    pub lost_after_millis: u64,
    pub preview_fps: f64,
    pub preview_size: (usize, usize),
}

#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct RigState {
    pub connected: bool,
    pub port: String,
    pub firmware: String,
    pub protocol: String,
    pub watchdog_ms: u64,
    pub homed: bool,
    pub angle_deg: f64,
    pub target_deg: f64,
    pub moving: bool,
    /// The turntable's travel.
    pub min_angle_deg: f64,
    pub max_angle_deg: f64,
    pub lights: Vec<LightState>,
    /// What the rig is doing for a request from the page, if anything.
    pub busy: Option<String>,
    /// The last error talking to the rig (cleared by the next success).
    pub error: Option<String>,
    /// `false` while a capture runs: the values then come from the capture's own steps.
    pub polled: bool,
    /// The simulated firmware's own state (only for the simulated rig): what the board really
    /// does, read beside the serial link, not what the host believes.
    pub sim: Option<SimTruth>,
}

#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct LightState {
    pub channel: usize,
    pub name: String,
    pub level: f64,
    /// Warmed up and steady (meaningful when the level is above 0).
    pub stable: bool,
    pub max_level: f64,
    pub azimuth_deg: f64,
    pub elevation_deg: f64,
    /// theta_d this channel gives with the camera (half the angle between light and view).
    pub theta_d_deg: Option<f64>,
}

#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct SimTruth {
    pub angle_deg: f64,
    pub levels: Vec<f64>,
    pub watchdog_trips: u64,
}

impl SimTruth {
    /// The simulated firmware's own state, for the page.
    pub fn of(s: &crate::sim::SimSnapshot) -> SimTruth {
        SimTruth {
            angle_deg: s.angle_deg,
            levels: s.levels.clone(),
            watchdog_trips: s.watchdog_trips,
        }
    }
}

/// A plan on offer.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PlanInfo {
    /// What the page sends back to choose it (the file name, or `built-in`).
    pub id: String,
    pub file: String,
    pub name: String,
    pub shots: usize,
    pub ambient: usize,
    pub single_light: usize,
    pub sphere: usize,
    pub white: usize,
    pub views: usize,
    pub width: usize,
    pub height: usize,
    /// `(channel, theta_d in degrees)` of each single-light channel.
    pub theta_d: Vec<(usize, f64)>,
    /// The covered theta_d range, in degrees.
    pub theta_d_range: Option<(f64, f64)>,
    /// Why the plan cannot be used (it does not parse, or does not fit the rig).
    pub error: Option<String>,
}

/// The id of the plan built into the binary.
pub const BUILT_IN_PLAN: &str = "built-in";

impl PlanInfo {
    /// The summary of a parsed plan on a rig of this geometry.
    pub fn of(id: &str, file: &str, plan: &CapturePlan, lab: &LabGeometry) -> PlanInfo {
        let shots = plan.shots();
        let count = |k: ShotKind| shots.iter().filter(|s| s.kind == k).count();
        let theta_d = plan.theta_d(lab);
        let theta_d_range = plan.theta_d_range(lab);
        PlanInfo {
            id: id.to_string(),
            file: file.to_string(),
            name: plan.name.clone(),
            shots: shots.len(),
            ambient: count(ShotKind::Ambient),
            single_light: count(ShotKind::SingleLight),
            sphere: count(ShotKind::Sphere),
            white: count(ShotKind::White),
            views: plan.ambient.views,
            width: plan.camera.width,
            height: plan.camera.height,
            theta_d,
            theta_d_range,
            error: None,
        }
    }

    /// Reads the plan file; a plan that does not parse is listed with its error.
    pub fn from_file(path: &Path, lab: &LabGeometry, channels: usize) -> PlanInfo {
        let id = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let file = path.display().to_string();
        match load_plan(path) {
            Ok(plan) => {
                let mut info = PlanInfo::of(&id, &file, &plan, lab);
                info.error = plan.check_rig(channels).err().map(|e| e.to_string());
                info
            }
            Err(e) => PlanInfo {
                id,
                file,
                error: Some(e.to_string()),
                ..PlanInfo::default()
            },
        }
    }

    /// The plans in `dir` (`*.toml`, by name), after the built-in one.
    pub fn list(dir: Option<&Path>, lab: &LabGeometry, channels: usize) -> Vec<PlanInfo> {
        let mut out = Vec::new();
        if let Ok(plan) = parse_plan(
            crate::capture::plan::DEFAULT_PLAN_TOML,
            "capture-plans/default.toml (built in)",
        ) {
            let mut info = PlanInfo::of(BUILT_IN_PLAN, "(built in)", &plan, lab);
            info.error = plan.check_rig(channels).err().map(|e| e.to_string());
            out.push(info);
        }
        if let Some(dir) = dir {
            let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
                .map(|rd| {
                    rd.filter_map(Result::ok)
                        .map(|e| e.path())
                        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
                        .collect()
                })
                .unwrap_or_default();
            files.sort();
            out.extend(files.iter().map(|p| PlanInfo::from_file(p, lab, channels)));
        }
        out
    }
}

/// A session folder under the sessions folder.
#[derive(Clone, Debug, Default, Serialize)]
pub struct SessionInfo {
    pub name: String,
    pub plan: String,
    pub planned: usize,
    /// Journaled shots (a re-take counts once per record).
    pub journaled: usize,
    pub status: String,
    pub created_utc: String,
    /// Fewer shots journaled than planned: `capture --resume` (or the page) continues it.
    pub resumable: bool,
}

impl SessionInfo {
    /// Reads one session folder's header, journal length and manifest status; `None` when it
    /// is not a session.
    pub fn read(dir: &Path) -> Option<SessionInfo> {
        // Through the session format's own readers (typed, version-checked): a folder of
        // another format version is not listed.
        let header = read_header(dir).ok()?;
        if !dir.join(PLAN_FILE).is_file() {
            return None;
        }
        let journaled = read_journal(&dir.join(JOURNAL_FILE))
            .map(|(records, _)| current_records(records).0.len())
            .unwrap_or(0);
        let status = read_manifest(dir)
            .map(|m| m.status)
            .unwrap_or_else(|_| "unknown".into());
        Some(SessionInfo {
            name: dir.file_name()?.to_string_lossy().into_owned(),
            plan: header.plan_name.clone(),
            planned: header.planned_shots,
            journaled,
            resumable: status != "complete",
            status,
            created_utc: header.created_utc,
        })
    }

    /// The sessions in `dir`, newest first.
    pub fn scan(dir: &Path) -> Vec<SessionInfo> {
        let mut out: Vec<SessionInfo> = std::fs::read_dir(dir)
            .map(|rd| {
                rd.filter_map(Result::ok)
                    .filter(|e| e.path().is_dir())
                    .filter_map(|e| SessionInfo::read(&e.path()))
                    .collect()
            })
            .unwrap_or_default();
        out.sort_by(|a, b| b.created_utc.cmp(&a.created_utc).then(a.name.cmp(&b.name)));
        out
    }
}

/// Where a capture is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// No capture since the server started.
    #[default]
    Idle,
    /// Checking, creating the session, homing.
    Starting,
    /// Taking shots.
    Running,
    /// Waiting for the operator (guided mode): see `instruction`.
    Waiting,
    /// A stop was asked for; the run ends at its next safe point.
    Stopping,
    /// Stopped at a safe point with the light off; resumable.
    Paused,
    /// Stopped by abort; the session keeps its shots and stays resumable.
    Aborted,
    /// Every planned shot is in the session.
    Complete,
    /// Stopped by an error; the session keeps its shots and stays resumable.
    Failed,
}

impl Phase {
    /// A run holds the rig (the page's rig buttons are refused).
    pub fn is_active(self) -> bool {
        matches!(
            self,
            Phase::Starting | Phase::Running | Phase::Waiting | Phase::Stopping
        )
    }
}

/// What the operator must do now (guided mode).
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct Instruction {
    /// Increases with every instruction; Continue names the one it answers.
    pub seq: u64,
    pub steps: Vec<String>,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct LastShot {
    pub id: String,
    pub kind: String,
    pub angle_deg: f64,
    pub channel: Option<usize>,
    pub exposure_secs: f64,
}

/// A session's checksum check at the end of a run (`session verify`).
#[derive(Clone, Debug, Default, Serialize)]
pub struct VerifyInfo {
    pub intact: bool,
    pub complete: bool,
    pub checked: usize,
    pub planned: usize,
    pub bytes: u64,
    pub problems: Vec<String>,
    pub retaken: usize,
}

impl VerifyInfo {
    pub fn of(r: &VerifyReport) -> VerifyInfo {
        VerifyInfo {
            intact: r.intact(),
            complete: r.complete(),
            checked: r.checked,
            planned: r.planned,
            bytes: r.bytes,
            problems: r.problems.iter().map(|p| p.to_string()).collect(),
            retaken: r.retaken.len(),
        }
    }
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct CaptureState {
    pub phase: Phase,
    /// Session folder name (under the sessions folder) and full path.
    pub session: Option<String>,
    pub dir: Option<String>,
    pub guided: bool,
    pub resumed: bool,
    pub plan: String,
    pub total: usize,
    /// Shots in the session (journaled before this run and taken by it).
    pub done: usize,
    /// Shots taken by this run.
    pub taken_now: usize,
    pub retakes: usize,
    pub started_unix: f64,
    /// Shots per second of this run so far (time waiting for the operator excluded).
    pub rate_per_sec: Option<f64>,
    /// Time left at that rate, seconds.
    pub eta_secs: Option<f64>,
    pub last_shot: Option<LastShot>,
    pub instruction: Option<Instruction>,
    /// Why the run stopped (paused, aborted, failed).
    pub stop_reason: Option<String>,
    /// The command that continues the session from a terminal.
    pub resume_command: Option<String>,
    /// Wall time of the finished run, seconds.
    pub wall_secs: Option<f64>,
    pub verify: Option<VerifyInfo>,
    /// The page's link to the session report.
    pub report_url: Option<String>,
}

/// Time left at the run's own pace: `remaining / rate`, rate = shots taken by this run over the
/// time it spent taking them (waiting for the operator excluded). `None` before the first shot.
pub fn eta_secs(taken_now: usize, busy_secs: f64, remaining: usize) -> (Option<f64>, Option<f64>) {
    if taken_now == 0 || busy_secs <= 0.0 {
        return (None, None);
    }
    let rate = taken_now as f64 / busy_secs;
    (Some(rate), Some(remaining as f64 / rate))
}

/// Who is connected and who controls.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ControlInfo {
    /// The controlling page, if any.
    pub controller: Option<ClientInfo>,
    /// Every connected page (the controller too).
    pub clients: Vec<ClientInfo>,
}

#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct ClientInfo {
    /// A public number for the page (its key stays secret).
    pub number: u64,
    pub name: String,
    pub address: String,
    pub since_utc: String,
}

#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PreviewSettings {
    pub exposure_secs: f64,
    pub gain: f64,
    /// Why live frames are not available, when they are not (a DSLR has no live view here).
    pub unavailable: Option<String>,
}

impl Default for PreviewSettings {
    fn default() -> Self {
        Self {
            exposure_secs: 0.02,
            gain: 1.0,
            unavailable: None,
        }
    }
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct LogLine {
    pub time_utc: String,
    pub level: String,
    pub text: String,
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    use super::*;

    #[test]
    fn time_left_is_the_remaining_shots_at_the_runs_rate() {
        assert_eq!(eta_secs(0, 10.0, 5), (None, None));
        let (rate, eta) = eta_secs(10, 5.0, 30);
        assert_eq!(rate, Some(2.0));
        assert_eq!(eta, Some(15.0));
    }

    #[test]
    fn the_log_keeps_the_last_lines() {
        let mut s = PageState::default();
        for i in 0..LOG_LINES + 5 {
            s.log("info", format!("line {i}"));
        }
        assert_eq!(s.log.len(), LOG_LINES);
        assert_eq!(s.log.front().unwrap().text, "line 5");
    }

    #[test]
    fn plans_list_their_theta_d_coverage_and_refuse_what_the_rig_lacks() {
        let lab = LabGeometry {
            camera_distance_m: 0.6,
            camera_elevation_deg: 0.0,
            vertical_fov_deg: 30.0,
            lights: vec![(20.0, 0.0), (60.0, 0.0), (110.0, 0.0)],
        };
        let tmp = tempfile::tempdir().unwrap();
        std::fs::write(
            tmp.path().join("quick.toml"),
            include_str!("../../capture-plans/quick.toml"),
        )
        .unwrap();
        std::fs::write(tmp.path().join("broken.toml"), "name = 3\n").unwrap();
        let plans = PlanInfo::list(Some(tmp.path()), &lab, 3);
        assert_eq!(plans.len(), 3);
        assert_eq!(plans[0].id, BUILT_IN_PLAN);
        let quick = plans.iter().find(|p| p.id == "quick.toml").unwrap();
        assert_eq!(quick.shots, 63);
        assert!(quick.error.is_none());
        let (lo, hi) = quick.theta_d_range.unwrap();
        assert!((lo - 10.0).abs() < 1e-9 && (hi - 55.0).abs() < 1e-9);
        let broken = plans.iter().find(|p| p.id == "broken.toml").unwrap();
        assert!(broken.error.as_ref().unwrap().contains("broken.toml"));
        let two = PlanInfo::list(Some(tmp.path()), &lab, 2);
        assert!(two[0].error.as_ref().unwrap().contains("channel"));
    }
}
