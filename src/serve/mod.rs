//! The lab page (`brdf-rig serve`): a small HTTP server that drives the rig and runs guided and
//! unattended captures from a browser, with a live camera preview, the next step, progress and
//! the session's health.
//!
//! Threads, and who may touch what:
//! - the rig's thread (`device`) owns the turntable, the light and the camera, and runs
//!   captures with the same engine as `brdf-rig capture` (`capture::run_session`, the checks and
//!   session creation of `pipeline::capture_start`); nothing else talks to a device;
//! - the preview worker (`preview`) turns images into JPEG frames with clipping marks and
//!   histograms;
//! - the async server (tokio, axum; its own thread) answers HTTP (`routes`) and keeps one event
//!   stream per page (`events`); it only reads the shared state and sends commands to the rig's
//!   thread through the `hub`.
//!
//! Safety: one page controls at a time (`control`); a capture runs only while its controlling
//! page is there: a page closed, crashed or cut off pauses the capture at its next safe point
//! with the light off, and the session stays resumable from a page or with
//! `brdf-rig capture --resume`. Bound beyond localhost, actions need the server's token.
//! See docs/web.md.

pub mod control;
pub mod device;
pub mod events;
pub mod hub;
pub mod live;
pub mod operator;
pub mod preview;
pub mod progress;
pub mod requests;
pub mod routes;
pub mod state;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use crate::pipeline::capture_start::{CaptureRig, StartError};
use crate::profile::Profile;

use hub::{Command, Hub, StopKind};
use state::{PageState, ServerInfo};

/// How `serve` was asked to run.
#[derive(Clone, Debug)]
pub struct ServeConfig {
    pub bind: SocketAddr,
    pub profile: Profile,
    /// `--port`: the rig's serial port instead of the profile's.
    pub port_override: Option<PathBuf>,
    /// The token acting requests need (required when bound beyond localhost).
    pub token: Option<String>,
    /// New sessions are created here; sessions here can be resumed from the page.
    pub sessions_dir: PathBuf,
    /// Plans on offer (`*.toml`), besides the built-in one.
    pub plans_dir: Option<PathBuf>,
    /// Live preview size (the simulated camera renders it; a V4L2 camera is asked for it).
    pub preview_size: (usize, usize),
    /// Live preview frames per second at most (also the rate of shot images during a capture).
    pub preview_fps: f64,
    /// A page silent this long is gone.
    pub lost_after: Duration,
}

#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    #[error("{0}")]
    Config(String),
    #[error(transparent)]
    Start(#[from] StartError),
    #[error("opening the rig of {profile} (port {port}): {reason}")]
    Rig {
        profile: String,
        port: String,
        reason: String,
    },
    #[error("{what}: {source}")]
    Io {
        what: String,
        #[source]
        source: std::io::Error,
    },
}

fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> ServeError {
    let what = what.into();
    move |source| ServeError::Io { what, source }
}

/// A running server.
pub struct Server {
    addr: SocketAddr,
    hub: Arc<Hub>,
    http: Option<(tokio::sync::oneshot::Sender<()>, JoinHandle<()>)>,
    rig: Option<JoinHandle<()>>,
}

impl Server {
    /// Checks the configuration, opens the rig, starts the threads and listens. Returns once
    /// the server answers.
    pub fn start(config: ServeConfig) -> Result<Server, ServeError> {
        if control::needs_token(&config.bind) && config.token.is_none() {
            return Err(ServeError::Config(format!(
                "--bind {}: beyond localhost every action needs a token; give --token-file FILE \
                 (a file whose first line is a secret of at least 12 characters)",
                config.bind
            )));
        }
        std::fs::create_dir_all(&config.sessions_dir).map_err(io(format!(
            "creating the sessions folder {}",
            config.sessions_dir.display()
        )))?;
        let kit = CaptureRig::load(config.profile.clone())?;
        let crate::rig_factory::OpenRig { rig, sim, .. } =
            crate::rig_factory::open(&kit.profile, config.port_override.as_deref()).map_err(
                |e| ServeError::Rig {
                    profile: kit.profile.origin.clone(),
                    port: config
                        .port_override
                        .as_ref()
                        .map(|p| p.display().to_string())
                        .unwrap_or_else(|| kit.profile.serial.port.clone()),
                    reason: e.to_string(),
                },
            )?;
        // bind before anything else runs, so a taken port is an error here
        let listener = std::net::TcpListener::bind(config.bind)
            .map_err(io(format!("listening on {}", config.bind)))?;
        listener
            .set_nonblocking(true)
            .map_err(io("setting up the listener"))?;
        let addr = listener.local_addr().map_err(io("reading the address"))?;

        let mut initial = PageState {
            server: ServerInfo {
                version: env!("CARGO_PKG_VERSION").to_string(),
                bind: addr.to_string(),
                token_required: config.token.is_some(),
                profile: kit.profile.origin.clone(),
                sessions_dir: config.sessions_dir.display().to_string(),
                lost_after_millis: config.lost_after.as_millis() as u64,
                preview_fps: config.preview_fps,
                preview_size: config.preview_size,
            },
            rig: device::initial_rig_state(&rig, &kit),
            ..PageState::default()
        };
        initial.log(
            "info",
            format!("serving on {addr}; rig on {}", rig.port.display()),
        );
        let limits = requests::RigLimits {
            max_levels: kit
                .profile
                .light
                .channels
                .iter()
                .map(|c| c.max_level)
                .collect(),
            min_angle_deg: kit.profile.turntable.min_angle_deg,
            max_angle_deg: kit.profile.turntable.max_angle_deg,
        };
        let (hub, ends) = Hub::new(
            initial,
            control::Token::new(config.token.as_deref()),
            sim.clone(),
        );

        let publish_hub = hub.clone();
        let (pw, ph) = config.preview_size;
        let worker = Arc::new(
            preview::Worker::spawn(pw, ph, move |frame| match frame {
                Ok(f) => publish_hub.publish_frame(f),
                Err(e) => publish_hub.log("warn", e.to_string()),
            })
            .map_err(io("starting the preview thread"))?,
        );
        let settings = device::DeviceSettings {
            sessions_dir: config.sessions_dir.clone(),
            plans_dir: config.plans_dir.clone(),
            port_override: config.port_override.clone(),
            preview_size: config.preview_size,
            preview_fps: config.preview_fps,
        };
        let rig_hub = hub.clone();
        let rig_thread = std::thread::Builder::new()
            .name("brdf-rig-rig".into())
            .spawn(move || {
                device::RigThread::new(rig_hub, kit, rig, sim, worker, settings).run(ends)
            })
            .map_err(io("starting the rig's thread"))?;

        let app = routes::App {
            hub: hub.clone(),
            lost_after: config.lost_after,
            local_only: config.bind.ip().is_loopback(),
            limits,
            sessions_dir: config.sessions_dir.clone(),
        };
        let (stop_tx, stop_rx) = tokio::sync::oneshot::channel::<()>();
        let (ready_tx, ready_rx) = std::sync::mpsc::channel::<Result<(), ServeError>>();
        let http_hub = hub.clone();
        let http = std::thread::Builder::new()
            .name("brdf-rig-http".into())
            .spawn(move || {
                let rt = match tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                {
                    Ok(rt) => rt,
                    Err(e) => {
                        let _ = ready_tx.send(Err(io("starting the async runtime")(e)));
                        return;
                    }
                };
                rt.block_on(async move {
                    let listener = match tokio::net::TcpListener::from_std(listener) {
                        Ok(l) => l,
                        Err(e) => {
                            let _ = ready_tx.send(Err(io("listening")(e)));
                            return;
                        }
                    };
                    tokio::spawn(watch_sim_truth(http_hub));
                    let _ = ready_tx.send(Ok(()));
                    let service =
                        routes::router(app).into_make_service_with_connect_info::<SocketAddr>();
                    let served = axum::serve(listener, service)
                        .with_graceful_shutdown(async move {
                            let _ = stop_rx.await;
                        })
                        .await;
                    if let Err(e) = served {
                        eprintln!("error: the HTTP server stopped: {e}");
                    }
                });
            })
            .map_err(io("starting the HTTP thread"))?;
        let mut server = Server {
            addr,
            hub,
            http: Some((stop_tx, http)),
            rig: Some(rig_thread),
        };
        match ready_rx.recv() {
            Ok(Ok(())) => Ok(server),
            Ok(Err(e)) => {
                server.shutdown();
                Err(e)
            }
            Err(_) => {
                server.shutdown();
                Err(ServeError::Config(
                    "the HTTP thread stopped at start".into(),
                ))
            }
        }
    }

    /// Where the server listens.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The shared state (for the benchmark and tests in this process).
    pub fn hub(&self) -> &Arc<Hub> {
        &self.hub
    }

    /// Stops: a capture under way pauses at its next safe point (light off), the rig's thread
    /// ends (light off), every page's stream closes, the server stops listening. Returns the
    /// page state at the end.
    pub fn stop(mut self) -> PageState {
        self.shutdown();
        self.hub.snapshot()
    }

    fn shutdown(&mut self) {
        if self.hub.phase().is_active() {
            self.hub
                .request_stop(StopKind::Pause, "the server is stopping".into());
        }
        if let Some(rig) = self.rig.take() {
            drop(self.hub.send(Command::Shutdown));
            let _ = rig.join();
        }
        self.hub.close();
        if let Some((stop, http)) = self.http.take() {
            let _ = stop.send(());
            let _ = http.join();
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Keeps `rig.sim` (the simulated board's own angle and light levels) current, read beside the
/// serial link every 100 ms, so a page sees what the board does even while a capture runs.
async fn watch_sim_truth(hub: Arc<Hub>) {
    let Some(sim) = hub.sim.clone() else { return };
    let mut tick = tokio::time::interval(Duration::from_millis(100));
    loop {
        tick.tick().await;
        let truth = state::SimTruth::of(&sim.snapshot());
        hub.update_if(|s| {
            if s.rig.sim.as_ref() == Some(&truth) {
                return false;
            }
            s.rig.sim = Some(truth);
            true
        });
    }
}
