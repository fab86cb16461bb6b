//! Study (session 33): with exact values where the images see a material (theta_d below a
//! limit) and nothing beyond, which extrapolation to the grazing theta_d renders nearer the
//! truth: the basis (ridge, leave-one-out) or Lambert + GGX fitted to the same bins? Neural
//! MERL fits as truth (approximations of MERL, not measured MERL data).
//!
//! `cargo run --release --example grazing_study -- THETA_D_MAX_DEG SH SD SP [TARGET...]`
//! (`SH SD SP`: the basis grid's stride; no targets: all materials; `BAND_DROP=LO,HI,TH` also
//! withholds the rows with theta_d in [LO, HI) and theta_h below TH degrees; `AUGMENT=N`, session
//! 37, builds each basis with the first N of 48 analytic dielectrics added as materials, see
//! [`analytic_family`]; `KNN=k`, session 54, adds two extrapolations from the `k` materials of
//! the basis nearest the seen values, see [`knn_extrapolations`], and, session 55, the basis's ridge
//! shrunk towards them ([`local_ridge`]) and three geometric blends of the basis, `knn_anchored`
//! and Lambert + GGX; `SEEN_BAND=LO,HI`, session
//! 55, sees only theta_d in [LO, HI), as one light beside the camera does). Prints, per target, the
//! environment error of each model over the whole table and with the truth kept where observed
//! (only the extrapolation judged).

use brdf_rig::brdf::analytic::{LambertGgx, ReflectanceSample, pixel_weight};
use brdf_rig::brdf::basis::{Basis, BasisSettings, GridStride};
use brdf_rig::brdf::basis_cache::{default_cache_dir, load_or_build};
use brdf_rig::brdf::coords::MerlBin;
use brdf_rig::brdf::metrics::bin_solid_angle;
use brdf_rig::brdf::nbrdf::{default_dir, load_dir};
use brdf_rig::brdf::ridge::{BasisSample, RidgeSettings, reconstruct};
use brdf_rig::brdf::{BinValues, Brdf};
use brdf_rig::eval::BrdfValues;
use brdf_rig::render::probe::{ProbeSettings, SphereProbe, compare};

/// Lambert + GGX dielectrics whose Schlick Fresnel rises to 1 at grazing theta_d: white
/// specular (ks 1), F0 0.03 and 0.06, alpha 0.01-0.32, four diffuse colours (48 in all). Added
/// as materials, they ask whether a basis that holds such a rise extrapolates a measured
/// material's grazing peak better (docs/evaluation.md section 1y).
fn analytic_family() -> Vec<(String, LambertGgx)> {
    let kds: [[f64; 3]; 4] = [
        [0.04, 0.04, 0.04],
        [0.3, 0.3, 0.3],
        [0.5, 0.3, 0.15],
        [0.1, 0.2, 0.5],
    ];
    let mut out = Vec::new();
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
    anyhow::ensure!(
        args.len() >= 4,
        "usage: THETA_D_MAX STRIDE_H STRIDE_D STRIDE_P [TARGET...]"
    );
    let d_max: f64 = args[0]
        .parse()
        .map_err(|e| anyhow::anyhow!("THETA_D_MAX {:?}: not a number ({e})", args[0]))?;
    let stride_arg = |i: usize, name: &str| -> anyhow::Result<usize> {
        args[i]
            .parse()
            .map_err(|e| anyhow::anyhow!("{name} {:?}: not a count ({e})", args[i]))
    };
    let stride = GridStride {
        theta_h: stride_arg(1, "STRIDE_H")?,
        theta_d: stride_arg(2, "STRIDE_D")?,
        phi_d: stride_arg(3, "STRIDE_P")?,
    };
    let materials = load_dir(&default_dir())?;
    let targets: Vec<String> = if args.len() > 4 {
        args[4..].to_vec()
    } else {
        materials.iter().map(|(n, _)| n.clone()).collect()
    };
    let augment: usize = match std::env::var("AUGMENT") {
        Ok(v) => v
            .parse()
            .map_err(|e| anyhow::anyhow!("AUGMENT={v}: not a count ({e})"))?,
        Err(_) => 0,
    };
    let family: Vec<(String, LambertGgx)> = analytic_family().into_iter().take(augment).collect();
    // `KNN=k`: also the k nearest materials' extrapolations (session 54).
    let knn: Option<usize> = match std::env::var("KNN") {
        Ok(v) => Some(
            v.parse()
                .map_err(|e| anyhow::anyhow!("KNN={v}: not a count ({e})"))?,
        ),
        Err(_) => None,
    };
    // `SEEN_BAND=LO,HI` (session 55): only theta_d in [LO, HI) is seen, as with one light fixed
    // beside the camera (THETA_D_MAX is then ignored).
    let seen_band: Option<(f64, f64)> = env_degrees("SEEN_BAND", 2)?.map(|p| (p[0], p[1]));
    let probe = SphereProbe::standard(ProbeSettings::default());
    let pbins = probe.bins().to_vec();
    let seen = |bin: usize| {
        MerlBin::from_index(bin).is_some_and(|b| {
            let (wi, wo) = b.centre_directions();
            let cos_d = wi.dot(&(wi + wo).normalize());
            let d = cos_d.clamp(-1.0, 1.0).acos().to_degrees();
            match seen_band {
                Some((lo, hi)) => d >= lo && d < hi,
                None => d < d_max,
            }
        })
    };
    // `BAND_DROP=LO,HI,TH`: also leave unseen the rows with theta_d in [LO, HI) and theta_h
    // below TH degrees (which rows of the band decide the extrapolation).
    let band: Option<(f64, f64, f64)> = env_degrees("BAND_DROP", 3)?.map(|p| (p[0], p[1], p[2]));
    let seen = |bin: usize| {
        seen(bin)
            && !MerlBin::from_index(bin).is_some_and(|b| {
                band.is_some_and(|(lo, hi, th)| {
                    let (wi, wo) = b.centre_directions();
                    let h = (wi + wo).normalize();
                    let d = wi.dot(&h).clamp(-1.0, 1.0).acos().to_degrees();
                    let t = h.z.clamp(-1.0, 1.0).acos().to_degrees();
                    d >= lo && d < hi && t < th
                })
            })
    };
    let pseen: Vec<bool> = pbins.iter().map(|&b| seen(b)).collect();
    println!(
        "# theta_d < {d_max} deg seen (SEEN_BAND {seen_band:?} overrides); stride {stride:?}; {} analytic materials added; env error (whole | extrapolation only)",
        family.len()
    );
    let cols = if knn.is_some() {
        "basis_eta1 basis_eta10 basis_eta40 lggx knn_scaled knn_anchored local_eta10 local_eta40 blend_knn blend_lggx blend3"
    } else {
        "basis_eta1 basis_eta10 basis_eta40 lggx"
    };
    println!("target {cols} | {cols}");
    for target in &targets {
        let settings = BasisSettings {
            stride,
            basis_components: 64,
            exclude: vec![target.clone()],
        };
        let basis = if family.is_empty() {
            load_or_build(&settings, &materials, &default_cache_dir())?.0
        } else {
            // not cached: the cache keys on the neural fits only
            let values: Vec<BrdfValues> = family.iter().map(|(_, m)| BrdfValues(m)).collect();
            let mut list: Vec<(&str, &dyn BinValues)> = materials
                .iter()
                .map(|(n, m)| (n.as_str(), m as &dyn BinValues))
                .collect();
            list.extend(
                family
                    .iter()
                    .zip(&values)
                    .map(|((n, _), v)| (n.as_str(), v as &dyn BinValues)),
            );
            Basis::build(&settings, &list)?
        };
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
        // Lambert + GGX to the same bins, each weighted as the pixels that would see it
        // (solid angle of its block, cos theta_i for image space).
        let samples: Vec<(ReflectanceSample, f64)> = obs
            .iter()
            .filter_map(|o| {
                let b = MerlBin::from_index(bins[o.row])?;
                let (wi, wo) = b.centre_directions();
                Some((
                    ReflectanceSample { wi, wo, rgb: o.rgb },
                    bin_solid_angle(&b).sqrt(),
                ))
            })
            .collect();
        let rs: Vec<ReflectanceSample> = samples.iter().map(|s| s.0).collect();
        let weights: std::collections::HashMap<[u64; 6], f64> = samples
            .iter()
            .map(|(s, w)| {
                (
                    [s.wi.x, s.wi.y, s.wi.z, s.wo.x, s.wo.y, s.wo.z].map(f64::to_bits),
                    *w,
                )
            })
            .collect();
        let lggx = LambertGgx::fit_weighted(&rs, |s| {
            pixel_weight(s)
                * weights
                    .get(&[s.wi.x, s.wi.y, s.wi.z, s.wo.x, s.wo.y, s.wo.z].map(f64::to_bits))
                    .copied()
                    .unwrap_or(0.0)
        })?;
        let t = net.values_at(&pbins);
        let tr = probe.render_values(&t);
        let mut whole = Vec::new();
        let mut extra = Vec::new();
        let mut score = |v: Vec<[f64; 3]>| {
            whole.push(compare(&tr, &probe.render_values(&v)).environment);
            let mixed: Vec<[f64; 3]> = v
                .iter()
                .zip(&t)
                .zip(&pseen)
                .map(|((m, t), &s)| if s { *t } else { *m })
                .collect();
            extra.push(compare(&tr, &probe.render_values(&mixed)).environment);
        };
        // the last of the three, eta 40, is the basis the blends take
        let mut basis40 = Vec::new();
        for eta in [1.0, 10.0, 40.0] {
            let rec = reconstruct(&basis, &obs, &RidgeSettings { k: 64, eta })?;
            basis40 = rec.values_at(&pbins);
            score(basis40.clone());
        }
        let lggx_values: Vec<[f64; 3]> = pbins
            .iter()
            .map(|&b| {
                MerlBin::from_index(b).map_or([0.0; 3], |m| {
                    let (wi, wo) = m.centre_directions();
                    lggx.eval_local(&wi, &wo)
                })
            })
            .collect();
        score(lggx_values.clone());
        if let Some(k) = knn {
            let others: Vec<&(String, brdf_rig::brdf::nbrdf::Nbrdf)> = materials
                .iter()
                .filter(|(n, _)| basis.materials().contains(n))
                .collect();
            let (a, b, near) = knn_extrapolations(&others, &bins, &truth, &pbins, net, &seen, k);
            score(a);
            score(b.clone());
            for eta in [10.0, 40.0] {
                score(local_ridge(&basis, &obs, &others, &near, &pbins, eta)?);
            }
            score(geometric_mean(&[&basis40, &b]));
            score(geometric_mean(&[&basis40, &lggx_values]));
            // the three guesses, each with weight 1/3
            score(geometric_mean(&[&basis40, &b, &lggx_values]));
        }
        println!(
            "{target} {} | {}   (alpha {:.3} f0 {:.3})",
            whole
                .iter()
                .map(|e| format!("{e:.4}"))
                .collect::<Vec<_>>()
                .join(" "),
            extra
                .iter()
                .map(|e| format!("{e:.4}"))
                .collect::<Vec<_>>()
                .join(" "),
            lggx.alpha,
            lggx.f0
        );
    }
    Ok(())
}

/// Session 54 (`KNN=k`, docs/evaluation.md 1ao): the unseen bins from the `k` materials of the
/// basis nearest the seen values (each scaled per channel to the seen energy; distance: mean
/// squared difference of `ln(rho c + eps)` over every 5th seen row), averaged geometrically
/// with weights `1 / distance`. Two ways: `knn_scaled`, the neighbours' scaled values
/// themselves; `knn_anchored`, the seen value at the same theta_h and phi_d and the largest
/// seen theta_d, times the neighbours' ratio between the bin and that anchor. Prints the
/// neighbours to stderr.
fn knn_extrapolations(
    others: &[&(String, brdf_rig::brdf::nbrdf::Nbrdf)],
    rows: &[usize],
    truth_rows: &[[f64; 3]],
    pbins: &[usize],
    truth: &dyn BinValues,
    seen: &dyn Fn(usize) -> bool,
    k: usize,
) -> (Vec<[f64; 3]>, Vec<[f64; 3]>, Vec<Neighbour>) {
    use brdf_rig::brdf::basis::{MAP_EPS, cos_map};
    let fit_rows: Vec<usize> = (0..rows.len())
        .filter(|&r| seen(rows[r]))
        .step_by(5)
        .collect();
    let fit_bins: Vec<usize> = fit_rows.iter().map(|&r| rows[r]).collect();
    let cs: Vec<f64> = fit_bins.iter().map(|&b| cos_map(b)).collect();
    let mut scored: Vec<(f64, [f64; 3], usize)> = others
        .iter()
        .enumerate()
        .map(|(j, (_, net))| {
            let v = net.values_at(&fit_bins);
            let mut scale = [1.0; 3];
            for ch in 0..3 {
                let (mut a, mut b) = (0.0, 0.0);
                for (i, &r) in fit_rows.iter().enumerate() {
                    let c = cs[i];
                    a += truth_rows[r][ch] * c;
                    b += v[i][ch] * c;
                }
                scale[ch] = if b > 0.0 { a / b } else { 1.0 };
            }
            let mut d = 0.0;
            for (i, &r) in fit_rows.iter().enumerate() {
                let c = cs[i];
                for ch in 0..3 {
                    let x = (truth_rows[r][ch].max(0.0) * c + MAP_EPS).ln()
                        - (scale[ch] * v[i][ch].max(0.0) * c + MAP_EPS).ln();
                    d += x * x;
                }
            }
            (d / (3 * fit_rows.len()).max(1) as f64, scale, j)
        })
        .collect();
    scored.sort_by(|a, b| a.0.total_cmp(&b.0));
    scored.truncate(k.max(1));
    let wsum: f64 = scored.iter().map(|s| 1.0 / s.0.max(1e-9)).sum();
    eprintln!(
        "  nearest: {}",
        scored
            .iter()
            .map(|s| format!("{} ({:.3})", others[s.2].0, s.0))
            .collect::<Vec<_>>()
            .join(", ")
    );
    // the anchor of each probe bin: same theta_h and phi_d, the nearest seen theta_d (below
    // first: with everything below a limit seen, the largest seen theta_d)
    let anchor: Vec<Option<usize>> = pbins
        .iter()
        .map(|&bin| {
            let b = MerlBin::from_index(bin)?;
            (0..=b.theta_d)
                .rev()
                .map(|d| MerlBin { theta_d: d, ..b }.index())
                .find(|&a| seen(a))
                .or_else(|| {
                    (b.theta_d..brdf_rig::brdf::coords::THETA_D_BINS)
                        .map(|d| MerlBin { theta_d: d, ..b }.index())
                        .find(|&a| seen(a))
                })
        })
        .collect();
    let anchors: Vec<usize> = anchor.iter().map(|a| a.unwrap_or(0)).collect();
    let mut ga = vec![[0.0f64; 3]; pbins.len()];
    let mut gb = vec![[0.0f64; 3]; pbins.len()];
    for s in &scored {
        let w = 1.0 / s.0.max(1e-9) / wsum;
        let net = &others[s.2].1;
        let v = net.values_at(pbins);
        let va = net.values_at(&anchors);
        for i in 0..pbins.len() {
            for ch in 0..3 {
                ga[i][ch] += w * (s.1[ch] * v[i][ch]).max(1e-9).ln();
                gb[i][ch] += w * (v[i][ch].max(1e-9) / va[i][ch].max(1e-9)).ln();
            }
        }
    }
    let ta = truth.values_at(&anchors);
    let a: Vec<[f64; 3]> = ga.iter().map(|g| g.map(f64::exp)).collect();
    let b: Vec<[f64; 3]> = (0..pbins.len())
        .map(|i| match anchor[i] {
            Some(_) => std::array::from_fn(|ch| ta[i][ch] * gb[i][ch].exp()),
            None => a[i],
        })
        .collect();
    let near: Vec<Neighbour> = scored
        .iter()
        .map(|s| Neighbour {
            weight: 1.0 / s.0.max(1e-9) / wsum,
            scale: s.1,
            index: s.2,
        })
        .collect();
    (a, b, near)
}

/// `NAME=a,b,...`: `n` numbers (degrees), or an error naming the variable; unset: `None`.
fn env_degrees(name: &str, n: usize) -> anyhow::Result<Option<Vec<f64>>> {
    let Ok(v) = std::env::var(name) else {
        return Ok(None);
    };
    let p = v
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<Vec<f64>, _>>()
        .map_err(|e| anyhow::anyhow!("{name}={v}: not a list of numbers ({e})"))?;
    anyhow::ensure!(
        p.len() == n,
        "{name}={v}: {n} numbers expected, got {}",
        p.len()
    );
    Ok(Some(p))
}

/// The bin-by-bin geometric mean of tables with equal weights (negative values as zero).
fn geometric_mean(tables: &[&[[f64; 3]]]) -> Vec<[f64; 3]> {
    let n = tables.len().max(1) as f64;
    (0..tables.first().map_or(0, |t| t.len()))
        .map(|i| {
            std::array::from_fn(|ch| {
                tables
                    .iter()
                    .map(|t| t[i][ch].max(0.0))
                    .product::<f64>()
                    .powf(1.0 / n)
            })
        })
        .collect()
}

/// One of the nearest materials: its weight (summing to 1), its per-channel scale to the seen
/// energy and its index in the basis's materials.
struct Neighbour {
    weight: f64,
    scale: [f64; 3],
    index: usize,
}

/// Session 55 (`KNN=k`, docs/evaluation.md 1ap): the basis's ridge fit shrunk towards the
/// nearest materials instead of towards the basis's mean: `min |A c - b|^2 + eta |c - c0|^2`,
/// `c0` the weighted mean of the neighbours' coefficients (each neighbour scaled per channel to
/// the seen energy, projected on the 64 components; weights as `knn_extrapolations`'). Where
/// the pixels pin the fit it is the basis's; where none do, the neighbours' shape.
fn local_ridge(
    basis: &Basis,
    obs: &[BasisSample],
    others: &[&(String, brdf_rig::brdf::nbrdf::Nbrdf)],
    near: &[Neighbour],
    pbins: &[usize],
    eta: f64,
) -> anyhow::Result<Vec<[f64; 3]>> {
    use nalgebra::{DMatrix, DVector};
    let n = basis.basis_components().min(64);
    let bins = basis.grid().bins().to_vec();
    let mut c0 = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    for nb in near {
        let v: Vec<[f64; 3]> = others[nb.index]
            .1
            .values_at(&bins)
            .iter()
            .map(|x| std::array::from_fn(|ch| x[ch] * nb.scale[ch]))
            .collect();
        let c = basis.project(&v, n);
        for ch in 0..3 {
            for (o, x) in c0[ch].iter_mut().zip(&c[ch]) {
                *o += nb.weight * x;
            }
        }
    }
    // The library's `ridge::NormalSystem` shrinks towards zero only; a shifted target is the same
    // normal equations with `eta c0` added to the right-hand side (shifting the observations
    // instead would go through `Basis::unmap`, which clamps at zero).
    let mut gram = DMatrix::<f64>::zeros(n, n);
    let mut rhs = [
        DVector::<f64>::zeros(n),
        DVector::zeros(n),
        DVector::zeros(n),
    ];
    for o in obs {
        let q = DVector::from_iterator(n, basis.q_row(o.row, n).iter().map(|v| f64::from(*v)));
        gram += &q * q.transpose();
        for (ch, r) in rhs.iter_mut().enumerate() {
            *r += &q * basis.map(o.row, o.rgb[ch]);
        }
    }
    let mut normal = gram;
    for j in 0..n {
        normal[(j, j)] += eta;
    }
    let chol = normal
        .cholesky()
        .ok_or_else(|| anyhow::anyhow!("local ridge: normal matrix not positive definite"))?;
    let coeffs: [Vec<f64>; 3] = std::array::from_fn(|ch| {
        let b = &rhs[ch] + DVector::from_column_slice(&c0[ch]) * eta;
        chol.solve(&b).iter().copied().collect()
    });
    Ok(pbins
        .iter()
        .map(|&bin| {
            basis
                .grid()
                .row_of_bin(bin)
                .map_or([0.0; 3], |row| basis.synthesize_row(&coeffs, row))
        })
        .collect())
}
