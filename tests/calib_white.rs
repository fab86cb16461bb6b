//! Irradiance from synthetic white-board images against the irradiance the renderer used, alone
//! and chained after the sphere (the light direction measured, not given).

#![allow(clippy::unwrap_used)] // tests: a panic is the failure report

use crate::calib_synth::{BoardScene, SphereScene, random_dir_around};
use brdf_rig::calib::light::{OutlineInput, SphereShot, calibrate_light};
use brdf_rig::calib::sphere::SphereOptions;
use brdf_rig::calib::white::{BoardRegion, WhiteError, WhiteOptions, calibrate_irradiance};
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

fn rel_errors(got: [f64; 3], want: [f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|k| (got[k] - want[k]).abs() / want[k])
}

#[test]
fn sphere_then_board_irradiance_within_2_percent_over_10_directions() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let (mut dir_err, mut irr_err) = (Vec::new(), Vec::new());
    for i in 0..10u64 {
        let mut board = BoardScene::new(Vector3::z());
        let l = random_dir_around(&mut rng, &board.normal, 0.0, 55.0);
        board.light_dir = l;
        board.glints = 6;
        board.dust = 6;
        let sphere = SphereScene::new(l);
        let light = sphere.render_light(400 + i);
        let ambient = sphere.render_ambient(500 + i);
        let cal = calibrate_light(
            &[SphereShot {
                light: &light,
                outline: OutlineInput::Image(&ambient),
            }],
            &sphere.intr,
            &SphereOptions::default(),
        )
        .unwrap();
        dir_err.push(cal.dir_camera.angle(&l).to_degrees());
        let img = board.render(600 + i);
        let r = calibrate_irradiance(
            &img,
            board.albedo,
            &cal.dir_camera,
            Some(&board.normal),
            &BoardRegion::Detect,
            &WhiteOptions {
                saturation: Some(1.0),
                ..Default::default()
            },
        )
        .unwrap();
        let e = rel_errors(r.irradiance, board.irradiance);
        irr_err.push(e.iter().copied().fold(0.0, f64::max));
        assert!(
            r.pixels_saturated >= 1,
            "the glints must be seen and dropped"
        );
    }
    let stats = |v: &[f64]| {
        (
            v.iter().sum::<f64>() / v.len() as f64,
            v.iter().copied().fold(0.0, f64::max),
        )
    };
    let (dm, dx) = stats(&dir_err);
    let (em, ex) = stats(&irr_err);
    eprintln!(
        "sphere -> board over 10 directions: direction error mean {dm:.3} max {dx:.3} deg; \
         irradiance error (worst channel) mean {:.3} % max {:.3} %",
        100.0 * em,
        100.0 * ex
    );
    assert!(dx < 0.5, "{dir_err:?}");
    assert!(ex < 0.02, "{irr_err:?}");
}

#[test]
fn given_roi_and_flat_field_warning() {
    let l = Vector3::new(0.2, -0.3, -1.0).normalize();
    let mut board = BoardScene::new(l);
    let roi = BoardRegion::Roi {
        x: 90,
        y: 60,
        width: 60,
        height: 60,
    };
    let opts = WhiteOptions {
        saturation: Some(1.0),
        ..Default::default()
    };
    let even = calibrate_irradiance(
        &board.render(1),
        board.albedo,
        &l,
        Some(&board.normal),
        &roi,
        &opts,
    )
    .unwrap();
    assert!(
        rel_errors(even.irradiance, board.irradiance)
            .iter()
            .all(|&e| e < 0.01)
    );
    assert!(even.flat_field.spread < 0.05 && even.warnings.is_empty());
    assert_eq!(even.region, [90, 60, 60, 60]);
    board.vignetting = 1.0;
    let uneven = calibrate_irradiance(
        &board.render(2),
        board.albedo,
        &l,
        Some(&board.normal),
        &BoardRegion::Detect,
        &opts,
    )
    .unwrap();
    assert!(uneven.flat_field.spread > 0.05);
    assert!(uneven.warnings.iter().any(|w| w.contains("not evenly lit")));
}

#[test]
fn without_a_normal_the_board_is_assumed_to_face_the_light() {
    let l = Vector3::new(0.1, -0.2, -1.0).normalize();
    let mut board = BoardScene::new(l);
    board.normal = l; // the board really faces the light
    let r = calibrate_irradiance(
        &board.render(3),
        board.albedo,
        &l,
        None,
        &BoardRegion::Detect,
        &WhiteOptions::default(),
    )
    .unwrap();
    assert!(r.normal_assumed && (r.cos_theta - 1.0).abs() < 1e-12);
    assert!(
        rel_errors(r.irradiance, board.irradiance)
            .iter()
            .all(|&e| e < 0.02)
    );
    assert!(r.warnings.iter().any(|w| w.contains("assumed")));
}

#[test]
fn clipped_board_grazing_light_and_bad_roi_are_errors() {
    let l = Vector3::new(0.1, -0.2, -1.0).normalize();
    let mut board = BoardScene::new(l);
    board.irradiance = [30.0; 3]; // radiance ~ 9: clipped at 1
    let img = board.render(4);
    let opts = WhiteOptions {
        saturation: Some(1.0),
        ..Default::default()
    };
    let err = calibrate_irradiance(
        &img,
        board.albedo,
        &l,
        Some(&board.normal),
        &BoardRegion::Detect,
        &opts,
    )
    .unwrap_err();
    assert!(matches!(err, WhiteError::TooFewPixels { .. }), "{err}");
    assert!(err.to_string().contains("shorten the exposure"));
    let side = board.normal.cross(&Vector3::y()).normalize();
    let err = calibrate_irradiance(
        &img,
        board.albedo,
        &side,
        Some(&board.normal),
        &BoardRegion::Detect,
        &opts,
    )
    .unwrap_err();
    assert!(matches!(err, WhiteError::Grazing { .. }), "{err}");
    let err = calibrate_irradiance(
        &img,
        board.albedo,
        &l,
        Some(&board.normal),
        &BoardRegion::Roi {
            x: 200,
            y: 0,
            width: 100,
            height: 10,
        },
        &opts,
    )
    .unwrap_err();
    assert!(
        err.to_string().contains("not inside the 240x180 image"),
        "{err}"
    );
}
