//! Calibration at a camera's resolution (issue #14): a sphere and a board large enough to go
//! through the downsampled searches (in the suite), and, run by hand, 24-megapixel images for a
//! timing of `calibrate sphere` and `calibrate white` (docs/calibration.md gives the commands;
//! speed goals live in benchmarks, not in tests) and a study of the sphere's accuracy:
//! `BRDF_RIG_CALIB24_DIR=/tmp/c24 cargo test --release --all-features --test tests -- --ignored
//! write_24_megapixel_calibration_images --nocapture`

use crate::calib_synth::{BoardScene, SphereScene, random_dir_around};
use brdf_rig::calib::light::{OutlineInput, SphereShot, calibrate_light};
use brdf_rig::calib::sphere::{OutlineSource, SphereOptions, SphereOutline, find_highlight};
use brdf_rig::calib::white::{BoardRegion, WhiteError, WhiteOptions, calibrate_irradiance};
use brdf_rig::geometry::camera::Intrinsics;
use brdf_rig::imageio::{ExrPrecision, write_exr};
use brdf_rig::render::image::LinearImage;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// The fixture's camera scaled to a `w`x`h` sensor (same field of view vertically, the
/// principal point moved with the wider frame).
fn sensor(k: &Intrinsics, w: usize, h: usize) -> Intrinsics {
    let s = h as f64 / k.height as f64;
    let mut big = k.scaled(s);
    big.width = w;
    big.height = h;
    big.cx += (w as f64 - k.width as f64 * s) / 2.0;
    big
}

fn sensor_24mp(k: &Intrinsics) -> Intrinsics {
    sensor(k, 6000, 4000)
}

/// A 1600x1200 sphere (radius 416 px) goes through the search on the image downsampled by 2,
/// the full-resolution profiles that follow its elliptical outline and the window around it
/// for the highlight: the light within 0.1 deg and within twice the uncertainty it reports,
/// nearly every profile kept.
#[test]
fn a_large_sphere_through_the_downsampled_search() {
    let mut rng = ChaCha8Rng::seed_from_u64(41);
    for i in 0..2 {
        let mut scene = SphereScene::new(Vector3::z());
        scene.light_dir = random_dir_around(&mut rng, &scene.view_axis(), 10.0, 70.0);
        scene.intr = sensor(&scene.intr, 1600, 1200);
        scene.supersample = 1;
        let light = scene.render_light(60 + i);
        let ambient = scene.render_ambient(70 + i);
        let cal = calibrate_light(
            &[SphereShot {
                light: &light,
                outline: OutlineInput::Image(&ambient),
            }],
            &scene.intr,
            &SphereOptions {
                saturation: Some(1.0),
                ..SphereOptions::default()
            },
        )
        .unwrap();
        let err = cal.dir_camera.angle(&scene.light_dir).to_degrees();
        let o = &cal.per_image[0].outline;
        println!(
            "1600x1200 sphere {i}: error {err:.4} deg, reported {:.4} deg, {} edge points, scatter {:.3} px",
            cal.uncertainty_deg,
            o.edge_points,
            o.rms_residual_rad * scene.intr.fx
        );
        assert!(
            err < 0.1 && err < 2.0 * cal.uncertainty_deg,
            "{err} {}",
            cal.uncertainty_deg
        );
        assert!(o.edge_points >= 1400, "{}", o.edge_points);
    }
}

/// A 2400x1800 board (about 800 000 board pixels, glints and dust) is found on the image
/// downsampled to 1200 px and read on a lattice: the irradiance within 0.5 % per channel, every
/// board pixel counted; pure noise at that size is still refused.
#[test]
fn a_large_board_is_found_downsampled_and_read_on_a_lattice() {
    let l = Vector3::new(0.2, -0.3, -1.0).normalize();
    let mut board = BoardScene::new(l);
    board.intr = sensor(&board.intr, 2400, 1800);
    board.supersample = 1;
    board.glints = 300;
    board.dust = 300;
    let img = board.render(9);
    let r = calibrate_irradiance(
        &img,
        board.albedo,
        &l,
        Some(&board.normal),
        &BoardRegion::Detect,
        &WhiteOptions {
            saturation: Some(1.0),
            ..WhiteOptions::default()
        },
    )
    .unwrap();
    let truth = board.irradiance;
    for (k, (got, want)) in r.irradiance.iter().zip(truth.iter()).enumerate() {
        let rel = (got - want).abs() / want;
        assert!(rel < 0.005, "channel {k}: {got} against {want}");
    }
    // every pixel of the board but a rim of a few blocks is counted; the fit read a lattice
    let k = &board.intr;
    let on_board = (0..k.width * k.height)
        .filter(|&i| {
            let (x, y) = ((i % k.width) as f64 + 0.5, (i / k.width) as f64 + 0.5);
            board.on_board(&Vector3::new((x - k.cx) / k.fx, (y - k.cy) / k.fy, 1.0).normalize())
        })
        .count();
    let counted = r.pixels_on_board + r.pixels_saturated;
    println!(
        "2400x1800 board: {counted} of {on_board} board pixels counted, read every {} px, {} used",
        r.sample_stride, r.pixels_used
    );
    assert!(counted <= on_board && counted as f64 > 0.95 * on_board as f64);
    assert!(r.sample_stride >= 2 && r.pixels_used <= 250_000 && r.pixels_used > 100_000);
    // pure noise of that size
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let noise: Vec<f32> = (0..2000 * 1500 * 3)
        .map(|_| rand::Rng::gen_range(&mut rng, 0.0..0.5))
        .collect();
    let e = calibrate_irradiance(
        &LinearImage::from_rgb(2000, 1500, noise).unwrap(),
        [0.8; 3],
        &Vector3::new(0.0, 0.0, -1.0),
        None,
        &BoardRegion::Detect,
        &WhiteOptions::default(),
    )
    .unwrap_err();
    assert!(matches!(e, WhiteError::NoBoard { .. }), "{e}");
}

#[test]
#[ignore = "writes ~900 MB of 24-megapixel images for a timing by hand"]
fn write_24_megapixel_calibration_images() {
    let Ok(dir) = std::env::var("BRDF_RIG_CALIB24_DIR") else {
        eprintln!("set BRDF_RIG_CALIB24_DIR to the folder to write to");
        return;
    };
    let d = std::path::Path::new(&dir);
    std::fs::create_dir_all(d).unwrap();
    let l = Vector3::new(0.35, -0.25, -1.0).normalize();
    let mut sphere = SphereScene::new(l);
    sphere.intr = sensor_24mp(&sphere.intr);
    sphere.supersample = 1;
    write_exr(
        &d.join("light.exr"),
        &sphere.render_light(1),
        ExrPrecision::F32,
    )
    .unwrap();
    write_exr(
        &d.join("ambient.exr"),
        &sphere.render_ambient(2),
        ExrPrecision::F32,
    )
    .unwrap();
    let mut board = BoardScene::new(l);
    board.intr = sensor_24mp(&board.intr);
    board.supersample = 1;
    board.glints = 40;
    write_exr(&d.join("board.exr"), &board.render(3), ExrPrecision::F32).unwrap();
    let k = &sphere.intr;
    let (a, n) = (board.albedo, board.normal);
    println!(
        "calibrate sphere --image {0}/light.exr --outline-image {0}/ambient.exr --intrinsics {1},{2},{3},{4} --saturation 1 --json",
        d.display(),
        k.fx,
        k.fy,
        k.cx,
        k.cy
    );
    println!(
        "calibrate white --image {}/board.exr --albedo {},{},{} --light-dir {},{},{} --normal {},{},{} --saturation 1 --json",
        d.display(),
        a[0],
        a[1],
        a[2],
        l.x,
        l.y,
        l.z,
        n.x,
        n.y,
        n.z
    );
    println!("light direction (camera axes): {},{},{}", l.x, l.y, l.z);
}

/// The sphere's light direction at camera resolutions against the truth, with the uncertainty
/// the calibration reports and the error of each part (outline centre and radius, highlight
/// normal read with the true outline): docs/calibration.md, "Accuracy at camera resolution".
/// `BRDF_RIG_STUDY_SIZES` (default `320x240,1500x1000,6000x4000`) and `BRDF_RIG_STUDY_CASES`
/// (light directions per sphere position, default 3; two sphere positions);
/// `BRDF_RIG_STUDY_COSINE=1` renders the lobe with the light's cosine (`SphereScene::lobe_cosine`):
/// `cargo test --release --all-features --test tests -- --ignored sphere_accuracy_at_camera_resolution --nocapture`
#[test]
#[ignore = "renders 24-megapixel images: a study run by hand"]
fn sphere_accuracy_at_camera_resolution() {
    let sizes = std::env::var("BRDF_RIG_STUDY_SIZES")
        .unwrap_or_else(|_| "320x240,1500x1000,6000x4000".into());
    let cases: usize = std::env::var("BRDF_RIG_STUDY_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let cosine = std::env::var("BRDF_RIG_STUDY_COSINE").is_ok_and(|v| v == "1");
    println!(
        "| size | sphere | light | error (deg) | reported (deg) | error / reported | centre (px) | radius (px) | highlight normal (deg) | its reported (deg) | edge points | edge rms (px) | seconds |"
    );
    println!("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for size in sizes.split(',') {
        let (w, h) = size.split_once('x').unwrap();
        let (w, h): (usize, usize) = (w.parse().unwrap(), h.parse().unwrap());
        for (position, centre) in [
            Vector3::new(0.025, -0.012, 0.42),
            Vector3::new(-0.04, 0.03, 0.45),
        ]
        .into_iter()
        .enumerate()
        {
            let mut rng = ChaCha8Rng::seed_from_u64(17 + position as u64);
            for case in 0..cases {
                let mut scene = SphereScene::new(Vector3::z());
                scene.centre = centre;
                scene.light_dir = random_dir_around(&mut rng, &scene.view_axis(), 10.0, 70.0);
                // the unit tests' supersampling at their size, less as the pixels shrink
                scene.supersample = (4 * 240 / h).clamp(1, 4);
                scene.intr = sensor(&scene.intr, w, h);
                scene.lobe_cosine = cosine;
                let seed = 100 * position as u64 + case as u64;
                let light = scene.render_light(seed);
                let ambient = scene.render_ambient(seed + 50);
                let opts = SphereOptions {
                    saturation: Some(1.0),
                    ..SphereOptions::default()
                };
                let t = std::time::Instant::now();
                let cal = calibrate_light(
                    &[SphereShot {
                        light: &light,
                        outline: OutlineInput::Image(&ambient),
                    }],
                    &scene.intr,
                    &opts,
                )
                .unwrap_or_else(|e| panic!("{size}, sphere {position}, light {case}: {e}"));
                let secs = t.elapsed().as_secs_f64();
                let one = &cal.per_image[0];
                let o = &one.outline;
                let f = scene.intr.fx;
                let alpha = (scene.radius / scene.centre.norm()).asin();
                let truth = SphereOutline {
                    centre_dir: scene.centre.normalize(),
                    angular_radius_rad: alpha,
                    centre_px: scene
                        .intr
                        .project(&scene.centre)
                        .map(|(x, y)| [x, y])
                        .unwrap(),
                    radius_px: alpha.tan() * f,
                    edge_points: 0,
                    rms_residual_rad: 0.0,
                    source: OutlineSource::UserCircle,
                };
                let h_true = find_highlight(&light, &truth, &scene.intr, &opts).unwrap();
                let err = cal.dir_camera.angle(&scene.light_dir).to_degrees();
                println!(
                    "| {size} | {position} | {case} | {err:.4} | {:.4} | {:.2} | {:.3} | {:+.3} | {:.4} | {:.4} | {} | {:.3} | {secs:.1} |",
                    cal.uncertainty_deg,
                    err / cal.uncertainty_deg,
                    o.centre_dir.angle(&truth.centre_dir) * f,
                    (o.angular_radius_rad - alpha) * f,
                    h_true.normal.angle(&scene.mirror_normal()).to_degrees(),
                    one.highlight.uncertainty_rad.to_degrees(),
                    o.edge_points,
                    o.rms_residual_rad * f,
                );
            }
        }
    }
}
