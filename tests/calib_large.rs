//! Calibration images at a camera's resolution (issue #14), written for a timing by hand of
//! `calibrate sphere` and `calibrate white` (docs/benchmarks-reconstruct.md gives the commands;
//! speed goals live in benchmarks, not in tests):
//! `BRDF_RIG_CALIB24_DIR=/tmp/c24 cargo test --release --all-features --test tests -- --ignored
//! write_24_megapixel_calibration_images --nocapture`

use crate::calib_synth::{BoardScene, SphereScene};
use brdf_rig::geometry::camera::Intrinsics;
use brdf_rig::imageio::{ExrPrecision, write_exr};
use nalgebra::Vector3;

/// The fixture's camera scaled to a 6000x4000 sensor (same field of view vertically, the
/// principal point moved with the wider frame).
fn sensor_24mp(k: &Intrinsics) -> Intrinsics {
    let s = 4000.0 / k.height as f64;
    let mut big = k.scaled(s);
    big.width = 6000;
    big.height = 4000;
    big.cx += (6000.0 - k.width as f64 * s) / 2.0;
    big
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
