//! `brdf-rig capture`: a capture session, new (`--out DIR`) or continued (`--resume DIR`).
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
use std::process::ExitCode;
use std::sync::atomic::Ordering;
use std::sync::mpsc;
use std::time::Duration;

use anyhow::{Context, bail};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use brdf_rig::capture::plan::{DEFAULT_PLAN_TOML, load_plan, parse_plan};
use brdf_rig::capture::runner::{KillPhase, Progress, RunOptions, stage_instructions};
use brdf_rig::capture::{
    CaptureError, Operator, Session, ShotRecord, Stage, check_disk_space, run_session,
};
use brdf_rig::pipeline::capture_start::{self, CaptureRig, PROFILE_COPY};
use brdf_rig::profile::Profile;
use brdf_rig::rig_factory::{self, OpenRig};
use brdf_rig::sim::scene::StageState;

use super::ranges::int_in;
use super::rig::RigArgs;

#[derive(Args, Debug)]
pub struct CaptureArgs {
    #[command(flatten)]
    pub rig: RigArgs,
    /// Capture plan (TOML); default: the built-in plan (capture-plans/default.toml).
    #[arg(long)]
    pub plan: Option<PathBuf>,
    /// New session folder (must not exist, or be empty).
    #[arg(long, required_unless_present = "resume", conflicts_with = "resume")]
    pub out: Option<PathBuf>,
    /// Continue the interrupted session in DIR with the plan and profile it was started with.
    #[arg(long, value_name = "DIR")]
    pub resume: Option<PathBuf>,
    /// No prompts: assume the room light, sphere and white reference are handled (the simulated
    /// rig's virtual operator does it).
    #[arg(long)]
    pub unattended: bool,
    /// Write manifest.json every N shots (it is also written at every stage change and at the
    /// end; the journal is written after every shot regardless). 1 to 100000.
    #[arg(long, default_value_t = 16, value_parser = int_in(1usize, 100_000))]
    pub snapshot_every: usize,
}

/// A person at the rig: prints what to do and waits for Enter. Ctrl-C while waiting stops.
struct Guided {
    cancel: std::sync::Arc<std::sync::atomic::AtomicBool>,
    lines: mpsc::Receiver<Option<String>>,
}

impl Guided {
    fn new(cancel: std::sync::Arc<std::sync::atomic::AtomicBool>) -> Self {
        // stdin is read on its own thread so that Ctrl-C can interrupt the wait.
        let (tx, rx) = mpsc::channel();
        let _ = std::thread::Builder::new()
            .name("stdin".into())
            .spawn(move || {
                let stdin = std::io::stdin();
                loop {
                    let mut line = String::new();
                    match stdin.read_line(&mut line) {
                        Ok(0) | Err(_) => {
                            let _ = tx.send(None);
                            return;
                        }
                        Ok(_) => {
                            if tx.send(Some(line)).is_err() {
                                return;
                            }
                        }
                    }
                }
            });
        Self { cancel, lines: rx }
    }
}

impl Operator for Guided {
    fn set_stage(&mut self, from: Option<Stage>, to: Stage) -> Result<(), CaptureError> {
        let steps = stage_instructions(from, to);
        if steps.is_empty() {
            return Ok(());
        }
        eprintln!();
        for s in &steps {
            eprintln!("  >>> {s}");
        }
        eprintln!("  Press Enter when done (Ctrl-C stops; the session can be resumed).");
        loop {
            if self.cancel.load(Ordering::SeqCst) {
                return Err(CaptureError::Setup("stopped by Ctrl-C at a prompt".into()));
            }
            match self.lines.recv_timeout(Duration::from_millis(100)) {
                Ok(Some(_)) => return Ok(()),
                Ok(None) | Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(CaptureError::Setup(
                        "standard input closed while waiting for the operator".into(),
                    ));
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {}
            }
        }
    }
}

/// Progress bar with time left; messages go above it.
struct Bars {
    bar: ProgressBar,
}

impl Bars {
    fn new() -> Self {
        let bar = ProgressBar::new(0);
        if let Ok(style) =
            ProgressStyle::with_template("{bar:40} {pos}/{len} shots  {per_sec}  {eta} left  {msg}")
        {
            bar.set_style(style);
        }
        Self { bar }
    }
}

impl Progress for Bars {
    fn start(&mut self, total: usize, already_done: usize) {
        self.bar.set_length(total as u64);
        self.bar.set_position(already_done as u64);
        self.bar.reset_eta();
    }
    fn shot_done(&mut self, record: &ShotRecord) {
        self.bar.set_message(record.id.clone());
        self.bar.inc(1);
    }
    fn message(&mut self, text: &str) {
        self.bar.println(format!("  {text}"));
    }
    fn finish(&mut self) {
        self.bar.finish_and_clear();
    }
}

fn kill_hook() -> anyhow::Result<Option<(usize, KillPhase)>> {
    let Ok(v) = std::env::var("BRDF_RIG_TEST_KILL_AT") else {
        return Ok(None);
    };
    let (n, phase) = v.split_once(':').unwrap_or((v.as_str(), "after-journal"));
    let n: usize = n
        .parse()
        .with_context(|| format!("BRDF_RIG_TEST_KILL_AT={v}: expected N:phase"))?;
    let phase = KillPhase::parse(phase).with_context(|| {
        format!("BRDF_RIG_TEST_KILL_AT={v}: phase is before-image, after-image or after-journal")
    })?;
    Ok(Some((n, phase)))
}

pub fn run(args: CaptureArgs) -> anyhow::Result<ExitCode> {
    let outcome = execute(args)?;
    report(outcome)
}

/// What a capture command did: the run's result, its session folder, and how to continue it.
pub struct Outcome {
    pub result: Result<brdf_rig::capture::RunSummary, CaptureError>,
    pub dir: PathBuf,
    /// The command that continues this session, as the user should type it.
    pub resume_command: String,
    /// A new session that failed before any shot was taken was removed again.
    pub removed: bool,
}

/// `brdf-rig capture --resume DIR`, with the options a resume cannot read from the session:
/// `--unattended` (without a terminal a guided resume refuses to start) and `--port`.
fn resume_command(args: &CaptureArgs, dir: &Path) -> String {
    capture_start::resume_command(dir, args.rig.port.as_deref(), args.unattended)
}

/// Prepares everything and runs the session. Everything that can be checked is checked before
/// the session folder is written; a new session whose start fails is removed again.
pub fn execute(args: CaptureArgs) -> anyhow::Result<Outcome> {
    let resuming = args.resume.is_some();
    // 1. Plan and profile, the camera and scene sections, the simulated scene.
    let (dir, plan, plan_text, profile) = match (&args.resume, &args.out) {
        (Some(dir), _) => {
            let plan_path = dir.join(brdf_rig::capture::session::PLAN_FILE);
            let plan = load_plan(&plan_path)
                .with_context(|| format!("resuming {}: is it a session folder?", dir.display()))?;
            let profile = match &args.rig.profile {
                Some(p) => Profile::load(p)?,
                None => Profile::load(&dir.join(PROFILE_COPY))?,
            };
            let text = std::fs::read_to_string(&plan_path)
                .with_context(|| format!("reading {}", plan_path.display()))?;
            (dir.clone(), plan, text, profile)
        }
        (None, Some(out)) => {
            let (plan, text) = match &args.plan {
                Some(p) => (
                    load_plan(p)?,
                    std::fs::read_to_string(p)
                        .with_context(|| format!("reading {}", p.display()))?,
                ),
                None => (
                    parse_plan(DEFAULT_PLAN_TOML, "capture-plans/default.toml (built in)")?,
                    DEFAULT_PLAN_TOML.to_string(),
                ),
            };
            (out.clone(), plan, text, args.rig.profile()?)
        }
        (None, None) => bail!("give --out DIR for a new capture or --resume DIR"),
    };
    let resume_cmd = resume_command(&args, &dir);
    let kit = CaptureRig::load(profile)?;
    let lab = kit.lab.clone();
    eprint!("{}", plan.summary(&lab));

    // 2. Guided mode needs someone at a terminal.
    if !args.unattended && !std::io::stdin().is_terminal() {
        bail!(
            "guided mode waits for the operator to press Enter, but standard input is not a terminal; \
             run it in a terminal, or pass --unattended when nobody needs to act (simulated rig, or a \
             rig whose room light and targets are already set)"
        );
    }

    // 3. The folder and its free space. A resumed session is opened (and locked) here: every
    // journaled image is checked against its checksum, and damaged ones are taken again.
    let mut resumed = None;
    let was_empty_folder = !resuming && dir.is_dir();
    let remaining = if resuming {
        eprintln!(
            "checking every journaled image of {} against its checksum",
            dir.display()
        );
        let s = Session::resume(&dir)?;
        if !s.repairs().is_empty() {
            eprintln!(
                "resume: {} journaled shot(s) are missing or damaged and will be taken again \
                 (a damaged file is kept in {}):",
                s.repairs().len(),
                dir.join(brdf_rig::capture::session::SET_ASIDE_DIR)
                    .display()
            );
            for r in s.repairs() {
                eprintln!("  {}: {} (shot {})", r.file, r.problem.what(), r.id);
            }
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
    let OpenRig { rig, sim, .. } = rig_factory::open(profile, args.rig.port.as_deref())
        .with_context(|| {
            format!(
                "opening the rig of {} (port {}); nothing has moved",
                profile.origin,
                args.rig
                    .port
                    .as_ref()
                    .map(|p| p.display().to_string())
                    .unwrap_or_else(|| profile.serial.port.clone())
            )
        })?;
    {
        use brdf_rig::devices::Light;
        plan.check_rig(rig.light.channel_count())
            .map_err(|e| anyhow::anyhow!("the plan does not fit the rig: {e}"))?;
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
        ..kit.run_options(args.snapshot_every)
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
    let cancel = options.cancel.clone();
    let _ = ctrlc::set_handler(move || {
        cancel.store(true, Ordering::SeqCst);
    });
    let mut guided;
    let mut unattended = brdf_rig::capture::Unattended;
    let base: &mut dyn Operator = if args.unattended {
        &mut unattended
    } else {
        guided = Guided::new(options.cancel.clone());
        &mut guided
    };
    let mut operator = capture_start::SimStage {
        inner: base,
        stage: stage.clone(),
    };
    let mut bars = Bars::new();
    let mut rig = rig;
    let result = run_session(
        &mut session,
        &mut rig.turntable,
        &mut rig.light,
        camera.as_mut(),
        &mut operator,
        &mut bars,
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

fn report(outcome: Outcome) -> anyhow::Result<ExitCode> {
    let Outcome {
        result,
        dir,
        resume_command,
        removed,
    } = outcome;
    if removed {
        let why = match &result {
            Err(CaptureError::Interrupted { .. }) => {
                eprintln!(
                    "interrupted before the first shot; the light is off and the new session \
                     folder {} was removed",
                    dir.display()
                );
                return Ok(ExitCode::from(130));
            }
            Err(e) => e.to_string(),
            Ok(_) => String::new(),
        };
        bail!(
            "capture into {} stopped before its first shot ({why}); the light is off and the new \
             session folder was removed: run the same command again",
            dir.display()
        );
    }
    match result {
        Ok(summary) => {
            eprintln!(
                "capture complete: {} shots in {} ({} taken now in {:.1} s, {:.2} shots/s); verify with `brdf-rig session verify {}`",
                summary.shots_total,
                dir.display(),
                summary.shots_taken,
                summary.wall.as_secs_f64(),
                summary.shots_taken as f64 / summary.wall.as_secs_f64().max(1e-9),
                dir.display()
            );
            if summary.retakes > 0 {
                eprintln!(
                    "  {} of them re-taken because their journaled image was missing or damaged \
                     (damaged files are kept in {})",
                    summary.retakes,
                    dir.join(brdf_rig::capture::session::SET_ASIDE_DIR).display()
                );
            }
            let per = |d: Duration| 1000.0 * d.as_secs_f64() / summary.shots_taken.max(1) as f64;
            eprintln!(
                "  per shot: {:.1} ms wall = devices {:.1} ms (camera {:.1}, settle {:.1}) + storage {:.1} ms + controller {:.2} ms",
                per(summary.wall),
                per(summary.device_time),
                per(summary.camera_time),
                per(summary.settle_time),
                per(summary.storage_time),
                1000.0 * summary.overhead_per_shot().as_secs_f64()
            );
            Ok(ExitCode::SUCCESS)
        }
        Err(CaptureError::Interrupted { done, total }) => {
            eprintln!(
                "interrupted: {done} of {total} shots are in {}; the light is off. Continue with `{resume_command}`",
                dir.display(),
            );
            Ok(ExitCode::from(130))
        }
        Err(e) => Err(anyhow::Error::new(e).context(format!(
            "capture into {} stopped; the light is off and the session is consistent: continue with `{resume_command}`",
            dir.display(),
        ))),
    }
}
