//! Material label masks in `job.toml` (`labels = "..."`, issue #17) through the real binary:
//! drawn from the simulation's truth on a few of the images of a two-material Spot, they fix
//! the materials where they label the object, with `--materials auto` and with the default
//! `one`; a label that contradicts the colours is obeyed; a mask of zeros changes nothing;
//! a bad label mask stops the job with an error naming the job file, the field and the file.

use crate::materials::{MATERIALS, map_face_labels, two_material_scene};
use crate::reconstruct::{QUICK_ARGS, run_cli, write_small_job};
use brdf_rig::geometry::bvh::Bvh;
use brdf_rig::geometry::labels::{FaceLabels, area_agreement, face_area, split_by_planes};
use brdf_rig::geometry::mesh::Mesh;
use brdf_rig::geometry::raster::Rasteriser;
use brdf_rig::reconstruct::Job;
use brdf_rig::reconstruct::materials::{self, MaterialsFile};
use brdf_rig::sim::job_scene::{SceneSpec, view_geometry};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};

/// The light images that get a label mask: a few of the eight.
const LABELLED_VIEWS: [usize; 3] = [0, 3, 6];

/// Per pixel of view `i`, the truth mesh's face it sees (the rasterised face ids).
fn face_ids(mesh: &Mesh, spec: &SceneSpec, i: usize) -> Vec<Option<u32>> {
    let bvh = Bvh::build(mesh);
    let (k, pose, _) = view_geometry(mesh, spec, i);
    let gbuf = Rasteriser::new(mesh, &bvh, &k, &pose, None).gbuffer();
    (0..k.height)
        .flat_map(|y| (0..k.width).map(move |x| (x, y)))
        .map(|(x, y)| gbuf.get(x, y).map(|f| f.face))
        .collect()
}

/// Writes a label mask per view of `views` (8-bit grey PNG, `label_of` each pixel's truth face,
/// 0 off the object) and a job `name` beside `job` naming them.
fn with_label_masks(
    job: &Job,
    mesh: &Mesh,
    spec: &SceneSpec,
    views: &[usize],
    name: &str,
    label_of: impl Fn(u32) -> u8,
) -> PathBuf {
    let dir = job.source.parent().unwrap();
    std::fs::create_dir_all(dir.join("masks")).unwrap();
    let mut job = job.clone();
    for &i in views {
        let values: Vec<u8> = face_ids(mesh, spec, i)
            .iter()
            .map(|f| f.map_or(0, &label_of))
            .collect();
        let file = dir.join(format!("masks/{name}_{i:02}.png"));
        image::GrayImage::from_raw(spec.width as u32, spec.height as u32, values)
            .unwrap()
            .save(&file)
            .unwrap();
        job.light_images[i].labels = Some(file);
    }
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, job.to_toml(dir).unwrap()).unwrap();
    path
}

/// The materials found and the face labels of the map (`material_map.ply`).
fn found(out: &Path, mesh: &Mesh) -> (MaterialsFile, FaceLabels) {
    let file = materials::read(out).unwrap().expect("materials.json");
    let faces = map_face_labels(&out.join(&file.material_map), mesh);
    (file, faces)
}

/// Share of the area of the faces `which` whose found material is the one the masks label
/// `mask_label` (no renaming: the masks name the materials).
fn share_labelled(
    mesh: &Mesh,
    file: &MaterialsFile,
    faces: &FaceLabels,
    which: impl Fn(usize) -> bool,
    mask_label: u32,
) -> f64 {
    let m = file
        .materials
        .iter()
        .position(|e| e.mask_label == Some(mask_label))
        .unwrap_or_else(|| panic!("no material with mask label {mask_label}"));
    let (mut hit, mut all) = (0.0, 0.0);
    for f in (0..mesh.faces().len()).filter(|&f| which(f)) {
        let a = face_area(mesh, f);
        all += a;
        if faces.labels[f] as usize == m {
            hit += a;
        }
    }
    hit / all
}

fn run_ok(job: &Path, out: &Path, extra: &[&str]) -> String {
    let run = run_cli(job, out, extra);
    let err = String::from_utf8_lossy(&run.stderr).into_owned();
    assert!(run.status.success(), "{err}");
    err
}

/// The quick settings of `tests/materials.rs` (a coarse basis without either material).
fn quick(materials_arg: Option<&str>) -> Vec<String> {
    // QUICK_ARGS's basis and trials, without either material of these objects in the basis.
    let mut a: Vec<String> = vec!["--exclude".to_string(), MATERIALS.join(",")];
    a.extend(QUICK_ARGS[2..].iter().map(|s| s.to_string()));
    if let Some(m) = materials_arg {
        a.extend(["--materials".to_string(), m.to_string()]);
    }
    a
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

#[test]
fn truth_label_masks_on_three_images_give_the_two_materials_at_least_as_well_as_automatic() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, truth, spec, job) = two_material_scene(&dir.path().join("scene"));
    let auto = quick(Some("auto"));
    let out_auto = dir.path().join("out-auto");
    run_ok(&job.source, &out_auto, &strs(&auto));
    let (file, faces) = found(&out_auto, &mesh);
    assert_eq!(file.count, 2, "{}", file.reason);
    assert!(file.mask_labels.is_empty() && file.materials.iter().all(|m| m.mask_label.is_none()));
    let agreement_auto = area_agreement(&mesh, &truth, &faces, None);

    // truth label 0 is drawn as 1, label 1 as 2, on three of the eight images
    let labelled = with_label_masks(&job, &mesh, &spec, &LABELLED_VIEWS, "labels", |f| {
        truth.labels[f as usize] as u8 + 1
    });
    for (arg, name) in [(Some("auto"), "auto"), (None, "default one")] {
        let out = dir
            .path()
            .join(format!("out-labels-{}", name.replace(' ', "-")));
        let err = run_ok(&labelled, &out, &strs(&quick(arg)));
        let (file, faces) = found(&out, &mesh);
        assert_eq!(file.count, 2, "{name}: {}", file.reason);
        assert_eq!(file.mask_labels, vec![1, 2], "{name}");
        assert!(
            file.reason.contains("label masks"),
            "{name}: {}",
            file.reason
        );
        for m in &file.materials {
            assert!(
                m.mask_label.is_some() && m.mask_vertices > 0,
                "{name}: {m:?}"
            );
        }
        assert!(err.contains("(mask label 1)"), "{name}: {err}");
        let agreement = area_agreement(&mesh, &truth, &faces, None);
        eprintln!("{name}: agreement {agreement:.4} against automatic {agreement_auto:.4}");
        assert!(
            agreement >= agreement_auto,
            "{name}: agreement {agreement} against automatic {agreement_auto}"
        );
        // the masks name the materials: no renaming needed
        let named = share_labelled(&mesh, &file, &faces, |f| truth.labels[f] == 0, 1);
        assert!(named > 0.9, "{name}: truth 0 under mask label 1: {named}");
        let report = brdf_rig::reconstruct::report_file::read(&out).unwrap();
        assert_eq!(report.materials.map(|m| m.mask_labels), Some(vec![1, 2]));
        // the HTML report says which material each label mask gave
        let html = crate::util::html_report(&out);
        for m in &file.materials {
            let l = m.mask_label.unwrap();
            assert!(
                html.contains(&format!("the job&#39;s label masks (label {l};"))
                    || html.contains(&format!("the job's label masks (label {l};")),
                "{name}: the report does not name mask label {l}"
            );
        }
    }
}

#[test]
fn a_label_mask_that_contradicts_the_colours_is_obeyed_where_it_labels() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, truth, spec, job) = two_material_scene(&dir.path().join("scene"));
    // The lowest quarter of Spot is green-latex (truth 0) but labelled 2, with pink-fabric.
    let quarter = split_by_planes(&mesh, Vector3::y(), 4);
    let region = |f: usize| quarter.labels[f] == 0;
    assert!((0..mesh.faces().len()).any(region));
    assert!(
        (0..mesh.faces().len())
            .filter(|&f| region(f))
            .all(|f| truth.labels[f] == 0)
    );
    let contradicting = with_label_masks(&job, &mesh, &spec, &LABELLED_VIEWS, "contra", |f| {
        if truth.labels[f as usize] == 1 || region(f as usize) {
            2
        } else {
            1
        }
    });
    // the region as the labelled images see it
    let mut seen = vec![false; mesh.faces().len()];
    for &i in &LABELLED_VIEWS {
        for f in face_ids(&mesh, &spec, i).into_iter().flatten() {
            seen[f as usize] = true;
        }
    }
    let labelled_region = |f: usize| region(f) && seen[f];
    let truthful = with_label_masks(&job, &mesh, &spec, &LABELLED_VIEWS, "truth", |f| {
        truth.labels[f as usize] as u8 + 1
    });
    let out = dir.path().join("out-truth");
    run_ok(&truthful, &out, &strs(&quick(None)));
    let (file, faces) = found(&out, &mesh);
    let by_colour = share_labelled(&mesh, &file, &faces, labelled_region, 2);
    for (arg, name) in [(None, "default one"), (Some("auto"), "auto")] {
        let out = dir
            .path()
            .join(format!("out-contra-{}", name.replace(' ', "-")));
        run_ok(&contradicting, &out, &strs(&quick(arg)));
        let (file, faces) = found(&out, &mesh);
        if arg.is_none() {
            assert_eq!(file.count, 2, "{name}: {}", file.reason);
        }
        let obeyed = share_labelled(&mesh, &file, &faces, labelled_region, 2);
        eprintln!(
            "{name}: {} materials; the region under mask label 2: {obeyed:.3} (labelled by the truth: {by_colour:.3})",
            file.count
        );
        assert!(obeyed > 0.9, "{name}: {obeyed}");
        assert!(
            by_colour < 0.1,
            "with truthful labels the region is material 1: {by_colour}"
        );
        // the rest of green-latex stays material 1
        let rest = share_labelled(
            &mesh,
            &file,
            &faces,
            |f| truth.labels[f] == 0 && !region(f),
            1,
        );
        assert!(rest > 0.8, "{name}: {rest}");
    }
}

/// A label mask of zeros gives no label: the result is the one without it, byte for byte, and
/// the pixel mask (`mask`, soft values included) removes pixels as before.
#[test]
fn a_label_mask_of_zeros_changes_nothing_and_pixel_masks_still_remove_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let job = write_small_job(dir.path());
    let (w, h) = (64u32, 48u32);
    std::fs::create_dir_all(dir.path().join("masks")).unwrap();
    // a soft pixel mask: the left half removed, the rest 128 or 255
    let soft = image::GrayImage::from_fn(w, h, |x, y| {
        image::Luma([if x < w / 2 {
            0
        } else if (x + y) % 2 == 0 {
            128
        } else {
            255
        }])
    });
    soft.save(dir.path().join("masks/soft.png")).unwrap();
    image::GrayImage::new(w, h)
        .save(dir.path().join("masks/zeros.png"))
        .unwrap();
    let mut masked = job.clone();
    masked.light_images[0].mask = Some(dir.path().join("masks/soft.png"));
    let masked_job = dir.path().join("masked.toml");
    std::fs::write(&masked_job, masked.to_toml(dir.path()).unwrap()).unwrap();
    let mut zeros = masked.clone();
    zeros.light_images[0].labels = Some(dir.path().join("masks/zeros.png"));
    zeros.light_images[1].labels = Some(dir.path().join("masks/zeros.png"));
    let zeros_job = dir.path().join("zeros.toml");
    std::fs::write(&zeros_job, zeros.to_toml(dir.path()).unwrap()).unwrap();

    let out_plain = dir.path().join("out-plain");
    run_ok(&job.source, &out_plain, &QUICK_ARGS);
    let out_masked = dir.path().join("out-masked");
    run_ok(&masked_job, &out_masked, &QUICK_ARGS);
    let out_zeros = dir.path().join("out-zeros");
    let err = run_ok(&zeros_job, &out_zeros, &QUICK_ARGS);
    assert!(err.contains("label no observed pixel"), "{err}");
    let read = |d: &Path| std::fs::read(d.join("brdf.binary")).unwrap();
    assert_eq!(read(&out_masked), read(&out_zeros));
    let masked_report = brdf_rig::reconstruct::report_file::read(&out_masked).unwrap();
    let zeros_report = brdf_rig::reconstruct::report_file::read(&out_zeros).unwrap();
    assert!(zeros_report.materials.is_none());
    assert!(masked_report.images[0].dropped.masked_out > 0);
    assert_eq!(masked_report.images[0], zeros_report.images[0]);
    let plain = brdf_rig::reconstruct::report_file::read(&out_plain).unwrap();
    assert_eq!(plain.images[0].dropped.masked_out, 0);
    assert_eq!(plain.images[0].covered, masked_report.images[0].covered);
    assert!(plain.images[0].observed > masked_report.images[0].observed);
}

#[test]
fn bad_label_masks_stop_the_job_naming_the_job_the_field_and_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let job = write_small_job(dir.path());
    let out = dir.path().join("out");
    std::fs::create_dir_all(dir.path().join("masks")).unwrap();
    let small = dir.path().join("masks/small.png");
    image::GrayImage::new(10, 10).save(&small).unwrap();
    let colour = dir.path().join("masks/colour.png");
    image::RgbImage::from_fn(64, 48, |x, _| image::Rgb([1, 1 + u8::from(x == 5), 1]))
        .save(&colour)
        .unwrap();
    let jpeg = dir.path().join("masks/labels.jpg");
    image::GrayImage::new(64, 48).save(&jpeg).unwrap();
    let missing = dir.path().join("masks/missing.png");
    let cases: [(&Path, &[&str]); 4] = [
        (&missing, &["missing.png"]),
        (&small, &["10x10", "64x48"]),
        (&colour, &["(5, 0)", "not grey"]),
        (&jpeg, &["JPEG"]),
    ];
    for (file, needles) in cases {
        let mut bad = job.clone();
        bad.light_images[1].labels = Some(file.to_path_buf());
        std::fs::write(&job.source, bad.to_toml(dir.path()).unwrap()).unwrap();
        let o = run_cli(&job.source, &out, &[]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{}: {err}", file.display());
        for n in [
            "job.toml",
            "light_image[1].labels",
            &file.display().to_string(),
        ]
        .iter()
        .chain(needles)
        {
            assert!(err.contains(n), "{n:?} not in {err}");
        }
        assert!(!err.contains("panicked"), "{err}");
    }
    // a label that is not a path: the job file's own check
    let text = std::fs::read_to_string(&job.source).unwrap();
    std::fs::write(&job.source, text.replacen("labels = ", "labels = 3 #", 1)).unwrap();
    let o = run_cli(&job.source, &out, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("light_image[1].labels") && err.contains("job.toml"),
        "{err}"
    );
}
