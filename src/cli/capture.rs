//! `brdf-rig capture`: a capture session, new (`--out DIR`) or continued (`--resume DIR`).
//! Thin: the arguments become a `pipeline::capture_run::CaptureRequest`, which the library
//! checks and runs (the order of its checks is written there); the terminal's part (prompts,
//! progress bar, Ctrl-C) and the final report are here.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use anyhow::bail;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};

use brdf_rig::capture::runner::{Progress, stage_instructions};
use brdf_rig::capture::{CaptureError, Operator, ShotRecord, Stage};
use brdf_rig::pipeline::capture_run::{CaptureRequest, Frontend, Outcome, execute};

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
    cancel: Arc<AtomicBool>,
    lines: mpsc::Receiver<Option<String>>,
}

impl Guided {
    fn new(cancel: Arc<AtomicBool>) -> Self {
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
        errln!();
        for s in &steps {
            errln!("  >>> {s}");
        }
        errln!("  Press Enter when done (Ctrl-C stops; the session can be resumed).");
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

/// The terminal's side of a capture: notes and the progress bar on stderr, prompts answered with
/// Enter, Ctrl-C stops.
pub struct Terminal;

impl Frontend for Terminal {
    fn note(&mut self, text: &str) {
        errout!("{text}");
    }
    fn progress(&mut self) -> Box<dyn Progress> {
        Box::new(Bars::new())
    }
    fn guided_operator(&mut self, cancel: Arc<AtomicBool>) -> Box<dyn Operator> {
        Box::new(Guided::new(cancel))
    }
    fn watch_cancel(&mut self, cancel: Arc<AtomicBool>) {
        let _ = ctrlc::set_handler(move || {
            cancel.store(true, Ordering::SeqCst);
        });
    }
}

impl CaptureArgs {
    pub fn request(&self) -> CaptureRequest {
        CaptureRequest {
            profile: self.rig.profile.clone(),
            port: self.rig.port.clone(),
            plan: self.plan.clone(),
            out: self.out.clone(),
            resume: self.resume.clone(),
            unattended: self.unattended,
            snapshot_every: self.snapshot_every,
        }
    }
}

pub fn run(args: CaptureArgs) -> anyhow::Result<ExitCode> {
    let outcome = execute(&args.request(), &mut Terminal)?;
    report(outcome)
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
                errln!(
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
            errln!(
                "capture complete: {} shots in {} ({} taken now in {:.1} s, {:.2} shots/s); verify with `brdf-rig session verify {}`",
                summary.shots_total,
                dir.display(),
                summary.shots_taken,
                summary.wall.as_secs_f64(),
                summary.shots_taken as f64 / summary.wall.as_secs_f64().max(1e-9),
                dir.display()
            );
            if summary.retakes > 0 {
                errln!(
                    "  {} of them re-taken because their journaled image was missing or damaged \
                     (damaged files are kept in {})",
                    summary.retakes,
                    dir.join(brdf_rig::capture::session::SET_ASIDE_DIR).display()
                );
            }
            let per = |d: Duration| 1000.0 * d.as_secs_f64() / summary.shots_taken.max(1) as f64;
            errln!(
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
            errln!(
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
