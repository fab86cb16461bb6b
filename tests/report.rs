//! `brdf-rig report`: builds a small reconstruction output and a session folder the way the
//! reconstruct and capture steps lay them out, makes the report through the real binary, and
//! loads the page in headless Chromium to check it renders (SVG plots drawn, images decoded).

use crate::util::bin;
use brdf_rig::brdf::analytic::LambertGgx;
use brdf_rig::brdf::merl::MerlTable;
use brdf_rig::calib::clip::ClipLevel;
use brdf_rig::calib::light::LightSummary;
use brdf_rig::geometry::camera::{Intrinsics, Pose};
use brdf_rig::imageio::{ExrPrecision, write_exr, write_preview_png};
use brdf_rig::pipeline::calibration_file::{self, ChannelCalibration, SessionCalibration};
use brdf_rig::reconstruct::components::{ComponentChoice, ValidationPoint};
use brdf_rig::reconstruct::confidence::{Confidence, Level};
use brdf_rig::reconstruct::core::{CoreSettings, ModelReport};
use brdf_rig::reconstruct::ladder::{Family, FoldScheme, Ladder, Rung};
use brdf_rig::reconstruct::nielsen::NielsenSettings;
use brdf_rig::reconstruct::observe::{DropCounts, ImageCounts, ObserveSettings};
use brdf_rig::reconstruct::plausible::Plausibility;
use brdf_rig::reconstruct::refine::{IterationReport, RefineReport, RefineSettings};
use brdf_rig::reconstruct::report_file::{
    self, BasisReport, REPORT_FORMAT_VERSION, Report, SettingsReport, StageTiming,
};
use brdf_rig::reconstruct::trials::{SamplePixel, Trial};
use brdf_rig::render::image::LinearImage;
use brdf_rig::render::light::DirectionalLight;
use brdf_rig::render::sphere::{Sphere, render_sphere};
use brdf_rig::report::avail::Avail;
use brdf_rig::report::gather::gather;
use brdf_rig::report::html::render_html;
use brdf_rig::report::options::ReportOptions;
use nalgebra::{Point3, Vector3};
use serde_json::json;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::process::Command;

const MATERIAL: LambertGgx = LambertGgx {
    kd: [0.35, 0.2, 0.08],
    ks: [0.6, 0.6, 0.6],
    alpha: 0.12,
    f0: 0.04,
};

/// A session folder as the capture step writes it: two single-light and one ambient EXR with
/// their SHA-256 in `manifest.json`.
fn make_session(dir: &Path) {
    std::fs::create_dir_all(dir.join("light")).unwrap();
    std::fs::create_dir_all(dir.join("ambient")).unwrap();
    let mut shots = Vec::new();
    let files = [
        ("ambient", "ambient/v000_e0.exr", 0.0, None),
        ("single_light", "light/v000_ch0_e0.exr", 0.0, Some(0)),
        ("single_light", "light/v003_ch1_e0.exr", 45.0, Some(1)),
    ];
    for (i, (kind, file, angle, channel)) in files.iter().enumerate() {
        let mut img = LinearImage::new(32, 24);
        for y in 0..24 {
            for x in 0..32 {
                let v = (x + y + i) as f32 / 60.0;
                img.set(x, y, [v, 0.5 * v, 0.25]);
            }
        }
        let path = dir.join(file);
        write_exr(&path, &img, ExrPrecision::F32).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        shots.push(json!({
            "id": format!("s{i}"), "index": i, "kind": kind, "view": 0,
            "angle_deg": angle, "measured_angle_deg": angle + 0.01, "channel": channel,
            "level": 1.0, "light_dir_lab": channel.map(|_| [0.0, 0.5, 0.866]),
            "exposure_secs": 0.01, "gain": 1.0, "saturation": 0.0, "device": "sim",
            "file": file, "width": 32, "height": 24, "bytes": bytes.len(),
            "sha256": hex::encode(Sha256::digest(&bytes)),
            "time_unix": 1_790_000_000.0 + 10.0 * i as f64,
            "time_utc": format!("2026-09-21T12:26:{:02}.000Z", 40 + 10 * i),
        }));
    }
    let manifest = json!({
        "header": {"format_version": 1, "tool": "brdf-rig", "plan_name": "test <plan>",
                   "planned_shots": 3, "profile": "simulated", "camera_backend": "sim",
                   "created_utc": "2026-09-21T12:26:40.000Z", "simulated": true},
        "status": "complete",
        "shots": shots,
    });
    std::fs::write(
        dir.join("manifest.json"),
        serde_json::to_vec_pretty(&manifest).unwrap(),
    )
    .unwrap();
    // calibration.json as `brdf-rig calibrate SESSION` writes it (its owner's type)
    let light = LightSummary {
        dir_camera: [0.1, -0.2, -0.97],
        uncertainty_deg: 0.4,
        spread_deg: 0.1,
        std_error_deg: 0.1,
        fit_uncertainty_deg: 0.3,
        images: 1,
    };
    let cal = SessionCalibration {
        format_version: 1,
        channels: vec![ChannelCalibration {
            channel: 0,
            light,
            irradiance: [3.1, 3.0, 2.9],
            irradiance_std_error: [0.01, 0.01, 0.02],
            flat_field_spread: 0.001,
            sphere_clip: ClipLevel::given(1.0),
            white_clip: ClipLevel::given(1.0),
            warnings: Vec::new(),
            truth_dir_error_deg: None,
            truth_irradiance_error: None,
        }],
        light_images: 2,
        job: "job.toml".into(),
    };
    calibration_file::write(dir, &cal).unwrap();
}

/// A reconstruction output: the MERL table of an analytic BRDF, a report.json with trials, and
/// one sphere render as the reconstruction writes them.
fn make_recon(dir: &Path, session: &Path) {
    std::fs::create_dir_all(dir).unwrap();
    MerlTable::tabulate(&MATERIAL)
        .write(&dir.join("brdf.binary"))
        .unwrap();
    let sphere = Sphere {
        centre: Point3::origin(),
        radius: 1.0,
    };
    let k = Intrinsics::pinhole(64, 64, 100.0, 100.0, 32.0, 32.0);
    let pose = Pose::look_at(Point3::new(0.0, 0.0, 4.0), sphere.centre, Vector3::y());
    let light = DirectionalLight::new(Vector3::new(0.3, 0.3, 1.0), [3.0; 3]).unwrap();
    let img = render_sphere(&sphere, &MATERIAL, &light, &k, &pose, [0.0; 3]);
    write_preview_png(&dir.join("sphere_chosen.png"), &img, 0.0).unwrap();
    std::fs::write(
        session.join("job.toml"),
        "# the job the capture step wrote\n",
    )
    .unwrap();
    report_file::write(dir, &example_report(session.join("job.toml"))).unwrap();
}

/// A reconstruction's report, every section filled, built from the typed record the
/// reconstruction writes (so a format change is a compile error here too).
fn example_report(job: PathBuf) -> Report {
    let trial = |index, similarity, rejected_by_monotonicity| Trial {
        index,
        similarity,
        rejected_by_monotonicity,
        samples: vec![SamplePixel {
            image: 0,
            x: 3,
            y: 4,
            bin: 1000,
            reflectance: [0.1, 0.2, 0.3],
        }],
        fitted_samples: 1,
        candidate: None,
    };
    let rung = |family, k: Option<usize>, error| Rung {
        family,
        k,
        eta: k.map(|_| 40.0),
        parameters: k.map_or(8, |k| 3 * k),
        fold_errors: vec![Some(error)],
        error: Some(error),
        standard_error: Some(0.01),
        fold_errors_log: vec![Some(error)],
        error_log: Some(error / 2.0),
        standard_error_log: Some(0.005),
        fold_errors_patch: vec![Some(error)],
        error_patch: Some(error),
        standard_error_patch: Some(0.01),
        image_errors: vec![Some(error), None],
        extrapolation_error_log: None,
    };
    let core = CoreSettings::default();
    Report {
        format_version: REPORT_FORMAT_VERSION,
        job,
        settings: SettingsReport {
            observe: ObserveSettings::default(),
            core: core.clone(),
            nielsen: NielsenSettings::default(),
            png_scale: 1.0,
            saturation: None,
        },
        basis: BasisReport {
            materials: 99,
            excluded: vec!["alum-bronze".into()],
            stride: [1, 2, 2],
            rows: 100,
            components: 80,
            cache: None,
            note: "basis built from neural fits <not measured>".into(),
        },
        mesh_vertices: 3,
        mesh_faces: 1,
        images: vec![ImageCounts {
            file: PathBuf::from("/data/light/v000.exr"),
            covered: 5000,
            observed: 4321,
            dropped: DropCounts::default(),
        }],
        dropped: DropCounts::default(),
        observed_pixels: 4321,
        reliable_pixels: 4321,
        dropped_by_curvature: 0,
        // not defined: written as null, read back as NaN
        curvature_threshold: Some(f64::NAN),
        components: ComponentChoice {
            k: 6,
            eta: 40.0,
            curve: [(2, Some(0.4)), (4, Some(0.25)), (6, Some(0.2)), (8, None)]
                .into_iter()
                .map(|(k, error)| ValidationPoint {
                    k,
                    eta: 40.0,
                    error,
                })
                .collect(),
            held_out_pixels: 50,
            samples: 80,
            note: None,
        },
        trials: vec![
            trial(0, 0.962, 4),
            trial(1, 0.981, 2),
            trial(2, 0.955, 7),
            trial(3, 0.974, 1),
        ],
        chosen_trial: 1,
        model: ModelReport {
            family: Family::Basis,
            k: Some(6),
            eta: Some(40.0),
            analytic: None,
            reason: "the simplest model within noise of the best".into(),
        },
        ladder: Some(Ladder {
            scheme: FoldScheme::Images { folds: 2 },
            held_out_pixels: 400,
            rungs: vec![
                rung(Family::Lambert, None, 0.5),
                rung(Family::Basis, Some(6), 0.2),
            ],
            chosen: 1,
            reason: "the simplest model within noise of the best".into(),
        }),
        plausibility: Plausibility {
            observed_cells: 120,
            prior_share: 0.7,
            invalid_bins: 0,
            max_albedo_before: 0.9,
            max_albedo_after: 0.9,
            max_albedo_theta_deg: 10.0,
            scaled_bins: 0,
            prior: "basis mean".into(),
            hedge: Some(brdf_rig::reconstruct::hedge::Hedge {
                unseen_share: 0.25,
                analytic_weight: 0.125,
                f0: Some(0.04),
                f0_held: true,
                unresolved_lobe: false,
            }),
            peak_average: None,
            rung_average: None,
            grazing_transfer: None,
            peak_energy: None,
            extrapolation: Vec::new(),
        },
        comparisons: Vec::new(),
        confidence: Confidence {
            level: Level::Medium,
            reasons: vec!["medium: the trials disagree by 20 %".into()],
            trial_disagreement: Some(0.2),
            held_out_error: Some(0.2),
            analytic_held_out_error: None,
            theta_d_span_deg: 12.0,
            unseen_energy: 0.1,
            unseen_band: None,
        },
        normals: Some(RefineReport {
            accepted: true,
            reason: "1 iteration lowered the held-out error".into(),
            settings: RefineSettings::default(),
            pixels: 800,
            pixels_offered: 1000,
            held_out_images: vec![1],
            vertices_refined: 3,
            starts: Vec::new(),
            chosen_start_smoothing: 0,
            iterations: vec![iteration(0, 0.0, 0.4), iteration(1, 1.4, 0.35)],
            chosen_iterations: 1,
            mean_tilt_deg: 1.5,
            max_tilt_deg: 9.0,
            seconds: 2.0,
            materials: 1,
            table_bins: RefineSettings::default().sparse_table_bins,
            table_samples_per_cell: Some(1.3),
            foreign_colour_pixels: 12,
        }),
        materials: None,
        timings: [("rasterise", 1.5), ("observe", 0.25), ("trials", 3.0)]
            .into_iter()
            .map(|(stage, seconds)| StageTiming {
                stage: stage.into(),
                seconds,
            })
            .collect(),
        peak_memory_bytes: Some(1 << 20),
        warnings: vec!["<script>alert('x')</script> few pixels near the peak".into()],
    }
}

fn iteration(iteration: usize, mean_tilt_deg: f64, held_out_error: f64) -> IterationReport {
    IterationReport {
        iteration,
        mean_tilt_deg,
        max_tilt_deg: 2.0 * mean_tilt_deg,
        train_error: held_out_error - 0.05,
        held_out_error,
        seconds: 0.5,
    }
}

/// Headless Chromium, or a failure that says how to install it (never a silent pass).
fn chromium() -> PathBuf {
    brdf_rig::report::headless::chromium()
        .expect("chromium is not installed: run scripts/setup.sh (it installs Debian's chromium)")
}

fn run_chromium(page: &Path, extra: &[&str]) -> std::process::Output {
    let profile = tempfile::tempdir().unwrap();
    let url = format!("file://{}", page.display());
    let mut cmd = Command::new(chromium());
    cmd.args(brdf_rig::report::headless::HEADLESS_FLAGS)
        .arg(format!("--user-data-dir={}", profile.path().display()))
        .args(extra)
        .arg(url);
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "chromium failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The value of `name="..."` on the `<body ...>` tag of a DOM dump.
fn body_attr(dom: &str, name: &str) -> Option<String> {
    let start = dom.find("<body")?;
    let tag = &dom[start..start + dom[start..].find('>')?];
    let key = format!("{name}=\"");
    let i = tag.find(&key)? + key.len();
    Some(tag[i..i + tag[i..].find('"')?].to_string())
}

#[test]
fn report_renders_in_headless_chromium() {
    let tmp = tempfile::tempdir().unwrap();
    let session = tmp.path().join("session");
    let recon = tmp.path().join("recon");
    make_session(&session);
    make_recon(&recon, &session);

    let out = Command::new(bin())
        .arg("report")
        .arg(&recon)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let page = recon.join("report.html");
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).trim(),
        page.display().to_string()
    );
    let html = std::fs::read_to_string(&page).unwrap();
    // Self-contained: nothing fetched from anywhere.
    for bad in ["http://", "https://", "src=\"file:", "<link"] {
        let hits: Vec<&str> = html.matches(bad).collect();
        // The SVG namespace URI is an identifier, not a fetch.
        let allowed = html.matches("xmlns=\"http://www.w3.org/2000/svg\"").count();
        if bad == "http://" {
            assert_eq!(hits.len(), allowed, "{bad}");
        } else {
            assert!(hits.is_empty(), "{bad}");
        }
    }
    // Strings from files are escaped: the warning's script tag is text, not a script.
    assert!(html.contains("&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;"));
    assert!(!html.contains("<script>alert"));

    let dom = run_chromium(&page, &["--dump-dom"]);
    let dom = String::from_utf8(dom.stdout).unwrap();
    assert_eq!(
        body_attr(&dom, "data-images-ok").as_deref(),
        Some("true"),
        "images did not decode"
    );
    // 3 sphere renders + 1 render from the reconstruction + 2 single-light thumbnails.
    assert_eq!(body_attr(&dom, "data-images").as_deref(), Some("6"));
    // 3 in-plane channels, similarity per trial, k curve.
    assert_eq!(body_attr(&dom, "data-svgs").as_deref(), Some("5"));
    // The plotted curves are real polylines with many points (361 view angles per curve).
    let longest = dom
        .split("<polyline")
        .skip(1)
        .filter_map(|p| {
            let i = p.find("points=\"")? + 8;
            Some(p[i..i + p[i..].find('"')?].split_whitespace().count())
        })
        .max()
        .unwrap_or(0);
    assert!(longest >= 300, "longest polyline has {longest} points");
    for text in [
        "Chosen trial: <b>#1</b>, cosine similarity <b>0.981</b>",
        "k chosen: <b>6</b>",
        "Confidence in the result: <b>medium</b>",
        "the trials disagree by 20 %",
        "all intact",
        "single_light: 2",
        "Provenance: basis built from neural fits &lt;not measured&gt;",
        "channel 1: 1 shots",
        "rasterise",
        "25 % of the rendered sphere from cells no pixel observed; Lambert + GGX's weight in the \
         written table 0.12 (its F0 0.040: one theta_d cannot tell it",
    ] {
        assert!(dom.contains(text), "page lacks {text:?}");
    }

    // A screenshot that is not blank.
    let shot = tmp.path().join("shot.png");
    run_chromium(
        &page,
        &[
            &format!("--screenshot={}", shot.display()),
            "--window-size=1100,1600",
            "--hide-scrollbars",
        ],
    );
    let img = image::open(&shot).unwrap().to_rgb8();
    let mut colours: Vec<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() > 50,
        "screenshot has {} colours",
        colours.len()
    );
}

#[test]
fn missing_and_broken_pieces_are_reported_not_fatal() {
    let tmp = tempfile::tempdir().unwrap();
    let session = tmp.path().join("session");
    make_session(&session);
    // Corrupt one image after its checksum was recorded.
    std::fs::write(
        session.join("light/v003_ch1_e0.exr"),
        b"not an exr any more",
    )
    .unwrap();
    let opts = ReportOptions::default();
    let data = gather(&session, &opts).unwrap();
    let Avail::Yes(c) = &data.capture else {
        panic!("no capture summary: {:?}", data.capture)
    };
    assert_eq!(c.shots, 3);
    assert_eq!(c.by_kind.get("single_light"), Some(&2));
    assert_eq!(c.angles_deg, vec![0.0, 45.0]);
    assert_eq!(c.span_secs, Some(20.0));
    let Avail::Yes(st) = &c.checksums else {
        panic!("checksums not checked")
    };
    assert_eq!((st.checked, st.ok), (3, 2));
    assert!(
        st.problems[0].contains("v003_ch1_e0.exr"),
        "{:?}",
        st.problems
    );
    // One thumbnail decoded, the broken one skipped.
    assert!(matches!(&c.thumbnails, Avail::Yes(t) if t.len() == 1));
    assert!(data.calibration.is_available());
    // No reconstruction here: each piece says why.
    for why in [
        match &data.brdf {
            Avail::No(w) => w.clone(),
            _ => panic!("brdf"),
        },
        match &data.trials {
            Avail::No(w) => w.clone(),
            _ => panic!("trials"),
        },
    ] {
        assert!(!why.is_empty());
    }
    let html = render_html(&data);
    assert!(html.contains("PROBLEMS: 2 of 3 files"));
    assert!(html.contains("not available: no brdf.binary"));
    assert!(html.contains("test &lt;plan&gt;"));

    // A reconstruction output whose job is in the session finds the capture summary there,
    // and every section of its report.json.
    std::fs::write(session.join("job.toml"), "# the job\n").unwrap();
    let named = tmp.path().join("named");
    std::fs::create_dir_all(&named).unwrap();
    report_file::write(&named, &example_report(session.join("job.toml"))).unwrap();
    let data = gather(&named, &opts).unwrap();
    assert!(matches!(&data.capture, Avail::Yes(c) if c.shots == 3));
    let Avail::Yes(l) = &data.ladder else {
        panic!("{:?}", data.ladder)
    };
    assert_eq!(l.model, "basis (k = 6, eta = 40)");
    assert_eq!(l.scheme, "whole images held out, 2 folds");
    assert_eq!((l.rows.len(), l.rows[1].chosen), (2, true));
    // both held-out errors, the log one (what the default choice reads) and the linear one
    assert_eq!(
        (l.rows[1].error_log, l.rows[1].error),
        (Some(0.1), Some(0.2))
    );
    let html = render_html(&data);
    let table = &html[html
        .find("<table class=\"ladder\">")
        .expect("the ladder's table")..];
    let table = &table[..table.find("</table>").unwrap()];
    assert!(table.contains("held-out error, log space"), "{table}");
    assert!(
        table.contains("<td>0.1</td><td>0.005</td><td>0.2</td><td>0.01</td>"),
        "{table}"
    );
    let n = data.normals.as_ref().unwrap();
    assert!(n.accepted);
    assert_eq!((n.rows.len(), n.rows[1].held_out_error), (2, Some(0.35)));
    // the refinement's table: the coarser shape, and why
    assert!(
        html.contains("32 x 16 x 8 (theta_h x theta_d x phi_d): 1.3 fitting samples per observed cell of 48 x 32 x 8"),
        "{}",
        n.table
    );
    // ... and the pixels the colour rule left out of it
    assert!(
        n.table.ends_with(
            "; 12 pixels of another material's colour near the labels' boundary left out"
        ) && html.contains(
            "; 12 pixels of another material&#39;s colour near the labels&#39; boundary left out"
        ),
        "{}",
        n.table
    );
    assert!(
        data.other_facts
            .iter()
            .any(|(k, v)| k == "curvature_threshold" && v == "null"),
        "{:?}",
        data.other_facts
    );
    assert!(data.other_facts.iter().all(|(k, _)| k != "normals"));

    // A report.json of the version before the typed one: refused with both versions named.
    std::fs::write(
        named.join("report.json"),
        br#"{"format_version": 1, "trials": [0.9]}"#,
    )
    .unwrap();
    let data = gather(&named, &opts).unwrap();
    assert!(
        data.warnings
            .iter()
            .any(|w| w.contains("format_version 1") && w.contains("reads version 2")),
        "{:?}",
        data.warnings
    );
    assert!(matches!(&data.trials, Avail::No(w) if w.contains("format_version 1")));

    // A broken report.json and a truncated brdf.binary: a page all the same, with reasons.
    let recon = tmp.path().join("recon");
    std::fs::create_dir_all(&recon).unwrap();
    std::fs::write(recon.join("report.json"), b"{ not json").unwrap();
    std::fs::write(recon.join("brdf.binary"), [90u8, 0, 0, 0]).unwrap();
    let data = gather(&recon, &opts).unwrap();
    assert!(matches!(&data.brdf, Avail::No(w) if w.contains("brdf.binary")));
    assert!(
        data.warnings
            .iter()
            .any(|w| w.contains("not a valid reconstruction report")),
        "{:?}",
        data.warnings
    );
    let html = render_html(&data);
    assert!(html.contains("not available"));

    // Not a report folder at all: the CLI says which folder and what it expected.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let out = Command::new(bin())
        .arg("report")
        .arg(&empty)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&empty.display().to_string()) && err.contains("brdf.binary"),
        "{err}"
    );
    // A bad --compare is refused before anything is read.
    let out = Command::new(bin())
        .args(["report", "--compare", "nolabel"])
        .arg(&session)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("LABEL=PATH"));
}
