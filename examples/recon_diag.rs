//! Diagnosis of the shiny-material failure (investigation tool): one simulated scene (Spot,
//! default scene), the default pipeline, then oracle fits that remove one cause at a time.
//! Neural MERL fits as truth (approximations of MERL, not measured MERL data).
//!
//! `cargo run --release --example recon_diag -- MATERIAL [NOISE ITER] [WxH] [SEED]`
//! (defaults: the bench's scene: SfM-like noise 0.05, 10 Taubin iterations, 128x96, seed 7;
//! `0 0` gives the exact mesh). Prints: where the truth's E_c weight lies, the peak profile,
//! how many pixels see the peak, the pixel error of the truth itself through the job's normals,
//! the default pipeline and its ablations, the truth flattened below a theta_h (what E_c a
//! perfect fit above that angle gets), and oracle fits to every observed basis row.

use brdf_rig::brdf::basis::{BasisSettings, GridStride};
use brdf_rig::brdf::basis_cache::{default_cache_dir, load_or_build};
use brdf_rig::brdf::coords::MerlBin;
use brdf_rig::brdf::nbrdf::{default_dir, load_dir};
use brdf_rig::brdf::{BinValues, Brdf};
use brdf_rig::eval::{Perturb, Truth, find_material, observe_case, write_case};
use brdf_rig::geometry::mesh_io::load_mesh;
use brdf_rig::geometry::sfm_like::SfmLikeParams;
use brdf_rig::reconstruct::core::{CoreSettings, reconstruct_observations};
use brdf_rig::reconstruct::nielsen::{NielsenPrior, NielsenSettings};
use brdf_rig::reconstruct::observe::{ObserveSettings, to_local};
use brdf_rig::reconstruct::prior::{Prior, Sample};
use brdf_rig::sim::job_scene::SceneSpec;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let material = args.first().cloned().unwrap_or("alum-bronze".into());
    let noise: f64 = args.get(1).map_or(Ok(0.05), |a| a.parse())?;
    let iters: usize = args.get(2).map_or(Ok(10), |a| a.parse())?;
    let (w, h): (usize, usize) = match args.get(3) {
        None => (128, 96),
        Some(a) => {
            let (w, h) = a
                .split_once('x')
                .ok_or_else(|| anyhow::anyhow!("size {a:?} is not WxH"))?;
            (w.parse()?, h.parse()?)
        }
    };
    let seed: u64 = args.get(4).map_or(Ok(7), |a| a.parse())?;
    let materials = load_dir(&default_dir())?;
    let net = find_material(&materials, &material)?;
    let (mesh, _) = load_mesh(
        &std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("data/meshes/spot_triangulated.obj"),
    )?;
    let bs = BasisSettings {
        stride: GridStride::default(),
        basis_components: 64,
        exclude: vec![material.clone()],
    };
    let (basis, _) = load_or_build(&bs, &materials, &default_cache_dir())?;
    let truth = Truth::new(net, 5);
    energy_table(&truth);
    println!("peak profile f (luminance, phi_d 90 deg): theta_h 0 / 0.5 / 1 / 2 deg");
    for td in [30.0f64, 60.0, 75.0] {
        let f = |th: f64| {
            let v = net.eval_angles(
                th.to_radians(),
                td.to_radians(),
                std::f64::consts::FRAC_PI_2,
            );
            (v[0] + v[1] + v[2]) / 3.0
        };
        println!(
            "  theta_d {td:2}: {:.3} / {:.3} / {:.3} / {:.3}",
            f(0.0),
            f(0.5),
            f(1.0),
            f(2.0)
        );
    }
    let dir = tempfile::tempdir()?;
    let sfm = SfmLikeParams {
        seed,
        noise_rel: noise,
        iterations: iters,
        ..SfmLikeParams::default()
    };
    let spec = SceneSpec {
        width: w,
        height: h,
        ..SceneSpec::default()
    };
    {
        // Normal error of the job mesh: angle between true and SfM-like vertex normals.
        let sm = brdf_rig::geometry::sfm_like::sfm_like(&mesh, &sfm);
        let mut a: Vec<f64> = mesh
            .vertex_normals()
            .iter()
            .zip(sm.vertex_normals())
            .map(|(n, m)| n.dot(m).clamp(-1.0, 1.0).acos().to_degrees())
            .collect();
        a.sort_by(f64::total_cmp);
        println!(
            "vertex normal error (deg): median {:.2}, p90 {:.2}",
            a[a.len() / 2],
            a[9 * a.len() / 10]
        );
    }
    let job = write_case(dir.path(), &mesh, &sfm, net, &spec)?;
    let obs = observe_case(&job, &ObserveSettings::default(), &Perturb::default())?;
    println!(
        "# {material}: {} observations ({w}x{h}, noise {noise}, iter {iters})",
        obs.len()
    );

    // (a) the data: how close to the peak, and does the observed r match the truth there?
    let deg = |x: f64| x.to_degrees();
    for lim in [1.0, 2.0, 5.0, 10.0] {
        let n = obs.iter().filter(|o| deg(o.angles.theta_h) < lim).count();
        println!("theta_h < {lim:>4} deg: {n}");
    }
    let truth_at = |o: &brdf_rig::reconstruct::observe::Observation| {
        let (wi, wo) = to_local(&o.normal, &o.light, &o.view);
        net.eval_local(&wi, &wo)
    };
    let lum = |v: [f64; 3]| (v[0] + v[1] + v[2]) / 3.0;
    let mut near: Vec<_> = obs.iter().filter(|o| deg(o.angles.theta_h) < 5.0).collect();
    near.sort_by(|a, b| a.angles.theta_h.total_cmp(&b.angles.theta_h));
    println!(
        "near-peak pixels (SfM normal): theta_h, theta_d, r_obs, f_true(at SfM angles), f_true(bin centre)"
    );
    for o in near.iter().take(12) {
        let c = bin_of(o.bin);
        let fc = net.values_at(&[o.bin])[0];
        println!(
            "  {:6.2} {:6.1} {:10.3} {:10.3} {:10.3}  (bin th {})",
            deg(o.angles.theta_h),
            deg(o.angles.theta_d),
            lum(o.reflectance),
            lum(truth_at(o)),
            lum(fc),
            c.theta_h
        );
    }
    let rmax = obs.iter().map(|o| lum(o.reflectance)).fold(0.0, f64::max);
    let tmax = truth.values.iter().map(|v| lum(*v)).fold(0.0, f64::max);
    println!("max observed r {rmax:.2}, max truth over eval bins {tmax:.2}");
    // How wrong the geometry is overall: r_obs / f_true at the SfM angles.
    let ratios: Vec<f64> = obs
        .iter()
        .map(|o| lum(o.reflectance) / lum(truth_at(o)).max(1e-9))
        .collect();
    let mut s = ratios.clone();
    s.sort_by(f64::total_cmp);
    println!(
        "r_obs / f_true(SfM angles): median {:.3}, p10 {:.3}, p90 {:.3}",
        s[s.len() / 2],
        s[s.len() / 10],
        s[9 * s.len() / 10]
    );

    // The floor of the held-out error: the truth itself, seen through the job's normals.
    let (mut num, mut den) = (0.0, 0.0);
    for o in &obs {
        let f = truth_at(o);
        for (fc, rc) in f.iter().zip(o.reflectance) {
            num += (o.cos_theta_i * (fc - rc)).powi(2);
            den += (o.cos_theta_i * rc).powi(2);
        }
    }
    println!(
        "pixel error of the truth itself (job normals): {:.3}",
        (num / den).sqrt()
    );
    let truth_bins = brdf_rig::reconstruct::components::held_out_error(&NetCandidate(net), &obs);
    println!("pixel error of the truth at bin centres: {truth_bins:.3}");

    // Default pipeline.
    let prior = NielsenPrior {
        basis: &basis,
        settings: NielsenSettings::default(),
    };
    let core = CoreSettings::default();
    let out = reconstruct_observations(&obs, &prior, &core, &mut |_| {})?;
    let e = truth.errors_of_candidate(out.brdf.as_ref());
    println!(
        "\ndefault pipeline: k {} eta {} E_c {:.3} E {:.3} E_s {:.3}",
        out.components.k, out.components.eta, e.cosine_weighted, e.relative, e.near_specular
    );
    for p in &out.components.curve {
        print!(
            " k{}/eta{}: {:.3};",
            p.k,
            p.eta,
            p.error.unwrap_or(f64::NAN)
        );
    }
    println!();
    let samples = &out.trials[out.chosen_trial].samples;
    let ns = samples
        .iter()
        .filter(|s| bin_of(s.bin).theta_h < 21)
        .count();
    println!(
        "chosen trial: {} samples, {ns} with theta_h bin < 21 (5.4 deg)",
        samples.len()
    );
    println!("prediction of the chosen fit for near-peak pixels: r_obs, f_pred");
    for o in near.iter().take(8) {
        println!(
            "  {:6.2} {:10.3} {:10.3}",
            deg(o.angles.theta_h),
            lum(o.reflectance),
            lum(out.brdf.eval_bin(o.bin))
        );
    }

    // Ablations of the pipeline's own choices.
    for (name, f) in [
        (
            "no brightest",
            &(|c: &mut CoreSettings| c.reliable.use_brightest = false)
                as &dyn Fn(&mut CoreSettings),
        ),
        ("no curvature", &|c: &mut CoreSettings| {
            c.reliable.use_curvature = false
        }),
        ("no monotonicity", &|c: &mut CoreSettings| {
            c.reliable.use_monotonicity = false
        }),
        ("none of the three", &|c: &mut CoreSettings| {
            c.reliable = brdf_rig::reconstruct::reliable::ReliableSettings::none()
        }),
        ("160 samples", &|c: &mut CoreSettings| {
            c.trials.samples = 160
        }),
    ] {
        let mut c = CoreSettings::default();
        f(&mut c);
        let out = reconstruct_observations(&obs, &prior, &c, &mut |_| {})?;
        let e = truth.errors_of_candidate(out.brdf.as_ref());
        let ho = out.confidence.held_out_error.unwrap_or(f64::NAN);
        println!(
            "{name:20} k {:2} eta {:4}: E_c {:.3} (held-out {ho:.3})",
            out.components.k, out.components.eta, e.cosine_weighted
        );
    }
    // How much of E_c the sub-degree peak carries: the truth with its theta_h < X bins replaced
    // by the value at the first bin at or above X (a perfect fit with a flat-topped peak).
    for lim in [0.5f64, 1.0, 2.0] {
        let vals: Vec<[f64; 3]> = truth
            .bins
            .iter()
            .map(|&b| {
                let m = bin_of(b);
                if m.centre().theta_h.to_degrees() < lim {
                    let mut m2 = m;
                    while m2.centre().theta_h.to_degrees() < lim {
                        m2.theta_h += 1;
                    }
                    net.values_at(&[m2.index()])[0]
                } else {
                    net.values_at(&[b])[0]
                }
            })
            .collect();
        let e = brdf_rig::brdf::metrics::compare_values(&truth.bins, &truth.values, &vals);
        println!(
            "truth flattened below theta_h {lim} deg: E_c {:.3}",
            e.cosine_weighted
        );
    }

    // Oracle fits: all observations as samples (one per row: the first), ridge at a grid.
    let mut seen = std::collections::HashMap::new();
    for o in &obs {
        if let Some(r) = prior.row_of(o.bin) {
            seen.entry(r).or_insert(*o);
        }
    }
    let all_obs: Vec<Sample> = seen
        .values()
        .map(|o| Sample {
            bin: o.bin,
            reflectance: o.reflectance,
        })
        .collect();
    let all_truth_centre: Vec<Sample> = seen
        .keys()
        .map(|&row| {
            let bin = basis.grid().bins()[row];
            Sample {
                bin,
                reflectance: net.values_at(&[bin])[0],
            }
        })
        .collect();
    let every_row: Vec<Sample> = basis
        .grid()
        .bins()
        .iter()
        .map(|&b| Sample {
            bin: b,
            reflectance: net.values_at(&[b])[0],
        })
        .collect();
    println!(
        "\noracles ({} observed rows of {}): E_c by (k, eta)",
        all_obs.len(),
        basis.n_rows()
    );
    for (name, ss) in [
        ("observed r, every observed row", &all_obs),
        ("true f at row centre, observed rows", &all_truth_centre),
        ("true f at every row", &every_row),
    ] {
        print!("{name:40}");
        for k in [5, 10, 20, 40] {
            for eta in [0.1, 1.0, 40.0] {
                let c = prior.fit(ss, k, eta).map_err(anyhow::Error::msg)?;
                let e = truth.errors_of_candidate(c.as_ref());
                print!(" {k}/{eta}:{:.3}", e.cosine_weighted);
            }
        }
        println!();
    }
    Ok(())
}

/// Where the truth's cosine-weighted energy lies (the denominator of E_c), by theta_h and theta_d.
fn energy_table(truth: &Truth) {
    use brdf_rig::brdf::basis::cos_map;
    let th_edges = [0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 90.1];
    let td_edges = [0.0, 30.0, 60.0, 70.0, 80.0, 85.0, 90.1];
    let mut e = [[0.0f64; 6]; 6];
    let mut tot = 0.0;
    for (&bin, t) in truth.bins.iter().zip(&truth.values) {
        let b = bin_of(bin);
        if !b.is_above_horizon() {
            continue;
        }
        let c = b.centre();
        let w = cos_map(bin);
        let v: f64 = t.iter().map(|x| (w * x).powi(2)).sum();
        let i = th_edges
            .iter()
            .rposition(|&x| c.theta_h.to_degrees() >= x)
            .map_or(0, |i| i.min(5));
        let j = td_edges
            .iter()
            .rposition(|&x| c.theta_d.to_degrees() >= x)
            .map_or(0, |i| i.min(5));
        e[i][j] += v;
        tot += v;
    }
    println!("share of sum (c t)^2: rows theta_h {th_edges:?}, cols theta_d {td_edges:?}");
    for (i, row) in e.iter().enumerate() {
        print!("  th>={:5}:", th_edges[i]);
        for x in row {
            print!(" {:6.3}", x / tot);
        }
        println!();
    }
}

struct NetCandidate<'a>(&'a brdf_rig::brdf::nbrdf::Nbrdf);
impl brdf_rig::reconstruct::prior::Candidate for NetCandidate<'_> {
    fn eval_bin(&self, bin: usize) -> [f64; 3] {
        self.0.values_at(&[bin])[0]
    }
}

/// A flat MERL index the pipeline produced (always in range).
#[allow(clippy::expect_used)] // an invariant: the index came from a MerlBin
fn bin_of(index: usize) -> MerlBin {
    MerlBin::from_index(index).expect("MERL indices from observations and the truth are in range")
}
