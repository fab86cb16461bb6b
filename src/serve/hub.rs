//! The meeting point of the lab page's threads: the async server (HTTP handlers, one task per
//! connected page), the rig's thread (device calls and captures) and the preview worker.
//!
//! It holds the page state and the latest preview frame in `tokio::sync::watch` channels (every
//! page task wakes on a change and sends the newest value; a slow page skips values, never
//! queues them), the control bookkeeping, the channel of commands to the rig's thread, the stop
//! request of the capture under way and the operator's Continue. Nothing here touches a device:
//! the rig's thread does (`device`), and async code only sends it commands.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, mpsc};
use std::time::Instant;

use tokio::sync::{oneshot, watch};

use super::control::{ClientKey, Control, Refusal, Token};
use super::preview::Frame;
use super::state::{PageState, Phase, PreviewSettings};
use crate::capture::CaptureError;
use crate::capture::plan::PlanError;
use crate::pipeline::capture_start::StartError;
use crate::sim::SimHandle;

/// Why the rig's thread did not do what the page asked. Its text is the page's reply (the
/// `error` of the JSON body), so it is written for the person at the page.
#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    #[error("the rig's thread has stopped")]
    Stopped,
    #[error("the rig was busy for too long; nothing was done, ask again")]
    Stale,
    /// A capture command sent where a light or turntable command was expected.
    #[error("not a rig command")]
    NotARigCommand,
    /// A light or turntable command failed; `doing` says what the rig was doing.
    #[error("{doing}: {source}")]
    Device {
        doing: String,
        #[source]
        source: crate::devices::DeviceError,
    },
    #[error(transparent)]
    Start(#[from] StartFailure),
}

/// Why a capture the page asked for did not start: the page's reply and the capture's stop
/// reason. The checks are `brdf-rig capture`'s, so most are its errors unchanged.
#[derive(Debug, thiserror::Error)]
pub enum StartFailure {
    /// No plans folder, so only the built-in plan exists.
    #[error("unknown plan {0:?}")]
    UnknownPlan(String),
    #[error("unknown plan {id:?} (not in {})", dir.display())]
    UnlistedPlan { id: String, dir: std::path::PathBuf },
    #[error("reading {}: {source}", path.display())]
    Read {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("the plan does not fit the rig: {0}")]
    PlanDoesNotFit(#[source] PlanError),
    #[error("{} is not a session folder", dir.display())]
    NotASession { dir: std::path::PathBuf },
    /// `command` continues the session from a terminal, on the rig it was captured with.
    #[error(
        "{} was captured with another rig profile than this server's ({profile}): continue it with `{command}`, or serve with --profile {}",
        dir.display(),
        copy.display()
    )]
    OtherProfile {
        dir: std::path::PathBuf,
        profile: String,
        command: String,
        copy: std::path::PathBuf,
    },
    #[error(transparent)]
    Capture(#[from] CaptureError),
    #[error(transparent)]
    Start(#[from] StartError),
}

/// Something for the rig's thread to do, with where to send the answer.
pub struct Request {
    pub command: Command,
    pub reply: oneshot::Sender<Result<String, CommandError>>,
    /// Requests older than [`STALE_AFTER`] when the rig's thread gets to them are refused
    /// (the rig was busy: acting late would surprise the person who asked).
    pub sent: Instant,
}

/// How old a request may be when the rig's thread reads it.
pub const STALE_AFTER: std::time::Duration = std::time::Duration::from_secs(3);

/// What the page can ask of the rig (all validated before they are sent).
#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    LightOn {
        channel: usize,
        level: f64,
    },
    LightOff,
    Home,
    MoveTo {
        angle_deg: f64,
    },
    Start(StartSpec),
    Resume {
        session: String,
        guided: bool,
    },
    /// Ends the rig's thread (the light goes off).
    Shutdown,
}

/// A new capture, as the page asked for it (names already checked).
#[derive(Clone, Debug, PartialEq)]
pub struct StartSpec {
    pub plan_id: String,
    pub session: String,
    pub guided: bool,
    pub snapshot_every: usize,
}

/// Why a capture is asked to stop.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum StopKind {
    /// Stop at a safe point, to be resumed.
    Pause,
    /// Stop at a safe point and leave the session (it stays resumable).
    Abort,
}

struct Stop {
    flag: Arc<AtomicBool>,
    kind: Option<(StopKind, String)>,
}

/// Shared by every thread of the server.
pub struct Hub {
    state: watch::Sender<PageState>,
    preview: watch::Sender<Option<Arc<Frame>>>,
    control: Mutex<Control>,
    pub token: Token,
    commands: Mutex<mpsc::Sender<Request>>,
    continues: Mutex<mpsc::Sender<u64>>,
    stop: Mutex<Stop>,
    /// The simulated rig's state, read beside the serial link (simulated rig only).
    pub sim: Option<SimHandle>,
    /// Preview frames sent, per client number.
    frames_sent: Mutex<std::collections::BTreeMap<u64, u64>>,
    frames_made: AtomicU64,
    /// Set when the server stops: every page's stream ends.
    closing: watch::Sender<bool>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic while holding one of these leaves plain data; keep serving.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The receiving ends the rig's thread owns.
pub struct DeviceEnds {
    pub commands: mpsc::Receiver<Request>,
    pub continues: mpsc::Receiver<u64>,
}

impl Hub {
    pub fn new(initial: PageState, token: Token, sim: Option<SimHandle>) -> (Arc<Hub>, DeviceEnds) {
        let (cmd_tx, cmd_rx) = mpsc::channel();
        let (cont_tx, cont_rx) = mpsc::channel();
        let hub = Hub {
            state: watch::Sender::new(initial),
            preview: watch::Sender::new(None),
            control: Mutex::new(Control::default()),
            token,
            commands: Mutex::new(cmd_tx),
            continues: Mutex::new(cont_tx),
            stop: Mutex::new(Stop {
                flag: Arc::new(AtomicBool::new(false)),
                kind: None,
            }),
            sim,
            frames_sent: Mutex::default(),
            frames_made: AtomicU64::new(0),
            closing: watch::Sender::new(false),
        };
        (
            Arc::new(hub),
            DeviceEnds {
                commands: cmd_rx,
                continues: cont_rx,
            },
        )
    }

    // ---- state ----

    /// Changes the page state (every page gets the new one).
    pub fn update(&self, f: impl FnOnce(&mut PageState)) {
        self.state.send_modify(f);
    }

    /// Changes the page state when `f` says it changed something (pages wake only then).
    pub fn update_if(&self, f: impl FnOnce(&mut PageState) -> bool) {
        self.state.send_if_modified(f);
    }

    /// Ends every page's stream (the server is stopping).
    pub fn close(&self) {
        self.closing.send_replace(true);
    }

    pub fn subscribe_closing(&self) -> watch::Receiver<bool> {
        self.closing.subscribe()
    }

    /// A copy of the page state now.
    pub fn snapshot(&self) -> PageState {
        self.state.borrow().clone()
    }

    pub fn subscribe_state(&self) -> watch::Receiver<PageState> {
        self.state.subscribe()
    }

    pub fn phase(&self) -> Phase {
        self.state.borrow().capture.phase
    }

    pub fn preview_settings(&self) -> PreviewSettings {
        self.state.borrow().preview.clone()
    }

    pub fn log(&self, level: &str, text: impl Into<String>) {
        let text = text.into();
        self.update(|s| s.log(level, text));
    }

    // ---- preview ----

    pub fn publish_frame(&self, frame: Frame) {
        self.frames_made.fetch_add(1, Ordering::Relaxed);
        self.preview.send_replace(Some(Arc::new(frame)));
    }

    pub fn subscribe_preview(&self) -> watch::Receiver<Option<Arc<Frame>>> {
        self.preview.subscribe()
    }

    /// Frames made since the server started.
    pub fn frames_made(&self) -> u64 {
        self.frames_made.load(Ordering::Relaxed)
    }

    pub fn count_frame_sent(&self, client: u64) {
        *lock(&self.frames_sent).entry(client).or_default() += 1;
    }

    /// Frames sent to each connected page, by page number.
    pub fn frames_sent(&self) -> Vec<(u64, u64)> {
        lock(&self.frames_sent)
            .iter()
            .map(|(k, v)| (*k, *v))
            .collect()
    }

    /// Pages are connected (live preview frames are worth making).
    pub fn has_watchers(&self) -> bool {
        lock(&self.control).count() > 0
    }

    // ---- control ----

    pub fn join(&self, address: SocketAddr) -> (ClientKey, u64) {
        let now = crate::capture::session::now_utc().1;
        let joined = lock(&self.control).join(address, now);
        lock(&self.frames_sent).insert(joined.1, 0);
        self.publish_control();
        joined
    }

    /// A page went away. When it controlled, a capture under way pauses.
    pub fn leave(&self, key: &str, number: u64, why: &str) {
        let was_controller = lock(&self.control).leave(key);
        lock(&self.frames_sent).remove(&number);
        self.publish_control();
        if was_controller {
            self.log(
                "warn",
                format!("the controlling page (page {number}) {why}"),
            );
            if self.phase().is_active() {
                self.request_stop(
                    StopKind::Pause,
                    format!("the controlling page (page {number}) {why}"),
                );
            } else {
                // a light it switched on does not stay on for nobody
                drop(self.send(Command::LightOff));
            }
        }
    }

    pub fn claim(&self, key: &str, name: &str) -> Result<(), Refusal> {
        let r = lock(&self.control).claim(key, name);
        self.publish_control();
        if r.is_ok() {
            let info = lock(&self.control).info();
            if let Some(c) = info.controller {
                self.log(
                    "info",
                    format!("{} ({}) controls the rig", c.name, c.address),
                );
            }
        }
        r
    }

    /// The controller gives control up; a capture under way pauses (a capture runs only while
    /// someone controls it).
    pub fn release(&self, key: &str) -> Result<(), Refusal> {
        lock(&self.control).check(Some(key))?;
        lock(&self.control).release(key);
        self.publish_control();
        if self.phase().is_active() {
            self.request_stop(StopKind::Pause, "control was released".into());
        }
        Ok(())
    }

    /// Ok when the request carries the token (if one is needed) and comes from the controller.
    pub fn authorize(
        &self,
        authorization: Option<&str>,
        client: Option<&str>,
    ) -> Result<(), Refusal> {
        self.token.check(authorization)?;
        lock(&self.control).check(client)
    }

    pub fn is_controller(&self, key: &str) -> bool {
        lock(&self.control).is_controller(key)
    }

    pub fn is_connected(&self, key: &str) -> bool {
        lock(&self.control).is_connected(key)
    }

    fn publish_control(&self) {
        let info = lock(&self.control).info();
        self.update(|s| s.control = info);
    }

    // ---- commands to the rig's thread ----

    /// Sends a command to the rig's thread; the answer arrives on the returned channel.
    pub fn send(&self, command: Command) -> oneshot::Receiver<Result<String, CommandError>> {
        let (tx, rx) = oneshot::channel();
        let req = Request {
            command,
            reply: tx,
            sent: Instant::now(),
        };
        if let Err(mpsc::SendError(req)) = lock(&self.commands).send(req) {
            let _ = req.reply.send(Err(CommandError::Stopped));
        }
        rx
    }

    /// The operator's Continue for instruction `seq`.
    pub fn send_continue(&self, seq: u64) {
        let _ = lock(&self.continues).send(seq);
    }

    // ---- stopping a capture ----

    /// A fresh stop flag for a run that starts now.
    pub fn arm_stop(&self) -> Arc<AtomicBool> {
        let mut s = lock(&self.stop);
        s.flag = Arc::new(AtomicBool::new(false));
        s.kind = None;
        s.flag.clone()
    }

    /// Asks the run under way to stop at its next safe point. A pause does not turn an abort
    /// already asked for into a pause.
    pub fn request_stop(&self, kind: StopKind, reason: String) {
        {
            let mut s = lock(&self.stop);
            if s.kind.as_ref().is_none_or(|(k, _)| *k == StopKind::Pause) {
                s.kind = Some((kind, reason.clone()));
            }
            s.flag.store(true, Ordering::SeqCst);
        }
        self.update(|st| {
            if st.capture.phase.is_active() {
                st.capture.phase = Phase::Stopping;
                st.capture.stop_reason = Some(reason.clone());
            }
        });
    }

    /// Why the run was asked to stop, if it was.
    pub fn stop_requested(&self) -> Option<(StopKind, String)> {
        lock(&self.stop).kind.clone()
    }
}
