//! `brdf-rig bench capture`: shots per second of whole simulated captures and where the time
//! goes (turntable and light, camera rendering, storage with fsync, the controller itself), for
//! docs/benchmarks-capture.md. Each configuration is a real capture through the serial stack to
//! the simulated firmware on a pty, into a temporary folder, run as `brdf-rig capture` runs it
//! ([`crate::pipeline::capture_run`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::{BenchError, Note, temp_dir, write_file};
use crate::capture::RunSummary;
use crate::capture::plan::DEFAULT_PLAN_TOML;
use crate::pipeline::capture_run::{CaptureRequest, Frontend, execute};
use crate::profile::SIMULATED;

/// The options of `bench capture`.
#[derive(Clone, Debug)]
pub struct CaptureBenchOptions {
    /// Ambient views of the benchmark plan.
    pub views: usize,
    /// Image sizes measured with the fast turntable (width, height).
    pub sizes: Vec<(usize, usize)>,
    /// Also measure the lab page.
    pub page: bool,
    /// Runs of each capture for the page (the median is reported).
    pub reps: usize,
    /// Where the markdown page is written (`None`: not written).
    pub write: Option<PathBuf>,
    /// The command as typed, quoted by the page.
    pub command: String,
}

/// The tables measured: the captures', and the lab page's with `page`.
pub struct CaptureBench {
    pub table: String,
    pub page: Option<String>,
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

/// One unattended capture as `brdf-rig capture --unattended` runs it, with `profile` and
/// `plan` written into `dir` under `profile_name` and `plan_name`; the run's summary.
fn capture(
    dir: &Path,
    (profile_name, profile): (&str, &str),
    (plan_name, plan): (&str, &str),
    out: PathBuf,
    frontend: &mut dyn Frontend,
) -> Result<RunSummary, BenchError> {
    let ppath = dir.join(profile_name);
    write_file(&ppath, profile).map_err(|e| BenchError::step("writing the profile", e))?;
    let plan_path = dir.join(plan_name);
    write_file(&plan_path, plan).map_err(|e| BenchError::step("writing the plan", e))?;
    let outcome = execute(
        &CaptureRequest {
            profile: Some(ppath),
            port: None,
            plan: Some(plan_path),
            out: Some(out),
            resume: None,
            unattended: true,
            snapshot_every: 16,
        },
        frontend,
    )?;
    Ok(outcome.result?)
}

/// Measures every configuration (and the lab page with `o.page`); writes the page to
/// `o.write` when given. The captures' notes and progress go to `frontend`.
pub fn run(
    o: &CaptureBenchOptions,
    frontend: &mut dyn Frontend,
) -> Result<CaptureBench, BenchError> {
    let tmp = temp_dir()?;
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
    for &(w, h) in &o.sizes {
        configs.push((profiles[1].0.to_string(), profiles[1].1.clone(), w, h));
    }
    let mut rows = Vec::new();
    for (i, (label, profile, w, h)) in configs.into_iter().enumerate() {
        let mut text = plan_text(o.views, w, h);
        if i > 0 {
            text = text
                .replace("turntable_millis = 200", "turntable_millis = 0")
                .replace("light_millis = 100", "light_millis = 0");
        }
        let s = capture(
            tmp.path(),
            (&format!("profile-{i}.toml"), &profile),
            (&format!("plan-{i}.toml"), &text),
            tmp.path().join(format!("session-{i}")),
            frontend,
        )?;
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
    let page = if o.page {
        let plan = plan_text(o.views, 320, 240)
            .replace("turntable_millis = 200", "turntable_millis = 0")
            .replace("light_millis = 100", "light_millis = 0");
        let dir = tmp.path().to_path_buf();
        let fast = &profiles[1].1;
        // The page's notes go where the captures' do.
        let frontend = std::cell::RefCell::new(frontend);
        Some(super::page::measure(
            fast,
            &plan,
            o.reps,
            |r| {
                let s = capture(
                    &dir,
                    (&format!("page-profile-{r}.toml"), fast),
                    (&format!("page-plan-{r}.toml"), &plan),
                    dir.join(format!("page-cli-{r}")),
                    &mut **frontend.borrow_mut(),
                )?;
                Ok(s.wall.as_secs_f64())
            },
            &mut |n| {
                let text = match n {
                    Note::Step(t) | Note::Detail(t) => t,
                };
                frontend.borrow_mut().note(&format!("{text}\n"));
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
    if let Some(path) = &o.write {
        let text = format!(
            "# Capture benchmark: shots per second on the simulated rig\n\n\
             Made by `{}` (plan: the default plan scaled to {} ambient views,\n\
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
            o.command,
            o.views,
            (o.views / 3).max(1),
            crate::eval::host::machine(),
            page.as_ref().map(|p| page_section(p)).unwrap_or_default()
        );
        write_file(path, text)?;
    }
    Ok(CaptureBench { table: md, page })
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
