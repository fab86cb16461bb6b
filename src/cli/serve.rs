//! `brdf-rig serve`: the lab page. Parses and checks the options, starts the server
//! (`brdf_rig::serve`), prints where it listens and waits for Ctrl-C or SIGTERM, which pause a
//! capture under way at its next safe point (light off) before the server stops.

use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use anyhow::Context;
use clap::Args;

use brdf_rig::serve::{ServeConfig, Server, control};

use super::ranges::{Closed, real_in};
use super::rig::RigArgs;

#[derive(Args, Debug)]
pub struct ServeArgs {
    #[command(flatten)]
    pub rig: RigArgs,
    /// Address and port to listen on. Beyond 127.0.0.1 / [::1], --token-file is required.
    /// Port 0 picks a free port (printed).
    #[arg(long, default_value = "127.0.0.1:8080")]
    pub bind: SocketAddr,
    /// File whose first line is the token every acting request needs (`Authorization: Bearer
    /// TOKEN`); at least 12 characters. Required when bound beyond localhost.
    #[arg(long, value_name = "FILE")]
    pub token_file: Option<PathBuf>,
    /// Folder for new sessions (created if missing); its sessions can be resumed from the page.
    #[arg(long, default_value = "sessions")]
    pub sessions: PathBuf,
    /// Folder of capture plans (*.toml) the page offers besides the built-in one
    /// [default: capture-plans, when it exists].
    #[arg(long)]
    pub plans: Option<PathBuf>,
    /// Live preview size, WIDTHxHEIGHT (16x16 to 4096x4096).
    #[arg(long, default_value = "640x480", value_parser = size)]
    pub preview_size: (usize, usize),
    /// Live preview frames per second at most (0.5 to 30).
    #[arg(long, default_value_t = 8.0, value_parser = real_in(Closed(0.5), Closed(30.0)))]
    pub preview_fps: f64,
    /// Seconds of silence after which a page is gone (and a capture it controls pauses);
    /// 0.5 to 60. A closed page is noticed at once.
    #[arg(long, default_value_t = 1.5, value_parser = real_in(Closed(0.5), Closed(60.0)))]
    pub lost_after: f64,
}

fn size(s: &str) -> Result<(usize, usize), String> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| format!("{s:?}: expected WIDTHxHEIGHT, e.g. 640x480"))?;
    let n = |v: &str| {
        v.trim()
            .parse::<usize>()
            .ok()
            .filter(|n| (16..=4096).contains(n))
            .ok_or_else(|| format!("{s:?}: width and height must be whole numbers in [16, 4096]"))
    };
    Ok((n(w)?, n(h)?))
}

pub fn run(args: ServeArgs) -> anyhow::Result<ExitCode> {
    let token = match &args.token_file {
        Some(f) => {
            let text = std::fs::read_to_string(f)
                .with_context(|| format!("reading the token file {}", f.display()))?;
            Some(control::read_token(&text, &f.display().to_string())?)
        }
        None => None,
    };
    let plans = args.plans.clone().or_else(|| {
        let d = PathBuf::from("capture-plans");
        d.is_dir().then_some(d)
    });
    let config = ServeConfig {
        bind: args.bind,
        profile: args.rig.profile()?,
        port_override: args.rig.port.clone(),
        token,
        sessions_dir: args.sessions.clone(),
        plans_dir: plans,
        preview_size: args.preview_size,
        preview_fps: args.preview_fps,
        lost_after: Duration::from_secs_f64(args.lost_after),
    };
    let server = Server::start(config).context("starting the lab page")?;
    let addr = server.addr();
    let shown = if addr.ip().is_unspecified() {
        format!("http://<this machine's address>:{}/", addr.port())
    } else {
        format!("http://{addr}/")
    };
    outln!("{shown}");
    errln!(
        "the lab page is at {shown} (sessions in {}); Ctrl-C stops (a capture under way pauses, light off)",
        args.sessions.display()
    );
    wait_for_signal()?;
    errln!("stopping: a capture under way pauses at its next safe point");
    let end = server.stop();
    if let (Some(dir), Some(cmd)) = (&end.capture.dir, &end.capture.resume_command) {
        errln!(
            "session {dir}: {} of {} shots; the light is off. Continue with `{cmd}` or from the page",
            end.capture.done,
            end.capture.total
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Ctrl-C or SIGTERM.
fn wait_for_signal() -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting the signal handler")?;
    rt.block_on(async {
        let mut term = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
            .context("listening for SIGTERM")?;
        tokio::select! {
            r = tokio::signal::ctrl_c() => r.context("listening for Ctrl-C"),
            _ = term.recv() => Ok(()),
        }
    })
}
