//! A scene rendered by an independent renderer (Mitsuba 3, not `src/sim` or `src/render`):
//! `tests/fixtures/independent/spot-3lights-lambert`, Spot with a Lambertian of albedo
//! (0.75, 0.6, 0.45) under three lights fixed in camera axes, 6 views at 96x72, made by
//! `scripts/render_recon_scenes.py` (its command is in the scene's `truth.json`;
//! docs/independent-scenes.md). Two checks:
//! - the conventions of the job (COLMAP poses and camera axes, `light_dir_camera`, irradiance)
//!   agree with what Mitsuba rendered, without the reconstruction: every observed pixel's
//!   reflectance `I / (E cos theta_i)` must be the albedo / pi;
//! - `brdf-rig reconstruct` recovers the BRDF within a measured bound at the truth's subset of
//!   MERL bins (Mitsuba's BSDF evaluated at bin centres computed in Python).
//!
//! And one object of two materials (`spot-3lights-split-lambert+cloth`, the same rig, the lower
//! half of Spot the Lambertian, the upper half a principled cloth): `--materials auto` finds two
//! materials that agree with the script's per-vertex truth.

use crate::util;
use brdf_rig::brdf::merl::MerlTable;
use brdf_rig::reconstruct::prepare::prepare;
use brdf_rig::reconstruct::{Job, Settings};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The committed scene; `BRDF_RIG_INDEPENDENT_SCENE` names another generated Lambertian scene
/// for the conventions check (the recovery bounds are the committed scene's).
fn scene() -> PathBuf {
    std::env::var_os("BRDF_RIG_INDEPENDENT_SCENE").map_or_else(
        || {
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("tests/fixtures/independent/spot-3lights-lambert")
        },
        PathBuf::from,
    )
}

fn truth_json() -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(scene().join("truth.json")).unwrap()).unwrap()
}

fn albedo() -> [f64; 3] {
    let v = &truth_json()["material"]["mitsuba_bsdf"]["reflectance"]["value"];
    [0, 1, 2].map(|c| v[c].as_f64().unwrap())
}

/// The truth at a subset of MERL bins (`truth_subset.bin`, format in
/// scripts/independent/merl.py): per bin its flat index, the cosines at the bin centre and f_r.
struct TruthBins {
    index: Vec<usize>,
    cos_i: Vec<f64>,
    cos_o: Vec<f64>,
    rgb: Vec<[f64; 3]>,
}

fn read_truth_bins(path: &Path) -> TruthBins {
    let b = std::fs::read(path).unwrap();
    assert_eq!(
        &b[..8],
        b"BRDFSUB1",
        "{}: not a truth subset",
        path.display()
    );
    let u32_at = |o: usize| u32::from_le_bytes(b[o..o + 4].try_into().unwrap());
    let f32_at = |o: usize| f64::from(f32::from_le_bytes(b[o..o + 4].try_into().unwrap()));
    let count = u32_at(8) as usize;
    assert_eq!(b.len(), 16 + 24 * count, "{}: truncated", path.display());
    let mut t = TruthBins {
        index: Vec::with_capacity(count),
        cos_i: Vec::with_capacity(count),
        cos_o: Vec::with_capacity(count),
        rgb: Vec::with_capacity(count),
    };
    for r in 0..count {
        let o = 16 + 24 * r;
        t.index.push(u32_at(o) as usize);
        t.cos_i.push(f32_at(o + 4));
        t.cos_o.push(f32_at(o + 8));
        t.rgb.push([f32_at(o + 12), f32_at(o + 16), f32_at(o + 20)]);
    }
    t
}

/// The three lights sit 20, 55 and 90 degrees from the camera, so the lit pixels' theta_d (half
/// the light-view angle) spans 5-15, 24-32 and 42-49 degrees (docs/independent-scenes.md): bins
/// above this are never observed.
const OBSERVED_THETA_D_DEG: usize = 50;

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Per image: `reflectance * pi / albedo` per channel over the observed pixels whose 8
/// neighbours are observed too (away from the silhouette and from shadow and grazing
/// boundaries, where a pixel's footprint mixes surfaces or light). 1 where the job's camera,
/// light direction and irradiance mean what Mitsuba rendered.
fn lambert_ratios(job: &Job) -> Vec<[Vec<f64>; 3]> {
    let prepared = prepare(job, &Settings::default(), &mut |_| {}).unwrap();
    let obs = &prepared.observed.observations;
    let a = albedo();
    (0..job.light_images.len())
        .map(|i| {
            let all: Vec<_> = obs.iter().filter(|o| o.image == i).collect();
            let seen: HashSet<(i64, i64)> = all.iter().map(|o| (o.x.into(), o.y.into())).collect();
            let inside = all.iter().filter(|o| {
                (-1..=1).all(|dy| {
                    (-1..=1).all(|dx| seen.contains(&(i64::from(o.x) + dx, i64::from(o.y) + dy)))
                })
            });
            let mut out = [Vec::new(), Vec::new(), Vec::new()];
            for o in inside {
                for c in 0..3 {
                    out[c].push(o.reflectance[c] * std::f64::consts::PI / a[c]);
                }
            }
            out
        })
        .collect()
}

/// (pixels, median ratio, share of pixels within `tol` of 1).
fn ratio_stats(ratio: &[f64], tol: f64) -> (usize, f64, f64) {
    if ratio.is_empty() {
        return (0, f64::NAN, 0.0);
    }
    let mut r = ratio.to_vec();
    let m = median(&mut r);
    let within = r.iter().filter(|x| (*x - 1.0).abs() < tol).count();
    (r.len(), m, within as f64 / r.len() as f64)
}

/// Measured when written (docs/independent-scenes.md): per image and channel, 126-739 inside
/// pixels, median ratio 0.9983-0.9993, 94.4-98.5 % of them within 2 % and 99.0-100 % within
/// 5 %. The median sits 0.1-0.2 % below 1 because Mitsuba's pixel is the mean over its square
/// (box filter) and the rasteriser samples its centre: the same Python check with 4x4 rays per
/// pixel (truth.json, `checks.pixel_prediction`) agrees to 0.03 % median.
#[test]
fn independent_lambertian_pixels_match_the_job_conventions() {
    let job = Job::from_file(&scene().join("job_exact.toml")).unwrap();
    for (i, channels) in lambert_ratios(&job).iter().enumerate() {
        for (c, ratio) in channels.iter().enumerate() {
            let (n, m, within2) = ratio_stats(ratio, 0.02);
            let (_, _, within5) = ratio_stats(ratio, 0.05);
            eprintln!(
                "image {i} channel {c}: {n} pixels, median ratio {m:.5}, within 2 %: {within2:.3}, within 5 %: {within5:.3}"
            );
            assert!(n > 100, "image {i}: only {n} pixels inside the lit surface");
            assert!((m - 1.0).abs() < 0.005, "image {i} channel {c}: median {m}");
            assert!(within2 > 0.9 && within5 > 0.97, "image {i} channel {c}");
        }
    }
    // The check has teeth: the light mirrored top to bottom in camera axes (the y-up mistake)
    // fails it on every image that is lit from above.
    let mut flipped = job.clone();
    for li in &mut flipped.light_images {
        li.light_dir_camera.y = -li.light_dir_camera.y;
    }
    let failing = lambert_ratios(&flipped)
        .iter()
        .enumerate()
        .filter(|(i, ch)| {
            let (n, m, within5) = ratio_stats(&ch[1], 0.05);
            eprintln!(
                "light flipped, image {i}: {n} pixels, median {m:.4}, within 5 %: {within5:.3}"
            );
            n <= 100 || (m - 1.0).abs() >= 0.005 || within5 <= 0.97
        })
        .count();
    assert_eq!(failing, job.light_images.len());
}

/// The 24 materials of the reduced test basis, as a folder of neural fits for `--nbrdf-dir`.
fn reduced_nbrdf_dir(dir: &Path) -> PathBuf {
    let out = dir.join("nbrdf");
    std::fs::create_dir_all(&out).unwrap();
    for (name, _) in crate::reconstruct::materials() {
        let file = format!("{name}.f32");
        std::fs::copy(
            util::shared_data().join("merl-nbrdf").join(&file),
            out.join(&file),
        )
        .unwrap();
    }
    out
}

/// Cosine-weighted relative error at the truth's bins whose theta_d bin (degrees: 90 bins over
/// 90 deg) is below `max_theta_d_deg`, and the median of rec / truth per channel there (for a
/// Lambertian: the recovered albedo over the true one). Bins where the result has no data count
/// as zero.
fn score(truth: &TruthBins, rec: &MerlTable, max_theta_d_deg: usize) -> (f64, [f64; 3]) {
    let (mut num, mut den) = (0.0, 0.0);
    let mut ratios = [Vec::new(), Vec::new(), Vec::new()];
    for (k, &b) in truth.index.iter().enumerate() {
        if (b / 180) % 90 >= max_theta_d_deg {
            continue;
        }
        let r = rec.get(b).unwrap_or([0.0; 3]);
        let w = truth.cos_i[k] * truth.cos_o[k];
        for c in 0..3 {
            let t = truth.rgb[k][c];
            num += (w * (r[c] - t)).powi(2);
            den += (w * t).powi(2);
            ratios[c].push(r[c] / t);
        }
    }
    let [r, g, b] = ratios.map(|mut v| median(&mut v));
    ((num / den).sqrt(), [r, g, b])
}

/// Bounds per mesh: (error for theta_d < 50 deg, |median rec/truth - 1| there, error over all
/// bins). Measured when written (4 trials, 40 samples, the 24-material basis at stride 1,4,6):
/// exact mesh 0.066, 0.9819-0.9914, 0.327; realistic mesh (median normal error 4.5 deg) 0.101,
/// 0.946-0.948, 0.458. The bounds allow about 1.5-2x. Where theta_d was observed the result is
/// within a few percent of the albedo; above it the basis extrapolates (theta_d 70-90 deg:
/// 5-8x the truth at the median on the exact mesh), which is the whole-table figure: a ceiling
/// against it getting worse, to be tightened once results shrink towards a prior there.
/// A factor of pi breaks the first two by far; smaller mix-ups are the conventions test's job.
const BOUNDS: [(&str, f64, f64, f64); 2] =
    [("exact", 0.12, 0.05, 0.5), ("realistic", 0.18, 0.1, 0.7)];

#[test]
fn reconstruct_recovers_the_independent_lambertian() {
    let dir = tempfile::tempdir().unwrap();
    let nbrdf = reduced_nbrdf_dir(dir.path());
    let truth = read_truth_bins(&scene().join("truth_subset.bin"));
    for (mesh, max_seen, max_bias, max_all) in BOUNDS {
        let out = dir.path().join(mesh);
        let o = Command::new(util::bin())
            .arg("reconstruct")
            .arg(scene().join(format!("job_{mesh}.toml")))
            .arg("--out")
            .arg(&out)
            .args(["--basis-stride", "1,4,6", "--basis-components", "40"])
            .args(["--trials", "4", "--samples", "40"])
            .arg("--nbrdf-dir")
            .arg(&nbrdf)
            .env(
                "BRDF_RIG_CACHE",
                std::env::temp_dir().join("brdf-rig-test-basis"),
            )
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{mesh}: {err}");
        let rec = MerlTable::read(&out.join("brdf.binary")).unwrap();
        let (e_seen, ratio_seen) = score(&truth, &rec, OBSERVED_THETA_D_DEG);
        let (e_all, _) = score(&truth, &rec, 90);
        eprintln!(
            "{mesh} mesh: cosine-weighted relative error {e_seen:.4} for theta_d < {OBSERVED_THETA_D_DEG} deg (median rec/truth {ratio_seen:.4?}), {e_all:.4} over all {} bins",
            truth.index.len()
        );
        assert!(e_seen < max_seen, "{mesh}: {e_seen}");
        assert!(
            ratio_seen.iter().all(|r| (r - 1.0).abs() < max_bias),
            "{mesh}: {ratio_seen:?}"
        );
        assert!(e_all < max_all, "{mesh}: {e_all}");
    }
}

/// `--materials auto` on another renderer's one-material scene (Mitsuba's Lambertian Spot, the
/// realistic mesh): one material is found, and the result (table and comparison panels) is byte
/// for byte the one-material reconstruction's.
#[test]
fn materials_auto_finds_one_material_on_the_independent_scene() {
    let dir = tempfile::tempdir().unwrap();
    let nbrdf = reduced_nbrdf_dir(dir.path());
    let run = |mode: &str| {
        let out = dir.path().join(mode);
        let o = Command::new(util::bin())
            .arg("reconstruct")
            .arg(scene().join("job_realistic.toml"))
            .arg("--out")
            .arg(&out)
            .args(["--basis-stride", "1,4,6", "--basis-components", "40"])
            .args(["--trials", "4", "--samples", "40"])
            .args(["--materials", mode])
            .arg("--nbrdf-dir")
            .arg(&nbrdf)
            .env(
                "BRDF_RIG_CACHE",
                std::env::temp_dir().join("brdf-rig-test-basis"),
            )
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{mode}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        out
    };
    let (one, auto) = (run("one"), run("auto"));
    let report = brdf_rig::reconstruct::report_file::read(&auto).unwrap();
    let m = report.materials.as_ref().expect("the segmentation ran");
    assert_eq!(m.count, 1, "{}", m.reason);
    assert_eq!(
        std::fs::read(one.join("brdf.binary")).unwrap(),
        std::fs::read(auto.join("brdf.binary")).unwrap(),
        "one material found: the same result as without segmentation"
    );
    assert!(!auto.join("materials.json").exists());
    // the photo against re-render panels too: three images, no material map
    let panels = std::fs::read_dir(one.join("compare")).unwrap();
    let mut n = 0;
    for p in panels {
        let name = p.unwrap().file_name();
        assert_eq!(
            std::fs::read(one.join("compare").join(&name)).unwrap(),
            std::fs::read(auto.join("compare").join(&name)).unwrap(),
            "{name:?}"
        );
        n += 1;
    }
    assert!(n > 0, "no panels written");
    assert!(report.comparisons.iter().all(|c| c.materials.is_empty()));
}

/// `--materials auto` on another renderer's object of two materials (Mitsuba's Spot, the lower
/// half Lambertian, the upper half the principled cloth; `--split lambert+cloth` of the script,
/// 6 views at 96x72, the realistic mesh): two materials are found, and they agree with the
/// script's per-vertex truth on most of the surface the images see.
#[test]
fn materials_auto_finds_the_two_materials_of_an_independent_object() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/independent/spot-3lights-split-lambert+cloth");
    let dir = tempfile::tempdir().unwrap();
    let mut settings = Settings {
        nbrdf_dir: reduced_nbrdf_dir(dir.path()),
        basis_cache: Some(std::env::temp_dir().join("brdf-rig-test-basis")),
        basis: util::small_basis(Vec::new()),
        materials: Some(Default::default()),
        ..Settings::default()
    };
    settings.core.trials.trials = 4;
    settings.core.trials.samples = 40;
    let job = Job::from_file(&scene.join("job_realistic.toml")).unwrap();
    let out = brdf_rig::reconstruct::reconstruct(&job, &settings, &mut |_| {}).unwrap();
    let m = out.materials.as_ref().expect("the segmentation ran");
    assert_eq!(m.segmentation.count, 2, "{}", m.segmentation.reason);
    assert_eq!(m.results.len(), 2);
    let truth = brdf_rig::eval::external::read_labels(
        &scene.join("labels_realistic.txt"),
        m.mesh.positions().len(),
    )
    .unwrap();
    // As `bench external` scores it. The Lambertian's truth is exact; the cloth's full table
    // is not in the fixture (35 MB), so it stands in with the Lambertian's: which truth each
    // found material's pixels have is checked for both, the error for the Lambertian only.
    let lambertian_truth = || {
        brdf_rig::eval::Truth::new(
            &brdf_rig::eval::BrdfValues(&brdf_rig::brdf::analytic::Lambert {
                albedo: [0.75, 0.6, 0.45],
            }),
            97,
        )
    };
    let scored = brdf_rig::eval::external::score_split(
        &out,
        &truth,
        &["lambert".to_string(), "cloth".to_string()],
        &[lambertian_truth(), lambertian_truth()],
    )
    .unwrap();
    assert_eq!((scored.count, scored.truth_count), (2, 2));
    assert!(scored.agreement > 0.9, "agreement {}", scored.agreement);
    let mut truths: Vec<&str> = scored.materials.iter().map(|f| f.truth.as_str()).collect();
    truths.sort_unstable();
    assert_eq!(truths, ["cloth", "lambert"]);
    for f in &scored.materials {
        assert!(f.purity > 0.9, "{}: purity {}", f.found, f.purity);
        assert!(f.pixels > 200, "{}: {} pixels", f.found, f.pixels);
    }
    let lambertian = scored
        .materials
        .iter()
        .find(|f| f.truth == "lambert")
        .unwrap();
    assert!(
        lambertian.ours < 0.1,
        "the Lambertian half's environment error: {}",
        lambertian.ours
    );
    // the found materials differ as the truths do: the cloth is blue, the Lambertian orange
    let blue = |c: [f64; 3]| c[2] / c[0];
    let mut ratios: Vec<f64> = m.results.iter().map(|r| blue(r.chromaticity)).collect();
    ratios.sort_by(f64::total_cmp);
    assert!(ratios[0] < 1.0 && ratios[1] > 1.5, "{ratios:?}");
}
