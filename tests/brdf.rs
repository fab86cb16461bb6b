//! BRDF pipeline end to end, as a user would run it: the `merl` CLI on the shipped neural fits,
//! and a small leave-one-out experiment (basis without the target, optimal samples, ridge,
//! errors). The neural fits are smooth approximations of MERL, not measured MERL data.
//! Sizes are reduced (a quarter of the materials, a coarse bin grid) so this runs in seconds;
//! `examples/brdf_loo.rs` runs the full-size version.

use crate::util;
use brdf_rig::brdf::BinValues;
use brdf_rig::brdf::basis::{Basis, BasisSettings, GridStride};
use brdf_rig::brdf::basis_cache::{CacheStatus, load_or_build};
use brdf_rig::brdf::coords::MerlBin;
use brdf_rig::brdf::metrics::{ErrorReport, compare_values};
use brdf_rig::brdf::nbrdf::{Nbrdf, load_dir};
use brdf_rig::brdf::ridge::{BasisSample, RidgeSettings, reconstruct};
use brdf_rig::brdf::sampling::{SamplingSettings, condition_number, select_samples};
use std::process::Command;

fn nbrdf_dir() -> std::path::PathBuf {
    util::shared_data().join("merl-nbrdf")
}

fn run_eval(file: &std::path::Path, angles: [f64; 4]) -> [f64; 3] {
    let out = Command::new(util::bin())
        .arg("merl")
        .arg("eval")
        .arg(file)
        .args(angles.map(|a| format!("{a:.12}")))
        .output()
        .expect("run brdf-rig");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).expect("utf8");
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| t.parse().expect("a number"))
        .collect();
    [v[0], v[1], v[2]]
}

fn spherical_deg(v: &nalgebra::Vector3<f64>) -> (f64, f64) {
    (
        v.z.clamp(-1.0, 1.0).acos().to_degrees(),
        v.y.atan2(v.x).to_degrees(),
    )
}

#[test]
fn merl_eval_on_a_neural_fit_matches_the_test_vector() {
    // testvectors.json: alum-bronze at theta_h = theta_d = phi_d = 0 (light = view = normal).
    let want = [3.220888738043394, 1.3394905912028094, 0.506085277626958];
    let got = run_eval(&nbrdf_dir().join("alum-bronze.f32"), [0.0, 0.0, 0.0, 0.0]);
    for c in 0..3 {
        // The CLI prints 10 significant digits.
        assert!((got[c] - want[c]).abs() < 1e-8 * want[c], "{got:?}");
    }
}

#[test]
fn merl_tabulate_then_eval_reads_back_the_bin_centres() {
    let dir = tempfile::tempdir().expect("tmp");
    let table = dir.path().join("blue-acrylic.binary");
    let src = nbrdf_dir().join("blue-acrylic.f32");
    let status = Command::new(util::bin())
        .args(["merl", "tabulate"])
        .arg(&src)
        .arg(&table)
        .status()
        .expect("run");
    assert!(status.success());
    let net = Nbrdf::load(&src).expect("load");
    for bin in [
        MerlBin {
            theta_h: 0,
            theta_d: 10,
            phi_d: 90,
        },
        MerlBin {
            theta_h: 20,
            theta_d: 40,
            phi_d: 30,
        },
        MerlBin {
            theta_h: 50,
            theta_d: 5,
            phi_d: 170,
        },
    ] {
        let c = bin.centre();
        let (wi, wo) = c.to_directions();
        let (ti, pi) = spherical_deg(&wi);
        let (to, po) = spherical_deg(&wo);
        let got = run_eval(&table, [ti, pi, to, po]);
        let want = net.eval_angles(c.theta_h, c.theta_d, c.phi_d);
        for k in 0..3 {
            // f32 tabulation (1e-4 (v + 1), see nbrdf.rs) and 10 printed digits.
            assert!(
                (got[k] - want[k]).abs() < 1e-4 * (want[k] + 1.0),
                "{bin:?} {got:?} {want:?}"
            );
        }
    }
    // A wrong file is refused with its name.
    let out = Command::new(util::bin())
        .args(["merl", "eval"])
        .arg(dir.path().join("missing.binary"))
        .args(["0", "0", "0", "0"])
        .output()
        .expect("run");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.binary"));
}

/// The centred mapped residual of a reconstruction against the truth, summed over rows and
/// channels: what the ridge fit minimises (plus its penalty).
fn mapped_residual(basis: &Basis, truth: &[[f64; 3]], rec: &[[f64; 3]]) -> f64 {
    let mut s = 0.0;
    for (row, (t, r)) in truth.iter().zip(rec).enumerate() {
        for c in 0..3 {
            s += (basis.map(row, t[c]) - basis.map(row, r[c])).powi(2);
        }
    }
    s
}

fn report(label: &str, e: &ErrorReport) {
    eprintln!(
        "{label:<44} relative {:.4}  cos-weighted {:.4}  near-specular {:.4}",
        e.relative, e.cosine_weighted, e.near_specular
    );
}

#[test]
fn leave_one_out_small() {
    let all = load_dir(&nbrdf_dir()).expect("load materials");
    let targets = ["alum-bronze", "pink-fabric", "blue-acrylic"];
    // A quarter of the database plus the targets; the targets are then excluded one at a time.
    let subset: Vec<(String, Nbrdf)> = all
        .iter()
        .enumerate()
        .filter(|(i, (n, _))| i % 4 == 0 || targets.contains(&n.as_str()))
        .map(|(_, m)| m.clone())
        .collect();
    let cache = tempfile::tempdir().expect("tmp");
    for target in targets {
        let settings = BasisSettings {
            stride: GridStride {
                theta_h: 3,
                theta_d: 6,
                phi_d: 12,
            },
            basis_components: 40,
            exclude: vec![target.to_string()],
        };
        let (basis, status) = load_or_build(&settings, &subset, cache.path()).expect("basis");
        assert!(matches!(status, CacheStatus::Built(_)));
        // Leave-one-out really leaves it out.
        assert!(!basis.materials().iter().any(|m| m == target));
        let net = &subset.iter().find(|(n, _)| n == target).expect("target").1;
        let bins = basis.grid().bins().to_vec();
        let truth = net.values_at(&bins);

        // The basis mean alone (all coefficients zero): the error to beat.
        let mean_only = basis.synthesize(&[vec![0.0], vec![0.0], vec![0.0]]);
        let e_mean = compare_values(&bins, &truth, &mean_only);
        report(&format!("{target}: basis mean only"), &e_mean);

        // Every bin observed: k = 5, 10, 20. The mapped residual cannot grow with k (each extra
        // component removes a non-negative share of it); the error at k = 20 must beat the mean.
        let obs: Vec<BasisSample> = truth
            .iter()
            .enumerate()
            .map(|(row, &rgb)| BasisSample { row, rgb })
            .collect();
        let mut last = f64::INFINITY;
        let mut e20 = None;
        for k in [5, 10, 20] {
            let rec = reconstruct(&basis, &obs, &RidgeSettings { k, eta: 40.0 }).expect("ridge");
            let r = mapped_residual(&basis, &truth, rec.values());
            assert!(
                r <= last * (1.0 + 1e-9),
                "{target} k={k}: residual {r} > {last}"
            );
            last = r;
            let e = compare_values(&bins, &truth, rec.values());
            report(&format!("{target}: all {} bins, k = {k}", bins.len()), &e);
            if k == 20 {
                e20 = Some(e);
            }
        }
        let e20 = e20.expect("k = 20 ran");
        assert!(e20.cosine_weighted < e_mean.cosine_weighted, "{target}");

        // 20 optimal samples among all bins, and among a rig's bins: one theta_d only (a fixed
        // light and camera, METHOD.md section 1), the block around 45 degrees.
        let sampling = SamplingSettings {
            n_random: 200,
            ..SamplingSettings::default()
        };
        for (label, candidates) in [
            ("20 optimal samples", None),
            (
                "20 optimal samples, theta_d = 45 deg only",
                Some(
                    (0..basis.n_rows())
                        .filter(|&r| MerlBin::from_index(bins[r]).expect("bin").theta_d / 6 == 7)
                        .collect::<Vec<_>>(),
                ),
            ),
        ] {
            let s = select_samples(&basis, 20, candidates.as_deref(), &sampling).expect("select");
            if let Some(c) = &candidates {
                assert!(s.iter().all(|r| c.contains(r)));
            }
            assert!(condition_number(&basis, &s, 20).is_finite());
            let obs: Vec<BasisSample> = s
                .iter()
                .map(|&row| BasisSample {
                    row,
                    rgb: truth[row],
                })
                .collect();
            let rec = reconstruct(&basis, &obs, &RidgeSettings::default()).expect("ridge");
            let e = compare_values(&bins, &truth, rec.values());
            report(&format!("{target}: {label}"), &e);
            assert!(e.cosine_weighted.is_finite());
        }
    }
}

fn compare(reference: &std::path::Path, candidate: &std::path::Path) -> std::process::Output {
    Command::new(util::bin())
        .args(["merl", "compare"])
        .arg(reference)
        .arg(candidate)
        .args(["--bin-step", "50"])
        .output()
        .expect("run brdf-rig")
}

fn environment_error(out: &std::process::Output) -> f64 {
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines()
        .find_map(|l| l.strip_prefix("environment (relative L2 of the rendered sphere): "))
        .and_then(|v| v.trim().parse().ok())
        .unwrap_or_else(|| panic!("no environment line in {text}"))
}

#[test]
fn merl_compare_scores_a_brdf_against_a_reference_as_images_see_it() {
    let acrylic = nbrdf_dir().join("blue-acrylic.f32");
    let same = compare(&acrylic, &acrylic);
    assert!(
        same.status.success(),
        "{}",
        String::from_utf8_lossy(&same.stderr)
    );
    assert!(environment_error(&same) < 1e-9);
    let other = compare(&acrylic, &nbrdf_dir().join("gold-metallic-paint.f32"));
    assert!(
        other.status.success(),
        "{}",
        String::from_utf8_lossy(&other.stderr)
    );
    assert!(
        environment_error(&other) > 0.1,
        "{}",
        String::from_utf8_lossy(&other.stdout)
    );
    // A missing file is named.
    let missing = compare(&acrylic, std::path::Path::new("/nonexistent/x.binary"));
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("/nonexistent/x.binary"));
}
