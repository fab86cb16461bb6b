//! Study (session 37): does a basis that also holds analytic dielectrics (Lambert + GGX with
//! Schlick's Fresnel, which rises at grazing theta_d) extrapolate a material's grazing peak
//! better from exact values where the images see it (theta_d below a limit)? Leave-one-out
//! over the neural MERL fits (approximations of MERL, not measured MERL data).
//!
//! `cargo run --release --example augment_study -- THETA_D_MAX [TARGET...]`
//! (`AUGMENT=n`: the number of analytic materials added, 0 for none; stride 1, 2, 2, k = 64).

use brdf_rig::brdf::BinValues;
use brdf_rig::brdf::analytic::LambertGgx;
use brdf_rig::brdf::basis::{Basis, BasisSettings, GridStride};
use brdf_rig::brdf::coords::MerlBin;
use brdf_rig::brdf::nbrdf::{default_dir, load_dir};
use brdf_rig::brdf::ridge::{BasisSample, RidgeSettings, reconstruct};
use brdf_rig::eval::BrdfValues;
use brdf_rig::render::probe::{ProbeSettings, SphereProbe, compare};

fn analytic_family() -> Vec<(String, LambertGgx)> {
    let mut out = Vec::new();
    let kds: [[f64; 3]; 4] = [
        [0.04, 0.04, 0.04],
        [0.3, 0.3, 0.3],
        [0.5, 0.3, 0.15],
        [0.1, 0.2, 0.5],
    ];
    for (ai, alpha) in [0.01, 0.02, 0.04, 0.08, 0.16, 0.32].iter().enumerate() {
        for (fi, f0) in [0.03, 0.06].iter().enumerate() {
            for (ki, kd) in kds.iter().enumerate() {
                out.push((
                    format!("~ggx-a{ai}-f{fi}-k{ki}"),
                    LambertGgx {
                        kd: *kd,
                        ks: [1.0; 3],
                        alpha: *alpha,
                        f0: *f0,
                    },
                ));
            }
        }
    }
    out
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    anyhow::ensure!(!args.is_empty(), "usage: THETA_D_MAX [TARGET...]");
    let d_max: f64 = args[0].parse()?;
    let n_aug: usize = std::env::var("AUGMENT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(48);
    let materials = load_dir(&default_dir())?;
    let targets: Vec<String> = if args.len() > 1 {
        args[1..].to_vec()
    } else {
        materials.iter().map(|(n, _)| n.clone()).collect()
    };
    let family: Vec<(String, LambertGgx)> = analytic_family().into_iter().take(n_aug).collect();
    let fam_values: Vec<(String, BrdfValues)> = family
        .iter()
        .map(|(n, m)| (n.clone(), BrdfValues(m)))
        .collect();
    let probe = SphereProbe::standard(ProbeSettings::default());
    let pbins = probe.bins().to_vec();
    let seen = |bin: usize| {
        MerlBin::from_index(bin).is_some_and(|b| {
            let (wi, wo) = b.centre_directions();
            let cos_d = wi.dot(&(wi + wo).normalize());
            cos_d.clamp(-1.0, 1.0).acos().to_degrees() < d_max
        })
    };
    println!(
        "# theta_d < {d_max} deg seen; {n_aug} analytic materials added; env error eta 1 10 40"
    );
    for target in &targets {
        let settings = BasisSettings {
            stride: GridStride::default(),
            basis_components: 64,
            exclude: vec![target.clone()],
        };
        let mut list: Vec<(&str, &dyn BinValues)> = materials
            .iter()
            .map(|(n, m)| (n.as_str(), m as &dyn BinValues))
            .collect();
        for (n, v) in &fam_values {
            list.push((n.as_str(), v as &dyn BinValues));
        }
        let basis = Basis::build(&settings, &list)?;
        let net = &materials
            .iter()
            .find(|(n, _)| n == target)
            .ok_or_else(|| anyhow::anyhow!("no material {target}"))?
            .1;
        let bins = basis.grid().bins().to_vec();
        let truth = net.values_at(&bins);
        let obs: Vec<BasisSample> = truth
            .iter()
            .enumerate()
            .filter(|(r, _)| seen(bins[*r]))
            .map(|(row, &rgb)| BasisSample { row, rgb })
            .collect();
        let tr = probe.render_values(&net.values_at(&pbins));
        let mut errs = Vec::new();
        for eta in [1.0, 10.0, 40.0] {
            let rec = reconstruct(&basis, &obs, &RidgeSettings { k: 64, eta })?;
            errs.push(compare(&tr, &probe.render_values(&rec.values_at(&pbins))).environment);
        }
        println!(
            "{target} {}",
            errs.iter()
                .map(|e| format!("{e:.4}"))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    Ok(())
}
