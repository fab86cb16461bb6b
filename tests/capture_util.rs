//! Shared by the capture tests: a fast simulated rig profile, tiny plans, running the binary.

#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use crate::util;

/// The built-in simulated profile with a fast turntable and short light warm-up, so tests spend
/// their time on the capture logic, not on simulated motion.
pub fn fast_profile(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("rig-profiles/simulated.toml"),
    )
    .unwrap()
    .replace("max_speed_deg_s = 90.0", "max_speed_deg_s = 3600.0")
    .replace("max_accel_deg_s2 = 180.0", "max_accel_deg_s2 = 36000.0")
    .replace("warmup_ms = 50", "warmup_ms = 2");
    let p = dir.join("fast-sim.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// A plan of `views` ambient views at 64x48, single-light shots on every third view under all
/// three channels with a two-step bracket, and both calibration targets.
pub fn tiny_plan(dir: &Path, views: usize) -> PathBuf {
    let text = format!(
        "name = \"tiny\"\n\
         [camera]\nwidth = 64\nheight = 48\ngain = 1.0\n\
         [ambient]\nviews = {views}\nexposures_secs = [0.02]\n\
         [single_light]\nevery = 3\nchannels = [0, 1, 2]\nexposures_secs = [0.004, 0.016]\n\
         [calibration]\nsphere = true\nwhite = true\n\
         [settle]\nturntable_millis = 0\nlight_millis = 0\n"
    );
    let p = dir.join("tiny-plan.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// The smallest plan `calibrate SESSION` accepts with margin: the tiny plan at 160x120 (64x48 is
/// too small for the sphere) with four views, and a bracket whose shortest exposure leaves the
/// white board below the clip level (the calibration takes the clip level from the bracket,
/// never a guess).
pub fn calibratable_plan(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(tiny_plan(dir, 4))
        .unwrap()
        .replace("width = 64", "width = 160")
        .replace("height = 48", "height = 120")
        .replace("every = 3", "every = 4")
        .replace(
            "exposures_secs = [0.004, 0.016]",
            "exposures_secs = [0.0005, 0.004, 0.016]",
        );
    let p = dir.join("plan160.toml");
    std::fs::write(&p, text).unwrap();
    p
}

pub fn brdf_rig(args: &[&str]) -> Command {
    let mut c = Command::new(util::bin());
    c.args(args).stdin(Stdio::null());
    c.env_remove("BRDF_RIG_TEST_KILL_AT");
    c.env_remove("BRDF_RIG_PROFILE");
    c
}

/// `capture --profile P --plan PLAN --out OUT --unattended`.
fn unattended_args<'a>(profile: &'a Path, plan: &'a Path, out: &'a Path) -> [&'a str; 8] {
    [
        "capture",
        "--profile",
        s(profile),
        "--plan",
        s(plan),
        "--out",
        s(out),
        "--unattended",
    ]
}

/// `brdf-rig capture --profile P --plan PLAN --out OUT --unattended`, run to the end.
pub fn capture_unattended(profile: &Path, plan: &Path, out: &Path) -> Output {
    run(&unattended_args(profile, plan, out))
}

pub fn run(args: &[&str]) -> Output {
    brdf_rig(args).output().unwrap()
}

pub fn text(o: &Output) -> String {
    format!(
        "status {:?}\nstdout:\n{}\nstderr:\n{}",
        o.status,
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A complete capture of `tiny_plan(dir, views)` on `fast_profile(dir)` into `dir/session`.
pub fn tiny_session(dir: &Path, views: usize) -> PathBuf {
    let out = dir.join("session");
    let o = capture_unattended(&fast_profile(dir), &tiny_plan(dir, views), &out);
    assert!(o.status.success(), "{}", text(&o));
    out
}

/// Starts `capture --profile P --plan PLAN --out OUT --unattended`, sends it SIGINT (Ctrl-C)
/// once its first shot is journaled, and returns what it printed and its exit status.
pub fn interrupt_after_first_shot(profile: &Path, plan: &Path, out: &Path) -> Output {
    let child = brdf_rig(&unattended_args(profile, plan, out))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let journal = out.join("journal.jsonl");
    let t0 = std::time::Instant::now();
    while std::fs::metadata(&journal).map(|m| m.len()).unwrap_or(0) == 0 {
        assert!(t0.elapsed().as_secs() < 30, "no shot within 30 s");
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    let st = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    child.wait_with_output().unwrap()
}
