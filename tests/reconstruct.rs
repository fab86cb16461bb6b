//! Reconstruction end to end on simulated scenes: Spot rendered with a neural MERL fit (a smooth
//! approximation of a MERL material, not measured data) from several views and light
//! directions, reconstructed from an SfM-like (smoothed, perturbed) mesh with a reduced basis
//! from which the target material is always left out. Also: job validation through the binary.

use crate::util;
use brdf_rig::brdf::basis::Basis;
use brdf_rig::brdf::basis_cache;
use brdf_rig::brdf::merl::MerlTable;
use brdf_rig::brdf::nbrdf::{Nbrdf, load_dir};
use brdf_rig::geometry::mesh::Mesh;
use brdf_rig::geometry::mesh_io::load_mesh;
use brdf_rig::reconstruct::reliable::ReliableSettings;
use brdf_rig::reconstruct::report_file;
use brdf_rig::reconstruct::{Job, Settings, reconstruct_with_basis};
use brdf_rig::sim::job_scene::{SceneSpec, write_scene};
use nalgebra::{Point3, Vector3};
use rand::{Rng, SeedableRng};
use std::path::Path;
use std::process::Command;

/// Materials of the reduced test basis (the paper's six among them; the target is excluded).
const BASIS_MATERIALS: [&str; 24] = [
    "alum-bronze",
    "fruitwood-241",
    "pink-fabric",
    "blue-acrylic",
    "pink-fabric2",
    "green-latex",
    "aluminium",
    "black-obsidian",
    "blue-metallic-paint",
    "brass",
    "chrome",
    "gold-paint",
    "green-plastic",
    "maroon-plastic",
    "nickel",
    "orange-paint",
    "red-fabric",
    "silver-paint",
    "specular-blue-phenolic",
    "teflon",
    "violet-rubber",
    "white-paint",
    "yellow-matte-plastic",
    "cherry-235",
];

pub fn materials() -> Vec<(String, Nbrdf)> {
    load_dir(&util::shared_data().join("merl-nbrdf"))
        .unwrap()
        .into_iter()
        .filter(|(n, _)| BASIS_MATERIALS.contains(&n.as_str()))
        .collect()
}

pub fn reduced_basis(target: &str, materials: &[(String, Nbrdf)]) -> Basis {
    let settings = crate::util::small_basis(vec![target.to_string()]);
    let cache = std::env::temp_dir().join("brdf-rig-test-basis");
    basis_cache::load_or_build(&settings, materials, &cache)
        .unwrap()
        .0
}

/// An SfM-like copy of a mesh: Laplacian smoothing (MVS rounds off curved detail, so normal
/// errors grow with curvature) and a small random displacement along the normals.
pub fn sfm_like(mesh: &Mesh, iterations: usize, noise: f64, seed: u64) -> Mesh {
    let n = mesh.positions().len();
    let mut nbrs: Vec<Vec<u32>> = vec![Vec::new(); n];
    for f in mesh.faces() {
        for (a, b) in [(f[0], f[1]), (f[1], f[2]), (f[2], f[0])] {
            nbrs[a as usize].push(b);
            nbrs[b as usize].push(a);
        }
    }
    let mut p: Vec<Point3<f64>> = mesh.positions().to_vec();
    for _ in 0..iterations {
        let q = p.clone();
        for (i, nb) in nbrs.iter().enumerate() {
            if nb.is_empty() {
                continue;
            }
            let mean: Vector3<f64> = nb
                .iter()
                .map(|&j| q[j as usize].coords)
                .sum::<Vector3<f64>>()
                / nb.len() as f64;
            p[i] = Point3::from(q[i].coords * 0.5 + mean * 0.5);
        }
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let scale = noise * mesh.diagonal();
    for (i, pi) in p.iter_mut().enumerate() {
        let d: f64 = rng.gen_range(-1.0..1.0);
        *pi += mesh.vertex_normals()[i] * d * scale;
    }
    let mut out = mesh.clone();
    assert!(out.set_positions(p));
    out
}

fn spot() -> Mesh {
    load_mesh(&util::shared_data().join("meshes/spot_triangulated.obj"))
        .unwrap()
        .0
}

pub fn test_settings() -> Settings {
    let mut s = Settings::default();
    s.core.trials.trials = 6;
    s.core.trials.samples = 40;
    s.core.components.grid = vec![5, 10, 20, 40];
    s
}

#[test]
fn three_assumptions_beat_none_and_the_analytic_baselines() {
    let target = "green-latex";
    let mats = materials();
    let truth = &mats.iter().find(|(n, _)| n == target).unwrap().1;
    let basis = reduced_basis(target, &mats);
    assert!(!basis.materials().iter().any(|m| m == target));
    let dir = tempfile::tempdir().unwrap();
    let mesh = spot();
    let job_mesh = sfm_like(&mesh, 3, 0.002, 7);
    let spec = SceneSpec {
        views: 8,
        ..SceneSpec::default()
    };
    let job = write_scene(dir.path(), &mesh, &job_mesh, truth, &spec).unwrap();
    let job = Job::from_file(&job.source).unwrap();

    let all = test_settings();
    let out = reconstruct_with_basis(&job, &all, &basis, &mut |_| {}).unwrap();
    let mut none = test_settings();
    none.core.reliable = ReliableSettings::none();
    let out_none = reconstruct_with_basis(&job, &none, &basis, &mut |_| {}).unwrap();

    // Scored as an image sees it (the rendered environment error, docs/error-metrics.md),
    // against the baselines a user would fit to the same pixels (image-space least squares).
    let scorer = brdf_rig::eval::Truth::new(truth, 5);
    let e_all = scorer.errors_of(&out.table).environment;
    let e_none = scorer.errors_of(&out_none.table).environment;
    let (lambert, ggx) = brdf_rig::eval::baseline_errors(&scorer, &out.observed.observations);
    let e_lambert = lambert.expect("Lambert fitted").environment;
    let e_ggx = ggx.expect("Lambert + GGX fitted").environment;
    eprintln!(
        "{target}: environment error: assumptions {e_all:.4} ({}), none {e_none:.4}, Lambert {e_lambert:.4}, Lambert+GGX {e_ggx:.4}; k = {}",
        out.report.model.family, out.report.components.k
    );
    assert!(e_all < e_lambert);
    // Never worse than the better baseline by more than the issue #11 bar.
    assert!(e_all <= 1.1 * e_ggx, "{e_all} against {e_ggx}");
    assert!(e_all <= 1.1 * e_none, "{e_all} against {e_none}");
    // The report carries what a user needs to judge the result.
    let r = &out.report;
    assert_eq!(r.trials.len(), 6);
    assert!(
        r.trials[r.chosen_trial].similarity
            >= r.trials.iter().map(|t| t.similarity).fold(0.0, f64::max)
    );
    assert!(r.observed_pixels > 1000, "{}", r.observed_pixels);
    assert!(r.dropped_by_curvature > 0);
    assert!(!r.components.curve.is_empty());
}

pub fn write_small_job(dir: &Path) -> Job {
    let mats = materials();
    let truth = &mats.iter().find(|(n, _)| n == "blue-acrylic").unwrap().1;
    let mesh = spot();
    let spec = SceneSpec {
        views: 2,
        width: 64,
        height: 48,
        ..SceneSpec::default()
    };
    write_scene(dir, &mesh, &mesh, truth, &spec).unwrap()
}

/// A reconstruction of the small job that takes a few seconds: a coarse basis of 10
/// components without the job's material, 3 trials of 15 samples.
pub const QUICK_ARGS: [&str; 10] = [
    "--exclude",
    "blue-acrylic",
    "--basis-stride",
    "3,10,10",
    "--basis-components",
    "10",
    "--trials",
    "3",
    "--samples",
    "15",
];

pub fn run_cli(job: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(util::bin())
        .arg("reconstruct")
        .arg(job)
        .arg("--out")
        .arg(out)
        .args(extra)
        .env(
            "BRDF_RIG_CACHE",
            std::env::temp_dir().join("brdf-rig-test-basis"),
        )
        .output()
        .unwrap()
}

#[test]
fn bad_jobs_fail_with_messages_naming_file_and_field() {
    let dir = tempfile::tempdir().unwrap();
    let job = write_small_job(dir.path());
    let text = std::fs::read_to_string(&job.source).unwrap();
    let out = dir.path().join("out");
    let cases: [(&str, String, &[&str]); 4] = [
        (
            "camera",
            text.replace("camera = \"view_01.exr\"", "camera = \"nope.exr\""),
            &["light_image[1].camera", "nope.exr", "view_00.exr"],
        ),
        (
            "mesh",
            text.replace("mesh.ply", "missing.ply"),
            &["missing.ply"],
        ),
        (
            "irradiance",
            text.replacen(
                "irradiance = [3.0, 3.0, 3.0]",
                "irradiance = [3.0, -1.0, 3.0]",
                1,
            ),
            &["light_image[0].irradiance", "job.toml"],
        ),
        (
            "light",
            text.replacen(
                "light_dir_camera = [",
                "light_dir_camera = [0.0, 0.0, 0.0] #",
                1,
            ),
            &["light_image[0].light_dir_camera", "unit"],
        ),
    ];
    for (what, bad, needles) in cases {
        std::fs::write(&job.source, &bad).unwrap();
        let o = run_cli(&job.source, &out, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{what}: {err}");
        for n in needles {
            assert!(err.contains(n), "{what}: {n:?} not in {err}");
        }
        assert!(!err.contains("panicked"), "{err}");
    }
    // An image whose size does not match its camera.
    std::fs::write(&job.source, &text).unwrap();
    let small = brdf_rig::render::image::LinearImage::new(10, 10);
    brdf_rig::imageio::write_exr(
        &job.light_images[1].file,
        &small,
        brdf_rig::imageio::ExrPrecision::F32,
    )
    .unwrap();
    let o = run_cli(&job.source, &out, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("10x10") && err.contains("64x48"), "{err}");
}

#[test]
fn cli_writes_merl_table_report_and_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let job = write_small_job(dir.path());
    let out = dir.path().join("out");
    let o = run_cli(&job.source, &out, &QUICK_ARGS);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("trials") && err.contains("done in"), "{err}");
    let table = MerlTable::read(&out.join("brdf.binary")).unwrap();
    // Some bin near the specular direction has a positive value.
    assert!(table.get(10).is_some_and(|v| v[0] > 0.0));
    // read back through the format's owner: what the writer wrote, the reader reads
    let report = report_file::read(&out).unwrap();
    assert_eq!(report.trials.len(), 3);
    assert_eq!(report.basis.excluded, ["blue-acrylic"]);
    assert!(report.basis.note.contains("not measured"));
    assert!(report.timings.len() >= 6);
    assert!(report.peak_memory_bytes.unwrap() > 0);
    let sphere = brdf_rig::imageio::read_exr(&out.join("sphere.exr")).unwrap();
    assert_eq!((sphere.width(), sphere.height()), (256, 256));
    assert!(sphere.luminance(128, 128) > 0.0);
    assert!(out.join("sphere.png").is_file());
}

/// Spot's vertex normals, each turned by up to `deg` about a random tangent axis.
fn turned_normals(mesh: &Mesh, deg: f64, seed: u64) -> Vec<Vector3<f64>> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    mesh.vertex_normals()
        .iter()
        .map(|n| {
            let r = Vector3::new(rng.r#gen(), rng.r#gen(), rng.r#gen());
            let axis = n.cross(&r).try_normalize(1e-9).unwrap_or(Vector3::x());
            let angle = deg.to_radians() * rng.gen_range(0.5..1.0);
            nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle) * n
        })
        .collect()
}

/// Spot rendered with its true vertex normals (green-latex, 8 views at 160x120); the job's mesh
/// is `job_mesh` with `normals`; the real pipeline (rasteriser, observation, pixel gathering)
/// then the refinement with `settings`. Returns the median vertex-normal error before and
/// after and the same over the pixels, degrees, against Spot's true normals.
fn refine_spot(
    job_mesh: &Mesh,
    normals: Vec<Vector3<f64>>,
    settings: &brdf_rig::reconstruct::refine::RefineSettings,
) -> (f64, f64, f64, f64) {
    let mats = materials();
    let truth = &mats.iter().find(|(n, _)| n == "green-latex").unwrap().1;
    let dir = tempfile::tempdir().unwrap();
    let mesh = spot();
    let spec = SceneSpec {
        views: 8,
        width: 160,
        height: 120,
        ..SceneSpec::default()
    };
    let job = write_scene(dir.path(), &mesh, job_mesh, truth, &spec).unwrap();
    let reconstruct_settings = Settings::default();
    let mut scene =
        brdf_rig::reconstruct::prepare::load_scene(&job, &reconstruct_settings).unwrap();
    assert!(scene.mesh.set_vertex_normals(normals));
    let observe = reconstruct_settings.observe;
    let observed = brdf_rig::reconstruct::prepare::observe_scene(&scene, &observe);
    let mut prepared = brdf_rig::reconstruct::prepare::Prepared {
        scene,
        observed,
        refinement: None,
        timings: Vec::new(),
    };
    let before = prepared.scene.mesh.vertex_normals().to_vec();
    let seen = brdf_rig::reconstruct::prepare::refine_prepared(
        &mut prepared,
        None,
        &observe,
        settings,
        &Default::default(),
        &mut |_| {},
    );
    let report = prepared.refinement.clone().expect("the refinement ran");
    let e = |n: &[Vector3<f64>]| {
        brdf_rig::reconstruct::refine::normal_error_deg(n, mesh.vertex_normals(), &seen)
            .expect("seen vertices")
            .0
    };
    let (b, a) = (e(&before), e(prepared.scene.mesh.vertex_normals()));
    // The error as the images see it: the normal each pixel gets (its face's corners blended).
    let px = brdf_rig::reconstruct::prepare::refine_pixels(&prepared.scene, &observe, 0);
    let pe = |n: &[Vector3<f64>]| {
        brdf_rig::reconstruct::refine::pixel_normal_error_deg(
            prepared.scene.mesh.faces(),
            &px,
            n,
            mesh.vertex_normals(),
        )
        .expect("pixels")
        .0
    };
    let (pb, pa) = (pe(&before), pe(prepared.scene.mesh.vertex_normals()));
    eprintln!(
        "median normal error {b:.2} -> {a:.2} deg (pixels {pb:.2} -> {pa:.2}): {}",
        report.reason
    );
    assert!(report.accepted, "{}", report.reason);
    assert_eq!(report.settings.depth, settings.depth);
    assert!(prepared.timings.iter().any(|(s, _)| s == "refine normals"));
    (b, a, pb, pa)
}

#[test]
fn normal_refinement_recovers_turned_normals_from_the_rendered_images() {
    // The job's mesh has the true positions but its normals turned by 4-8 degrees; the free
    // normals (two tangent angles per vertex) must turn them back. Every vertex is turned at
    // random, independently of its neighbours, and at 160x120 Spot has about one pixel per
    // vertex and view: the images pin the normals the pixels get more than each vertex's own
    // (docs/normal-refinement.md). A quarter of the pixels' error must go, and the vertices'
    // must fall.
    let mesh = spot();
    let settings = brdf_rig::reconstruct::refine::RefineSettings {
        depth: false,
        ..Default::default()
    };
    let (b, a, pb, pa) = refine_spot(&mesh, turned_normals(&mesh, 8.0, 11), &settings);
    assert!(
        pa < 0.75 * pb,
        "median pixel normal error {pb:.2} -> {pa:.2} deg"
    );
    assert!(a < 0.9 * b, "median normal error {b:.2} -> {a:.2} deg");
}

#[test]
fn normal_refinement_undoes_a_photogrammetry_meshs_depth_noise() {
    // The job's mesh is Spot smoothed and its vertices displaced along their normals
    // (`geometry::sfm_like`, as the accuracy grid's), normals from those positions; the
    // default refinement (one displacement per vertex, the normals following) must take more
    // than a third of the vertices' and the pixels' error away at this small size (about one
    // pixel per vertex and view; the grid at 320x240 is where the half is measured,
    // docs/normal-refinement.md), and beat the free normals on the same images by 5 %.
    let mesh = spot();
    let sfm = brdf_rig::geometry::sfm_like::sfm_like(
        &mesh,
        &brdf_rig::geometry::sfm_like::SfmLikeParams {
            seed: 7,
            ..Default::default()
        },
    );
    let depth = brdf_rig::reconstruct::refine::RefineSettings::default();
    assert!(depth.depth, "displacements are the default unknowns");
    let free = brdf_rig::reconstruct::refine::RefineSettings {
        depth: false,
        ..Default::default()
    };
    let (b, a, pb, pa) = refine_spot(&sfm, sfm.vertex_normals().to_vec(), &depth);
    let (_, a_free, _, pa_free) = refine_spot(&sfm, sfm.vertex_normals().to_vec(), &free);
    assert!(a < 0.65 * b, "median normal error {b:.2} -> {a:.2} deg");
    assert!(
        pa < 0.65 * pb,
        "median pixel normal error {pb:.2} -> {pa:.2} deg"
    );
    assert!(
        a < 0.95 * a_free && pa < 0.95 * pa_free,
        "displacements {a:.2} (pixels {pa:.2}) against free normals {a_free:.2} ({pa_free:.2})"
    );
}

/// The refinement is the default since session 48; `--no-refine-normals` turns it off, and of
/// the two flags the last given wins.
#[test]
fn cli_refines_the_normals_by_default_and_no_refine_normals_turns_it_off() {
    let dir = tempfile::tempdir().unwrap();
    let job = write_small_job(dir.path());
    let ran = |name: &str, extra: &[&str]| {
        let out = dir.path().join(name);
        let mut args = QUICK_ARGS.to_vec();
        args.extend_from_slice(extra);
        let o = run_cli(&job.source, &out, &args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        report_file::read(&out).unwrap().normals.is_some()
    };
    assert!(ran("default", &[]));
    assert!(!ran("off", &["--no-refine-normals"]));
    assert!(ran("on-last", &["--no-refine-normals", "--refine-normals"]));
    assert!(!ran(
        "off-last",
        &["--refine-normals", "--no-refine-normals"]
    ));
}

/// By default the refinement is skipped, said in a warning, when the light images hold more
/// pixels than `refine_max_pixels` (it holds every image); without a limit it runs.
#[test]
fn the_refinement_is_skipped_with_a_warning_above_its_pixel_limit() {
    let dir = tempfile::tempdir().unwrap();
    let job = write_small_job(dir.path());
    let mut settings = brdf_rig::reconstruct::Settings {
        refine: Some(brdf_rig::reconstruct::refine::RefineSettings::default()),
        refine_max_pixels: Some(1),
        ..Default::default()
    };
    let p = brdf_rig::reconstruct::prepare::prepare(&job, &settings, &mut |_| {}).unwrap();
    assert!(p.refinement.is_none());
    assert!(
        p.scene
            .warnings
            .iter()
            .any(|w| w.contains("normals not refined") && w.contains("--refine-normals")),
        "{:?}",
        p.scene.warnings
    );
    assert!(
        p.scene.views.iter().all(|v| v.image.is_none()),
        "streamed, not held"
    );
    settings.refine_max_pixels = None;
    let p = brdf_rig::reconstruct::prepare::prepare(&job, &settings, &mut |_| {}).unwrap();
    assert!(p.refinement.is_some());
    assert!(
        !p.scene
            .warnings
            .iter()
            .any(|w| w.contains("normals not refined"))
    );
    // the default limit is far above a small job's pixels
    settings.refine_max_pixels = brdf_rig::reconstruct::Settings::default().refine_max_pixels;
    let p = brdf_rig::reconstruct::prepare::prepare(&job, &settings, &mut |_| {}).unwrap();
    assert!(p.refinement.is_some());
}

#[test]
fn cli_refine_normals_reports_what_it_did() {
    // Two light images cannot hold one out: the refinement is refused, said so, and no
    // refined mesh is written.
    let dir = tempfile::tempdir().unwrap();
    let job = write_small_job(dir.path());
    let out = dir.path().join("out");
    let mut args = QUICK_ARGS.to_vec();
    args.push("--refine-normals");
    let o = run_cli(&job.source, &out, &args);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("normals: kept"), "{err}");
    let normals = report_file::read(&out).unwrap().normals.unwrap();
    assert!(!normals.accepted);
    assert!(normals.reason.contains("at least 3"), "{}", normals.reason);
    assert!(
        normals.settings.depth,
        "displacements are the default unknowns"
    );
    assert!(
        !normals.settings.foreign_colours,
        "the colour rule in the refinement is a study knob, off by default"
    );
    assert!(!out.join("mesh_refined.ply").exists());
    // The HTML report says what the refinement did.
    let html = util::html_report(&out);
    assert!(html.contains("Normals refined from the images"));
    assert!(html.contains("<b>kept</b>") && html.contains("at least 3"));
    // Out of range: refused before any work, naming the option.
    let o = run_cli(&job.source, &out, &["--refine-normals", "--max-tilt", "90"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--max-tilt"));
    // The free normals on request, said in report.json; an unknown choice is refused.
    let free = dir.path().join("free");
    let mut args = QUICK_ARGS.to_vec();
    args.extend([
        "--refine-normals",
        "--refine-unknowns",
        "normals",
        "--refine-colour-rule",
        "--peak-energy-bands",
        "4",
    ]);
    let o = run_cli(&job.source, &free, &args);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report = report_file::read(&free).unwrap();
    // the study knob of the peak's factor per theta_d band reaches the core, off by default
    assert_eq!(report.settings.core.peak_energy_bands, 4);
    assert_eq!(
        brdf_rig::reconstruct::core::CoreSettings::default().peak_energy_bands,
        0
    );
    let normals = report.normals.unwrap();
    assert!(!normals.settings.depth);
    assert!(normals.settings.foreign_colours);
    let o = run_cli(&job.source, &free, &["--peak-energy-bands", "9"]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--peak-energy-bands"));
    let o = run_cli(
        &job.source,
        &free,
        &["--refine-normals", "--refine-unknowns", "vertices"],
    );
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--refine-unknowns"));
}
