//! The session runner: takes the remaining shots of a session with any turntable, light and
//! camera (the device traits), asking an [`Operator`] for what only a person can do (room light,
//! placing the sphere and the white reference).
//!
//! The seams a front end plugs into (the terminal of `brdf-rig capture`, the lab page of
//! `brdf-rig serve`): the [`Operator`] is told each change of stage and returns when the person
//! has done it; [`Progress`] is told each step, each shot and its image; the cancel flag of
//! [`RunOptions`] asks the run to stop at its next safe point. Safe points come before each
//! shot, after the operator's part, after each move (before a light is switched on) and before
//! the camera fires; a run that stops there ends like any other, light off and snapshot written.
//!
//! Guarantees: the light is switched off when the run ends, whether it finished, failed or was
//! cancelled (Ctrl-C sets the cancel flag, checked between steps); a shot is in the session only
//! once its image is on disk and its record is journaled (see `session`), so an interrupted run
//! can be resumed without losing or repeating a shot. A resumed session's remaining shots include
//! those whose image was found missing or damaged (`Session::repairs`), taken again in plan order.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use super::error::CaptureError;
use super::plan::{LabGeometry, PlannedShot, ShotKind, Stage, Target};
use super::session::{Session, ShotRecord, now_utc};
use crate::devices::{Camera, DeviceError, Light, ShotSettings, Turntable};
use crate::imageio::{ExrPrecision, encode_exr};
use crate::render::image::LinearImage;

/// Whoever sets up what the rig cannot: the room light, what stands on the turntable.
pub trait Operator {
    /// Brings the scene from `from` (unknown at the start of a run) to `to`; returns when done.
    fn set_stage(&mut self, from: Option<Stage>, to: Stage) -> Result<(), CaptureError>;
}

/// The instruction for a change of stage, as the operator reads it.
pub fn stage_instructions(from: Option<Stage>, to: Stage) -> Vec<String> {
    let mut steps = Vec::new();
    if from.map(|f| f.target) != Some(to.target) {
        steps.push(match to.target {
            Target::Object => "Place the object at the centre of the turntable.".to_string(),
            Target::Sphere => {
                "Remove what is on the turntable and place the black glossy sphere at its centre."
                    .to_string()
            }
            Target::White => {
                "Remove the sphere and place the white reference target at the centre of the turntable, facing the camera."
                    .to_string()
            }
        });
    }
    if from.map(|f| f.room_light) != Some(to.room_light) {
        steps.push(if to.room_light {
            "Switch the room lights ON (ambient shots for photogrammetry).".to_string()
        } else {
            "Switch the room lights OFF and block stray light (single-light shots).".to_string()
        });
    }
    steps
}

/// An operator that is not there: assumes the stage is already right (unattended mode).
pub struct Unattended;

impl Operator for Unattended {
    fn set_stage(&mut self, _from: Option<Stage>, _to: Stage) -> Result<(), CaptureError> {
        Ok(())
    }
}

/// Told after each step; the CLI draws progress bars with it, the lab page pushes it to browsers.
pub trait Progress {
    fn start(&mut self, _total: usize, _already_done: usize) {}
    fn shot_done(&mut self, _record: &ShotRecord) {}
    /// The image of the shot just journaled (after [`Progress::shot_done`]), for a preview.
    /// Called on the run's thread: keep it short (hand the image over, do not encode it here).
    fn shot_image(&mut self, _record: &ShotRecord, _image: &LinearImage) {}
    fn message(&mut self, _text: &str) {}
    fn finish(&mut self) {}
}

/// No progress output.
pub struct Quiet;
impl Progress for Quiet {}

/// Where a test may kill the process in the middle of a shot (see [`RunOptions::kill_hook`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KillPhase {
    /// After the camera returned, before the image is written.
    BeforeImage,
    /// After the image is on disk, before its journal record.
    AfterImage,
    /// After the journal record, before anything else.
    AfterJournal,
}

impl KillPhase {
    pub fn parse(s: &str) -> Option<Self> {
        match s {
            "before-image" => Some(Self::BeforeImage),
            "after-image" => Some(Self::AfterImage),
            "after-journal" => Some(Self::AfterJournal),
            _ => None,
        }
    }
}

/// Options of one run.
#[derive(Clone)]
pub struct RunOptions {
    /// Set by Ctrl-C; checked between steps.
    pub cancel: Arc<AtomicBool>,
    /// Home the turntable before the first move.
    pub home: bool,
    /// Test hook: `(n, phase)` kills this process with SIGKILL at `phase` of the n-th shot this
    /// run takes (0-based). Only the CLI sets it, from `BRDF_RIG_TEST_KILL_AT`.
    pub kill_hook: Option<(usize, KillPhase)>,
    /// Write `manifest.json` at least every this many shots (also at every stage change).
    pub snapshot_every: usize,
    /// Nominal rig geometry, to record each shot's light direction.
    pub lab: Option<LabGeometry>,
    /// The turntable's travel `(min_deg, max_deg)`: with it, moves take the shorter way round.
    pub angle_range: Option<(f64, f64)>,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            cancel: Arc::new(AtomicBool::new(false)),
            home: true,
            kill_hook: None,
            snapshot_every: 16,
            lab: None,
            angle_range: None,
        }
    }
}

/// What a run did, with timings for the benchmark.
#[derive(Clone, Debug, Default)]
pub struct RunSummary {
    pub shots_taken: usize,
    /// Of `shots_taken`, shots whose journaled image a resume found missing or damaged.
    pub retakes: usize,
    pub shots_total: usize,
    pub complete: bool,
    pub wall: Duration,
    /// Time in device calls (turntable, light, camera) and the settle waits.
    pub device_time: Duration,
    pub camera_time: Duration,
    pub settle_time: Duration,
    /// Time encoding, checksumming, writing images, journaling and snapshotting.
    pub storage_time: Duration,
}

impl RunSummary {
    /// Controller time per shot: everything but devices, settling and storage.
    pub fn overhead_per_shot(&self) -> Duration {
        let busy = self.device_time + self.storage_time;
        self.wall
            .saturating_sub(busy)
            .checked_div(self.shots_taken.max(1) as u32)
            .unwrap_or_default()
    }
}

fn kill_self() -> ! {
    // A real SIGKILL, as a crash or `kill -9` would deliver: no destructor, no flush.
    let pid = std::process::id().to_string();
    let _ = std::process::Command::new("kill")
        .args(["-KILL", &pid])
        .status();
    std::process::abort()
}

struct Devices<'a> {
    turntable: &'a mut dyn Turntable,
    light: &'a mut dyn Light,
    camera: &'a mut dyn Camera,
}

fn dev(shot: &PlannedShot, source: DeviceError) -> CaptureError {
    CaptureError::Device {
        shot: shot.id.clone(),
        source,
    }
}

/// Takes every remaining shot of `session`. The light is off when this returns.
pub fn run_session(
    session: &mut Session,
    turntable: &mut dyn Turntable,
    light: &mut dyn Light,
    camera: &mut dyn Camera,
    operator: &mut dyn Operator,
    progress: &mut dyn Progress,
    options: &RunOptions,
) -> Result<RunSummary, CaptureError> {
    let mut d = Devices {
        turntable,
        light,
        camera,
    };
    let start = Instant::now();
    let mut summary = RunSummary {
        shots_total: session.planned().len(),
        ..RunSummary::default()
    };
    let result = take_shots(session, &mut d, operator, progress, options, &mut summary);
    // Whatever happened, the light goes off and the snapshot matches the journal.
    let off = d.light.off(None);
    let complete = session.is_complete();
    let snap = session.write_snapshot(complete);
    progress.finish();
    summary.wall = start.elapsed();
    summary.complete = complete;
    result?;
    off.map_err(|source| CaptureError::Device {
        shot: "switching the light off at the end".into(),
        source,
    })?;
    snap?;
    Ok(summary)
}

/// The turntable angle of a shot. The white reference stands facing the camera at angle 0; for
/// each channel it is turned to face the bisector of camera and light (half the channel's
/// azimuth), so a light from the side still lights it and `cos(theta_i) = cos(theta_o)`.
/// `None` for the sphere, which is shot wherever the table stands.
pub fn shot_angle(shot: &PlannedShot, lab: Option<&LabGeometry>) -> Option<f64> {
    match (shot.kind, shot.channel, lab) {
        (ShotKind::Sphere, _, _) => None,
        (ShotKind::White, Some(ch), Some(lab)) => Some(
            lab.lights
                .get(ch)
                .map(|&(az, _)| (0.5 * az).rem_euclid(360.0))
                .unwrap_or(shot.angle_deg),
        ),
        _ => Some(shot.angle_deg),
    }
}

/// The position equivalent to `target` (modulo 360) nearest to `from`, within `range`
/// (the turntable's limits); `target` itself when there is no range or no current position.
pub fn nearest_equivalent(target: f64, from: Option<f64>, range: Option<(f64, f64)>) -> f64 {
    let (Some(from), Some((lo, hi))) = (from, range) else {
        return target;
    };
    let mut best: Option<f64> = None;
    for k in -3..=3 {
        let c = target + 360.0 * f64::from(k);
        if c < lo - 1e-9 || c > hi + 1e-9 {
            continue;
        }
        if best.is_none_or(|b| (c - from).abs() < (b - from).abs()) {
            best = Some(c);
        }
    }
    best.unwrap_or(target)
}

fn check_cancel(session: &Session, options: &RunOptions) -> Result<(), CaptureError> {
    if options.cancel.load(Ordering::SeqCst) {
        return Err(CaptureError::Interrupted {
            done: session.records().len(),
            total: session.planned().len(),
        });
    }
    Ok(())
}

fn take_shots(
    session: &mut Session,
    d: &mut Devices<'_>,
    operator: &mut dyn Operator,
    progress: &mut dyn Progress,
    options: &RunOptions,
    summary: &mut RunSummary,
) -> Result<(), CaptureError> {
    let remaining = session.remaining();
    progress.start(session.planned().len(), session.records().len());
    if remaining.is_empty() {
        progress.message("every planned shot is already in the session");
        return Ok(());
    }
    let settle = session.plan().settle.clone();
    let first = &remaining[0];
    let t = Instant::now();
    d.light.off(None).map_err(|e| dev(first, e))?;
    if options.home {
        progress.message("homing the turntable");
        d.turntable.home().map_err(|e| dev(first, e))?;
    }
    summary.device_time += t.elapsed();
    let mut stage: Option<Stage> = None;
    // Commanded position (may be outside [0, 360) when the shortest way goes round).
    let mut angle: Option<f64> = None;
    let mut measured_angle = 0.0;
    let mut lit: Option<Option<usize>> = None;
    let mut since_snapshot = 0usize;
    for (n, shot) in remaining.iter().enumerate() {
        check_cancel(session, options)?;
        let want = shot.kind.stage();
        if stage != Some(want) {
            let t = Instant::now();
            d.light.off(None).map_err(|e| dev(shot, e))?;
            lit = Some(None);
            summary.device_time += t.elapsed();
            if stage.is_some() {
                let ts = Instant::now();
                session.write_snapshot(false)?;
                summary.storage_time += ts.elapsed();
                since_snapshot = 0;
            }
            for line in stage_instructions(stage, want) {
                progress.message(&line);
            }
            operator.set_stage(stage, want)?;
            stage = Some(want);
            check_cancel(session, options)?;
        }
        let t = Instant::now();
        let target = shot_angle(shot, options.lab.as_ref());
        let needs_move = match (target, angle) {
            // the sphere looks the same from every side: shoot it wherever the table is
            (None, Some(_)) => false,
            (None, None) => true,
            (Some(t), Some(a)) => (a - t).rem_euclid(360.0).min((t - a).rem_euclid(360.0)) > 1e-6,
            (Some(_), None) => true,
        };
        if needs_move {
            let goal = nearest_equivalent(target.unwrap_or(0.0), angle, options.angle_range);
            d.turntable.move_to(goal).map_err(|e| dev(shot, e))?;
            let ts = Instant::now();
            std::thread::sleep(Duration::from_millis(settle.turntable_millis));
            summary.settle_time += ts.elapsed();
            measured_angle = d.turntable.status().map_err(|e| dev(shot, e))?.angle_deg;
            angle = Some(goal);
            // A move can take seconds: stop here rather than switch a light on first.
            check_cancel(session, options)?;
        }
        let recorded_angle = angle.unwrap_or(0.0).rem_euclid(360.0);
        if lit != Some(shot.channel) {
            match shot.channel {
                Some(ch) => d.light.on(ch, shot.level, true).map_err(|e| dev(shot, e))?,
                None => d.light.off(None).map_err(|e| dev(shot, e))?,
            }
            let ts = Instant::now();
            std::thread::sleep(Duration::from_millis(settle.light_millis));
            summary.settle_time += ts.elapsed();
            lit = Some(shot.channel);
        }
        check_cancel(session, options)?;
        let tc = Instant::now();
        let settings = ShotSettings {
            exposure_secs: shot.exposure_secs,
            gain: shot.gain,
        };
        let (image, meta) = match d.camera.capture(settings) {
            Err(e) if e.is_retryable() => d.camera.capture(settings),
            r => r,
        }
        .map_err(|e| dev(shot, e))?;
        summary.camera_time += tc.elapsed();
        summary.device_time += t.elapsed();
        let hook = |phase| {
            if options.kill_hook == Some((n, phase)) {
                kill_self();
            }
        };
        hook(KillPhase::BeforeImage);
        let ts = Instant::now();
        let bytes = encode_exr(&image, ExrPrecision::F32).map_err(|e| CaptureError::Encode {
            file: shot.file.clone(),
            reason: e.to_string(),
        })?;
        let (len, sha) = session.write_image(&shot.id, &shot.file, &bytes)?;
        hook(KillPhase::AfterImage);
        let (time_unix, time_utc) = now_utc();
        let record = ShotRecord {
            id: shot.id.clone(),
            index: shot.index,
            kind: shot.kind,
            view: shot.view,
            angle_deg: recorded_angle,
            measured_angle_deg: measured_angle,
            channel: shot.channel,
            level: if shot.channel.is_some() {
                shot.level
            } else {
                0.0
            },
            light_dir_lab: shot
                .channel
                .and_then(|ch| options.lab.as_ref()?.light_dir_lab(ch))
                .map(|v| [v.x, v.y, v.z]),
            exposure_secs: meta.exposure_secs,
            gain: meta.gain,
            saturation: meta.saturation,
            device: meta.device,
            file: shot.file.clone(),
            width: image.width(),
            height: image.height(),
            bytes: len,
            sha256: sha,
            time_unix,
            time_utc,
            retake: None,
        };
        session.append(record)?;
        hook(KillPhase::AfterJournal);
        since_snapshot += 1;
        if since_snapshot >= options.snapshot_every.max(1) {
            session.write_snapshot(false)?;
            since_snapshot = 0;
        }
        summary.storage_time += ts.elapsed();
        summary.shots_taken += 1;
        if let Some(r) = session.records().last() {
            if r.retake.is_some() {
                summary.retakes += 1;
            }
            progress.shot_done(r);
            progress.shot_image(r, &image);
        }
    }
    Ok(())
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // tests: a panic is the failure report
mod tests {
    //! Logic tests with in-memory fakes (not the simulated rig, which runs the real serial
    //! stack: see tests/capture*.rs).
    use super::*;
    use crate::capture::plan::{CapturePlan, ShotKind, parse_plan};
    use crate::capture::session::{SessionHeader, format_utc, read_journal};
    use crate::devices::{ChannelStatus, ShotMetadata, TurntableStatus};
    use crate::render::image::LinearImage;
    use std::cell::RefCell;
    use std::rc::Rc;

    #[derive(Default)]
    struct Log {
        events: Vec<String>,
        angle: f64,
        lit: Option<usize>,
    }
    type Shared = Rc<RefCell<Log>>;

    struct FakeTable(Shared);
    impl Turntable for FakeTable {
        fn home(&mut self) -> Result<(), DeviceError> {
            self.0.borrow_mut().events.push("home".into());
            Ok(())
        }
        fn move_to(&mut self, a: f64) -> Result<(), DeviceError> {
            let mut l = self.0.borrow_mut();
            l.angle = a;
            l.events.push(format!("move {a}"));
            Ok(())
        }
        fn move_by(&mut self, d: f64) -> Result<(), DeviceError> {
            let a = self.0.borrow().angle + d;
            self.move_to(a)
        }
        fn stop(&mut self) -> Result<(), DeviceError> {
            Ok(())
        }
        fn status(&mut self) -> Result<TurntableStatus, DeviceError> {
            let a = self.0.borrow().angle;
            Ok(TurntableStatus {
                angle_deg: a,
                target_deg: a,
                moving: false,
                homed: true,
            })
        }
    }
    struct FakeLight(Shared);
    impl Light for FakeLight {
        fn channel_count(&self) -> usize {
            3
        }
        fn on(&mut self, ch: usize, _level: f64, _ex: bool) -> Result<(), DeviceError> {
            let mut l = self.0.borrow_mut();
            l.lit = Some(ch);
            l.events.push(format!("on {ch}"));
            Ok(())
        }
        fn off(&mut self, _ch: Option<usize>) -> Result<(), DeviceError> {
            let mut l = self.0.borrow_mut();
            l.lit = None;
            l.events.push("off".into());
            Ok(())
        }
        fn status(&mut self) -> Result<Vec<ChannelStatus>, DeviceError> {
            Ok(vec![])
        }
    }
    /// Encodes the angle and lit channel into the pixel so the test can check what was shot.
    struct FakeCamera {
        log: Shared,
        fail_at: Option<usize>,
        count: usize,
        cancel_at: Option<(usize, Arc<AtomicBool>)>,
    }
    impl Camera for FakeCamera {
        fn capture(&mut self, s: ShotSettings) -> Result<(LinearImage, ShotMetadata), DeviceError> {
            let n = self.count;
            self.count += 1;
            if let Some((at, flag)) = &self.cancel_at
                && *at == n
            {
                flag.store(true, Ordering::SeqCst);
            }
            if self.fail_at == Some(n) {
                return Err(DeviceError::Fault {
                    device: "fake camera".into(),
                    reason: "sensor fault".into(),
                });
            }
            let l = self.log.borrow();
            let mut img = LinearImage::new(2, 2);
            let ch = l.lit.map(|c| c as f32).unwrap_or(-1.0);
            img.set(0, 0, [l.angle as f32, ch, s.exposure_secs as f32]);
            Ok((
                img,
                ShotMetadata {
                    exposure_secs: s.exposure_secs,
                    gain: s.gain,
                    saturation: 1.0,
                    device: "fake".into(),
                },
            ))
        }
    }

    fn small_plan() -> (CapturePlan, String) {
        let text = crate::capture::plan::DEFAULT_PLAN_TOML
            .replace("views = 55", "views = 6")
            .replace("every = 5", "every = 3")
            .replace("channels = [0, 1, 2]", "channels = [0, 2]")
            .replace("turntable_millis = 200", "turntable_millis = 0")
            .replace("light_millis = 100", "light_millis = 0");
        (parse_plan(&text, "test").unwrap(), text)
    }

    fn header() -> SessionHeader {
        SessionHeader {
            format_version: 0,
            tool: "test".into(),
            plan_name: String::new(),
            planned_shots: 0,
            profile: "fake".into(),
            camera_backend: "fake".into(),
            created_utc: format_utc(0.0),
            simulated: false,
        }
    }

    type RunOutcome = (
        Result<RunSummary, CaptureError>,
        Shared,
        Vec<(Option<Stage>, Stage)>,
    );

    struct Recorder(Vec<(Option<Stage>, Stage)>);
    impl Operator for Recorder {
        fn set_stage(&mut self, from: Option<Stage>, to: Stage) -> Result<(), CaptureError> {
            self.0.push((from, to));
            Ok(())
        }
    }

    fn run(
        dir: &std::path::Path,
        resume: bool,
        fail_at: Option<usize>,
        cancel_at: Option<usize>,
    ) -> RunOutcome {
        let (plan, text) = small_plan();
        let mut session = if resume {
            Session::resume(dir).unwrap()
        } else {
            Session::create(dir, &plan, &text, header(), &[]).unwrap()
        };
        let log: Shared = Rc::default();
        let options = RunOptions {
            snapshot_every: 4,
            ..RunOptions::default()
        };
        let mut cam = FakeCamera {
            log: log.clone(),
            fail_at,
            count: 0,
            cancel_at: cancel_at.map(|n| (n, options.cancel.clone())),
        };
        let mut op = Recorder(Vec::new());
        let r = run_session(
            &mut session,
            &mut FakeTable(log.clone()),
            &mut FakeLight(log.clone()),
            &mut cam,
            &mut op,
            &mut Quiet,
            &options,
        );
        (r, log, op.0)
    }

    #[test]
    fn every_shot_sees_its_angle_and_channel_and_stages_come_in_order() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("s");
        let (r, log, stages) = run(&dir, false, None, None);
        let summary = r.unwrap();
        let (plan, _) = small_plan();
        assert!(summary.complete);
        assert_eq!(summary.shots_taken, plan.shots().len());
        let (records, _) = read_journal(&dir.join("journal.jsonl")).unwrap();
        assert_eq!(records.len(), plan.shots().len());
        for (rec, shot) in records.iter().zip(plan.shots()) {
            assert_eq!(rec.id, shot.id);
            let bytes = std::fs::read(dir.join(&rec.file)).unwrap();
            assert_eq!(crate::capture::session::sha256_hex(&bytes), rec.sha256);
            let img = crate::imageio::decode_exr(&bytes).unwrap();
            let [a, ch, e] = img.get(0, 0);
            assert_eq!(a as f64, rec.angle_deg as f32 as f64);
            if shot.kind != ShotKind::Sphere {
                assert_eq!(rec.angle_deg, shot.angle_deg);
            }
            assert_eq!(ch, shot.channel.map(|c| c as f32).unwrap_or(-1.0));
            assert_eq!(e, shot.exposure_secs as f32);
        }
        // object + room light, then room light off, then sphere, then white
        let targets: Vec<_> = stages
            .iter()
            .map(|(_, s)| (s.target, s.room_light))
            .collect();
        assert_eq!(
            targets,
            vec![
                (Target::Object, true),
                (Target::Object, false),
                (Target::Sphere, false),
                (Target::White, false)
            ]
        );
        let l = log.borrow();
        assert_eq!(l.events.last().map(String::as_str), Some("off"));
        assert_eq!(l.events.iter().filter(|e| *e == "home").count(), 1);
        // the turntable moves once per view of each phase, not once per shot
        let moves = l.events.iter().filter(|e| e.starts_with("move")).count();
        let sl_views = plan.single_light_views().len();
        assert!(moves <= plan.ambient.views + sl_views + 2, "{moves}");
        let m: crate::capture::session::Manifest =
            serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
        assert_eq!(m.status, "complete");
        assert_eq!(m.shots.len(), records.len());
    }

    #[test]
    fn a_device_error_leaves_the_light_off_and_resume_finishes_without_repeats() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("s");
        let (plan, _) = small_plan();
        let fail = plan
            .shots()
            .iter()
            .position(|s| s.kind == ShotKind::SingleLight)
            .unwrap()
            + 1;
        let (r, log, _) = run(&dir, false, Some(fail), None);
        let err = r.unwrap_err().to_string();
        assert!(
            err.contains("sensor fault") && err.contains("light/v000"),
            "{err}"
        );
        assert_eq!(log.borrow().lit, None, "light left on");
        assert_eq!(log.borrow().events.last().map(String::as_str), Some("off"));
        let (records, _) = read_journal(&dir.join("journal.jsonl")).unwrap();
        assert_eq!(records.len(), fail);
        let (r, _, stages) = run(&dir, true, None, None);
        assert!(r.unwrap().complete);
        // the resumed run starts from the single-light stage
        assert!(!stages[0].1.room_light);
        let (records, _) = read_journal(&dir.join("journal.jsonl")).unwrap();
        let ids: Vec<_> = records.iter().map(|r| r.id.clone()).collect();
        let planned: Vec<_> = plan.shots().iter().map(|s| s.id.clone()).collect();
        assert_eq!(ids, planned);
    }

    #[test]
    fn moves_take_the_short_way_within_the_limits() {
        let r = Some((-360.0, 360.0));
        assert_eq!(nearest_equivalent(0.0, Some(330.0), r), 360.0);
        assert_eq!(nearest_equivalent(10.0, Some(240.0), r), 10.0);
        assert_eq!(nearest_equivalent(330.0, Some(0.0), r), -30.0);
        assert_eq!(
            nearest_equivalent(330.0, Some(0.0), Some((0.0, 360.0))),
            330.0
        );
        assert_eq!(nearest_equivalent(330.0, None, r), 330.0);
        assert_eq!(nearest_equivalent(330.0, Some(0.0), None), 330.0);
    }

    #[test]
    fn cancel_stops_between_shots_with_the_light_off() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("s");
        let (plan, _) = small_plan();
        let at = plan.shots().len() - 3; // a calibration shot, light on
        let (r, log, _) = run(&dir, false, None, Some(at));
        match r {
            Err(CaptureError::Interrupted { done, total }) => {
                assert_eq!(done, at + 1);
                assert_eq!(total, plan.shots().len());
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(log.borrow().lit, None);
        let m: crate::capture::session::Manifest =
            serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap();
        assert_eq!(m.status, "in_progress");
        assert_eq!(m.shots.len(), at + 1);
    }
}
