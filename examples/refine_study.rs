//! Normal refinement study (investigation tool, issue #12): one simulated scene, the
//! refinement run with several settings, the vertex-normal error against the truth before and
//! after, and the held-out image error it saw; plus the same held-out error with the true
//! normals (how much the objective could gain). Neural MERL fits as truth (approximations of
//! MERL, not measured MERL data).
//!
//! `cargo run --release --example refine_study -- MATERIAL MESH RIG WxH SEED [VARIANT...]`
//! MESH: spot | bunny; RIG: spread | one30; a VARIANT is `key=value,...` over
//! iters, sweeps, step, tilt, sigma, smooth, smooth_normals, anchor, cg, cgtol, minpx, gain, movecos,
//! fitcos, facecap, final, passes, margin, holdout, depth (0/1), dsigma, dcg, dsweeps, starts (a list: `starts=0/2/4`),
//! bins (the reflectance table's shape: `bins=32x16x8`), and `from_truth=1` (start from the true vertex normals on the
//! SfM-like mesh's positions: how far the objective's own minimum lies from the truth), and
//! `true_pos=1` (the true positions under the SfM-like normals: the pixels land where they
//! should; with `from_truth=1`, the truth on the true positions), and `blend=F` (start from
//! the SfM-like normals turned a fraction F of the way to the true ones: does the refinement
//! keep a share of any start's error?)
//! (e.g. `smooth=5,anchor=40`); no variant = the defaults.
//! An argument `scene:KEY=VALUE,...` (anywhere after SEED) sets the scene instead: `views`
//! (11), `sfm_iters` (the SfM-like mesh's Taubin iterations, 10), `sfm_noise` (its depth
//! noise in mean edges, 0.05), so the two parts of the degradation can be studied apart, and
//! `below=1` (the spread rig's light also from below, `SceneSpec::light_from_below`). The
//! tool prints how far the SfM-like mesh's vertices lie from the true ones, in mean edges.

use brdf_rig::brdf::nbrdf::{default_dir, load_dir};
use brdf_rig::eval::{Perturb, find_material, load_case, refine_case, write_case};
use brdf_rig::geometry::mesh_io::load_mesh;
use brdf_rig::geometry::sfm_like::{SfmLikeParams, mean_edge_length, sfm_like};
use brdf_rig::reconstruct::observe::ObserveSettings;
use brdf_rig::reconstruct::refine::{RefineSettings, TableBins};
use brdf_rig::sim::job_scene::SceneSpec;
use std::time::Instant;

fn variant(spec: &str) -> anyhow::Result<RefineSettings> {
    let mut s = RefineSettings::default();
    for kv in spec.split(',').filter(|x| !x.is_empty()) {
        let (k, v) = kv
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("{kv:?} is not key=value"))?;
        if k == "starts" {
            // a list: `starts=0/2/4`
            s.start_smoothing = v
                .split('/')
                .map(str::parse)
                .collect::<Result<Vec<usize>, _>>()?;
            continue;
        }
        if k == "bins" {
            // the reflectance table's shape: `bins=48x32x8` (theta_h x theta_d x phi_d)
            let b = v
                .split('x')
                .map(str::parse)
                .collect::<Result<Vec<usize>, _>>()
                .map_err(|e| anyhow::anyhow!("bins={v}: {e}"))?;
            let [theta_h, theta_d, phi_d] = b[..] else {
                anyhow::bail!("bins={v}: three counts HxDxP");
            };
            s.table_bins = TableBins {
                theta_h,
                theta_d,
                phi_d,
            };
            continue;
        }
        let f: f64 = v.parse()?;
        match k {
            "iters" => s.max_iterations = f as usize,
            "sweeps" => s.sweeps = f as usize,
            "step" => s.step = f,
            "tilt" => s.max_tilt_deg = f,
            "sigma" => s.residual_sigma = f,
            "smooth" => s.smooth_deg = f,
            "smooth_normals" => s.smooth_normals = f,
            "anchor" => s.anchor_deg = f,
            "cg" => s.cg_iterations = f as usize,
            "cgtol" => s.cg_tolerance = f,
            "minpx" => s.min_pixels_per_vertex = f as usize,
            "gain" => s.min_gain = f,
            "movecos" => s.move_min_cos = f,
            "fitcos" => s.fit_min_cos = f,
            "facecap" => s.max_pixels_per_face = f as usize,
            "final" => s.final_alternations = f as usize,
            "passes" => s.table_passes = f as usize,
            "margin" => s.edge_margin_px = f as usize,
            "holdout" => s.hold_out_every = f as usize,
            "depth" => s.depth = f != 0.0,
            "dsigma" => s.depth_sigma_edges = f,
            "dcg" => s.depth_cg_iterations = f as usize,
            "dsweeps" => s.depth_sweeps = f as usize,
            _ => anyhow::bail!("unknown key {k:?}"),
        }
    }
    Ok(s)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let arg = |i: usize, d: &str| args.get(i).cloned().unwrap_or_else(|| d.to_string());
    let material = arg(0, "alum-bronze");
    let mesh_name = arg(1, "spot");
    let rig = arg(2, "spread");
    let size = arg(3, "320x240");
    let seed: u64 = arg(4, "0").parse()?;
    let (w, h) = size
        .split_once('x')
        .ok_or_else(|| anyhow::anyhow!("size {size:?} is not WxH"))?;
    let (scene_keys, mut variants): (Vec<String>, Vec<String>) = args
        .iter()
        .skip(5)
        .cloned()
        .partition(|a| a.starts_with("scene:"));
    if variants.is_empty() {
        variants.push(String::new());
    }
    let mut views = 11;
    let mut below = false;
    let mut sfm = SfmLikeParams {
        seed: 7 + seed,
        ..SfmLikeParams::default()
    };
    for kv in scene_keys
        .iter()
        .flat_map(|a| a.trim_start_matches("scene:").split(','))
        .filter(|x| !x.is_empty())
    {
        let (k, v) = kv
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("scene key {kv:?} is not key=value"))?;
        let bad = |e: &dyn std::fmt::Display| anyhow::anyhow!("scene key {kv:?}: {e}");
        match k {
            "views" => views = v.parse().map_err(|e| bad(&e))?,
            "sfm_iters" => sfm.iterations = v.parse().map_err(|e| bad(&e))?,
            "sfm_noise" => sfm.noise_rel = v.parse().map_err(|e| bad(&e))?,
            "below" => below = v == "1",
            other => {
                anyhow::bail!("unknown scene key {other:?} (views, sfm_iters, sfm_noise, below)")
            }
        }
    }
    let materials = load_dir(&default_dir())?;
    let net = find_material(&materials, &material)?;
    let data = brdf_rig::data::data_dir().join("meshes");
    let file = match mesh_name.as_str() {
        "spot" => data.join("spot_triangulated.obj"),
        "bunny" => data.join("stanford-bunny.obj"),
        other => other.into(),
    };
    let (mesh, _) = load_mesh(&file)?;
    let base = match rig.as_str() {
        "spread" => SceneSpec::default(),
        "one30" => SceneSpec::one_light(30.0),
        other => anyhow::bail!("unknown rig {other:?}"),
    };
    let spec = SceneSpec {
        views,
        light_from_below: below,
        width: w.parse()?,
        height: h.parse()?,
        ..base
    };
    {
        // how far the degradation moves the vertices (the pixels land that far off)
        let e = mean_edge_length(&mesh);
        let moved = sfm_like(&mesh, &sfm);
        let mut d: Vec<f64> = mesh
            .positions()
            .iter()
            .zip(moved.positions())
            .map(|(a, b)| (a - b).norm() / e)
            .collect();
        d.sort_by(f64::total_cmp);
        if let (Some(mid), Some(p90)) = (d.get(d.len() / 2), d.get(d.len() * 9 / 10)) {
            println!(
                "SfM-like mesh ({} Taubin iterations, depth noise {} edges): vertices off the \
                 truth by a median {mid:.3} and a 90th percentile {p90:.3} mean edges",
                sfm.iterations, sfm.noise_rel
            );
        }
    }
    let dir = tempfile::tempdir()?;
    let job = write_case(dir.path(), &mesh, &sfm, net, &spec)?;
    let observe = ObserveSettings::default();
    // The objective's headroom: the held-out error with the true normals.
    {
        let mut scene = load_case(&job, &observe, &Perturb::default())?;
        scene.mesh = mesh.clone();
        let s = RefineSettings {
            max_iterations: 1,
            ..RefineSettings::default()
        };
        let c = refine_case(scene, &observe, &s, None, &mesh);
        if let Some(st) = c.study {
            println!(
                "true normals: held-out error {:.4} (training {:.4})",
                st.report.iterations[0].held_out_error, st.report.iterations[0].train_error
            );
        }
    }
    for v in &variants {
        // `from_truth` (a key of its own): the SfM-like mesh with the true vertex normals, to
        // see whether the objective's minimum stays at the truth.
        let from_truth = v.split(',').any(|kv| kv == "from_truth=1");
        let true_pos = v.split(',').any(|kv| kv == "true_pos=1");
        let spec: Vec<&str> = v
            .split(',')
            .filter(|kv| *kv != "from_truth=1" && *kv != "true_pos=1" && !kv.starts_with("blend="))
            .collect();
        let blend: Option<f64> = v
            .split(',')
            .find_map(|kv| kv.strip_prefix("blend="))
            .map(str::parse)
            .transpose()
            .map_err(|e| anyhow::anyhow!("{v:?}: blend: {e}"))?;
        let s = variant(&spec.join(","))?;
        let mut scene = load_case(&job, &observe, &Perturb::default())?;
        if from_truth
            && !scene
                .mesh
                .set_vertex_normals(mesh.vertex_normals().to_vec())
        {
            anyhow::bail!("the true mesh's normals do not fit the scene's mesh");
        }
        if let Some(f) = blend {
            let n: Vec<_> = scene
                .mesh
                .vertex_normals()
                .iter()
                .zip(mesh.vertex_normals())
                .map(|(a, b)| (a * (1.0 - f) + b * f).try_normalize(1e-12).unwrap_or(*a))
                .collect();
            if !scene.mesh.set_vertex_normals(n) {
                anyhow::bail!("the true mesh's normals do not fit the scene's mesh");
            }
        }
        if true_pos {
            // the true positions under the SfM-like normals: how far the refinement gets when the
            // pixels land where they should
            let n = scene.mesh.vertex_normals().to_vec();
            if !(scene.mesh.set_positions(mesh.positions().to_vec())
                && scene.mesh.set_vertex_normals(n))
            {
                anyhow::bail!("the true mesh's positions do not fit the scene's mesh");
            }
        }
        let t = Instant::now();
        let c = refine_case(scene, &observe, &s, None, &mesh);
        let secs = t.elapsed().as_secs_f64();
        let Some(st) = c.study else {
            println!("{v:?}: no study");
            continue;
        };
        let its: Vec<String> = st
            .report
            .iterations
            .iter()
            .map(|i| format!("{:.4}/{:.4}", i.train_error, i.held_out_error))
            .collect();
        let starts: Vec<String> = st
            .report
            .starts
            .iter()
            .map(|x| format!("{}:{:.4}", x.smoothing_iterations, x.held_out_error))
            .collect();
        println!(
            "{v:?}: start {} of [{}]; normal error median {:.2} -> {:.2} (mean {:.2} -> {:.2}), accepted {} ({} it), \
             train/held {}, {secs:.1} s (refinement {:.1} s on {} of {} pixels)",
            st.report.chosen_start_smoothing,
            starts.join(" "),
            st.median_before_deg,
            st.median_after_deg,
            st.mean_before_deg,
            st.mean_after_deg,
            st.report.accepted,
            st.report.chosen_iterations,
            its.join(" "),
            st.report.seconds,
            st.report.pixels,
            st.report.pixels_offered,
        );
    }
    Ok(())
}
