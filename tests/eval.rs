//! The accuracy grid in miniature (`brdf-rig bench accuracy`, docs/evaluation.md): one target
//! material on Spot, a coarse leave-one-out basis, small images, few trials. Ground truth is a
//! neural MERL fit (a smooth approximation of a MERL material, not measured data).
//!
//! Scored by the rendered environment error (docs/error-metrics.md). The bounds come from
//! measured runs of this exact configuration (see CEILING): a pipeline that returns a wrong or
//! empty BRDF (error near 1), loses the specular lobe (no better than Lambert), loses to the
//! Lambert + GGX fit a user would make by more than the issue #11 bar (10 %), or scores trials
//! against the wrong truth fails them.

use crate::util;
use brdf_rig::brdf::basis::{BasisSettings, GridStride};
use brdf_rig::brdf::nbrdf::load_dir;
use brdf_rig::eval::accuracy::{AccuracySpec, Rig, Variant, run};
use brdf_rig::geometry::mesh_io::load_mesh;
use brdf_rig::reconstruct::core::CoreSettings;
use brdf_rig::reconstruct::nielsen::NielsenSettings;

/// Ceiling on the rendered environment error with all three assumptions: measured 0.146 (the
/// model ladder's choice, made plausible); Lambert scores 0.255 here, a zero BRDF 1.0.
const CEILING: f64 = 0.2;

/// The miniature grid: green-latex on Spot, one seed, the given rig and core settings.
fn small_spec(spot: brdf_rig::geometry::mesh::Mesh, rig: Rig, core: CoreSettings) -> AccuracySpec {
    let stride = GridStride {
        theta_h: 1,
        theta_d: 4,
        phi_d: 6,
    };
    AccuracySpec {
        materials: vec!["green-latex".to_string()],
        meshes: vec![("spot".to_string(), spot)],
        mesh_names: vec!["spot".to_string()],
        views: 8,
        width: 96,
        height: 72,
        basis: BasisSettings {
            stride,
            basis_components: 40,
            exclude: Vec::new(),
        },
        basis_stride: [1, 4, 6],
        basis_components: 40,
        core,
        nielsen: NielsenSettings::default(),
        sfm_iterations: 10,
        sfm_noise_rel: 0.05,
        variants: vec![Variant::ablation()[0], Variant::ALL],
        bin_step: 5,
        seeds: 1,
        rigs: vec![rig],
        refine: None,
        exact_reference: false,
    }
}

fn small_core() -> CoreSettings {
    let mut core = CoreSettings::default();
    core.trials.trials = 4;
    core.trials.samples = 40;
    core
}

/// Runs the miniature grid in a scratch folder, with the tests' shared basis cache.
fn run_small(
    spec: &AccuracySpec,
    materials: &[(String, brdf_rig::brdf::nbrdf::Nbrdf)],
) -> Vec<brdf_rig::eval::accuracy::SceneResult> {
    let scratch = tempfile::tempdir().unwrap();
    let cache = std::env::temp_dir().join("brdf-rig-test-basis");
    run(
        spec,
        materials,
        &cache,
        scratch.path(),
        &mut |_| {},
        &mut |_| {},
    )
    .unwrap()
}

#[test]
fn small_accuracy_grid_beats_lambert_and_a_measured_ceiling() {
    let materials = load_dir(&util::shared_data().join("merl-nbrdf")).unwrap();
    let (spot, _) = load_mesh(&util::shared_data().join("meshes/spot_triangulated.obj")).unwrap();
    let spec = small_spec(spot, Rig::Spread, small_core());
    let results = run_small(&spec, &materials);
    assert_eq!(results.len(), 1);
    let r = &results[0];
    let all = r.all().expect("all three assumptions ran");
    let lambert = r.lambert.expect("Lambert fitted").environment;
    let ggx = r.lambert_ggx.expect("Lambert+GGX fitted").environment;
    eprintln!(
        "green-latex on spot: env ours {:.3} ({}), Lambert {lambert:.3}, Lambert+GGX {ggx:.3}; rank {} of {}",
        all.chosen.environment,
        all.model.family,
        all.chosen_rank,
        all.trials.len()
    );
    assert!(all.chosen.environment < CEILING, "{:?}", all.chosen);
    assert!(all.chosen.environment < lambert);
    // Not asserted here: the issue #11 bar (within 10 % of Lambert + GGX). With this test's
    // reduced basis (stride 1,4,6, 40 components) the ladder's basis + peak scores 0.146
    // against Lambert + GGX's 0.101; the full-size grid (docs/eval/accuracy.md) is where the
    // bar is measured.
    // Every trial was scored, the chosen one has the highest similarity, and its rank agrees
    // with the per-trial errors.
    assert_eq!(all.trials.len(), 4);
    let best_sim = all.trials.iter().map(|t| t.0).fold(f64::MIN, f64::max);
    assert_eq!(all.trials[all.chosen_trial].0, best_sim);
    let better = all
        .trials
        .iter()
        .filter_map(|t| t.1)
        .filter(|e| e.environment < all.chosen.environment)
        .count();
    assert_eq!(all.chosen_rank, better + 1);
    // The basis left the target out (the grid's leave-one-out rule).
    assert!(!r.target_in_basis);
    assert_eq!(r.basis_materials, materials.len() - 1);
    assert!(r.variants.iter().all(|(_, x)| x.is_ok()));
}

/// The multi-material study in miniature: `objects` on Spot (`views` light images of `width` x
/// `height`), spread lights, one seed, a coarse
/// basis without the objects' materials, the tests' small core; run in a scratch folder with
/// the tests' shared basis cache; with `time_command`, the whole commands timed too.
fn run_small_materials(
    objects: &[&str],
    (width, height, views): (usize, usize, usize),
    segment: brdf_rig::reconstruct::segment::SegmentSettings,
    refine: Option<brdf_rig::reconstruct::refine::RefineSettings>,
    time_command: bool,
) -> Vec<brdf_rig::eval::materials::ObjectResult> {
    let materials = load_dir(&util::shared_data().join("merl-nbrdf")).unwrap();
    let (spot, _) = load_mesh(&util::shared_data().join("meshes/spot_triangulated.obj")).unwrap();
    let spec = brdf_rig::eval::materials::MaterialsSpec {
        objects: vec![objects.iter().map(|m| m.to_string()).collect()],
        meshes: vec![("spot".to_string(), spot)],
        mesh_names: vec!["spot".to_string()],
        views,
        width,
        height,
        basis: crate::util::small_basis(Vec::new()),
        core: small_core(),
        segment,
        seeds: 1,
        rigs: vec![Rig::Spread],
        bin_step: 5,
        refine,
        time_repeats: 1,
        time_command,
        nbrdf_dir: Some(util::shared_data().join("merl-nbrdf")),
    };
    let scratch = tempfile::tempdir().unwrap();
    let cache = std::env::temp_dir().join("brdf-rig-test-basis");
    let results = brdf_rig::eval::materials::run(
        &spec,
        &materials,
        &cache,
        scratch.path(),
        &mut |_| {},
        &mut |_| {},
    )
    .unwrap();
    // the whole commands' output folders are not kept (tens of MB each)
    let left: Vec<String> = walk_names(scratch.path())
        .into_iter()
        .filter(|n| n.starts_with("command-"))
        .collect();
    assert!(left.is_empty(), "left behind: {left:?}");
    results
}

/// Every file and folder name under `dir`, recursively.
fn walk_names(dir: &std::path::Path) -> Vec<String> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let e = e.unwrap();
        out.push(e.file_name().to_string_lossy().into_owned());
        if e.file_type().unwrap().is_dir() {
            out.extend(walk_names(&e.path()));
        }
    }
    out
}

/// The multi-material study in miniature (`bench materials --refine-normals`): a two-material
/// Spot, the normals refined first with a reflectance table per material, then the materials
/// found and fitted. The count and the labels are right, the refinement fitted two tables and
/// lowered the normals' error, and every found material is scored against its truth beside the
/// baselines (fitted to the unrefined pixels). The whole `reconstruct` is timed both ways
/// (`--time-command`) and its output folders are not left behind.
#[test]
fn small_materials_study_refines_the_normals_with_a_table_per_material() {
    use brdf_rig::reconstruct::refine::RefineSettings;
    use brdf_rig::reconstruct::segment::SegmentSettings;
    let results = run_small_materials(
        &["green-latex", "pink-fabric"],
        (128, 96, 8),
        SegmentSettings::default(),
        Some(RefineSettings::default()),
        true,
    );
    assert_eq!(results.len(), 1);
    let r = &results[0];
    let n = r.normals.expect("the refinement ran against the truth");
    eprintln!(
        "count {}, agreement {:.3}; normals {:.2} -> {:.2} deg ({} tables, accepted {}); {:?}",
        r.count,
        r.agreement,
        n.median_before_deg,
        n.median_after_deg,
        n.tables,
        n.accepted,
        r.scores
            .iter()
            .map(|m| (m.truth.clone(), m.ours, m.lambert_ggx))
            .collect::<Vec<_>>()
    );
    assert_eq!(r.count, 2, "{}", r.reason);
    assert!(r.agreement >= 0.9);
    assert_eq!(n.tables, 2);
    assert!(n.accepted && n.median_after_deg < 0.9 * n.median_before_deg);
    // the whole commands were timed, both ways
    let (auto, one) = r.command_seconds.expect("the whole commands timed");
    assert!(auto > 0.0 && one > 0.0, "{auto} {one}");
    let mut truths: Vec<&str> = r.scores.iter().map(|m| m.truth.as_str()).collect();
    truths.sort_unstable();
    assert_eq!(truths, ["green-latex", "pink-fabric"]);
    for m in &r.scores {
        assert!(m.purity > 0.9 && m.ours < CEILING, "{m:?}");
        assert!(m.lambert.is_some() && m.lambert_ggx.is_some());
    }
}

/// A one-material shiny object at the accuracy grid's size (blue-acrylic on Spot, spread
/// lights, 320x240, seed 0) is one material: with the pixels near the specular peak in the
/// count's fits and scores (`count_min_theta_h_deg` 0, as before session 29) and no merge by
/// body colour (as before session 34) a second scale on part of it eased the held-out
/// highlights' miss by 19 % and the object was split in two. Either guard alone keeps it whole.
#[test]
fn a_shiny_one_material_object_is_not_split_at_the_grids_size() {
    use brdf_rig::reconstruct::segment::SegmentSettings;
    let count = |segment: SegmentSettings| {
        let r = run_small_materials(&["blue-acrylic"], (320, 240, 11), segment, None, false);
        assert!(r[0].command_seconds.is_none(), "timed though not asked");
        (r[0].count, r[0].reason.clone())
    };
    let with_peak = SegmentSettings {
        count_min_theta_h_deg: 0.0,
        ..SegmentSettings::default()
    };
    let before = count(SegmentSettings {
        merge_same_body: false,
        ..with_peak
    });
    let merged = count(with_peak);
    let now = count(SegmentSettings::default());
    eprintln!("with the peak, no merge: {before:?}; with the peak: {merged:?}; now: {now:?}");
    assert_eq!(
        before.0, 2,
        "the case this guards against is gone: {}",
        before.1
    );
    assert_eq!(merged.0, 1, "{}", merged.1);
    assert_eq!(now.0, 1, "{}", now.1);
}

/// Where the ladder chooses the basis and the basis + peak scores within noise of it, the
/// written table is their geometric mean (`CoreSettings::peak_average`): the model stays the
/// basis, the table and its rendered error change, the albedo stays at most 1, and the model's
/// reason says what was done. Measured on this scene (pink-fabric, spread lights, 96x72): 0.0180
/// averaged, 0.0173 with the basis alone. (green-latex, the scene before session 46, fits a
/// negligible GGX peak: both tables rendered alike to 12 digits, so comparing them tested
/// rounding.)
#[test]
fn a_peak_the_held_out_images_cannot_judge_is_averaged_in() {
    let materials = load_dir(&util::shared_data().join("merl-nbrdf")).unwrap();
    let (spot, _) = load_mesh(&util::shared_data().join("meshes/spot_triangulated.obj")).unwrap();
    let mut runs = Vec::new();
    for weight in [0.5, 0.0] {
        let mut core = small_core();
        core.peak_average = weight;
        let mut spec = small_spec(spot.clone(), Rig::Spread, core);
        spec.materials = vec!["pink-fabric".to_string()];
        let results = run_small(&spec, &materials);
        let all = results[0].all().expect("all three assumptions ran").clone();
        eprintln!(
            "peak average {weight}: env ours {:.4} ({}), {:?}; {:?}; {}",
            all.chosen.environment,
            all.model.family,
            all.plausibility.peak_average,
            all.plausibility.peak_energy,
            all.model.reason
        );
        runs.push(all);
    }
    let (averaged, alone) = (&runs[0], &runs[1]);
    assert_eq!(averaged.model.family, alone.model.family);
    assert_eq!(averaged.plausibility.peak_average, Some(0.5));
    assert!(alone.plausibility.peak_average.is_none());
    assert!(
        averaged
            .model
            .reason
            .contains("the written table is the basis averaged")
    );
    assert!(!alone.model.reason.contains("averaged"));
    assert!(averaged.plausibility.max_albedo_after <= 1.0);
    let change = (averaged.chosen.environment / alone.chosen.environment - 1.0).abs();
    assert!(
        change > 0.01,
        "the average changed the render by {change:.2e}"
    );
}

/// With one light by the camera (one theta_d) most of a rendered sphere comes from cells no
/// pixel saw, and the held-out images cannot rank the basis's extrapolation against Lambert +
/// GGX's: the hedge (`reconstruct::hedge`) averages them by that share. Measured on this
/// scene (green-latex, one light at 30 deg, 96x72): 49 % of the render unobserved, the basis
/// chosen either way; hedged 0.097, unhedged 0.123 (worse than the issue #11 bar), Lambert +
/// GGX 0.108.
#[test]
fn one_light_results_are_hedged_towards_lambert_ggx_by_the_unseen_share() {
    let materials = load_dir(&util::shared_data().join("merl-nbrdf")).unwrap();
    let (spot, _) = load_mesh(&util::shared_data().join("meshes/spot_triangulated.obj")).unwrap();
    let rig = Rig::OneLight { alpha_deg: 30.0 };
    let mut runs = Vec::new();
    for strength in [0.5, 0.0] {
        let mut core = small_core();
        core.hedge.strength = strength;
        let results = run_small(&small_spec(spot.clone(), rig, core), &materials);
        let r = &results[0];
        let all = r.all().expect("all three assumptions ran").clone();
        let ggx = r.lambert_ggx.expect("Lambert+GGX fitted").environment;
        eprintln!(
            "hedge {strength}: env ours {:.4} ({}), Lambert+GGX {ggx:.4}, hedge {:?}",
            all.chosen.environment, all.model.family, all.plausibility.hedge
        );
        runs.push((all, ggx));
    }
    let (hedged, ggx) = &runs[0];
    let (unhedged, _) = &runs[1];
    // The ladder's choice is the same; only the written table changes.
    assert_eq!(hedged.model.family, unhedged.model.family);
    let h = hedged
        .plausibility
        .hedge
        .expect("the hedge ran on the basis");
    assert!(h.unseen_share > 0.3, "{h:?}");
    assert!(
        (h.analytic_weight - 0.5 * h.unseen_share).abs() < 1e-12,
        "{h:?}"
    );
    assert!(unhedged.plausibility.hedge.is_none());
    assert!(hedged.plausibility.max_albedo_after <= 1.0);
    // Better than the unhedged table, and within the issue #11 bar of Lambert + GGX.
    assert!(
        hedged.chosen.environment < unhedged.chosen.environment,
        "{} vs {}",
        hedged.chosen.environment,
        unhedged.chosen.environment
    );
    assert!(
        hedged.chosen.environment < 1.1 * ggx,
        "{} vs {ggx}",
        hedged.chosen.environment
    );
}

/// The small scene of the sweeps (`eval::sweeps`) with the test's coarse basis and few trials.
fn small_setting() -> brdf_rig::eval::sweeps::Setting {
    let mut s = brdf_rig::eval::sweeps::base_setting("green-latex");
    s.scene.width = 96;
    s.scene.height = 72;
    s.scene.views = 8;
    s.stride = GridStride {
        theta_h: 1,
        theta_d: 4,
        phi_d: 6,
    };
    s.components = 40;
    s.core.trials.trials = 4;
    s.core.trials.samples = 40;
    s
}

/// Where the method breaks (docs/evaluation.md, "Stability"), the pipeline must say so itself:
/// low confidence with a reason, or an error; never a confident wrong answer. The same scene
/// with all its images is the control: trusted, and accurate.
#[test]
fn failure_cases_report_low_confidence_or_an_error() {
    use brdf_rig::reconstruct::confidence::Level;
    let materials = load_dir(&util::shared_data().join("merl-nbrdf")).unwrap();
    let (spot, _) = load_mesh(&util::shared_data().join("meshes/spot_triangulated.obj")).unwrap();
    let scratch = tempfile::tempdir().unwrap();
    let cache = std::env::temp_dir().join("brdf-rig-test-basis");
    let mut runner =
        brdf_rig::eval::sweeps::Runner::new(&materials, &spot, &cache, scratch.path(), 5);

    let control = runner.run(&small_setting()).unwrap();
    let c = control.confidence.as_ref().expect("the control ran");
    let ec = control.errors.expect("control errors").environment;
    eprintln!("control: env {ec:.3}, confidence {:?}", c);
    assert!(ec < CEILING, "control env {ec}");
    assert!(c.level >= Level::Medium, "{c:?}");

    // One single-light image: a single theta_d, the rest of the domain extrapolated.
    let mut one = small_setting();
    one.perturb.views = Some(1);
    let p = runner.run(&one).unwrap();
    let c = p.confidence.as_ref().expect("one image still reconstructs");
    let e1 = p.errors.expect("errors").environment;
    eprintln!("one image: env {e1:.3}, confidence {:?}", c);
    assert_eq!(c.level, Level::Low, "{c:?}");
    assert!(c.reasons.iter().any(|r| r.contains("theta_d")), "{c:?}");
    assert!(e1 > ec, "the low-confidence result is also the worse one");

    // Every highlight and most of the object clipped: no usable pixels, an error, no BRDF.
    let mut clipped = small_setting();
    clipped.perturb.clip_fraction = 0.02;
    let p = runner.run(&clipped).unwrap();
    assert!(p.errors.is_none() && p.confidence.is_none());
    let why = p.failure.expect("a clear error");
    assert!(why.contains("no usable pixels"), "{why}");
}

/// `brdf-rig reconstruct --min-confidence` turns a low-confidence result into exit status 3,
/// with the results still written and the reasons printed.
#[test]
fn reconstruct_cli_exits_3_below_the_required_confidence() {
    use brdf_rig::eval::write_case;
    let materials = load_dir(&util::shared_data().join("merl-nbrdf")).unwrap();
    let (spot, _) = load_mesh(&util::shared_data().join("meshes/spot_triangulated.obj")).unwrap();
    let brdf = &materials
        .iter()
        .find(|(n, _)| n == "green-latex")
        .unwrap()
        .1;
    let dir = tempfile::tempdir().unwrap();
    let mut s = small_setting();
    s.scene.views = 1;
    let job = write_case(&dir.path().join("scene"), &spot, &s.sfm, brdf, &s.scene).unwrap();
    let out = dir.path().join("out");
    let cache = std::env::temp_dir().join("brdf-rig-test-basis");
    let run = std::process::Command::new(util::bin())
        .arg("reconstruct")
        .arg(&job.source)
        .arg("--out")
        .arg(&out)
        .args(["--exclude", "green-latex", "--basis-stride", "1,4,6"])
        .args([
            "--basis-components",
            "40",
            "--trials",
            "4",
            "--samples",
            "40",
        ])
        .arg("--basis-cache")
        .arg(&cache)
        .args(["--min-confidence", "medium"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("confidence: low"), "{stderr}");
    assert!(stderr.contains("theta_d"), "{stderr}");
    let report = brdf_rig::reconstruct::report_file::read(&out).unwrap();
    assert_eq!(
        report.confidence.level,
        brdf_rig::reconstruct::confidence::Level::Low
    );
    assert!(out.join("brdf.binary").is_file());
}
