//! `brdf-rig bench capture --page`: what the lab page costs. The live preview's frame rate at
//! the preview size (frames delivered to a connected page per second), and the wall time of the
//! same unattended capture run by `brdf-rig capture`, by `brdf-rig serve` with no page, and by
//! `brdf-rig serve` with a headless Chromium showing the page (which receives the state and a
//! preview frame of the shots as they are taken). The server runs in this process; the
//! benchmark starts the captures itself through the server's command channel (as the page's
//! Start does, without the control and token checks). Chromium is Debian's, with a fresh
//! profile and no background networking; it talks only to 127.0.0.1.

use std::fmt::Write as _;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use super::{BenchError, Note, temp_dir};
use crate::profile::Profile;
use crate::serve::hub::{Command as RigCommand, StartSpec};
use crate::serve::state::Phase;
use crate::serve::{ServeConfig, Server};

/// A headless Chromium showing `url` until dropped.
struct Page {
    child: Child,
    _profile: tempfile::TempDir,
}

impl Page {
    fn open(url: &str) -> Result<Page, BenchError> {
        let exe = crate::report::headless::chromium().ok_or_else(|| {
            BenchError::Invalid(
                "--page needs Debian's chromium (scripts/setup.sh installs it)".into(),
            )
        })?;
        let profile = tempfile::tempdir()
            .map_err(|e| BenchError::step("creating a browser profile folder", e))?;
        let child = Command::new(exe)
            .args(crate::report::headless::HEADLESS_FLAGS)
            .arg("--window-size=1280,1000")
            .arg(format!("--user-data-dir={}", profile.path().display()))
            .arg(url)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| BenchError::step("starting chromium", e))?;
        Ok(Page {
            child,
            _profile: profile,
        })
    }
}

impl Drop for Page {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// CPU seconds (user + system) of this process, all its threads: the capture, and the server
/// when it runs here. Linux counts in USER_HZ = 100 ticks per second.
fn own_cpu_secs() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let f: Vec<&str> = stat
        .rsplit_once(')')
        .map(|(_, rest)| rest.split_whitespace().collect())
        .unwrap_or_default();
    let num = |i: usize| f.get(i).and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
    (num(11) + num(12)) as f64 / 100.0
}

/// CPU seconds (user + system, with reaped children) of process `pid` and its descendants,
/// from /proc; 0 for processes already gone.
fn tree_cpu_secs(pid: u32) -> f64 {
    let mut procs = Vec::new();
    if let Ok(dir) = std::fs::read_dir("/proc") {
        for e in dir.flatten() {
            let Some(id) = e.file_name().to_str().and_then(|n| n.parse::<u32>().ok()) else {
                continue;
            };
            let Ok(stat) = std::fs::read_to_string(e.path().join("stat")) else {
                continue;
            };
            // fields after the command name (which may hold spaces): state ppid ... utime(14th)
            let Some((_, rest)) = stat.rsplit_once(')') else {
                continue;
            };
            let f: Vec<&str> = rest.split_whitespace().collect();
            let num = |i: usize| f.get(i).and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
            procs.push((id, num(1) as u32, num(11) + num(12) + num(13) + num(14)));
        }
    }
    let mut tree = vec![pid];
    let mut ticks = 0;
    while let Some(p) = tree.pop() {
        for &(id, parent, t) in &procs {
            if id == p {
                ticks += t;
            }
            if parent == p {
                tree.push(id);
            }
        }
    }
    ticks as f64 / 100.0
}

fn wait_for(what: &str, secs: u64, mut ok: impl FnMut() -> bool) -> Result<(), BenchError> {
    let t = Instant::now();
    while !ok() {
        if t.elapsed() > Duration::from_secs(secs) {
            return Err(BenchError::Invalid(format!("{what}: not within {secs} s")));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(())
}

fn serve(profile: &Profile, dir: &Path, fps: f64) -> Result<Server, BenchError> {
    Server::start(ServeConfig {
        bind: std::net::SocketAddr::from(([127, 0, 0, 1], 0)),
        profile: profile.clone(),
        port_override: None,
        token: None,
        sessions_dir: dir.join("sessions"),
        plans_dir: Some(dir.join("plans")),
        preview_size: (640, 480),
        preview_fps: fps,
        lost_after: Duration::from_millis(1500),
    })
    .map_err(|e| BenchError::step("starting the lab page server", e))
}

/// Waits until a page is connected and settled (it has been sent a few live frames): the
/// browser's own start-up is not what a connected page costs.
fn page_settled(hub: &crate::serve::hub::Hub) -> Result<(), BenchError> {
    wait_for("the page connects and gets frames", 60, || {
        hub.frames_sent().iter().any(|&(_, n)| n >= 3)
    })
}

/// Frames per second delivered to the one connected page over `secs`, idle.
fn preview_rate(server: &Server, secs: f64) -> Result<(f64, f64), BenchError> {
    let page = Page::open(&format!("http://{}/", server.addr()))?;
    let hub = server.hub().clone();
    page_settled(&hub)?;
    let sent = |h: &crate::serve::hub::Hub| h.frames_sent().iter().map(|&(_, n)| n).sum::<u64>();
    let (s0, m0, t0) = (sent(&hub), hub.frames_made(), Instant::now());
    std::thread::sleep(Duration::from_secs_f64(secs));
    let dt = t0.elapsed().as_secs_f64();
    let rate = (sent(&hub) - s0) as f64 / dt;
    let made = (hub.frames_made() - m0) as f64 / dt;
    drop(page);
    Ok((rate, made))
}

/// Runs the plan `plan_id` unattended through the server; the capture's own wall time.
fn served_capture(server: &Server, plan_id: &str, session: &str) -> Result<f64, BenchError> {
    let hub = server.hub();
    let answer = hub
        .send(RigCommand::Start(StartSpec {
            plan_id: plan_id.into(),
            session: session.into(),
            guided: false,
            snapshot_every: 16,
        }))
        .blocking_recv()
        .map_err(|e| BenchError::step("the rig's thread stopped", e))?;
    answer.map_err(|e| BenchError::Invalid(e.to_string()))?;
    wait_for("the capture ends", 600, || !hub.phase().is_active())?;
    let s = hub.snapshot();
    if s.capture.phase != Phase::Complete {
        return Err(BenchError::Invalid(format!(
            "the served capture ended {:?}: {:?}",
            s.capture.phase, s.capture.stop_reason
        )));
    }
    s.capture
        .wall_secs
        .ok_or_else(|| BenchError::Invalid("the capture reported no wall time".into()))
}

/// The median of `v` ([`crate::stats::median`]); NaN for none.
fn median(mut v: Vec<f64>) -> f64 {
    crate::stats::median(&mut v).unwrap_or(f64::NAN)
}

/// The page section of docs/benchmarks-capture.md. `cli_capture` runs the same plan as
/// `brdf-rig capture` does and returns its wall time.
pub fn measure(
    profile_text: &str,
    plan_text: &str,
    reps: usize,
    mut cli_capture: impl FnMut(usize) -> Result<f64, BenchError>,
    note: &mut dyn FnMut(Note<'_>),
) -> Result<String, BenchError> {
    let tmp = temp_dir()?;
    std::fs::create_dir_all(tmp.path().join("plans"))?;
    std::fs::write(tmp.path().join("plans/bench.toml"), plan_text)?;
    let ppath = tmp.path().join("profile.toml");
    std::fs::write(&ppath, profile_text)?;
    let profile = Profile::load(&ppath)?;

    let mut rates = Vec::new();
    for fps in [8.0, 30.0] {
        let server = serve(&profile, tmp.path(), fps)?;
        let (rate, made) = preview_rate(&server, 10.0)?;
        rates.push((fps, rate, made));
        server.stop();
    }

    let (mut cli, mut bare, mut with_page) = (Vec::new(), Vec::new(), Vec::new());
    // CPU seconds of this process (capture and server) per run, and of the browser
    let (mut cli_cpu, mut bare_cpu, mut page_cpu, mut browser_cpu) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let server = serve(&profile, tmp.path(), 8.0)?;
    for r in 0..reps {
        let c0 = own_cpu_secs();
        cli.push(cli_capture(r)?);
        cli_cpu.push(own_cpu_secs() - c0);
        let c0 = own_cpu_secs();
        bare.push(served_capture(&server, "bench.toml", &format!("bare-{r}"))?);
        bare_cpu.push(own_cpu_secs() - c0);
        let page = Page::open(&format!("http://{}/", server.addr()))?;
        let hub = server.hub().clone();
        page_settled(&hub)?;
        let sent = || hub.frames_sent().iter().map(|&(_, n)| n).sum::<u64>();
        let (c0, b0, f0) = (own_cpu_secs(), tree_cpu_secs(page.child.id()), sent());
        with_page.push(served_capture(&server, "bench.toml", &format!("page-{r}"))?);
        page_cpu.push(own_cpu_secs() - c0);
        browser_cpu.push(tree_cpu_secs(page.child.id()) - b0);
        let frames = sent() - f0;
        drop(page);
        note(Note::Detail(&format!(
            "rep {r}: capture {:.2} s ({:.2} s CPU), served {:.2} s ({:.2} s CPU), served with a page \
             {:.2} s ({:.2} s CPU, browser {:.2} s CPU; {frames} frames sent during it)",
            cli[r], cli_cpu[r], bare[r], bare_cpu[r], with_page[r], page_cpu[r], browser_cpu[r]
        )));
    }
    server.stop();

    let mut md = String::new();
    let _ = writeln!(
        md,
        "| preview at 640x480, `--preview-fps` | frames/s delivered to the page | frames/s made |"
    );
    let _ = writeln!(md, "|---:|---:|---:|");
    for (fps, rate, made) in &rates {
        let _ = writeln!(md, "| {fps} | {rate:.1} | {made:.1} |");
    }
    let (c, b, p) = (
        median(cli.clone()),
        median(bare.clone()),
        median(with_page.clone()),
    );
    let _ = writeln!(md);
    let _ = writeln!(
        md,
        "| the same unattended capture ({reps} runs each, median) | wall (s) | vs `capture` | \
         vs no page | CPU of brdf-rig (s) | CPU of the browser (s) |"
    );
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|");
    let _ = writeln!(
        md,
        "| `brdf-rig capture --unattended` | {c:.2} | | | {:.2} | |",
        median(cli_cpu)
    );
    let _ = writeln!(
        md,
        "| `brdf-rig serve`, no page connected | {b:.2} | {:+.1} % | | {:.2} | |",
        100.0 * (b / c - 1.0),
        median(bare_cpu)
    );
    let _ = writeln!(
        md,
        "| `brdf-rig serve`, headless Chromium showing the page | {p:.2} | {:+.1} % | {:+.1} % | \
         {:.2} | {:.2} |",
        100.0 * (p / c - 1.0),
        100.0 * (p / b - 1.0),
        median(page_cpu),
        median(browser_cpu)
    );
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let _ = writeln!(
        md,
        "\nEvery run (s): capture {}; served {}; served with a page {}.",
        list(&cli),
        list(&bare),
        list(&with_page)
    );
    Ok(md)
}
