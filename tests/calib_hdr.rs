//! HDR merging against the radiance the synthetic brackets were made from, and recovery of a
//! known gamma-like camera response.

#![allow(clippy::unwrap_used)] // tests: a panic is the failure report

use crate::calib_synth::gauss;
use brdf_rig::calib::hdr::{
    Exposure, Exposure8, MergeOptions, ResponseOptions, Rgb8Image, merge_linear, recover_response,
};
use brdf_rig::render::image::LinearImage;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Radiance log-uniform over `[lo, hi]`, independently per channel.
fn scene(w: usize, h: usize, lo: f64, hi: f64, seed: u64) -> Vec<f64> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    (0..w * h * 3)
        .map(|_| (lo.ln() + rng.r#gen::<f64>() * (hi / lo).ln()).exp())
        .collect()
}

#[test]
fn linear_bracket_recovers_radiance_beyond_the_clip_level() {
    let (w, h) = (64, 48);
    let radiance = scene(w, h, 0.02, 200.0, 1);
    let times = [1.0 / 256.0, 1.0 / 32.0, 1.0 / 4.0, 2.0];
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    let images: Vec<LinearImage> = times
        .iter()
        .map(|t| {
            let data = radiance
                .iter()
                .map(|e| {
                    let x = e * t;
                    (x + (0.001 + 0.01 * x) * gauss(&mut rng)).clamp(0.0, 1.0) as f32
                })
                .collect();
            LinearImage::from_rgb(w, h, data).unwrap()
        })
        .collect();
    // a single exposure clips the bright end
    assert!(images[2].data().iter().filter(|&&v| v >= 1.0).count() > 1000);
    let brackets: Vec<Exposure> = images
        .iter()
        .zip(times)
        .map(|(image, exposure_secs)| Exposure {
            image,
            exposure_secs,
        })
        .collect();
    let merged = merge_linear(&brackets, &MergeOptions::new(1.0, 0.01)).unwrap();
    assert_eq!(merged.clipped_everywhere, 0);
    let mut errs: Vec<f64> = merged
        .image
        .data()
        .iter()
        .zip(&radiance)
        .map(|(&m, &e)| (m as f64 - e).abs() / e)
        .collect();
    errs.sort_by(f64::total_cmp);
    let median = errs[errs.len() / 2];
    let p99 = errs[errs.len() * 99 / 100];
    eprintln!("linear merge: median relative error {median:.4}, 99th percentile {p99:.4}");
    assert!(median < 0.01 && p99 < 0.05, "{median} {p99}");
}

/// A gamma-like response: codes = round(255 * clip(x)^(1/2.2)).
fn camera8(x: f64) -> u8 {
    (255.0 * x.clamp(0.0, 1.0).powf(1.0 / 2.2)).round() as u8
}

#[test]
fn debevec_malik_recovers_a_gamma_response_and_radiance() {
    let (w, h) = (60, 40);
    let radiance = scene(w, h, 0.05, 50.0, 3);
    let times = [1.0 / 64.0, 1.0 / 16.0, 1.0 / 4.0, 1.0, 4.0];
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let images: Vec<Rgb8Image> = times
        .iter()
        .map(|t| Rgb8Image {
            width: w,
            height: h,
            data: radiance
                .iter()
                .map(|e| {
                    let x = e * t;
                    camera8(x * (1.0 + 0.005 * gauss(&mut rng)))
                })
                .collect(),
        })
        .collect();
    let brackets: Vec<Exposure8> = images
        .iter()
        .zip(times)
        .map(|(image, exposure_secs)| Exposure8 {
            image,
            exposure_secs,
        })
        .collect();
    let curve = recover_response(&brackets, &ResponseOptions::default()).unwrap();
    assert!(curve.is_monotonic(5, 250));
    // truth: g(z) = ln f^-1(z) = 2.2 ln(z / 255), compared with both pinned at z = 128; below
    // code 16 one code step is itself more than 14 % of radiance, so the comparison starts there
    let truth = |z: usize| 2.2 * (z as f64 / 255.0).ln();
    let mut worst: f64 = 0.0;
    for g in &curve.log_exposure {
        for z in 16..=245 {
            let d = (g[z] - g[128]) - (truth(z) - truth(128));
            worst = worst.max(d.abs());
        }
    }
    eprintln!("response curve: worst |g - g_true| over codes 16..=245: {worst:.4} (log units)");
    assert!(worst < 0.05, "{worst}");
    // merged radiance up to one scale per channel
    let merged = curve.merge(&brackets).unwrap();
    for c in 0..3 {
        let mut ratios: Vec<f64> = (0..w * h)
            .map(|p| merged.data()[3 * p + c] as f64 / radiance[3 * p + c])
            .collect();
        ratios.sort_by(f64::total_cmp);
        let scale = ratios[ratios.len() / 2];
        let mut errs: Vec<f64> = ratios.iter().map(|r| (r / scale - 1.0).abs()).collect();
        errs.sort_by(f64::total_cmp);
        let median = errs[errs.len() / 2];
        let p95 = errs[errs.len() * 95 / 100];
        eprintln!("channel {c}: relative radiance error median {median:.4}, 95th pct {p95:.4}");
        assert!(median < 0.02 && p95 < 0.06, "{median} {p95}");
    }
    // linearising one exposure gives the same radiance where it is well exposed
    let lin = curve.linearise(&images[3], times[3]);
    let p = (0..w * h)
        .find(|&p| (100..160).contains(&images[3].data[3 * p]))
        .unwrap();
    let rel = lin.data()[3 * p] as f64 / merged.data()[3 * p] as f64;
    assert!((rel - 1.0).abs() < 0.05, "{rel}");
}
