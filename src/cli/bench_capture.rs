//! `brdf-rig bench capture`: shots per second of whole simulated captures and where the time
//! goes (turntable and light, camera rendering, storage with fsync, the controller itself), for
//! docs/benchmarks-capture.md. Each configuration is a real capture through the serial stack to
//! the simulated firmware on a pty, into a temporary folder.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;

use brdf_rig::capture::plan::DEFAULT_PLAN_TOML;
use brdf_rig::profile::SIMULATED;

use super::capture::{CaptureArgs, execute};
use super::ranges::int_in;
use super::rig::RigArgs;

#[derive(Args, Debug)]
pub struct BenchCaptureArgs {
    /// Ambient views of the benchmark plan (single-light shots on every fourth view).
    #[arg(long, default_value_t = 12, value_parser = int_in(1usize, 3600))]
    pub views: usize,
    /// Image sizes to measure (WIDTHxHEIGHT), with the fast turntable.
    #[arg(long, value_delimiter = ',', default_value = "64x48,160x120,320x240")]
    pub sizes: Vec<String>,
    /// Also write the markdown page here (e.g. docs/benchmarks-capture.md).
    #[arg(long)]
    pub write: Option<PathBuf>,
    /// Also measure the lab page (`serve`): the live preview's frame rate at 640x480, and the
    /// 320x240 fast capture through the server with and without a headless Chromium showing
    /// the page (needs Debian's chromium).
    #[arg(long)]
    pub page: bool,
    /// Runs of each capture for --page (the median is reported); 1 to 20.
    #[arg(long, default_value_t = 3, value_parser = int_in(1usize, 20))]
    pub reps: usize,
}

fn plan_text(views: usize, w: usize, h: usize) -> String {
    let every = (views / 3).max(1);
    DEFAULT_PLAN_TOML
        .replace("views = 55", &format!("views = {views}"))
        .replace("every = 5", &format!("every = {every}"))
        .replace("width = 320", &format!("width = {w}"))
        .replace("height = 240", &format!("height = {h}"))
}

struct Row {
    label: String,
    shots: usize,
    wall: f64,
    device: f64,
    camera: f64,
    settle: f64,
    storage: f64,
    overhead: f64,
}

pub fn run(args: BenchCaptureArgs) -> anyhow::Result<ExitCode> {
    let tmp = tempfile::tempdir().context("creating a temporary folder")?;
    let fast = SIMULATED
        .replace("max_speed_deg_s = 90.0", "max_speed_deg_s = 3600.0")
        .replace("max_accel_deg_s2 = 180.0", "max_accel_deg_s2 = 36000.0")
        .replace("warmup_ms = 50", "warmup_ms = 1");
    let profiles = [
        ("built-in simulated rig", SIMULATED.to_string()),
        ("fast turntable, 1 ms light warm-up", fast),
    ];
    let mut configs: Vec<(String, String, usize, usize)> = Vec::new();
    configs.push((profiles[0].0.to_string(), profiles[0].1.clone(), 160, 120));
    for size in &args.sizes {
        let (w, h) = size
            .split_once('x')
            .and_then(|(w, h)| Some((w.parse().ok()?, h.parse().ok()?)))
            .with_context(|| format!("--sizes: {size:?} is not WIDTHxHEIGHT"))?;
        configs.push((profiles[1].0.to_string(), profiles[1].1.clone(), w, h));
    }
    let mut rows = Vec::new();
    for (i, (label, profile, w, h)) in configs.into_iter().enumerate() {
        let ppath = tmp.path().join(format!("profile-{i}.toml"));
        std::fs::write(&ppath, &profile).context("writing the profile")?;
        let plan_path = tmp.path().join(format!("plan-{i}.toml"));
        let mut text = plan_text(args.views, w, h);
        if i > 0 {
            text = text
                .replace("turntable_millis = 200", "turntable_millis = 0")
                .replace("light_millis = 100", "light_millis = 0");
        }
        std::fs::write(&plan_path, text).context("writing the plan")?;
        let out = tmp.path().join(format!("session-{i}"));
        let outcome = execute(CaptureArgs {
            rig: RigArgs {
                profile: Some(ppath),
                port: None,
            },
            plan: Some(plan_path),
            out: Some(out),
            resume: None,
            unattended: true,
            snapshot_every: 16,
        })?;
        let s = outcome.result?;
        let n = s.shots_taken.max(1) as f64;
        let ms = |d: std::time::Duration| 1000.0 * d.as_secs_f64() / n;
        rows.push(Row {
            label: format!("{label}, {w}x{h}"),
            shots: s.shots_taken,
            wall: s.wall.as_secs_f64(),
            device: ms(s.device_time),
            camera: ms(s.camera_time),
            settle: ms(s.settle_time),
            storage: ms(s.storage_time),
            overhead: 1000.0 * s.overhead_per_shot().as_secs_f64(),
        });
    }
    let page = if args.page {
        let plan = plan_text(args.views, 320, 240)
            .replace("turntable_millis = 200", "turntable_millis = 0")
            .replace("light_millis = 100", "light_millis = 0");
        let dir = tmp.path().to_path_buf();
        let (fast, plan2) = (profiles[1].1.clone(), plan.clone());
        Some(super::bench_page::measure(
            &profiles[1].1,
            &plan,
            args.reps,
            |r| {
                let ppath = dir.join(format!("page-profile-{r}.toml"));
                let plan_path = dir.join(format!("page-plan-{r}.toml"));
                std::fs::write(&ppath, &fast).context("writing the profile")?;
                std::fs::write(&plan_path, &plan2).context("writing the plan")?;
                let outcome = execute(CaptureArgs {
                    rig: RigArgs {
                        profile: Some(ppath),
                        port: None,
                    },
                    plan: Some(plan_path),
                    out: Some(dir.join(format!("page-cli-{r}"))),
                    resume: None,
                    unattended: true,
                    snapshot_every: 16,
                })?;
                Ok(outcome.result?.wall.as_secs_f64())
            },
        )?)
    } else {
        None
    };
    let mut md = String::new();
    let _ = writeln!(
        md,
        "| configuration | shots | wall (s) | shots/s | per shot (ms) | devices (ms) | of which camera (ms) | of which settle (ms) | storage (ms) | controller (ms) |"
    );
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in &rows {
        let _ = writeln!(
            md,
            "| {} | {} | {:.1} | {:.2} | {:.1} | {:.1} | {:.1} | {:.1} | {:.1} | {:.3} |",
            r.label,
            r.shots,
            r.wall,
            r.shots as f64 / r.wall.max(1e-9),
            1000.0 * r.wall / r.shots.max(1) as f64,
            r.device,
            r.camera,
            r.settle,
            r.storage,
            r.overhead
        );
    }
    println!("{md}");
    if let Some(p) = &page {
        println!("{p}");
    }
    if let Some(path) = args.write {
        // the command that makes this page, as it was run
        let mut command = String::from("brdf-rig bench capture");
        if args.views != 12 {
            let _ = write!(command, " --views {}", args.views);
        }
        if args.page {
            let _ = write!(command, " --page --reps {}", args.reps);
        }
        let _ = write!(command, " --write {}", path.display());
        let page = format!(
            "# Capture benchmark: shots per second on the simulated rig\n\n\
             Made by `{command}` (plan: the default plan scaled to {} ambient views,\n\
             single-light shots on every {}th view under 3 channels with a 3-step bracket, sphere and\n\
             white reference under each channel; unattended; release build).\n\
             Machine: {}.\n\n{md}\n\
             Columns, per shot: *devices* is time inside turntable, light and camera calls plus the\n\
             settle waits (the camera renders the scene: ray casting, neural-BRDF shading, sensor\n\
             noise; an exposure bracket renders once); *storage* is OpenEXR encoding, SHA-256, the\n\
             atomic write with fsync, the journal append with fsync and the manifest snapshots;\n\
             *controller* is everything else the session runner does (wall minus devices minus\n\
             storage).\n\n\
             Reading: on the built-in simulated rig the turntable's motion (90 deg/s, 180 deg/s^2)\n\
             dominates; with a fast turntable the camera's rendering dominates and grows with the\n\
             image size; the controller's own overhead stays well under a millisecond per shot.\n{}",
            args.views,
            (args.views / 3).max(1),
            brdf_rig::eval::host::machine(),
            page.as_ref().map(|p| page_section(p)).unwrap_or_default()
        );
        std::fs::write(&path, page).with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}

/// The lab page's section of the markdown page.
fn page_section(table: &str) -> String {
    format!(
        "\n## The lab page (`brdf-rig serve`)\n\n\
         Measured by the `--page` part of the command above (the fast turntable, 320x240 row's plan\n\
         and profile; the server in the benchmark's process, a headless Chromium showing the page;\n\
         the simulated camera's live preview at 640x480).\n\n{table}\n\
         The preview rate is what reaches the page; the scene at rest renders once and each frame\n\
         is a new sensor exposure (noise), a shrink-mark-histogram pass and a JPEG. While a capture\n\
         runs the page is sent the shots themselves (at most one a second), not live frames, and\n\
         the state at most once a second. The CPU columns are the steadier measure on a shared\n\
         machine: the wall times move with the other work on it.\n"
    )
}
