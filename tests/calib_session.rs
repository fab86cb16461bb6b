//! The light calibration on simulated captures (issue 5): whole captures through the real binary
//! (the serial stack to the simulated firmware on a pty, the simulated camera with its pixel
//! integration, lens blur, shot and read noise and clipping), then `brdf-rig calibrate SESSION`,
//! scored against the simulator's truth. Twelve seeded random light directions, three per
//! capture (the simulated rig has three channels), at 320x240 (sphere radius 37 px).

use brdf_rig::imageio::decode_exr;
use rand::{Rng, SeedableRng};

use crate::capture_util::{fast_profile, run, s, text};

/// `(azimuth_deg, elevation_deg)` of `n` lights 10 to 120 degrees from the camera (which sits at
/// azimuth 0, elevation 0), at most 50 degrees above or below the table's plane, and lighting the
/// white reference (turned to half the azimuth) at no more than 70 degrees from its normal.
fn random_lights(n: usize, seed: u64) -> Vec<(f64, f64)> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    while out.len() < n {
        let gamma = rng.gen_range(10.0f64..120.0).to_radians();
        let psi = rng.gen_range(0.0f64..360.0).to_radians();
        // camera along +x: the light at angle gamma from it, turned by psi about it
        let l = [
            gamma.cos(),
            gamma.sin() * psi.cos(),
            gamma.sin() * psi.sin(),
        ];
        let el = l[2].asin();
        let az = l[1].atan2(l[0]);
        let board = el.cos() * (0.5 * az).cos();
        if el.abs() <= 50f64.to_radians() && board >= 70f64.to_radians().cos() {
            out.push((az.to_degrees(), el.to_degrees()));
        }
    }
    out
}

/// The simulated profile with these three light directions.
fn profile_with_lights(dir: &std::path::Path, lights: &[(f64, f64)]) -> std::path::PathBuf {
    let base = fast_profile(dir);
    let mut text = std::fs::read_to_string(&base).unwrap();
    for ((az0, el0), (az, el)) in [(20.0, 0.0), (60.0, 0.0), (110.0, 0.0)].iter().zip(lights) {
        let old = format!("azimuth_deg = {az0:.1}\nelevation_deg = {el0:.1}\n");
        assert!(text.contains(&old), "the simulated profile changed: {old}");
        text = text.replace(&old, &format!("azimuth_deg = {az}\nelevation_deg = {el}\n"));
    }
    let p = dir.join("lights.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// Three ambient views (for the turntable axis), one single-light view, and the calibration
/// brackets of the quick plan, whose shortest exposure still clips the sphere's highlight.
fn calib_plan(dir: &std::path::Path) -> std::path::PathBuf {
    let text = "name = \"calib-test\"\n\
         [camera]\nwidth = 320\nheight = 240\ngain = 1.0\n\
         [ambient]\nviews = 3\nexposures_secs = [0.02]\n\
         [single_light]\nevery = 3\nchannels = [0, 1, 2]\nexposures_secs = [0.016]\n\
         [calibration]\nsphere = true\nwhite = true\n\
         exposures_secs = [0.0001, 0.0005, 0.0025, 0.0125]\n\
         [settle]\nturntable_millis = 0\nlight_millis = 0\n";
    let p = dir.join("calib-plan.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn light_within_half_a_degree_and_irradiance_within_2_percent_over_12_random_directions() {
    let lights = random_lights(12, 5);
    let tmp = tempfile::tempdir().unwrap();
    let plan = calib_plan(tmp.path());
    let (mut worst_dir, mut worst_irr, mut clipped) = (0.0f64, 0.0f64, 0);
    let mut report = String::new();
    for (k, three) in lights.chunks(3).enumerate() {
        let profile = profile_with_lights(tmp.path(), three);
        let out = tmp.path().join(format!("session{k}"));
        let o = crate::capture_util::capture_unattended(&profile, &plan, &out);
        assert!(o.status.success(), "{}", text(&o));
        let o = run(&["calibrate", s(&out)]);
        assert!(o.status.success(), "{}", text(&o));
        assert!(
            text(&o).contains("clip level of the sphere image"),
            "{}",
            text(&o)
        );
        let cal: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("calibration.json")).unwrap()).unwrap();
        for (ch, (az, el)) in three.iter().enumerate() {
            let c = &cal["channels"][ch];
            assert_eq!(c["channel"].as_u64(), Some(ch as u64));
            let dir_err = c["truth_dir_error_deg"].as_f64().unwrap();
            let irr_err = c["truth_irradiance_error"].as_f64().unwrap();
            // the clip levels are the merged brackets' (never guessed), and they are said
            for key in ["sphere_clip", "white_clip"] {
                assert_eq!(c[key]["source"], "merged_bracket", "{key}: {}", c[key]);
                assert!(
                    c[key]["value"].as_f64().is_some_and(|v| v > 1.0),
                    "{}",
                    c[key]
                );
            }
            // the sphere's highlight clips even in the shortest exposure of the bracket?
            let shortest = decode_exr(
                &std::fs::read(out.join(format!("calib/sphere_ch{ch}_e0.exr"))).unwrap(),
            )
            .unwrap();
            let clips = shortest.data().iter().any(|&v| v >= 1.0);
            clipped += clips as usize;
            let gamma = (el.to_radians().cos() * az.to_radians().cos())
                .acos()
                .to_degrees();
            report += &format!(
                "az {az:7.2} el {el:6.2} ({gamma:5.1} from the camera): light {dir_err:.3} deg, irradiance {:.2} %{}\n",
                100.0 * irr_err,
                if clips { ", highlight clipped" } else { "" }
            );
            worst_dir = worst_dir.max(dir_err);
            worst_irr = worst_irr.max(irr_err);
        }
    }
    eprintln!("{report}");
    assert!(
        worst_dir < 0.5,
        "light direction error {worst_dir} deg\n{report}"
    );
    assert!(worst_irr < 0.02, "irradiance error {worst_irr}\n{report}");
    assert!(clipped >= 1, "no case with a clipped highlight\n{report}");
}
