//! Issue 16: every file format has one owner, and every path written into a file is absolute or
//! relative to that file, so the files mean the same from any working folder. Each test runs the
//! real binary the way a user does.

use std::path::Path;
use std::process::Output;

use crate::capture_util::{brdf_rig, fast_profile, text, tiny_plan};

/// `brdf-rig ARGS` run in the folder `cwd`, with the fast simulated profile.
fn run_in(cwd: &Path, profile: &Path, args: &[&str]) -> Output {
    brdf_rig(args)
        .current_dir(cwd)
        .env("BRDF_RIG_PROFILE", profile)
        .output()
        .unwrap()
}

/// The README's main job as written (`demo --out demo-out`, a path relative to the caller's
/// folder) makes a report whose Capture and Calibration sections show what the demo made. Before
/// the fix both said "not available": the reconstruction recorded paths relative to the caller's
/// folder, and the report resolved them beside `report.json`.
#[test]
fn the_demo_with_a_relative_out_reports_its_capture_and_calibration() {
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    // The calibratable session of tests/regression.rs: 160x120 with four views (the tiny
    // plan's 64x48 is too small for the sphere), and a bracket whose shortest exposure leaves
    // the white board below the clip level.
    let plan_text = std::fs::read_to_string(tiny_plan(tmp.path(), 4))
        .unwrap()
        .replace("width = 64", "width = 160")
        .replace("height = 48", "height = 120")
        .replace("every = 3", "every = 4")
        .replace(
            "exposures_secs = [0.004, 0.016]",
            "exposures_secs = [0.0005, 0.004, 0.016]",
        );
    std::fs::write(tmp.path().join("plan.toml"), plan_text).unwrap();
    let o = run_in(
        tmp.path(),
        &profile,
        &["demo", "--out", "demo-out", "--plan", "plan.toml"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let out = tmp.path().join("demo-out");

    // Paths inside the files: absolute, or relative to the file's own folder.
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("reconstruction/report.json")).unwrap())
            .unwrap();
    let job = report["job"].as_str().unwrap();
    assert!(Path::new(job).is_absolute(), "report.json job: {job}");
    assert!(Path::new(job).is_file(), "report.json job: {job}");
    for c in report["comparisons"].as_array().unwrap() {
        let photo = Path::new(c["photo"].as_str().unwrap());
        assert!(photo.is_absolute() && photo.is_file(), "{}", photo.display());
    }
    for i in report["images"].as_array().unwrap() {
        let file = Path::new(i["file"].as_str().unwrap());
        assert!(file.is_absolute() && file.is_file(), "{}", file.display());
    }
    let cal: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("session/calibration.json")).unwrap())
            .unwrap();
    let job = cal["job"].as_str().unwrap();
    assert!(out.join("session").join(job).is_file(), "calibration.json job: {job}");

    // The page shows both sections (a section that is missing says "not available").
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    for (id, next) in [("capture", "<h2"), ("calibration", "<h2")] {
        let start = html
            .find(&format!("<h2 id=\"{id}\">"))
            .unwrap_or_else(|| panic!("no {id} section"));
        let rest = &html[start + 4..];
        let section = &rest[..rest.find(next).unwrap_or(rest.len())];
        assert!(
            !section.contains("not available"),
            "{id} section: {section}"
        );
    }
    assert!(html.contains("calibration.json channel 0"), "no calibration entry");
}
