//! `brdf-rig calibrate sphere` and `calibrate white` on every fixture of the corpus that Mitsuba 3,
//! a path tracer independent of this project, rendered (`scripts/render_calibration_fixtures.py`;
//! the files and their truth are in `tests/fixtures/calibration/`): glossiness and Fresnel
//! strengths, surrounds, holders, framing, light shapes, camera effects and file formats.
//!
//! Each usable sphere fixture must give the light direction within 0.5 deg of the truth with its
//! outline detected, within twice the uncertainty it reports (an RMS angle), and with the true
//! outline given as `--circle` a fixture that passes must pass without it too; each usable board must give the irradiance within 2 % (worst colour
//! channel). A fixture meant to be unusable must be refused, with a message that says why.
//! The tests print the per-fixture tables of docs/calibration.md:
//!
//! ```sh
//! cargo test --release --test tests calib_fixtures -- --nocapture --test-threads 1
//! ```

use crate::util::bin;
use nalgebra::Vector3;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::process::Command;

const MAX_DIRECTION_ERROR_DEG: f64 = 0.5;
const MAX_IRRADIANCE_ERROR: f64 = 0.02;

fn corpus() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/calibration")
}

#[derive(Deserialize)]
struct Camera {
    fx: f64,
    fy: f64,
    cx: f64,
    cy: f64,
}

#[derive(Deserialize)]
struct Unusable {
    reason: String,
    /// A phrase the error must contain.
    error: String,
}

#[derive(Deserialize)]
struct SphereGeometry {
    outline_circle_px: [f64; 3],
    /// `tan(alpha) f` and the centre's projection: what `calibrate sphere` reports.
    outline_radius_px: f64,
    centre_px: [f64; 2],
}

#[derive(Deserialize)]
struct BoardGeometry {
    normal_camera: [f64; 3],
}

/// The fields of `truth.json` the tests use (the script writes more, for the record).
#[derive(Deserialize)]
struct Truth {
    name: String,
    kind: String,
    description: String,
    intrinsics: Camera,
    light_dir_camera: [f64; 3],
    irradiance: [f64; 3],
    transfer: String,
    scale: Option<f64>,
    unusable: Option<Unusable>,
    // sphere fixtures
    light_image: Option<String>,
    outline_image: Option<String>,
    sphere: Option<SphereGeometry>,
    // white fixtures
    board_image: Option<String>,
    albedo: Option<[f64; 3]>,
    board: Option<BoardGeometry>,
}

/// The fixtures of one kind, sorted by name; the corpus must hold at least `at_least`.
fn fixtures(kind: &str, at_least: usize) -> Vec<(PathBuf, Truth)> {
    let mut out = Vec::new();
    for entry in std::fs::read_dir(corpus()).unwrap() {
        let dir = entry.unwrap().path();
        let text = std::fs::read_to_string(dir.join("truth.json")).unwrap();
        let truth: Truth = serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.join("truth.json").display()));
        if truth.kind == kind {
            out.push((dir, truth));
        }
    }
    out.sort_by(|a, b| a.1.name.cmp(&b.1.name));
    assert!(
        out.len() >= at_least,
        "the corpus has {} {kind} fixtures",
        out.len()
    );
    out
}

fn csv(v: &[f64]) -> String {
    v.iter()
        .map(|x| format!("{x}"))
        .collect::<Vec<_>>()
        .join(",")
}

/// The arguments a user would give for the file's encoding.
fn format_args(t: &Truth) -> Vec<String> {
    let mut a = Vec::new();
    if t.transfer != "linear" {
        a.extend(["--transfer".into(), t.transfer.clone()]);
    }
    if let Some(s) = t.scale {
        a.extend(["--scale".into(), format!("{s}")]);
    }
    a
}

/// What one run of the binary gave.
enum Outcome {
    /// The measured value's error (degrees, or relative) and the JSON it printed.
    Measured(f64, serde_json::Value),
    /// Refused: the error message.
    Refused(String),
}

impl Outcome {
    fn cell(&self, bound: f64, unit: &str, scale: f64) -> String {
        match self {
            Outcome::Measured(e, _) if *e < bound => format!("{:.3} {unit}", e * scale),
            Outcome::Measured(e, _) => format!("**{:.3} {unit}** (over the bound)", e * scale),
            Outcome::Refused(m) => format!("refused: {}", first_line(m)),
        }
    }
    fn passes(&self, bound: f64) -> bool {
        matches!(self, Outcome::Measured(e, _) if *e < bound)
    }
}

/// The root cause of a refusal (the last line of the error chain), paths relative to the corpus.
fn first_line(m: &str) -> String {
    let corpus = format!("{}/", corpus().display());
    let line = m
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("")
        .trim()
        .trim_start_matches("error: ")
        .trim_start_matches("caused by: ")
        .replace(&corpus, "");
    line.chars().take(200).collect()
}

fn run(args: &[String], measure: impl Fn(&serde_json::Value) -> f64) -> Outcome {
    let out = Command::new(bin()).args(args).output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    if !out.status.success() {
        return Outcome::Refused(stderr);
    }
    let j: serde_json::Value = serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}", String::from_utf8_lossy(&out.stdout)));
    Outcome::Measured(measure(&j), j)
}

/// The clip level used and its source, short: "none (float file)", "0.5 (16-bit file)".
fn clip_cell(j: &serde_json::Value) -> String {
    let c = &j["clip_level"];
    let value = c["value"]
        .as_f64()
        .map_or("none".to_string(), |v| format!("{v:.4}"));
    let source = match c["source"].as_str() {
        Some("integer_file") => format!("{}-bit file", c["bits"]),
        Some(s) => s.replace('_', " "),
        None => "?".into(),
    };
    format!("{value} ({source})")
}

fn vec3(j: &serde_json::Value) -> Vector3<f64> {
    let v: Vec<f64> = serde_json::from_value(j.clone()).unwrap();
    Vector3::new(v[0], v[1], v[2])
}

fn sphere_run(dir: &Path, t: &Truth, circle: bool) -> Outcome {
    let k = &t.intrinsics;
    let image = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let mut args: Vec<String> = vec![
        "calibrate".into(),
        "sphere".into(),
        "--image".into(),
        image(t.light_image.as_deref().unwrap()),
        "--intrinsics".into(),
        csv(&[k.fx, k.fy, k.cx, k.cy]),
        "--json".into(),
    ];
    if circle {
        let c = t.sphere.as_ref().unwrap().outline_circle_px;
        args.extend(["--circle".into(), csv(&c)]);
    } else if let Some(o) = &t.outline_image {
        args.extend(["--outline-image".into(), image(o)]);
    }
    args.extend(format_args(t));
    let truth = Vector3::from(t.light_dir_camera);
    run(&args, |j| {
        vec3(&j["light_dir_camera"]).angle(&truth).to_degrees()
    })
}

#[test]
fn every_sphere_fixture_within_half_a_degree_or_refused_with_the_reason() {
    let all = fixtures("sphere", 20);
    let mut failures = Vec::new();
    println!(
        "| fixture | what it shows | radius (px) | outline detected | reported uncertainty | its centre / radius error (px) | outline given (--circle) | clip level |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (dir, t) in &all {
        let detected = sphere_run(dir, t, false);
        let circle = sphere_run(dir, t, true);
        let geometry = t.sphere.as_ref().unwrap();
        let (clip, outline_error, reported) = match &detected {
            Outcome::Measured(e, j) => {
                let image = &j["images"][0];
                let c: Vec<f64> =
                    serde_json::from_value(image["sphere_centre_px"].clone()).unwrap();
                let r = image["sphere_radius_px"].as_f64().unwrap();
                (
                    clip_cell(j),
                    format!(
                        "{:.2} / {:+.2}",
                        (c[0] - geometry.centre_px[0]).hypot(c[1] - geometry.centre_px[1]),
                        r - geometry.outline_radius_px
                    ),
                    {
                        let u = j["uncertainty_deg"].as_f64().unwrap();
                        format!("{u:.3} deg (error {:.2} of it)", e / u)
                    },
                )
            }
            Outcome::Refused(_) => (String::new(), String::new(), String::new()),
        };
        let what = match (&t.unusable, &t.outline_image) {
            (Some(u), _) => format!("{} (meant to be unusable: {})", t.description, u.reason),
            (None, Some(_)) => format!("{}; outline image given", t.description),
            (None, None) => t.description.clone(),
        };
        println!(
            "| {} | {} | {:.1} | {} | {} | {} | {} | {} |",
            t.name,
            what,
            geometry.outline_radius_px,
            detected.cell(MAX_DIRECTION_ERROR_DEG, "deg", 1.0),
            reported,
            outline_error,
            circle.cell(MAX_DIRECTION_ERROR_DEG, "deg", 1.0),
            clip
        );
        match &t.unusable {
            None => {
                // the reported uncertainty (an RMS angle) covers the error: a Gaussian error
                // exceeds twice its RMS in 2 % of cases
                if let Outcome::Measured(e, j) = &detected
                    && let Some(u) = j["uncertainty_deg"].as_f64()
                    && *e > 2.0 * u
                {
                    failures.push(format!(
                        "{}: error {e:.3} deg over twice the reported {u:.3} deg",
                        t.name
                    ));
                }
                if !detected.passes(MAX_DIRECTION_ERROR_DEG) {
                    failures.push(format!(
                        "{}: {}",
                        t.name,
                        detected.cell(MAX_DIRECTION_ERROR_DEG, "deg", 1.0)
                    ));
                }
            }
            Some(u) => {
                for (how, o) in [("detected", &detected), ("--circle", &circle)] {
                    match o {
                        Outcome::Refused(m) if m.contains(&u.error) => {}
                        Outcome::Refused(m) => failures.push(format!(
                            "{} ({how}): refused, but the message lacks \"{}\": {m}",
                            t.name, u.error
                        )),
                        Outcome::Measured(e, _) => failures.push(format!(
                            "{} ({how}): meant to be refused ({}), measured {e:.3} deg",
                            t.name, u.reason
                        )),
                    }
                }
            }
        }
        // a fixture that passes with the outline given must pass without it
        if circle.passes(MAX_DIRECTION_ERROR_DEG) && !detected.passes(MAX_DIRECTION_ERROR_DEG) {
            failures.push(format!("{}: passes with --circle but not without", t.name));
        }
        // a refusal to find the outline says what it saw and suggests --circle
        if let Outcome::Refused(m) = &detected
            && m.contains("no sphere found")
        {
            assert!(m.contains("--circle"), "{}: {m}", t.name);
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

#[test]
fn every_white_fixture_within_two_percent_or_refused_with_the_reason() {
    let all = fixtures("white", 6);
    let mut failures = Vec::new();
    println!(
        "| fixture | what it shows | irradiance error (worst channel) | clip level | warnings |"
    );
    println!("|---|---|---|---|---|");
    for (dir, t) in &all {
        let mut args: Vec<String> = vec![
            "calibrate".into(),
            "white".into(),
            "--image".into(),
            dir.join(t.board_image.as_deref().unwrap())
                .to_str()
                .unwrap()
                .into(),
            "--albedo".into(),
            csv(&t.albedo.unwrap()),
            "--light-dir".into(),
            csv(&t.light_dir_camera),
            "--normal".into(),
            csv(&t.board.as_ref().unwrap().normal_camera),
            "--json".into(),
        ];
        args.extend(format_args(t));
        let truth = t.irradiance;
        let o = run(&args, |j| {
            let e: Vec<f64> = serde_json::from_value(j["irradiance"].clone()).unwrap();
            (0..3)
                .map(|k| (e[k] / truth[k] - 1.0).abs())
                .fold(0.0, f64::max)
        });
        let (clip, warnings) = match &o {
            Outcome::Measured(_, j) => (
                clip_cell(j),
                j["warnings"]
                    .as_array()
                    .map(|w| {
                        w.iter()
                            .filter_map(|s| s.as_str())
                            .map(|s| s.split(':').next().unwrap_or(s).to_string())
                            .collect::<Vec<_>>()
                            .join("; ")
                    })
                    .unwrap_or_default(),
            ),
            Outcome::Refused(_) => (String::new(), String::new()),
        };
        let what = match &t.unusable {
            Some(u) => format!("{} (meant to be unusable: {})", t.description, u.reason),
            None => t.description.clone(),
        };
        println!(
            "| {} | {} | {} | {} | {} |",
            t.name,
            what,
            o.cell(MAX_IRRADIANCE_ERROR, "%", 100.0),
            clip,
            warnings
        );
        match (&t.unusable, &o) {
            (None, o) if o.passes(MAX_IRRADIANCE_ERROR) => {}
            (None, o) => failures.push(format!(
                "{}: {}",
                t.name,
                o.cell(MAX_IRRADIANCE_ERROR, "%", 100.0)
            )),
            (Some(u), Outcome::Refused(m)) if m.contains(&u.error) => {}
            (Some(u), o) => failures.push(format!(
                "{}: meant to be refused with \"{}\" ({}), got {}",
                t.name,
                u.error,
                u.reason,
                o.cell(MAX_IRRADIANCE_ERROR, "%", 100.0)
            )),
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
