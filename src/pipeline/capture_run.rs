//! A whole capture command: a session, new or continued, prepared and run on the rig a profile
//! describes. `brdf-rig capture` and `brdf-rig bench capture` both run it; the person at the
//! terminal (prompts, progress bar, Ctrl-C) is the caller's, behind [`Frontend`].
//!
//! Order of checks, so that nothing moves and nothing is written before everything is known to be
//! there: plan and profile parse, the simulated scene loads, guided mode needs a terminal, the
//! output folder is new or empty and its parent takes new files (or, resuming, every journaled
//! image is checked against its checksum), there is room, the rig answers (a missing port fails
//! here), the plan's channels exist, the camera opens. Only then is the session folder created
//! and the turntable homed. A new session whose start fails before its first shot is removed
//! again, so the same command can simply be run again.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use crate::capture::plan::{DEFAULT_PLAN_TOML, load_plan, parse_plan};
use crate::capture::runner::{KillPhase, Progress, RunOptions};
use crate::capture::{
    CaptureError, Operator, RunSummary, Session, Unattended, check_disk_space, run_session,
};
use crate::devices::DeviceError;
use crate::pipeline::capture_start::{self, CaptureRig, PROFILE_COPY, StartError};
use crate::profile::{Profile, ProfileError};
use crate::rig_factory::{self, OpenRig};
use crate::sim::scene::StageState;

/// What to capture: the options of `brdf-rig capture`.
#[derive(Clone, Debug, Default)]
pub struct CaptureRequest {
    /// Rig profile; `None`: [`Profile::chosen`] (the built-in rig, for `port` or simulated).
    pub profile: Option<PathBuf>,
    /// Serial port overriding the profile's.
    pub port: Option<PathBuf>,
    /// Capture plan; `None`: the built-in plan.
    pub plan: Option<PathBuf>,
    /// New session folder.
    pub out: Option<PathBuf>,
    /// Session folder to continue.
    pub resume: Option<PathBuf>,
    /// No prompts (nobody needs to act).
    pub unattended: bool,
    /// Write manifest.json every N shots.
    pub snapshot_every: usize,
}

/// The caller's side of a capture: where notes go, the progress shown, the person who acts on
/// prompts, and what stops the run.
pub trait Frontend {
    /// A note for the operator (the plan's summary, the repairs a resume will make).
    fn note(&mut self, text: &str);
    /// The progress display of one run.
    fn progress(&mut self) -> Box<dyn Progress>;
    /// The operator of a guided capture (someone at a terminal); `cancel` is the run's stop flag,
    /// which a prompt should honour.
    fn guided_operator(&mut self, cancel: Arc<AtomicBool>) -> Box<dyn Operator>;
    /// The run's stop flag, before the run (a terminal wires Ctrl-C to it).
    fn watch_cancel(&mut self, cancel: Arc<AtomicBool>);
}

/// Why a capture command could not run (a failure during the run is in [`Outcome::result`]).
#[derive(Debug, thiserror::Error)]
pub enum CaptureRunError {
    #[error("give --out DIR for a new capture or --resume DIR")]
    NoFolder,
    #[error("resuming {}: is it a session folder?", dir.display())]
    NotASession {
        dir: PathBuf,
        #[source]
        source: Box<CaptureError>,
    },
    #[error("reading {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "guided mode waits for the operator to press Enter, but standard input is not a terminal; \
         run it in a terminal, or pass --unattended when nobody needs to act (simulated rig, or a \
         rig whose room light and targets are already set)"
    )]
    NotATerminal,
    #[error("opening the rig of {origin} (port {port}); nothing has moved")]
    OpenRig {
        origin: String,
        port: String,
        #[source]
        source: Box<DeviceError>,
    },
    #[error("the plan does not fit the rig: {0}")]
    PlanDoesNotFit(crate::capture::plan::PlanError),
    #[error("BRDF_RIG_TEST_KILL_AT={value}: expected N:phase")]
    KillHookNumber {
        value: String,
        #[source]
        source: std::num::ParseIntError,
    },
    #[error("BRDF_RIG_TEST_KILL_AT={0}: phase is before-image, after-image or after-journal")]
    KillHookPhase(String),
    #[error(transparent)]
    Profile(#[from] ProfileError),
    #[error(transparent)]
    Start(#[from] StartError),
    #[error(transparent)]
    Capture(#[from] CaptureError),
}

/// What a capture command did: the run's result, its session folder, and how to continue it.
pub struct Outcome {
    pub result: Result<RunSummary, CaptureError>,
    pub dir: PathBuf,
    /// The command that continues this session, as the user should type it.
    pub resume_command: String,
    /// A new session that failed before any shot was taken was removed again.
    pub removed: bool,
}

/// The test hook `BRDF_RIG_TEST_KILL_AT=N[:phase]`: where the process kills itself mid-shot.
fn kill_hook() -> Result<Option<(usize, KillPhase)>, CaptureRunError> {
    let Ok(v) = std::env::var("BRDF_RIG_TEST_KILL_AT") else {
        return Ok(None);
    };
    let (n, phase) = v.split_once(':').unwrap_or((v.as_str(), "after-journal"));
    let n: usize = n
        .parse()
        .map_err(|source| CaptureRunError::KillHookNumber {
            value: v.clone(),
            source,
        })?;
    let phase = KillPhase::parse(phase).ok_or_else(|| CaptureRunError::KillHookPhase(v.clone()))?;
    Ok(Some((n, phase)))
}

/// Prepares everything and runs the session. Everything that can be checked is checked before
/// the session folder is written; a new session whose start fails is removed again.
pub fn execute(
    req: &CaptureRequest,
    frontend: &mut dyn Frontend,
) -> Result<Outcome, CaptureRunError> {
    let resuming = req.resume.is_some();
    // 1. Plan and profile, the camera and scene sections, the simulated scene.
    let (dir, plan, plan_text, profile) = match (&req.resume, &req.out) {
        (Some(dir), _) => {
            let plan_path = dir.join(crate::capture::session::PLAN_FILE);
            let plan = load_plan(&plan_path).map_err(|source| CaptureRunError::NotASession {
                dir: dir.clone(),
                source: Box::new(source),
            })?;
            let profile = match &req.profile {
                Some(p) => Profile::load(p)?,
                None => Profile::load(&dir.join(PROFILE_COPY))?,
            };
            let text = read(&plan_path)?;
            (dir.clone(), plan, text, profile)
        }
        (None, Some(out)) => {
            let (plan, text) = match &req.plan {
                Some(p) => (load_plan(p)?, read(p)?),
                None => (
                    parse_plan(DEFAULT_PLAN_TOML, "capture-plans/default.toml (built in)")?,
                    DEFAULT_PLAN_TOML.to_string(),
                ),
            };
            let profile = Profile::chosen(req.profile.as_deref(), req.port.as_deref())?;
            (out.clone(), plan, text, profile)
        }
        (None, None) => return Err(CaptureRunError::NoFolder),
    };
    let resume_cmd = capture_start::resume_command(&dir, req.port.as_deref(), req.unattended);
    let kit = CaptureRig::load(profile)?;
    frontend.note(&plan.summary(&kit.lab));

    // 2. Guided mode needs someone at a terminal.
    if !req.unattended && !std::io::stdin().is_terminal() {
        return Err(CaptureRunError::NotATerminal);
    }

    // 3. The folder and its free space. A resumed session is opened (and locked) here: every
    // journaled image is checked against its checksum, and damaged ones are taken again.
    let mut resumed = None;
    let was_empty_folder = !resuming && dir.is_dir();
    let remaining = if resuming {
        frontend.note(&format!(
            "checking every journaled image of {} against its checksum\n",
            dir.display()
        ));
        let s = Session::resume(&dir)?;
        if !s.repairs().is_empty() {
            let mut text = format!(
                "resume: {} journaled shot(s) are missing or damaged and will be taken again \
                 (a damaged file is kept in {}):\n",
                s.repairs().len(),
                dir.join(crate::capture::session::SET_ASIDE_DIR).display()
            );
            for r in s.repairs() {
                text += &format!("  {}: {} (shot {})\n", r.file, r.problem.what(), r.id);
            }
            frontend.note(&text);
        }
        let n = s.remaining().len();
        resumed = Some(s);
        n
    } else {
        capture_start::check_output_folder(&dir)?;
        plan.shots().len()
    };
    check_disk_space(&dir, remaining, plan.camera.width, plan.camera.height)?;

    // 4. Devices, before anything moves or is written.
    let profile = &kit.profile;
    let OpenRig { rig, sim, .. } =
        rig_factory::open(profile, req.port.as_deref()).map_err(|source| {
            CaptureRunError::OpenRig {
                origin: profile.origin.clone(),
                port: req
                    .port
                    .as_ref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_else(|| profile.serial.port.clone()),
                source: Box::new(source),
            }
        })?;
    {
        use crate::devices::Light;
        plan.check_rig(rig.light.channel_count())
            .map_err(CaptureRunError::PlanDoesNotFit)?;
    }
    let stage = StageState::default();
    let mut camera = kit.open_camera(
        plan.camera.width,
        plan.camera.height,
        sim.as_ref(),
        &stage,
        &dir.join(".download"),
    )?;
    let options = RunOptions {
        kill_hook: kill_hook()?,
        ..kit.run_options(req.snapshot_every)
    };

    // 5. The session: everything is checked, so it is written now (with the simulated ground
    // truth; deterministic and cheap, so written again on resume in case a kill interrupted it).
    let mut session = match resumed {
        Some(s) => {
            kit.refresh_ground_truth(&dir, &plan)?;
            s
        }
        None => kit.create_session(&dir, &plan, &plan_text, was_empty_folder)?,
    };

    // 6. Run.
    frontend.watch_cancel(options.cancel.clone());
    let mut base: Box<dyn Operator> = if req.unattended {
        Box::new(Unattended)
    } else {
        frontend.guided_operator(options.cancel.clone())
    };
    let mut operator = capture_start::SimStage {
        inner: base.as_mut(),
        stage: stage.clone(),
    };
    let mut progress = frontend.progress();
    let mut rig = rig;
    let result = run_session(
        &mut session,
        &mut rig.turntable,
        &mut rig.light,
        camera.as_mut(),
        &mut operator,
        progress.as_mut(),
        &options,
    );
    // A new session that stopped before its first shot holds nothing worth resuming.
    let removed = !resuming && result.is_err() && session.records().is_empty();
    drop(session);
    if removed {
        capture_start::remove_new_session(&dir, was_empty_folder)?;
    }
    Ok(Outcome {
        result,
        dir,
        resume_command: resume_cmd,
        removed,
    })
}

fn read(path: &Path) -> Result<String, CaptureRunError> {
    std::fs::read_to_string(path).map_err(|source| CaptureRunError::Read {
        path: path.to_path_buf(),
        source,
    })
}
