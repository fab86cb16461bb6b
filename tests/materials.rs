//! Simulated multi-material scenes: Spot split by a plane into two materials (neural MERL fits,
//! smooth approximations of MERL materials by Sztrajman et al. 2021, not measured data), written
//! as a job folder with the truth per face beside it; the images really show each face's
//! material, and the truth file reads back to the labels the scene was rendered with.

use crate::util;
use brdf_rig::brdf::Brdf;
use brdf_rig::brdf::nbrdf::Nbrdf;
use brdf_rig::geometry::bvh::Bvh;
use brdf_rig::geometry::labels::{FaceLabels, area_agreement, split_by_planes};
use brdf_rig::geometry::mesh::Mesh;
use brdf_rig::geometry::mesh_io::load_mesh;
use brdf_rig::geometry::raster::Rasteriser;
use brdf_rig::geometry::sfm_like::{SfmLikeParams, sfm_like};
use brdf_rig::imageio::read_exr;
use brdf_rig::render::light::DirectionalLight;
use brdf_rig::render::shade::{ShadeOptions, render_mesh, render_mesh_materials};
use brdf_rig::sim::job_scene::{
    SceneSpec, TRUTH_LABELS_FILE, read_truth_labels, view_geometry, write_scene,
    write_scene_materials,
};
use nalgebra::Vector3;

pub const MATERIALS: [&str; 2] = ["green-latex", "pink-fabric"];

pub fn spot() -> Mesh {
    load_mesh(&util::shared_data().join("meshes/spot_triangulated.obj"))
        .unwrap()
        .0
}

pub fn material(name: &str) -> Nbrdf {
    Nbrdf::load(
        &util::shared_data()
            .join("merl-nbrdf")
            .join(format!("{name}.f32")),
    )
    .unwrap()
}

/// Red and green chromaticity `(r, g) / (r + g + b)`.
fn chromaticity(rgb: [f64; 3]) -> [f64; 2] {
    let s = rgb[0] + rgb[1] + rgb[2];
    [rgb[0] / s, rgb[1] / s]
}

fn distance(a: [f64; 2], b: [f64; 2]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
}

#[test]
fn two_material_spot_shows_each_faces_material_and_writes_its_truth() {
    let mesh = spot();
    let job_mesh = sfm_like(&mesh, &SfmLikeParams::default());
    assert_eq!(
        job_mesh.faces(),
        mesh.faces(),
        "sfm_like keeps the faces, so the truth labels are the job mesh's too"
    );
    let mats: Vec<Nbrdf> = MATERIALS.iter().map(|n| material(n)).collect();
    let brdfs: Vec<&dyn Brdf> = mats.iter().map(|m| m as &dyn Brdf).collect();
    let names: Vec<String> = MATERIALS.iter().map(|n| n.to_string()).collect();
    // Spot's length runs along z: front half one material, back half the other
    let labels = split_by_planes(&mesh, Vector3::z(), 2);
    let per_label = |l: u32| labels.labels.iter().filter(|&&x| x == l).count();
    assert!(per_label(0) > mesh.faces().len() / 5 && per_label(1) > mesh.faces().len() / 5);

    let spec = SceneSpec {
        views: 5,
        width: 64,
        height: 48,
        ..SceneSpec::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let job = write_scene_materials(dir.path(), &mesh, &job_mesh, &brdfs, &labels, &names, &spec)
        .unwrap();
    assert_eq!(job.light_images.len(), 5);

    let truth = read_truth_labels(&dir.path().join(TRUTH_LABELS_FILE)).unwrap();
    assert_eq!(truth.labels, labels);
    assert_eq!(truth.names, names);
    assert!((area_agreement(&mesh, &truth.labels, &labels, None) - 1.0).abs() < 1e-12);

    // Mean colour of the lit pixels of each truth label, over the views.
    let bvh = Bvh::build(&mesh);
    let mut sum = [[0.0f64; 3]; 2];
    let mut pixels = [0usize; 2];
    for (i, light_image) in job.light_images.iter().enumerate() {
        let img = read_exr(&light_image.file).unwrap();
        let (k, pose, _) = view_geometry(&mesh, &spec, i);
        let gbuf = Rasteriser::new(&mesh, &bvh, &k, &pose, None).gbuffer();
        for y in 0..k.height {
            for x in 0..k.width {
                let Some(f) = gbuf.get(x, y) else { continue };
                let rgb = img.get(x, y).map(f64::from);
                if rgb.iter().sum::<f64>() <= 1e-4 {
                    continue; // shadowed or facing away: no colour to see
                }
                let l = truth.labels.labels[f.face as usize] as usize;
                pixels[l] += 1;
                for c in 0..3 {
                    sum[l][c] += rgb[c];
                }
            }
        }
    }
    assert!(pixels[0] > 200 && pixels[1] > 200, "lit pixels {pixels:?}");
    let seen = [chromaticity(sum[0]), chromaticity(sum[1])];
    // Each material's own colour: near-retro reflection, theta_h 0.3 rad, theta_d 0.4 rad.
    let own = [
        chromaticity(mats[0].eval_angles(0.3, 0.4, std::f64::consts::FRAC_PI_2)),
        chromaticity(mats[1].eval_angles(0.3, 0.4, std::f64::consts::FRAC_PI_2)),
    ];
    assert!(
        distance(own[0], own[1]) > 0.05,
        "the materials differ in colour: {own:?}"
    );
    for l in 0..2 {
        assert!(
            distance(seen[l], own[l]) < distance(seen[l], own[1 - l]),
            "label {l} ({}) looks like {:?}, own colour {:?}, the other's {:?}",
            MATERIALS[l],
            seen[l],
            own[l],
            own[1 - l]
        );
    }
    assert!(seen[0][1] > seen[1][1], "green-latex is greener: {seen:?}");
    assert!(seen[1][0] > seen[0][0], "pink-fabric is redder: {seen:?}");
}

#[test]
fn one_material_is_the_single_material_scene() {
    let mesh = spot();
    let mat = material(MATERIALS[0]);
    let spec = SceneSpec {
        views: 2,
        width: 32,
        height: 24,
        ..SceneSpec::default()
    };
    // the same BRDF on both halves renders exactly render_mesh's image
    let bvh = Bvh::build(&mesh);
    let (k, pose, l_cam) = view_geometry(&mesh, &spec, 0);
    let light = DirectionalLight::new(pose.dir_to_world(&l_cam), spec.irradiance).unwrap();
    let opts = ShadeOptions::single_light(light);
    let one = render_mesh(&mesh, &bvh, &k, &pose, &mat, &opts);
    let split = split_by_planes(&mesh, Vector3::x(), 2);
    let twice = render_mesh_materials(&mesh, &bvh, &k, &pose, &[&mat, &mat], &split, &opts);
    assert_eq!(one.data(), twice.data());

    // one material: no truth file, the same folder as write_scene's
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    write_scene(a.path(), &mesh, &mesh, &mat, &spec).unwrap();
    let uniform = FaceLabels::uniform(mesh.faces().len());
    write_scene_materials(b.path(), &mesh, &mesh, &[&mat], &uniform, &[], &spec).unwrap();
    assert!(!b.path().join(TRUTH_LABELS_FILE).exists());
    for file in ["light/view_00.exr", "light/view_01.exr", "mesh.ply"] {
        assert_eq!(
            std::fs::read(a.path().join(file)).unwrap(),
            std::fs::read(b.path().join(file)).unwrap(),
            "{file}"
        );
    }

    // refused before anything is written: a label without a BRDF, names that do not fit
    let c = tempfile::tempdir().unwrap();
    let e = write_scene_materials(c.path(), &mesh, &mesh, &[&mat], &split, &[], &spec)
        .unwrap_err()
        .to_string();
    assert!(e.contains("material 1") && e.contains("1 BRDFs"), "{e}");
    let e = write_scene_materials(
        c.path(),
        &mesh,
        &mesh,
        &[&mat, &mat],
        &split,
        &["only one".to_string()],
        &spec,
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("1 material names for 2"), "{e}");
    assert!(!c.path().join("light").exists());
}

/// The face labels of a `material_map.ply`, read by a peer's PLY reader (ply-rs): each face
/// takes the majority label of its corners.
pub fn map_face_labels(path: &std::path::Path, mesh: &Mesh) -> FaceLabels {
    let mut f = std::io::BufReader::new(std::fs::File::open(path).unwrap());
    let ply = ply_rs::parser::Parser::<ply_rs::ply::DefaultElement>::new()
        .read_ply(&mut f)
        .unwrap();
    let vertex_labels: Vec<u32> = ply.payload["vertex"]
        .iter()
        .map(|v| match v["label"] {
            ply_rs::ply::Property::UChar(l) => u32::from(l),
            ref other => panic!("label {other:?}"),
        })
        .collect();
    FaceLabels::from_vertex_labels(mesh, &vertex_labels)
}

/// The scene of the reconstruction below (and of `tests/label_masks.rs`): Spot cut along its height into
/// green-latex (label 0, below) and pink-fabric, 8 views at 96x72, the SfM-like mesh.
pub fn two_material_scene(
    dir: &std::path::Path,
) -> (Mesh, FaceLabels, SceneSpec, brdf_rig::reconstruct::Job) {
    two_material_scene_sized(dir, 96, 72)
}

/// [`two_material_scene`] with light images of `width` x `height`.
pub fn two_material_scene_sized(
    dir: &std::path::Path,
    width: usize,
    height: usize,
) -> (Mesh, FaceLabels, SceneSpec, brdf_rig::reconstruct::Job) {
    let mesh = spot();
    let job_mesh = sfm_like(&mesh, &SfmLikeParams::default());
    let mats: Vec<Nbrdf> = MATERIALS.iter().map(|n| material(n)).collect();
    let brdfs: Vec<&dyn Brdf> = mats.iter().map(|m| m as &dyn Brdf).collect();
    let names: Vec<String> = MATERIALS.iter().map(|n| n.to_string()).collect();
    let labels = split_by_planes(&mesh, Vector3::y(), 2);
    let spec = SceneSpec {
        views: 8,
        width,
        height,
        ..SceneSpec::default()
    };
    let job = write_scene_materials(dir, &mesh, &job_mesh, &brdfs, &labels, &names, &spec).unwrap();
    (mesh, labels, spec, job)
}

/// The normal refinement on the two-material Spot: the materials are found first (as
/// `reconstruct --materials auto --refine-normals` does) and each gets its own reflectance
/// table; the normals come closer to the truth than with one
/// table for both, which leaves each material's difference from their mean for the normals to
/// absorb and which the held-out images accept. Without `--materials auto` the pipeline finds
/// them for the refinement too, and warns.
#[test]
fn normal_refinement_fits_a_reflectance_table_to_each_material() {
    use brdf_rig::reconstruct::prepare::{
        Prepared, Settings, load_scene, observe_scene_and_pixels, refine_prepared,
    };
    use brdf_rig::reconstruct::refine::{RefineSettings, normal_error_deg};
    let dir = tempfile::tempdir().unwrap();
    let (mesh, _, _, job) = two_material_scene_sized(dir.path(), 160, 120);
    let settings = Settings::default();
    let refine = RefineSettings::default();
    // one table, as before session 29: the refinement given no materials
    let scene = load_scene(&job, &settings).unwrap();
    let before = scene.mesh.vertex_normals().to_vec();
    let (observed, pixels) =
        observe_scene_and_pixels(&scene, &settings.observe, refine.edge_margin_px);
    let mut prepared = Prepared {
        scene,
        observed,
        refinement: None,
        timings: Vec::new(),
    };
    let seen = refine_prepared(
        &mut prepared,
        Some(pixels),
        &settings.observe,
        &refine,
        &Default::default(),
        &mut |_| {},
    );
    let e = |n: &[Vector3<f64>]| normal_error_deg(n, mesh.vertex_normals(), &seen).unwrap().0;
    let one = prepared.refinement.clone().unwrap();
    let (one_before, one_after) = (e(&before), e(prepared.scene.mesh.vertex_normals()));
    // as the pipeline runs it with --materials auto: the materials found first
    let scene = load_scene(&job, &settings).unwrap();
    let materials = Some(brdf_rig::reconstruct::segment::SegmentSettings::default());
    let two = brdf_rig::eval::refine_case(scene, &settings.observe, &refine, materials, &mesh)
        .study
        .expect("the mesh has the truth's vertices");
    eprintln!(
        "median vertex-normal error {one_before:.2} -> {one_after:.2} deg (one table: {}), {:.2} -> {:.2} (a table per material: {})",
        one.reason, two.median_before_deg, two.median_after_deg, two.report.reason
    );
    assert_eq!((one.materials, two.report.materials), (1, 2));
    assert!(two.report.accepted);
    assert!(two.median_after_deg < 0.8 * two.median_before_deg);
    assert!(two.median_after_deg < 0.9 * one_after);
    // without --materials auto the pipeline finds them for the refinement all the same (the
    // result stays one BRDF), and says so
    let asked_one = Settings {
        refine: Some(refine.clone()),
        ..Settings::default()
    };
    let p = brdf_rig::reconstruct::prepare::prepare(&job, &asked_one, &mut |_| {}).unwrap();
    let r = p.refinement.expect("the refinement ran");
    assert_eq!(r.materials, 2, "{}", r.reason);
    // by default every pixel enters; with the colour rule (a study knob) the pixels near the
    // found labels' boundary (off the true one by a ring or so) of the other material's colour
    // are left out, a few of them
    assert_eq!(r.foreign_colour_pixels, 0);
    let colour_rule = Settings {
        refine: Some(RefineSettings {
            foreign_colours: true,
            ..refine.clone()
        }),
        ..Settings::default()
    };
    let p_rule = brdf_rig::reconstruct::prepare::prepare(&job, &colour_rule, &mut |_| {}).unwrap();
    let r_rule = p_rule.refinement.expect("the refinement ran");
    assert!(
        r_rule.foreign_colour_pixels > 0 && r_rule.foreign_colour_pixels * 20 < r.pixels_offered,
        "{} of {}",
        r_rule.foreign_colour_pixels,
        r.pixels_offered
    );
    assert_eq!(
        r.pixels_offered,
        r_rule.pixels_offered + r_rule.foreign_colour_pixels
    );
    assert!(
        p.scene
            .warnings
            .iter()
            .any(|w| w.contains("2 materials") && w.contains("--materials auto")),
        "{:?}",
        p.scene.warnings
    );
}

/// `brdf-rig reconstruct --materials auto` on a two-material Spot (SfM-like mesh, small images,
/// a coarse basis without either material): two materials found where they are, a MERL table
/// each, `materials.json` and the labelled `material_map.ply`; the same object made of one
/// material gives one and writes no per-material files.
#[test]
fn reconstruct_finds_two_materials_and_writes_one_table_each() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, labels, spec, job) = two_material_scene(&dir.path().join("two"));
    // one --exclude with both names, comma-separated
    // QUICK_ARGS's basis and trials, without either material in the basis.
    let exclude = MATERIALS.join(",");
    let mut quick = vec!["--exclude", exclude.as_str()];
    quick.extend(&crate::reconstruct::QUICK_ARGS[2..]);
    quick.extend(["--materials", "auto"]);
    let out = dir.path().join("out-two");
    let run = crate::reconstruct::run_cli(&job.source, &out, &quick);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let file = brdf_rig::reconstruct::materials::read(&out)
        .unwrap()
        .unwrap();
    assert_eq!(file.count, 2, "{}", file.reason);
    assert_eq!(file.materials.len(), 2);
    // the pixels on faces across the boundary (and those of the other's colour near it) are
    // counted, left out of both fits, and said
    let stderr = String::from_utf8_lossy(&run.stderr);
    for m in &file.materials {
        assert!(
            m.boundary_pixels > 0 && 2 * m.boundary_pixels < m.observed_pixels,
            "{}: {} of {} pixels on the boundary",
            m.name,
            m.boundary_pixels,
            m.observed_pixels
        );
        assert!(
            stderr.contains(&format!(
                "{} pixels ({} on faces across a boundary or of another material's colour near it, left out of its fit)",
                m.observed_pixels, m.boundary_pixels
            )),
            "{stderr}"
        );
    }
    for m in &file.materials {
        let table = brdf_rig::brdf::merl::MerlTable::read(&out.join(&m.file)).unwrap();
        assert!(table.get(0).is_some(), "{} reads back", m.file);
        // its own ladder, whose chosen rung is the model it reports, and its plausibility step
        let ladder = m.ladder.as_ref().expect("each material keeps its ladder");
        assert!(
            ladder.rungs.len() >= 3,
            "{}: {} rungs",
            m.name,
            ladder.rungs.len()
        );
        let chosen = &ladder.rungs[ladder.chosen];
        assert!(
            m.model.starts_with(&chosen.family.to_string()),
            "{}: model {} but the ladder chose {}",
            m.name,
            m.model,
            chosen.family
        );
        let p = m
            .plausibility
            .as_ref()
            .expect("each material keeps its plausibility");
        assert!(
            p.max_albedo_after <= 1.0 + 1e-9,
            "{}: albedo {}",
            m.name,
            p.max_albedo_after
        );
    }
    assert_ne!(
        file.materials[0].ladder, file.materials[1].ladder,
        "each material's ladder is its own"
    );
    // `brdf.binary` is the largest (first) material's table, byte for byte, and no temporary
    // file of its link is left beside it
    assert_eq!(
        std::fs::read(out.join("brdf.binary")).unwrap(),
        std::fs::read(out.join(&file.materials[0].file)).unwrap()
    );
    assert!(
        std::fs::read_dir(&out).unwrap().all(|e| !e
            .unwrap()
            .file_name()
            .to_string_lossy()
            .contains(".tmp-")),
        "a temporary file left in {}",
        out.display()
    );
    // the map's labels, per face by the majority of its corners, against the truth
    let found = map_face_labels(&out.join(&file.material_map), &mesh);
    let agreement = area_agreement(&mesh, &labels, &found, None);
    assert!(agreement > 0.85, "agreement {agreement}");
    let report = brdf_rig::reconstruct::report_file::read(&out).unwrap();
    assert_eq!(report.materials.as_ref().map(|m| m.count), Some(2));
    // the HTML report shows a section with both materials and their files
    let html = util::html_report(&out);
    assert!(html.contains("id=\"materials\""), "no materials section");
    for m in &file.materials {
        assert!(html.contains(&m.file), "{} not in the report", m.file);
    }
    // one section per material, each with its three sphere renders embedded
    let sections = material_sections(&html);
    assert_eq!(sections.len(), 2);
    for (i, (s, m)) in sections.iter().zip(&file.materials).enumerate() {
        assert!(s.contains(&format!("id=\"material-{}\"", i + 1)), "{s}");
        let reason = brdf_rig::report::html::escape(&m.model_reason);
        assert!(s.contains(&m.name) && s.contains(&reason), "{}", m.name);
        // its ladder as a table, one row per rung, the chosen one marked
        let ladder = m.ladder.as_ref().unwrap();
        let table = &s[s
            .find("<table class=\"ladder\">")
            .expect("its ladder table")..];
        let table = &table[..table.find("</table>").unwrap()];
        assert_eq!(
            table.matches("<tr").count(),
            ladder.rungs.len() + 1,
            "{table}"
        );
        assert_eq!(table.matches("class=\"chosen\"").count(), 1, "{table}");
        assert!(s.contains("Plausibility of its written table"), "{s}");
        assert!(
            s.contains(&format!(
                "{} pixels on faces across a boundary",
                m.boundary_pixels
            )),
            "{s}"
        );
        assert_eq!(
            s.matches("<img src=\"data:image/png;base64,").count(),
            3,
            "{s}"
        );
        assert!(!s.contains("not available"), "{s}");
    }
    // the panels have the material map, and the page says so
    assert!(html.contains("id=\"material-map-legend\""));
    assert!(html.contains("| material map"));
    check_material_maps(&out, &report, &file);

    // a material's table gone: its section says so, naming the file; the page is still made
    std::fs::remove_file(out.join(&file.materials[1].file)).unwrap();
    let html = util::html_report(&out);
    let sections = material_sections(&html);
    assert_eq!(sections[0].matches("<img").count(), 3);
    assert_eq!(sections[1].matches("<img").count(), 0);
    let hole = format!(
        "not available: {}",
        out.join(&file.materials[1].file).display()
    );
    assert!(sections[1].contains(&hole), "{}", sections[1]);

    // the same object in one material
    let one = dir.path().join("one");
    let job_mesh = sfm_like(&mesh, &SfmLikeParams::default());
    let job = write_scene(&one, &mesh, &job_mesh, &material(MATERIALS[0]), &spec).unwrap();
    let out = dir.path().join("out-one");
    let run = crate::reconstruct::run_cli(&job.source, &out, &quick);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let report = brdf_rig::reconstruct::report_file::read(&out).unwrap();
    let m = report.materials.as_ref().expect("the segmentation ran");
    assert_eq!(m.count, 1, "{}", m.reason);
    assert!(
        brdf_rig::reconstruct::materials::read(&out)
            .unwrap()
            .is_none()
    );
    assert!(!out.join("material_map.ply").exists());
    // one material: the three-image panels, no per-material errors
    for c in &report.comparisons {
        assert!(c.materials.is_empty());
        let panel = image::open(out.join(&c.file)).unwrap();
        assert_eq!(panel.width(), 3 * spec.width as u32, "{}", c.file);
    }
}

/// The `<section class="material">` elements of a report page, in order.
fn material_sections(html: &str) -> Vec<&str> {
    html.split("<section class=\"material\"")
        .skip(1)
        .map(|s| &s[..s.find("</section>").unwrap()])
        .collect()
}

/// Each panel of a two-material result is four images wide; its fourth, the material map,
/// shows both materials in their palette colours (`geometry::labels::label_colour`), each where
/// the photo has that material's colour: the mean chromaticity of the photo's pixels under a
/// map colour is nearer its own material's (materials.json) than the other's. The per-material
/// pixels in report.json add up to no more than the image's.
fn check_material_maps(
    out: &std::path::Path,
    report: &brdf_rig::reconstruct::report_file::Report,
    file: &brdf_rig::reconstruct::materials::MaterialsFile,
) {
    use brdf_rig::geometry::labels::label_colour;
    use brdf_rig::imageio::srgb_decode;
    let linear = |p: [u8; 3]| p.map(|c| f64::from(srgb_decode(f32::from(c) / 255.0)));
    let shares = |p: [f64; 3]| {
        let s = p[0] + p[1] + p[2];
        p.map(|c| c / s)
    };
    let dist = |a: [f64; 3], b: [f64; 3]| (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>();
    let palette: Vec<[f64; 3]> = (0..2).map(|l| shares(linear(label_colour(l)))).collect();
    let mut photo_sum = [[0.0f64; 3]; 2];
    let mut full = [0usize; 2];
    assert!(!report.comparisons.is_empty());
    for c in &report.comparisons {
        assert_eq!(c.materials.len(), 2, "{}", c.file);
        let labelled: usize = c.materials.iter().map(|m| m.observed_pixels).sum();
        assert!(
            labelled <= c.observed_pixels && (labelled > 0) == (c.observed_pixels > 0),
            "{}: {labelled} labelled of {} observed",
            c.file,
            c.observed_pixels
        );
        let panel = image::open(out.join(&c.file)).unwrap().to_rgb8();
        let w = panel.width() / 4;
        assert_eq!(panel.width(), 4 * w, "{}: four images", c.file);
        for y in 0..panel.height() {
            for x in 0..w {
                let m = panel.get_pixel(3 * w + x, y).0;
                if m.iter().all(|&v| v < 2) {
                    continue; // black: no shading to read a colour from
                }
                let hue = shares(linear(m));
                let Some(l) = (0..2).find(|&l| dist(hue, palette[l]) < 1e-3) else {
                    continue; // the grey of unobserved pixels
                };
                if m == label_colour(l as u32) {
                    full[l] += 1;
                }
                let p = linear(panel.get_pixel(x, y).0);
                for ch in 0..3 {
                    photo_sum[l][ch] += p[ch];
                }
            }
        }
    }
    assert!(
        full[0] > 0 && full[1] > 0,
        "palette colours at full shading: {full:?}"
    );
    for (l, &sum) in photo_sum.iter().enumerate() {
        let seen = shares(sum);
        let own = file.materials[l].chromaticity;
        let other = file.materials[1 - l].chromaticity;
        assert!(
            dist(seen, own) < dist(seen, other),
            "under the map's colour {l} the photo is {seen:?}: own {own:?}, other {other:?}"
        );
    }
}
