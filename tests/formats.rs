//! Issue 16: every file format has one owner, and every path written into a file is absolute or
//! relative to that file, so the files mean the same from any working folder. Each test runs the
//! real binary the way a user does.

use std::path::Path;
use std::process::Output;

use brdf_rig::pipeline::calibration_file;
use brdf_rig::reconstruct::report_file;

use crate::capture_util::{brdf_rig, calibratable_plan, fast_profile, text, tiny_session};

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
    std::fs::copy(calibratable_plan(tmp.path()), tmp.path().join("plan.toml")).unwrap();
    let o = run_in(
        tmp.path(),
        &profile,
        &["demo", "--out", "demo-out", "--plan", "plan.toml"],
    );
    assert!(o.status.success(), "{}", text(&o));
    let out = tmp.path().join("demo-out");

    // Paths inside the files: absolute, or relative to the file's own folder.
    let report = report_file::read(&out.join("reconstruction")).unwrap();
    let job = &report.job;
    assert!(job.is_absolute(), "report.json job: {}", job.display());
    assert!(job.is_file(), "report.json job: {}", job.display());
    for c in &report.comparisons {
        assert!(
            c.photo.is_absolute() && c.photo.is_file(),
            "{}",
            c.photo.display()
        );
    }
    for i in &report.images {
        assert!(
            i.file.is_absolute() && i.file.is_file(),
            "{}",
            i.file.display()
        );
    }
    let cal = calibration_file::read(&out.join("session")).unwrap();
    assert!(
        out.join("session").join(&cal.job).is_file(),
        "calibration.json job: {}",
        cal.job.display()
    );

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
    assert!(
        html.contains("calibration.json channel 0"),
        "no calibration entry"
    );
}

/// `calibrate SESSION` knows nothing of simulation: a session without `sim/` (a real capture)
/// and without `--cameras` is refused with what to give, never pointed at `sim/` paths.
#[test]
fn calibrating_a_real_session_asks_for_the_photogrammetry_model() {
    let tmp = tempfile::tempdir().unwrap();
    let session = tiny_session(tmp.path(), 3);
    std::fs::remove_dir_all(session.join("sim")).unwrap();
    let o = crate::capture_util::run(&["calibrate", session.to_str().unwrap()]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("--cameras") && !err.contains("sim/colmap"),
        "{err}"
    );
    assert!(!session.join("calibration.json").exists());
}

/// Session files of another format version are refused by every reader, naming the file and
/// both versions; the report says so instead of misreading them.
#[test]
fn a_session_of_another_version_is_refused_by_name() {
    let tmp = tempfile::tempdir().unwrap();
    let session = tiny_session(tmp.path(), 3);
    for name in ["session.json", "manifest.json"] {
        let p = session.join(name);
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains("\"format_version\": 1"), "{name}: {text}");
        std::fs::write(
            &p,
            text.replace("\"format_version\": 1", "\"format_version\": 9"),
        )
        .unwrap();
    }
    let s = session.to_str().unwrap();
    for args in [vec!["session", "verify", s], vec!["calibrate", s]] {
        let o = crate::capture_util::run(&args);
        assert!(!o.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains("format version 9") && err.contains("version 1") && err.contains(".json"),
            "{args:?}: {err}"
        );
    }
    let data = brdf_rig::report::gather::gather(
        &session,
        &brdf_rig::report::options::ReportOptions::default(),
    )
    .unwrap();
    let brdf_rig::report::avail::Avail::Yes(c) = &data.capture else {
        panic!("{:?}", data.capture)
    };
    assert_eq!(c.shots, 0);
    assert!(
        c.notes.iter().any(|n| n.contains("format version 9")),
        "{:?}",
        c.notes
    );
}
