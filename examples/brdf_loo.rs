//! Leave-one-out experiment on the neural MERL fits (smooth approximations of MERL, NOT measured
//! MERL data): for each target material, build the PCA basis from the other 99 materials, then
//! reconstruct the target (a) from every basis bin, with k = 5..40 components, and (b) from |S|
//! optimally chosen bins, and print the relative, cosine-weighted and near-specular errors.
//!
//! `cargo run --release --example brdf_loo -- [--keep-target] [STRIDE_H STRIDE_D STRIDE_P] [TARGET...]`
//! (`--keep-target` leaves the target IN the basis: the in-sample floor, not a fair result)
//! (defaults: stride 1 2 2, targets alum-bronze pink-fabric blue-acrylic). The basis is cached
//! in `$BRDF_RIG_CACHE` or `~/.cache/brdf-rig`.

use brdf_rig::brdf::analytic::{LambertGgx, ReflectanceSample, cosine_map_weight};
use brdf_rig::brdf::basis::{BasisSettings, GridStride};
use brdf_rig::brdf::basis_cache::{default_cache_dir, load_or_build};
use brdf_rig::brdf::coords::MerlBin;
use brdf_rig::brdf::metrics::compare_values;
use brdf_rig::brdf::nbrdf::{default_dir, load_dir};
use brdf_rig::brdf::ridge::{BasisSample, RidgeSettings, reconstruct};
use brdf_rig::brdf::sampling::{SamplingSettings, select_samples_with};
use brdf_rig::brdf::{BinValues, Brdf};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let keep_target = args.first().is_some_and(|a| a == "--keep-target");
    if keep_target {
        args.remove(0);
    }
    let (stride, targets) = match args.first().and_then(|a| a.parse::<usize>().ok()) {
        Some(_) if args.len() >= 3 => (
            GridStride {
                theta_h: args[0].parse()?,
                theta_d: args[1].parse()?,
                phi_d: args[2].parse()?,
            },
            args[3..].to_vec(),
        ),
        _ => (GridStride::default(), args.clone()),
    };
    let targets = if targets.is_empty() {
        vec![
            "alum-bronze".into(),
            "pink-fabric".into(),
            "blue-acrylic".into(),
        ]
    } else {
        targets
    };
    let materials = load_dir(&default_dir())?;
    println!("# neural MERL fits (approximations, not measured MERL data); stride {stride:?}");
    for target in &targets {
        let settings = BasisSettings {
            stride,
            basis_components: 64,
            exclude: if keep_target {
                vec![]
            } else {
                vec![target.clone()]
            },
        };
        let t0 = Instant::now();
        let (basis, status) = load_or_build(&settings, &materials, &default_cache_dir())?;
        println!(
            "\n## {target}: basis of {} materials, {} rows, {:.1} s ({status:?})",
            basis.materials().len(),
            basis.n_rows(),
            t0.elapsed().as_secs_f64()
        );
        let net = &materials
            .iter()
            .find(|(n, _)| n == target)
            .ok_or_else(|| anyhow::anyhow!("no material {target}"))?
            .1;
        let bins = basis.grid().bins().to_vec();
        let truth = net.values_at(&bins);
        let all: Vec<BasisSample> = truth
            .iter()
            .enumerate()
            .map(|(row, &rgb)| BasisSample { row, rgb })
            .collect();
        println!("all bins observed:   k  relative  cos-weighted  near-specular");
        for k in [5, 10, 20, 30, 40] {
            let rec = reconstruct(&basis, &all, &RidgeSettings { k, eta: 40.0 })?;
            let e = compare_values(&bins, &truth, rec.values());
            println!(
                "                   {k:3}  {:8.4}  {:12.4}  {:13.4}",
                e.relative, e.cosine_weighted, e.near_specular
            );
        }
        // Baseline: Lambert + GGX fitted by least squares to every basis bin.
        let obs_dirs: Vec<ReflectanceSample> = bins
            .iter()
            .zip(&truth)
            .filter_map(|(&b, &rgb)| {
                let (wi, wo) = MerlBin::from_index(b)?.centre().to_directions();
                Some(ReflectanceSample { wi, wo, rgb })
            })
            .collect();
        for (label, fit) in [
            ("Lambert+GGX LS       ", LambertGgx::fit(&obs_dirs)?),
            (
                "Lambert+GGX cos-w LS ",
                LambertGgx::fit_weighted(&obs_dirs, cosine_map_weight)?,
            ),
        ] {
            let fitted: Vec<[f64; 3]> = obs_dirs
                .iter()
                .map(|o| fit.eval_local(&o.wi, &o.wo))
                .collect();
            let e = compare_values(&bins, &truth, &fitted);
            println!(
                "{label}  {:8.4}  {:12.4}  {:13.4}   (all bins; alpha {:.3}, F0 {:.3})",
                e.relative, e.cosine_weighted, e.near_specular, fit.alpha, fit.f0
            );
        }
        // A fixed light and camera see one theta_d only (METHOD.md section 1).
        let one_theta_d: Vec<usize> = (0..basis.n_rows())
            .filter(|&r| {
                MerlBin::from_index(bins[r])
                    .is_some_and(|b| b.theta_d / stride.theta_d == 45 / stride.theta_d)
            })
            .collect();
        println!(
            "optimal samples:   |S|  relative  cos-weighted  near-specular  (k = min(|S|, 20))"
        );
        // The brightest bin among the candidates: the paper's always-used specular peak.
        let brightest = |rows: &mut dyn Iterator<Item = usize>| {
            rows.max_by(|&a, &b| {
                let l = |r: usize| truth[r].iter().sum::<f64>();
                l(a).total_cmp(&l(b))
            })
        };
        let peak_all = brightest(&mut (0..basis.n_rows()));
        let peak_one = brightest(&mut one_theta_d.iter().copied());
        type Plan<'a> = (usize, Option<&'a Vec<usize>>, Option<usize>);
        let plans: [Plan; 8] = [
            (10, None, None),
            (20, None, None),
            (40, None, None),
            (20, None, peak_all),
            (20, Some(&one_theta_d), None),
            (40, Some(&one_theta_d), None),
            (20, Some(&one_theta_d), peak_one),
            (40, Some(&one_theta_d), peak_one),
        ];
        for (n, cands, peak) in plans {
            let fixed: Vec<usize> = peak.into_iter().collect();
            let s = select_samples_with(
                &basis,
                n,
                cands.map(|c| c.as_slice()),
                &fixed,
                &SamplingSettings::default(),
            )?;
            let obs: Vec<BasisSample> = s
                .iter()
                .map(|&row| BasisSample {
                    row,
                    rgb: truth[row],
                })
                .collect();
            let rec = reconstruct(&basis, &obs, &RidgeSettings::default())?;
            let e = compare_values(&bins, &truth, rec.values());
            println!(
                "                   {n:3}  {:8.4}  {:12.4}  {:13.4}{}",
                e.relative,
                e.cosine_weighted,
                e.near_specular,
                match (cands.is_some(), peak.is_some()) {
                    (false, false) => "",
                    (false, true) => "   (+ brightest bin fixed)",
                    (true, false) => "   (theta_d = 45 deg only)",
                    (true, true) => "   (theta_d = 45 deg only, + brightest bin fixed)",
                }
            );
        }
    }
    Ok(())
}
