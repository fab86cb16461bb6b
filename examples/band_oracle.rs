//! Study (session 33, docs/evaluation.md section 1r): on a simulated scene, how far the basis
//! fit's rendered error moves when the values of some basis rows are replaced by the truth, to
//! tell coverage (which rows the pixels reach) from the values the pixels give there. Neural
//! MERL fits as truth (approximations of MERL, not measured MERL data).
//!
//! `cargo run --release --example band_oracle -- MATERIAL MESH RIG SEED [exact]`
//! (`$SIZE` = `WxH`, default 320x240; scenes written once under `$STUDY_DIR`, default
//! /tmp/band-oracle). The basis fit is the pipeline's (one median sample per basis row of the
//! reliable pixels, ridge weight scaled by rows / 80, k = 64), scored raw (before the
//! plausibility step) by the environment error:
//! - as the pixels give it;
//! - each pixel given the truth at its own directions (its job normal), then the row medians;
//! - each pixel carried to its row's centre by Lambert + GGX's ratio (all three angles; and
//!   read back through the same ratio at every bin); and along theta_d and phi_d only, as
//!   `reconstruct --carry difference` does;
//! - the rows with theta_d 45-55 and theta_h below 10 degrees given the truth at their centre;
//! - every observed row given the truth at its centre (coverage alone);
//! - that, plus every unobserved row of the band given the truth (the band fully seen).
//! - (session 34, section 1t) the rows weighted by how well their pixels agree: the inverse
//!   variance of the row's median in log space (`1.57 MAD^2 / n`, the typical row's spread
//!   for rows of fewer than 3 pixels) plus a floor `s0^2` (0.03, 0.1, 0.3), as integer
//!   duplicates of each row's sample (1 to 40, 4 on average).
//! - (session 35, section 1v) the rows weighted by their pixels' sensitivity to the normal
//!   (errors in the variables); the normals' error estimated from the rows' spread against
//!   that sensitivity; the fit deblurred for a normal tilt of RMS 2-9 degrees
//!   (`reconstruct::deblur`'s step, up to three times), and whether held-out images (every 4th)
//!   can tell the tilt; and (section 1w) the reliable pixels' theta_d percentiles.

use brdf_rig::brdf::basis::{BasisSettings, GridStride};
use brdf_rig::brdf::basis_cache::{default_cache_dir, load_or_build};
use brdf_rig::brdf::coords::MerlBin;
use brdf_rig::brdf::nbrdf::{default_dir, load_dir};
use brdf_rig::brdf::{BinValues, Brdf};
use brdf_rig::eval::{Perturb, Truth, baseline_errors, find_material, observe_case};
use brdf_rig::geometry::mesh_io::load_mesh;
use brdf_rig::geometry::sfm_like::{SfmLikeParams, sfm_like};
use brdf_rig::reconstruct::Job;
use brdf_rig::reconstruct::core::CoreSettings;
use brdf_rig::reconstruct::nielsen::{NielsenPrior, NielsenSettings};
use brdf_rig::reconstruct::observe::{Observation, ObserveSettings, to_local};
use brdf_rig::reconstruct::prior::{Prior, Sample};
use brdf_rig::reconstruct::reliable::select_reliable;
use brdf_rig::reconstruct::trials::dense_samples;
use brdf_rig::sim::job_scene::{SceneSpec, write_scene};
use std::path::PathBuf;

/// theta_h and theta_d of a bin's centre, degrees.
fn angles(bin: usize) -> Option<(f64, f64)> {
    let b = MerlBin::from_index(bin)?;
    let (wi, wo) = b.centre_directions();
    let h = (wi + wo).normalize();
    Some((
        h.z.clamp(-1.0, 1.0).acos().to_degrees(),
        wi.dot(&h).clamp(-1.0, 1.0).acos().to_degrees(),
    ))
}

fn in_band(bin: usize) -> bool {
    angles(bin).is_some_and(|(h, d)| (45.0..55.0).contains(&d) && h < 10.0)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    anyhow::ensure!(args.len() >= 4, "usage: MATERIAL MESH RIG SEED [exact]");
    let (name, mesh_name, rig) = (&args[0], &args[1], &args[2]);
    let seed: u64 = args[3].parse()?;
    let exact = args.get(4).is_some_and(|a| a == "exact");
    let root = PathBuf::from(std::env::var("STUDY_DIR").unwrap_or("/tmp/band-oracle".into()));
    let materials = load_dir(&default_dir())?;
    let net = find_material(&materials, name)?;
    let bs = BasisSettings {
        stride: GridStride::default(),
        basis_components: 64,
        exclude: vec![name.clone()],
    };
    let (basis, _) = load_or_build(&bs, &materials, &default_cache_dir())?;
    let truth = Truth::new(net, 5);
    let file = match mesh_name.as_str() {
        "spot" => "spot_triangulated.obj",
        _ => "stanford-bunny.obj",
    };
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/meshes");
    let (mesh, _) = load_mesh(&data.join(file))?;
    let size = std::env::var("SIZE").unwrap_or("320x240".into());
    let dir = root.join(format!(
        "{mesh_name}-{name}-{rig}-{seed}-{size}{}",
        if exact { "-exact" } else { "" }
    ));
    let job_file = dir.join("job.toml");
    let job = if job_file.exists() {
        Job::from_file(&job_file)?
    } else {
        let mut spec = match rig.as_str() {
            "one-light" => SceneSpec::one_light(30.0),
            _ => SceneSpec::default(),
        };
        let (w, h) = size
            .split_once('x')
            .ok_or_else(|| anyhow::anyhow!("SIZE={size:?}: write WxH"))?;
        spec.width = w.parse()?;
        spec.height = h.parse()?;
        let job_mesh = if exact {
            mesh.clone()
        } else {
            sfm_like(
                &mesh,
                &SfmLikeParams {
                    seed: 7 + seed,
                    ..SfmLikeParams::default()
                },
            )
        };
        write_scene(&dir, &mesh, &job_mesh, net, &spec)?
    };
    let obs = observe_case(&job, &ObserveSettings::default(), &Perturb::default())?;
    let (lam, ggx) = baseline_errors(&truth, &obs);
    let core = CoreSettings::default();
    let reliable = select_reliable(&obs, &core.reliable);
    let prior = NielsenPrior {
        basis: &basis,
        settings: NielsenSettings::default(),
    };
    let samples = dense_samples(&prior, &reliable.pixels, reliable.brightest.as_ref());
    let centre = |s: &Sample| {
        prior
            .row_of(s.bin)
            .map_or(s.bin, |r| basis.grid().bins()[r])
    };
    let at = |bin: usize| net.values_at(&[bin])[0];
    let band_rows: Vec<usize> = (0..basis.n_rows())
        .filter(|&r| in_band(basis.grid().bins()[r]))
        .collect();
    let seen_rows: std::collections::HashSet<usize> =
        samples.iter().filter_map(|s| prior.row_of(s.bin)).collect();
    let seen_band = band_rows.iter().filter(|r| seen_rows.contains(r)).count();
    let band_pixels = reliable
        .pixels
        .iter()
        .filter(|o| {
            prior
                .row_of(o.bin)
                .is_some_and(|r| in_band(basis.grid().bins()[r]))
        })
        .count();
    let truth_band: Vec<Sample> = samples
        .iter()
        .map(|s| {
            let c = centre(s);
            if in_band(c) {
                Sample {
                    bin: c,
                    reflectance: at(c),
                }
            } else {
                *s
            }
        })
        .collect();
    let truth_all: Vec<Sample> = samples
        .iter()
        .map(|s| {
            let c = centre(s);
            Sample {
                bin: c,
                reflectance: at(c),
            }
        })
        .collect();
    // Each pixel given the truth at its own directions (its job normal), then the row medians:
    // what the pixels would give without noise, shading errors or a wrong normal's value.
    let truth_px: Vec<Observation> = reliable
        .pixels
        .iter()
        .map(|o| {
            let (wi, wo) = to_local(&o.normal, &o.light, &o.view);
            Observation {
                reflectance: net.eval_local(&wi, &wo),
                ..*o
            }
        })
        .collect();
    let first = reliable.brightest.as_ref().map(|o| {
        let (wi, wo) = to_local(&o.normal, &o.light, &o.view);
        Observation {
            reflectance: net.eval_local(&wi, &wo),
            ..*o
        }
    });
    let truth_pixels = dense_samples(&prior, &truth_px, first.as_ref());
    // Each pixel carried to its row's centre by Lambert + GGX's ratio (fitted to the same
    // pixels): r * LG(centre) / LG(pixel's directions), channel by channel.
    let lg = brdf_rig::reconstruct::baselines::fit_lambert_ggx(&reliable.pixels)
        .ok_or_else(|| anyhow::anyhow!("no Lambert + GGX"))?;
    let carry = |o: &Observation, model: &dyn Brdf| -> Observation {
        let (wi, wo) = to_local(&o.normal, &o.light, &o.view);
        let c = prior
            .row_of(o.bin)
            .map_or(o.bin, |r| basis.grid().bins()[r]);
        let Some(b) = MerlBin::from_index(c) else {
            return *o;
        };
        let (ci, co) = b.centre_directions();
        let (at_c, at_p) = (model.eval_local(&ci, &co), model.eval_local(&wi, &wo));
        Observation {
            reflectance: std::array::from_fn(|k| {
                if at_p[k] > 0.0 && at_c[k].is_finite() {
                    o.reflectance[k] * at_c[k] / at_p[k]
                } else {
                    o.reflectance[k]
                }
            }),
            ..*o
        }
    };
    let carried: Vec<Observation> = reliable.pixels.iter().map(|o| carry(o, &lg)).collect();
    let carried_first = reliable.brightest.as_ref().map(|o| carry(o, &lg));
    let carried_samples = dense_samples(&prior, &carried, carried_first.as_ref());
    // The library's carry (`reconstruct --carry difference`): theta_d and phi_d only.
    let knob = brdf_rig::reconstruct::carry::CarriedPrior {
        inner: &prior,
        model: lg,
    };
    let knob_samples = dense_samples(&knob, &reliable.pixels, reliable.brightest.as_ref());
    let mut band_full = truth_all.clone();
    for &r in &band_rows {
        if !seen_rows.contains(&r) {
            let c = basis.grid().bins()[r];
            band_full.push(Sample {
                bin: c,
                reflectance: at(c),
            });
        }
    }
    println!(
        "{mesh_name} {name} {rig} seed {seed}{}: {} reliable pixels, {} rows; band theta_d 45-55, theta_h < 10: {} of {} rows seen, {} pixels; Lambert {:.3}, Lambert + GGX {:.3}",
        if exact { " (exact mesh)" } else { "" },
        reliable.pixels.len(),
        samples.len(),
        seen_band,
        band_rows.len(),
        band_pixels,
        lam.map_or(f64::NAN, |e| e.environment),
        ggx.map_or(f64::NAN, |e| e.environment),
    );
    let mut theta_d: Vec<f64> = reliable
        .pixels
        .iter()
        .map(|o| o.angles.theta_d.to_degrees())
        .collect();
    theta_d.sort_by(f64::total_cmp);
    let td = |q: f64| brdf_rig::stats::percentile_sorted(&theta_d, q);
    println!(
        "  reliable pixels' theta_d: p50 {:.1}, p90 {:.1}, p99 {:.1} deg",
        td(0.5),
        td(0.9),
        td(0.99)
    );
    // The carried fit read back at every bin through the same model: the row's value times
    // m(bin) / m(row centre) (the block no longer flat).
    struct Uncarried<'a> {
        fit: &'a dyn brdf_rig::reconstruct::prior::Candidate,
        prior: &'a dyn Prior,
        model: &'a dyn Brdf,
    }
    impl BinValues for Uncarried<'_> {
        fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
            bins.iter()
                .map(|&b| {
                    let v = self.fit.eval_bin(b);
                    let Some(c) = self.prior.row_of(b).and_then(|r| self.prior.row_centre(r))
                    else {
                        return v;
                    };
                    let (Some(bb), Some(cb)) = (MerlBin::from_index(b), MerlBin::from_index(c))
                    else {
                        return v;
                    };
                    let ((bi, bo), (ci, co)) = (bb.centre_directions(), cb.centre_directions());
                    let (mb, mc) = (
                        self.model.eval_local(&bi, &bo),
                        self.model.eval_local(&ci, &co),
                    );
                    std::array::from_fn(|k| {
                        let r = mb[k] / mc[k];
                        if mb[k] > 0.0 && mc[k] > 0.0 && r.is_finite() {
                            v[k] * r.clamp(0.25, 4.0)
                        } else {
                            v[k]
                        }
                    })
                })
                .collect()
        }
    }
    {
        let scale = (carried_samples.len() as f64 / 80.0).max(1.0);
        let mut line = String::new();
        for eta in [1.0, 10.0, 40.0] {
            let fit = prior.fit(&carried_samples, 64, eta * scale)?;
            let u = Uncarried {
                fit: fit.as_ref(),
                prior: &prior,
                model: &lg,
            };
            line += &format!(" {:.3}", truth.errors_of(&u).environment);
        }
        println!(
            "  {:24} env error at eta 1 / 10 / 40:{line}",
            "carried, read uncarried"
        );
    }
    // The raw basis fit's environment error at eta 1, 10 and 40 (scaled by rows / 80).
    let env_line = |samples: &[Sample]| -> anyhow::Result<String> {
        let scale = (samples.len() as f64 / 80.0).max(1.0);
        let mut line = String::new();
        for eta in [1.0, 10.0, 40.0] {
            let fit = prior.fit(samples, 64, eta * scale)?;
            line += &format!(
                " {:.3}",
                truth.errors_of_candidate(fit.as_ref()).environment
            );
        }
        Ok(line)
    };
    // Rows weighted by how well their pixels agree (inverse variance of the row median in log
    // space, with a floor `s0` for what the basis cannot fit), as integer duplicates of each
    // row's sample (the ridge's normal equations sum its samples).
    let weighted = |s0: f64| -> Vec<Sample> {
        let mut by_row: std::collections::BTreeMap<usize, Vec<f64>> = Default::default();
        for o in &reliable.pixels {
            if let Some(r) = prior.row_of(o.bin) {
                let v = o.reflectance.iter().map(|x| x.max(1e-9).ln()).sum::<f64>() / 3.0;
                by_row.entry(r).or_default().push(v);
            }
        }
        let spread = |v: &[f64]| -> Option<f64> {
            if v.len() < 3 {
                return None;
            }
            let mut s = v.to_vec();
            let m = brdf_rig::stats::median(&mut s)?;
            let mut d: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
            brdf_rig::stats::median(&mut d).map(|x| 1.4826 * x)
        };
        let mut all: Vec<f64> = by_row.values().filter_map(|v| spread(v)).collect();
        let typical = brdf_rig::stats::median(&mut all).unwrap_or(0.1);
        let var = |r: usize| -> f64 {
            let v = &by_row[&r];
            let sd = spread(v).unwrap_or(typical);
            s0 * s0 + 1.57 * sd * sd / v.len() as f64
        };
        let ws: Vec<(Sample, f64)> = samples
            .iter()
            .map(|s| {
                let w = prior
                    .row_of(s.bin)
                    .filter(|r| by_row.contains_key(r))
                    .map_or(1.0 / (s0 * s0), |r| 1.0 / var(r));
                (*s, w)
            })
            .collect();
        let mean = ws.iter().map(|x| x.1).sum::<f64>() / ws.len().max(1) as f64;
        ws.iter()
            .flat_map(|(s, w)| {
                let d = ((4.0 * w / mean).round() as usize).clamp(1, 40);
                std::iter::repeat_n(*s, d)
            })
            .collect()
    };
    for s0 in [0.03, 0.1, 0.3] {
        let w = weighted(s0);
        let line = env_line(&w)?;
        println!(
            "  {:24} env error at eta 1 / 10 / 40:{line}",
            format!("rows weighted, s0 {s0}")
        );
    }
    // Rows weighted by how much a wrong normal moves their pixels' values (errors in the
    // variables): the log value's gradient over the normal, from Lambert + GGX, squared and
    // taken as the row's median, times a normal error sigma^2, plus a floor s0^2.
    let sensitivity = |o: &Observation| -> f64 {
        let frame = brdf_rig::render::frame::ShadingFrame::new(o.normal);
        let y = |n: nalgebra::Vector3<f64>| -> f64 {
            let n = n.normalize();
            let (wi, wo) = to_local(&n, &o.light, &o.view);
            let f = lg.eval_local(&wi, &wo);
            let c = n.dot(&o.light).max(1e-3);
            (1e-6 + c * (f[0] + f[1] + f[2]) / 3.0).ln()
        };
        let d = 0.5f64.to_radians();
        let g = |t: nalgebra::Vector3<f64>| (y(o.normal + d * t) - y(o.normal - d * t)) / (2.0 * d);
        g(frame.t).powi(2) + g(frame.b).powi(2)
    };
    let sens_rows = {
        let mut by_row: std::collections::BTreeMap<usize, Vec<f64>> = Default::default();
        for o in &reliable.pixels {
            if let Some(r) = prior.row_of(o.bin) {
                by_row.entry(r).or_default().push(sensitivity(o));
            }
        }
        by_row
            .into_iter()
            .filter_map(|(r, mut v)| brdf_rig::stats::median(&mut v).map(|m| (r, m)))
            .collect::<std::collections::BTreeMap<usize, f64>>()
    };
    {
        let mut all: Vec<f64> = sens_rows.values().map(|x| x.sqrt()).collect();
        all.sort_by(f64::total_cmp);
        let q = |p: f64| all[((all.len() - 1) as f64 * p) as usize];
        println!(
            "  row sensitivity |d ln(f cos)/dn| quartiles: {:.2} {:.2} {:.2}, max {:.2}",
            q(0.25),
            q(0.5),
            q(0.75),
            q(1.0)
        );
    }
    // The normals' error from the pixels' spread: within a row the log values scatter by
    // sigma_n^2 |d ln(f cos)/dn|^2 plus a floor; the slope of the rows' variance on their
    // sensitivity^2 estimates sigma_n^2 (rows of at least 3 pixels; medians over sensitivity
    // deciles, then least squares through them).
    {
        let mut by_row: std::collections::BTreeMap<usize, (Vec<f64>, Vec<f64>)> =
            Default::default();
        for o in &reliable.pixels {
            if let Some(r) = prior.row_of(o.bin) {
                let v = o.reflectance.iter().map(|x| x.max(1e-9)).sum::<f64>() / 3.0;
                let e = by_row.entry(r).or_default();
                e.0.push((v * o.cos_theta_i + 1e-6).ln());
                e.1.push(sensitivity(o));
            }
        }
        let mut pts: Vec<(f64, f64)> = by_row
            .values()
            .filter(|(v, _)| v.len() >= 3)
            .filter_map(|(v, g)| {
                let mut s = v.clone();
                let m = brdf_rig::stats::median(&mut s)?;
                let mut d: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
                let sd = 1.4826 * brdf_rig::stats::median(&mut d)?;
                let mut g = g.clone();
                Some((brdf_rig::stats::median(&mut g)?, sd * sd))
            })
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let n = pts.len();
        let deciles: Vec<(f64, f64)> = (0..10)
            .filter_map(|k| {
                let chunk = &pts[k * n / 10..(k + 1) * n / 10];
                let mut x: Vec<f64> = chunk.iter().map(|p| p.0).collect();
                let mut y: Vec<f64> = chunk.iter().map(|p| p.1).collect();
                Some((
                    brdf_rig::stats::median(&mut x)?,
                    brdf_rig::stats::median(&mut y)?,
                ))
            })
            .collect();
        let m = deciles.len() as f64;
        let (mx, my) = (
            deciles.iter().map(|p| p.0).sum::<f64>() / m,
            deciles.iter().map(|p| p.1).sum::<f64>() / m,
        );
        let sxy: f64 = deciles.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        let sxx: f64 = deciles.iter().map(|p| (p.0 - mx).powi(2)).sum();
        let slope = sxy / sxx;
        println!(
            "  normals' error from the rows' spread: sigma {:.2} deg (slope {slope:.2e}, floor {:.4}, {n} rows); deciles (g^2, var): {}",
            slope.max(0.0).sqrt().to_degrees(),
            my - slope * mx,
            deciles
                .iter()
                .map(|p| format!("({:.2}, {:.4})", p.0, p.1))
                .collect::<Vec<_>>()
                .join(" ")
        );
    }
    for (s0, sigma_deg) in [(0.1, 3.0), (0.1, 6.0), (0.1, 12.0), (0.3, 6.0)] {
        let sigma = f64::to_radians(sigma_deg);
        let ws: Vec<(Sample, f64)> = samples
            .iter()
            .map(|s| {
                let g2 = prior
                    .row_of(s.bin)
                    .and_then(|r| sens_rows.get(&r).copied())
                    .unwrap_or(0.0);
                (*s, 1.0 / (s0 * s0 + sigma * sigma * g2))
            })
            .collect();
        let mean = ws.iter().map(|x| x.1).sum::<f64>() / ws.len().max(1) as f64;
        let w: Vec<Sample> = ws
            .iter()
            .flat_map(|(s, w)| {
                let d = ((4.0 * w / mean).round() as usize).clamp(1, 40);
                std::iter::repeat_n(*s, d)
            })
            .collect();
        let line = env_line(&w)?;
        println!(
            "  {:24} env error at eta 1 / 10 / 40:{line}",
            format!("sens s0 {s0} sigma {sigma_deg}")
        );
    }
    // Deblurring (`reconstruct::deblur`): each row's sample corrected by the current fit's
    // ratio of its value to its value blurred over normal tilts of RMS sigma, and refitted.
    let deblur = |base: &[Sample],
                  sigma: f64,
                  eta: f64,
                  iterations: usize|
     -> anyhow::Result<Vec<Box<dyn brdf_rig::reconstruct::prior::Candidate>>> {
        let scale = (base.len() as f64 / 80.0).max(1.0);
        let mut fit = prior.fit(base, 64, eta * scale)?;
        let mut out = Vec::new();
        for _ in 0..iterations {
            let corrected = brdf_rig::reconstruct::deblur::corrected(fit.as_ref(), base, sigma);
            let next = prior.fit(&corrected, 64, eta * scale)?;
            out.push(std::mem::replace(&mut fit, next));
        }
        out.push(fit);
        Ok(out)
    };
    for sigma_deg in [2.0, 4.0, 6.0, 9.0] {
        let sigma = f64::to_radians(sigma_deg);
        let mut line = String::new();
        for eta in [1.0, 10.0] {
            for fit in deblur(&samples, sigma, eta, 3)?.iter().skip(1) {
                line += &format!(
                    " {:.3}",
                    truth.errors_of_candidate(fit.as_ref()).environment
                );
            }
            line += " |";
        }
        println!(
            "  {:24} env error, 3 iterations at eta 1 | 10:{line}",
            format!("deblurred sigma {sigma_deg}")
        );
    }
    // Can held-out images tell? Every 4th image held out; the rows of the others fitted and
    // deblurred (one iteration, eta 1); the log error on the held-out pixels beside the
    // environment error of the fit to every image.
    {
        let train: Vec<Observation> = reliable
            .pixels
            .iter()
            .filter(|o| o.image % 4 != 0)
            .copied()
            .collect();
        let held: Vec<Observation> = reliable
            .pixels
            .iter()
            .filter(|o| o.image % 4 == 0)
            .copied()
            .collect();
        let train_samples = dense_samples(&prior, &train, None);
        let mut line = String::new();
        for sigma_deg in [0.0, 2.0, 4.0, 6.0, 9.0] {
            let sigma = f64::to_radians(sigma_deg);
            let fits = deblur(&train_samples, sigma, 1.0, 1)?;
            let fit = fits.last().ok_or_else(|| anyhow::anyhow!("no fit"))?;
            let held_err =
                brdf_rig::reconstruct::ladder::log_error(fit.as_ref(), &held).unwrap_or(f64::NAN);
            let all = deblur(&samples, sigma, 1.0, 1)?;
            let env = all.last().map_or(f64::NAN, |f| {
                truth.errors_of_candidate(f.as_ref()).environment
            });
            line += &format!(" {sigma_deg}: {held_err:.4} / {env:.3};");
        }
        println!("  held-out log / env by sigma:{line}");
    }
    for (label, s) in [
        ("pixels", &samples),
        ("pixels' own truth", &truth_pixels),
        ("pixels carried by L+GGX", &carried_samples),
        ("carried (--carry)", &knob_samples),
        ("band rows true", &truth_band),
        ("seen rows true", &truth_all),
        ("seen rows + band true", &band_full),
    ] {
        let line = env_line(s)?;
        println!("  {label:24} env error at eta 1 / 10 / 40:{line}");
    }
    Ok(())
}
