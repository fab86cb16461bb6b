//! `brdf-rig calibrate` as a user runs it: synthetic images written to EXR, the real binary,
//! its JSON read back and compared with the light and irradiance the images were made with.

use crate::calib_synth::{BoardScene, SphereScene};
use crate::util::bin;
use brdf_rig::imageio::{ExrPrecision, write_exr};
use nalgebra::Vector3;
use std::process::{Command, Output};

fn run(args: &[&str]) -> Output {
    Command::new(bin()).args(args).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

#[test]
fn sphere_then_white_through_the_binary() {
    let dir = tempfile::tempdir().unwrap();
    let l = Vector3::new(0.35, -0.25, -1.0).normalize();
    let scene = SphereScene::new(l);
    let light = dir.path().join("sphere light.exr");
    let ambient = dir.path().join("sphere ambient.exr");
    write_exr(&light, &scene.render_light(1), ExrPrecision::F32).unwrap();
    write_exr(&ambient, &scene.render_ambient(2), ExrPrecision::F32).unwrap();
    let k = &scene.intr;
    let intrinsics = format!("{},{},{},{}", k.fx, k.fy, k.cx, k.cy);
    let out = run(&[
        "calibrate",
        "sphere",
        "--image",
        light.to_str().unwrap(),
        "--outline-image",
        ambient.to_str().unwrap(),
        "--intrinsics",
        &intrinsics,
        "--saturation",
        "1",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let d: Vec<f64> = serde_json::from_value(j["light_dir_camera"].clone()).unwrap();
    let d = Vector3::new(d[0], d[1], d[2]);
    assert!(d.angle(&l).to_degrees() < 0.5, "{j}");
    assert!(j["uncertainty_deg"].as_f64().unwrap() > 0.0);

    // the text form says which axes it uses
    let text = run(&[
        "calibrate",
        "sphere",
        "--image",
        light.to_str().unwrap(),
        "--outline-image",
        ambient.to_str().unwrap(),
        "--intrinsics",
        &intrinsics,
    ]);
    let text = String::from_utf8_lossy(&text.stdout);
    eprintln!("{text}");
    assert!(text.contains("x right, y down, z forward"));

    // irradiance with the measured direction
    let mut board = BoardScene::new(l);
    board.glints = 4;
    let board_file = dir.path().join("board.exr");
    write_exr(&board_file, &board.render(3), ExrPrecision::F32).unwrap();
    let n = board.normal;
    let out = run(&[
        "calibrate",
        "white",
        "--image",
        board_file.to_str().unwrap(),
        "--albedo",
        &format!(
            "{},{},{}",
            board.albedo[0], board.albedo[1], board.albedo[2]
        ),
        "--light-dir",
        &format!("{},{},{}", d.x, d.y, d.z),
        "--normal",
        &format!("{},{},{}", n.x, n.y, n.z),
        "--saturation",
        "1",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let e: Vec<f64> = serde_json::from_value(j["irradiance"].clone()).unwrap();
    for (got, want) in e.iter().zip(board.irradiance) {
        assert!((got / want - 1.0).abs() < 0.02, "{j}");
    }
}

#[test]
fn errors_name_the_field_or_the_file() {
    let out = run(&[
        "calibrate",
        "sphere",
        "--image",
        "x.exr",
        "--intrinsics",
        "500,500,160",
    ]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("--intrinsics: expected 4"),
        "{}",
        stderr(&out)
    );

    let out = run(&[
        "calibrate",
        "white",
        "--image",
        "x.exr",
        "--albedo",
        "0",
        "--light-dir",
        "0,0,-1",
    ]);
    assert!(stderr(&out).contains("--albedo"), "{}", stderr(&out));

    let out = run(&[
        "calibrate",
        "sphere",
        "--image",
        "/nonexistent/sphere.exr",
        "--intrinsics",
        "500,500,160,120",
    ]);
    assert!(!out.status.success());
    assert!(
        stderr(&out).contains("/nonexistent/sphere.exr"),
        "{}",
        stderr(&out)
    );

    // an image without a sphere: the error says so and names the file
    let dir = tempfile::tempdir().unwrap();
    let mut scene = SphereScene::new(Vector3::new(0.0, 0.0, -1.0));
    scene.radius = 0.0;
    let empty = dir.path().join("empty.exr");
    write_exr(&empty, &scene.render_ambient(4), ExrPrecision::F32).unwrap();
    let out = run(&[
        "calibrate",
        "sphere",
        "--image",
        empty.to_str().unwrap(),
        "--intrinsics",
        "520,520,160,120",
    ]);
    assert!(!out.status.success());
    let e = stderr(&out);
    assert!(
        e.contains("empty.exr") && e.contains("no sphere found"),
        "{e}"
    );
}
