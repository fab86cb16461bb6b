//! The rig's thread of the lab page: the only code of the server that talks to the turntable,
//! the light and the camera. It owns them for the server's lifetime, serves the commands the
//! async side sends (light, turntable, start and resume a capture), polls the rig's state while
//! idle, takes live preview frames, and runs captures through the same engine as
//! `brdf-rig capture`: the plans, session folders and checks of `capture` and
//! `pipeline::capture_start`, and `run_session` with the page as the operator.
//!
//! A capture runs on this thread from start to end; meanwhile the async side refuses rig
//! commands (409) and a command that waited here longer than `hub::STALE_AFTER` is refused
//! rather than carried out late. When the thread ends (the server stops) the light is switched
//! off.

use std::cell::Cell;
use std::path::{Path, PathBuf};
use std::rc::Rc;
use std::sync::Arc;
use std::time::{Duration, Instant};

use super::hub::{Command, CommandError, DeviceEnds, Hub, StartFailure, StartSpec, StopKind};
use super::live::{LiveFeed, SharedCamera};
use super::operator::PageOperator;
use super::preview::Worker;
use super::progress::PageProgress;
use super::state::{
    BUILT_IN_PLAN, LightState, Phase, PlanInfo, RigState, SessionInfo, SimTruth, VerifyInfo,
};
use crate::capture::plan::{CapturePlan, DEFAULT_PLAN_TOML, load_plan, parse_plan};
use crate::capture::{
    CaptureError, Operator, RunOptions, Session, Unattended, check_disk_space, run_session,
    verify_session,
};
use crate::devices::rig::Rig;
use crate::devices::{Light, Turntable};
use crate::pipeline::capture_start::{
    self, CaptureRig, PROFILE_COPY, SimStage, check_output_folder,
};
use crate::sim::SimHandle;
use crate::sim::scene::StageState;

/// How often the rig's state is polled while idle.
const STATUS_EVERY: Duration = Duration::from_millis(400);

fn read(path: &Path) -> Result<String, StartFailure> {
    std::fs::read_to_string(path).map_err(|source| StartFailure::Read {
        path: path.to_owned(),
        source,
    })
}

/// Where things are and how fast the preview goes.
#[derive(Clone, Debug)]
pub struct DeviceSettings {
    pub sessions_dir: PathBuf,
    pub plans_dir: Option<PathBuf>,
    /// The `--port` the server was given (for the resume command it prints).
    pub port_override: Option<PathBuf>,
    pub preview_size: (usize, usize),
    pub preview_fps: f64,
}

/// A capture ready to run: its session is open (and locked), its camera open.
struct Prepared {
    session: Session,
    camera: SharedCamera,
    options: RunOptions,
    guided: bool,
    resumed: bool,
    was_empty_folder: bool,
}

pub struct RigThread {
    hub: Arc<Hub>,
    kit: CaptureRig,
    rig: Rig,
    /// The simulated rig's state, which the simulated camera looks at; `None` for a board.
    sim: Option<SimHandle>,
    stage: StageState,
    worker: Arc<Worker>,
    live: LiveFeed,
    settings: DeviceSettings,
}

impl RigThread {
    pub fn new(
        hub: Arc<Hub>,
        kit: CaptureRig,
        rig: Rig,
        sim: Option<SimHandle>,
        worker: Arc<Worker>,
        settings: DeviceSettings,
    ) -> RigThread {
        let live = LiveFeed::new(hub.clone(), worker.clone(), settings.preview_fps);
        let mut t = RigThread {
            hub,
            kit,
            rig,
            sim,
            stage: StageState::default(),
            worker,
            live,
            settings,
        };
        t.open_preview_camera();
        t.refresh_lists();
        t.poll_status();
        t
    }

    /// The loop: commands, status polls and live frames until the server stops.
    pub fn run(mut self, ends: DeviceEnds) {
        let mut next_status = Instant::now();
        loop {
            let wait = next_status
                .saturating_duration_since(Instant::now())
                .min(self.live.due_in())
                .max(Duration::from_millis(2));
            match ends.commands.recv_timeout(wait) {
                Ok(req) => {
                    if req.command == Command::Shutdown {
                        let _ = req.reply.send(Ok("stopping".into()));
                        break;
                    }
                    if req.sent.elapsed() > super::hub::STALE_AFTER {
                        let _ = req.reply.send(Err(CommandError::Stale));
                        continue;
                    }
                    self.handle(req.command, req.reply, &ends);
                    next_status = Instant::now();
                }
                Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {}
                Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
            }
            if Instant::now() >= next_status {
                self.poll_status();
                next_status = Instant::now() + STATUS_EVERY;
            }
            self.live.tick();
        }
        if let Err(e) = self.rig.light.off(None) {
            self.hub
                .log("error", format!("switching the light off at the end: {e}"));
        }
        self.poll_status();
    }

    fn handle(
        &mut self,
        command: Command,
        reply: tokio::sync::oneshot::Sender<Result<String, CommandError>>,
        ends: &DeviceEnds,
    ) {
        match command {
            Command::Start(spec) => match self.prepare_new(&spec) {
                Ok(p) => {
                    let _ = reply.send(Ok(spec.session.clone()));
                    self.run_capture(p, ends);
                }
                Err(e) => {
                    self.start_failed(&e);
                    let _ = reply.send(Err(e.into()));
                }
            },
            Command::Resume { session, guided } => match self.prepare_resume(&session, guided) {
                Ok(p) => {
                    let _ = reply.send(Ok(session));
                    self.run_capture(p, ends);
                }
                Err(e) => {
                    self.start_failed(&e);
                    let _ = reply.send(Err(e.into()));
                }
            },
            other => {
                let r = self.rig_command(&other);
                if let Err(e) = &r {
                    self.hub.log("error", e.to_string());
                }
                let _ = reply.send(r);
            }
        }
    }

    /// Light and turntable, while idle.
    fn rig_command(&mut self, command: &Command) -> Result<String, CommandError> {
        let busy = match command {
            Command::LightOn { channel, level } => {
                format!("switching light channel {channel} on at {level}")
            }
            Command::LightOff => "switching the light off".into(),
            Command::Home => "homing the turntable".into(),
            Command::MoveTo { angle_deg } => format!("moving the turntable to {angle_deg} deg"),
            _ => return Err(CommandError::NotARigCommand),
        };
        self.hub.update(|s| s.rig.busy = Some(busy.clone()));
        let r = match *command {
            Command::LightOn { channel, level } => self
                .rig
                .light
                .on(channel, level, true)
                .map(|()| format!("light channel {channel} on at {level}")),
            Command::LightOff => self.rig.light.off(None).map(|()| "light off".to_string()),
            Command::Home => self
                .rig
                .turntable
                .home()
                .map(|()| "turntable homed".to_string()),
            Command::MoveTo { angle_deg } => {
                let homed = self.rig.turntable.status().map(|s| s.homed);
                match homed {
                    Ok(false) => self.rig.turntable.home(),
                    Ok(true) => Ok(()),
                    Err(e) => Err(e),
                }
                .and_then(|()| self.rig.turntable.move_to(angle_deg))
                .map(|()| format!("turntable at {angle_deg} deg"))
            }
            _ => Ok(String::new()),
        }
        .map_err(|source| CommandError::Device {
            doing: busy,
            source,
        });
        self.hub.update(|s| s.rig.busy = None);
        self.poll_status();
        r
    }

    fn session_dir(&self, name: &str) -> PathBuf {
        self.settings.sessions_dir.join(name)
    }

    /// The plan the page chose, read again from its file (so an edited plan is checked now).
    fn load_plan(&self, id: &str) -> Result<(CapturePlan, String), StartFailure> {
        if id == BUILT_IN_PLAN {
            let plan = parse_plan(DEFAULT_PLAN_TOML, "capture-plans/default.toml (built in)")?;
            return Ok((plan, DEFAULT_PLAN_TOML.to_string()));
        }
        let Some(dir) = &self.settings.plans_dir else {
            return Err(StartFailure::UnknownPlan(id.to_owned()));
        };
        // only a plan the server lists: a name in the plans folder, never a path
        let listed = PlanInfo::list(Some(dir), &self.kit.lab, self.rig.light.channel_count());
        if !listed.iter().any(|p| p.id == id) {
            return Err(StartFailure::UnlistedPlan {
                id: id.to_owned(),
                dir: dir.clone(),
            });
        }
        let path = dir.join(id);
        let plan = load_plan(&path)?;
        let text = read(&path)?;
        Ok((plan, text))
    }

    /// The checks of `brdf-rig capture`, in its order, for a new session; then the session.
    fn prepare_new(&mut self, spec: &StartSpec) -> Result<Prepared, StartFailure> {
        let (plan, text) = self.load_plan(&spec.plan_id)?;
        let dir = self.session_dir(&spec.session);
        let was_empty_folder = dir.is_dir();
        check_output_folder(&dir)?;
        check_disk_space(
            &dir,
            plan.shots().len(),
            plan.camera.width,
            plan.camera.height,
        )?;
        plan.check_rig(self.rig.light.channel_count())
            .map_err(StartFailure::PlanDoesNotFit)?;
        self.begin(&spec.session, &plan.name, spec.guided, false);
        let camera = self.open_capture_camera(&plan, &dir)?;
        let session = self
            .kit
            .create_session(&dir, &plan, &text, was_empty_folder)?;
        self.refresh_lists();
        Ok(Prepared {
            session,
            camera,
            options: self.options(spec.snapshot_every),
            guided: spec.guided,
            resumed: false,
            was_empty_folder,
        })
    }

    /// The checks of `brdf-rig capture --resume` for a session under the sessions folder.
    fn prepare_resume(&mut self, name: &str, guided: bool) -> Result<Prepared, StartFailure> {
        let dir = self.session_dir(name);
        if SessionInfo::read(&dir).is_none() {
            return Err(StartFailure::NotASession { dir });
        }
        // The session's light directions and limits are its profile's: resume only on that rig.
        let copy = dir.join(PROFILE_COPY);
        let theirs = read(&copy)?;
        if theirs != self.kit.profile.source {
            return Err(StartFailure::OtherProfile {
                command: capture_start::resume_command(
                    &dir,
                    self.settings.port_override.as_deref(),
                    false,
                ),
                dir,
                profile: self.kit.profile.origin.clone(),
                copy,
            });
        }
        self.hub.log(
            "info",
            format!(
                "checking every journaled image of {} against its checksum",
                dir.display()
            ),
        );
        let session = Session::resume(&dir)?;
        for r in session.repairs() {
            self.hub.log(
                "warn",
                format!(
                    "{}: {} (shot {}): it will be taken again",
                    r.file,
                    r.problem.what(),
                    r.id
                ),
            );
        }
        let plan = session.plan().clone();
        check_disk_space(
            &dir,
            session.remaining().len(),
            plan.camera.width,
            plan.camera.height,
        )?;
        plan.check_rig(self.rig.light.channel_count())
            .map_err(StartFailure::PlanDoesNotFit)?;
        self.begin(name, &plan.name, guided, true);
        let camera = self.open_capture_camera(&plan, &dir)?;
        self.kit.refresh_ground_truth(&dir, &plan)?;
        Ok(Prepared {
            session,
            camera,
            options: self.options(16),
            guided,
            resumed: true,
            was_empty_folder: false,
        })
    }

    /// The page shows a capture starting; its stop flag is armed.
    fn begin(&mut self, name: &str, plan: &str, guided: bool, resumed: bool) {
        let dir = self.session_dir(name).display().to_string();
        let now = crate::capture::session::now_utc().0;
        self.hub.update(|s| {
            s.capture = super::state::CaptureState {
                phase: Phase::Starting,
                session: Some(name.to_string()),
                dir: Some(dir.clone()),
                guided,
                resumed,
                plan: plan.to_string(),
                started_unix: now,
                ..Default::default()
            };
            s.log(
                "info",
                format!(
                    "{} {} capture into {dir} (plan `{plan}`)",
                    if resumed { "resuming" } else { "starting" },
                    if guided { "a guided" } else { "an unattended" },
                ),
            );
        });
    }

    fn start_failed(&mut self, reason: &StartFailure) {
        let reason = reason.to_string();
        self.hub.update(|s| {
            if s.capture.phase == Phase::Starting {
                s.capture.phase = Phase::Failed;
                s.capture.stop_reason = Some(reason.clone());
            }
            s.log("error", format!("the capture did not start: {reason}"));
        });
        self.open_preview_camera();
    }

    fn options(&self, snapshot_every: usize) -> RunOptions {
        RunOptions {
            cancel: self.hub.arm_stop(),
            ..self.kit.run_options(snapshot_every)
        }
    }

    /// The capture's camera (the preview's is closed first: a real camera opens once).
    fn open_capture_camera(
        &mut self,
        plan: &CapturePlan,
        dir: &Path,
    ) -> Result<SharedCamera, StartFailure> {
        self.live.set_camera(None);
        let camera = self.kit.open_camera(
            plan.camera.width,
            plan.camera.height,
            self.sim.as_ref(),
            &self.stage,
            &dir.join(".download"),
        )?;
        let shared = SharedCamera::new(camera);
        if self.live_view() {
            self.live.set_camera(Some(shared.clone()));
        }
        Ok(shared)
    }

    /// Backends with a live view (a DSLR would fire its shutter for every preview frame).
    fn live_view(&self) -> bool {
        self.kit.camera.backend != "gphoto2"
    }

    fn open_preview_camera(&mut self) {
        self.live.set_camera(None);
        if !self.live_view() {
            self.hub.update(|s| {
                s.preview.unavailable = Some(
                    "this camera (gphoto2) has no live view here: the preview shows each shot as it is taken"
                        .into(),
                )
            });
            return;
        }
        let (w, h) = self.settings.preview_size;
        let download = std::env::temp_dir().join("brdf-rig-preview");
        match self
            .kit
            .open_camera(w, h, self.sim.as_ref(), &self.stage, &download)
        {
            Ok(c) => self.live.set_camera(Some(SharedCamera::new(c))),
            Err(e) => self.hub.update(|s| {
                s.preview.unavailable = Some(format!("no live preview: {e}"));
            }),
        }
    }

    fn run_capture(&mut self, p: Prepared, ends: &DeviceEnds) {
        let Prepared {
            mut session,
            mut camera,
            options,
            guided,
            resumed,
            was_empty_folder,
        } = p;
        let dir = session.dir().to_path_buf();
        let waited = Rc::new(Cell::new(Duration::ZERO));
        let mut progress = PageProgress::new(
            self.hub.clone(),
            self.worker.clone(),
            waited.clone(),
            self.settings.preview_fps,
        );
        self.hub.update(|s| {
            if s.capture.phase == Phase::Starting {
                s.capture.phase = Phase::Running;
            }
        });
        let result = {
            let mut page = PageOperator {
                hub: self.hub.clone(),
                continues: &ends.continues,
                stop: options.cancel.clone(),
                live: &mut self.live,
                waited,
                seq: 0,
            };
            let mut unattended = Unattended;
            let base: &mut dyn Operator = if guided { &mut page } else { &mut unattended };
            let mut operator = SimStage {
                inner: base,
                stage: self.stage.clone(),
            };
            run_session(
                &mut session,
                &mut self.rig.turntable,
                &mut self.rig.light,
                &mut camera,
                &mut operator,
                &mut progress,
                &options,
            )
        };
        let removed = !resumed && result.is_err() && session.records().is_empty();
        drop(session);
        drop(camera);
        self.live.set_camera(None);
        let removed = removed
            && match capture_start::remove_new_session(&dir, was_empty_folder) {
                Ok(()) => true,
                Err(e) => {
                    self.hub.log("error", e.to_string());
                    false
                }
            };
        self.finish(&dir, result, removed, guided);
        self.open_preview_camera();
        self.refresh_lists();
        self.poll_status();
    }

    /// The page's account of a finished run: phase, why it stopped, checksum status, the
    /// command that continues it, the report link.
    fn finish(
        &mut self,
        dir: &Path,
        result: Result<crate::capture::RunSummary, CaptureError>,
        removed: bool,
        guided: bool,
    ) {
        let stop = self.hub.stop_requested();
        let (phase, reason, wall) = match &result {
            Ok(summary) => (Phase::Complete, None, Some(summary.wall.as_secs_f64())),
            Err(CaptureError::Interrupted { .. }) => match &stop {
                Some((StopKind::Abort, why)) => (Phase::Aborted, Some(why.clone()), None),
                Some((StopKind::Pause, why)) => (Phase::Paused, Some(why.clone()), None),
                None => (Phase::Paused, Some("interrupted".to_string()), None),
            },
            Err(e) => (Phase::Failed, Some(e.to_string()), None),
        };
        let verify = if removed {
            None
        } else {
            match verify_session(dir) {
                Ok(r) => Some(VerifyInfo::of(&r)),
                Err(e) => {
                    self.hub
                        .log("error", format!("verifying {}: {e}", dir.display()));
                    None
                }
            }
        };
        let name = dir
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let resume = (!removed && phase != Phase::Complete).then(|| {
            capture_start::resume_command(dir, self.settings.port_override.as_deref(), !guided)
        });
        self.hub.update(|s| {
            let c = &mut s.capture;
            c.phase = phase;
            c.instruction = None;
            c.stop_reason = reason.clone();
            c.wall_secs = wall;
            c.verify = verify.clone();
            c.resume_command = resume.clone();
            c.report_url = (!removed).then(|| format!("/sessions/{name}/report"));
            if removed {
                c.session = None;
            }
            let line = match (phase, &reason) {
                (Phase::Complete, _) => format!(
                    "capture complete: {} shots in {}",
                    c.total,
                    dir.display()
                ),
                (_, Some(why)) if removed => format!(
                    "the capture stopped before its first shot ({why}); the light is off and the new session folder was removed"
                ),
                (_, Some(why)) => format!(
                    "capture {phase:?} ({why}): {} of {} shots are in {}; the light is off",
                    c.done,
                    c.total,
                    dir.display()
                )
                .to_lowercase(),
                _ => String::new(),
            };
            if !line.is_empty() {
                s.log(if phase == Phase::Failed { "error" } else { "info" }, line);
            }
            if let Some(v) = &verify {
                s.log(
                    if v.intact { "info" } else { "error" },
                    if v.intact {
                        format!("checksums: all {} images intact", v.checked)
                    } else {
                        format!(
                            "checksums: {} problem(s): {}",
                            v.problems.len(),
                            v.problems.join("; ")
                        )
                    },
                );
            }
        });
    }

    fn refresh_lists(&mut self) {
        let plans = PlanInfo::list(
            self.settings.plans_dir.as_deref(),
            &self.kit.lab,
            self.rig.light.channel_count(),
        );
        let sessions = SessionInfo::scan(&self.settings.sessions_dir);
        self.hub.update(|s| {
            s.plans = plans;
            s.sessions = sessions;
        });
    }

    /// Reads the turntable and the light through the serial link; the page state changes only
    /// when the rig did.
    fn poll_status(&mut self) {
        let t = self.rig.turntable.status();
        let l = self.rig.light.status();
        let sim = self.hub.sim.as_ref().map(|h| SimTruth::of(&h.snapshot()));
        // pages wake only when something changed (a rig at rest sends nothing)
        self.hub.update_if(|s| {
            let before = s.rig.clone();
            let r = &mut s.rig;
            r.polled = true;
            r.sim = sim;
            let mut errors = Vec::new();
            match &t {
                Ok(t) => {
                    r.angle_deg = t.angle_deg;
                    r.target_deg = t.target_deg;
                    r.moving = t.moving;
                    r.homed = t.homed;
                }
                Err(e) => errors.push(format!("turntable: {e}")),
            }
            match &l {
                Ok(levels) => {
                    for (light, status) in r.lights.iter_mut().zip(levels) {
                        light.level = status.level;
                        light.stable = status.stable;
                    }
                }
                Err(e) => errors.push(format!("light: {e}")),
            }
            r.connected = errors.is_empty();
            r.error = (!errors.is_empty()).then(|| errors.join("; "));
            s.rig != before
        });
    }
}

/// The rig as the page first shows it: port, firmware, limits, channels.
pub fn initial_rig_state(rig: &Rig, kit: &CaptureRig) -> RigState {
    let h = &rig.hello;
    let t = &kit.profile.turntable;
    RigState {
        connected: true,
        port: rig.port.display().to_string(),
        firmware: h.name.clone(),
        protocol: format!("{}.{}", h.major, h.minor),
        watchdog_ms: u64::from(h.watchdog_ms),
        min_angle_deg: t.min_angle_deg,
        max_angle_deg: t.max_angle_deg,
        lights: kit
            .profile
            .light
            .channels
            .iter()
            .enumerate()
            .map(|(i, c)| LightState {
                channel: i,
                name: c.name.clone(),
                level: 0.0,
                stable: false,
                max_level: c.max_level,
                azimuth_deg: c.azimuth_deg,
                elevation_deg: c.elevation_deg,
                theta_d_deg: kit.lab.theta_d_deg(i),
            })
            .collect(),
        ..RigState::default()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_start_refused_for_another_profile_names_the_session_and_the_way_on() {
        let e = StartFailure::OtherProfile {
            dir: PathBuf::from("/s/a"),
            profile: "/p/rig.toml".into(),
            command: "brdf-rig capture --resume /s/a".into(),
            copy: PathBuf::from("/s/a/profile.toml"),
        };
        assert_eq!(
            e.to_string(),
            "/s/a was captured with another rig profile than this server's (/p/rig.toml): \
             continue it with `brdf-rig capture --resume /s/a`, or serve with --profile \
             /s/a/profile.toml"
        );
        let e = CommandError::from(StartFailure::UnlistedPlan {
            id: "x.toml".into(),
            dir: PathBuf::from("/plans"),
        });
        assert_eq!(e.to_string(), "unknown plan \"x.toml\" (not in /plans)");
    }
}
