//! The model ladder and the plausibility step, studied against the truth (investigation tool,
//! not a benchmark): for each simulated scene, every family's final fit is made plausible
//! with several shrink settings and scored by the rendered environment error, and the ladder's
//! held-out scores are read with each choice rule. Neural MERL fits as truth (approximations of
//! MERL, not measured MERL data).
//!
//! `cargo run --release --example ladder_study -- [MATERIALS] [MESHES] [RIGS] [SEEDS]`
//! (comma lists; defaults: the paper's six, spot,bunny, spread,one-light, 1). Scenes are
//! written once to `$STUDY_DIR` (default /tmp/ladder-study) and reused; `$SIZE` (`WxH`,
//! default 128x96) sets their light images' size. With `DIAG=1`, per scene also: where in
//! (theta_h, theta_d) the rendered error lies (each region set to the truth in turn), the
//! pixels in the grazing peak, a per-cell correction of the table by its pixels' residuals,
//! the families' training error weighted by each cell's share of the render, and cell-wise
//! blends with Lambert + GGX by the cell's pixel count (docs/evaluation.md section 1n). With
//! `AVG_HYBRID=1`, where the basis was chosen: the written table averaged (geometrically) with
//! the basis + peak at several weights (section 1o).

use brdf_rig::brdf::BinValues;
use brdf_rig::brdf::basis::{BasisSettings, GridStride};
use brdf_rig::brdf::basis_cache::{default_cache_dir, load_or_build};
use brdf_rig::brdf::coords::MerlBin;
use brdf_rig::brdf::merl::MerlTable;
use brdf_rig::brdf::nbrdf::{default_dir, load_dir};
use brdf_rig::eval::{
    PAPER_MATERIALS, Perturb, Truth, baseline_errors, find_material, observe_case,
};
use brdf_rig::geometry::mesh_io::load_mesh;
use brdf_rig::geometry::sfm_like::{SfmLikeParams, sfm_like};
use brdf_rig::reconstruct::Job;
use brdf_rig::reconstruct::core::{CoreSettings, reconstruct_observations};
use brdf_rig::reconstruct::ladder::{AnalyticCandidate, ChoiceRule, Family, choose};
use brdf_rig::reconstruct::nielsen::{NielsenPrior, NielsenSettings};
use brdf_rig::reconstruct::observe::{Observation, ObserveSettings};
use brdf_rig::reconstruct::plausible::{PlausibleSettings, make_plausible};
use brdf_rig::reconstruct::prior::{Candidate, CandidateValues};
use brdf_rig::reconstruct::reliable::select_reliable;
use brdf_rig::sim::job_scene::{SceneSpec, write_scene};
use std::path::PathBuf;

fn list(arg: Option<&String>, default: &[&str]) -> Vec<String> {
    arg.map_or_else(
        || default.iter().map(|s| s.to_string()).collect(),
        |a| a.split(',').map(str::to_string).collect(),
    )
}

/// One scene's row: scene, rig, the better baseline's error, every family's errors per
/// variant, and each choice rule's pick.
type Row = (
    String,
    String,
    f64,
    Vec<(Family, Vec<f64>)>,
    Vec<(String, Family)>,
);

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let materials_wanted = list(args.first(), &PAPER_MATERIALS);
    let meshes = list(args.get(1), &["spot", "bunny"]);
    let rigs = list(args.get(2), &["spread", "one-light"]);
    let seeds: u64 = args.get(3).map_or(Ok(1), |a| a.parse())?;
    let root = PathBuf::from(std::env::var("STUDY_DIR").unwrap_or("/tmp/ladder-study".into()));
    let materials = load_dir(&default_dir())?;
    let data = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/meshes");
    // (label, shrink settings); `None` = as fitted.
    let variants: Vec<(String, Option<PlausibleSettings>)> = {
        let mut v = vec![("fitted".to_string(), None)];
        v.push((
            "albedo only".to_string(),
            Some(PlausibleSettings {
                shrink: false,
                ..Default::default()
            }),
        ));
        for (l, rs) in [(6.0, vec![3.0, 10.0, 30.0])] {
            for r in rs {
                v.push((
                    format!("L{l} R{r}"),
                    Some(PlausibleSettings {
                        shrink_length_bins: l,
                        prior_ratio_limit: r,
                        ..Default::default()
                    }),
                ));
            }
        }
        v
    };
    let mut rows: Vec<Row> = Vec::new();
    let mut blends: Vec<(String, f64, Vec<f64>)> = Vec::new();
    let mut locals: Vec<(String, f64, Vec<f64>)> = Vec::new();
    let mut hybrids: Vec<(String, f64, Vec<f64>)> = Vec::new();
    let mut dump: Vec<serde_json::Value> = Vec::new();
    for name in &materials_wanted {
        let net = find_material(&materials, name)?;
        let bs = BasisSettings {
            stride: GridStride::default(),
            basis_components: 64,
            exclude: vec![name.clone()],
        };
        let (basis, _) = load_or_build(&bs, &materials, &default_cache_dir())?;
        let truth = Truth::new(net, 5);
        for mesh_name in &meshes {
            let file = match mesh_name.as_str() {
                "spot" => "spot_triangulated.obj",
                _ => "stanford-bunny.obj",
            };
            let (mesh, _) = load_mesh(&data.join(file))?;
            for rig in &rigs {
                for seed in 0..seeds {
                    let dir = root.join(format!("{mesh_name}-{name}-{rig}-{seed}"));
                    let job_file = dir.join("job.toml");
                    let job = if job_file.exists() {
                        Job::from_file(&job_file)?
                    } else {
                        let mut spec = match rig.as_str() {
                            "one-light" => SceneSpec::one_light(30.0),
                            _ => SceneSpec::default(),
                        };
                        if let Ok(size) = std::env::var("SIZE") {
                            let (w, h) = size
                                .split_once('x')
                                .ok_or_else(|| anyhow::anyhow!("SIZE={size:?}: write WxH"))?;
                            spec.width = w.parse()?;
                            spec.height = h.parse()?;
                        }
                        let sfm = sfm_like(
                            &mesh,
                            &SfmLikeParams {
                                seed: 7 + seed,
                                ..SfmLikeParams::default()
                            },
                        );
                        write_scene(&dir, &mesh, &sfm, net, &spec)?
                    };
                    let obs = observe_case(&job, &ObserveSettings::default(), &Perturb::default())?;
                    let (lam, ggx) = baseline_errors(&truth, &obs);
                    let better = match (lam, ggx) {
                        (Some(a), Some(b)) => a.environment.min(b.environment),
                        (a, b) => a.or(b).map_or(f64::NAN, |e| e.environment),
                    };
                    let mut core = CoreSettings {
                        keep_alternatives: true,
                        ..CoreSettings::default()
                    };
                    core.trials.seed += seed;
                    let prior = NielsenPrior {
                        basis: &basis,
                        settings: NielsenSettings::default(),
                    };
                    let out = reconstruct_observations(&obs, &prior, &core, &mut |_| {})?;
                    let reliable = select_reliable(&obs, &core.reliable);
                    let used: Vec<&Observation> = reliable
                        .pixels
                        .iter()
                        .chain(reliable.brightest.as_ref())
                        .collect();
                    let lggx = out.alternatives.iter().find(|a| a.0 == Family::LambertGgx);
                    let ggx_model =
                        brdf_rig::reconstruct::baselines::fit_lambert_ggx(&reliable.pixels)
                            .map(AnalyticCandidate);
                    let mut fams: Vec<(Family, &dyn Candidate)> = out
                        .alternatives
                        .iter()
                        .map(|(f, c)| (*f, c.as_ref()))
                        .collect();
                    fams.push((out.model.family, out.brdf.as_ref()));
                    let _ = lggx;
                    let mut per_family = Vec::new();
                    for (f, c) in &fams {
                        let mut errs = Vec::new();
                        for (_, v) in &variants {
                            let e = match v {
                                None => truth.errors_of_candidate(*c).environment,
                                Some(ps) => {
                                    let (t, _) = make_plausible(
                                        *c,
                                        ggx_model
                                            .as_ref()
                                            .filter(|_| matches!(f, Family::Basis | Family::Hybrid))
                                            .map(|p| (p as &dyn Candidate, "L+GGX")),
                                        &used,
                                        ps,
                                    );
                                    truth.errors_of(&t).environment
                                }
                            };
                            errs.push(e);
                        }
                        per_family.push((*f, errs));
                    }
                    // Blends of the chosen model's plausible table with Lambert + GGX's.
                    {
                        let ps = PlausibleSettings::default();
                        let (chosen_t, _) = make_plausible(
                            out.brdf.as_ref(),
                            ggx_model.as_ref().map(|p| (p as &dyn Candidate, "L+GGX")),
                            &used,
                            &ps,
                        );
                        if std::env::var("AVG_HYBRID").is_ok()
                            && out.model.family == Family::Basis
                            && let Some((_, hy)) =
                                out.alternatives.iter().find(|a| a.0 == Family::Hybrid)
                        {
                            let (hy_t, _) = make_plausible(
                                hy.as_ref(),
                                ggx_model.as_ref().map(|p| (p as &dyn Candidate, "L+GGX")),
                                &used,
                                &ps,
                            );
                            let mut line = String::new();
                            let mut errs = vec![truth.errors_of(&out.table).environment];
                            for w in [0.75, 0.5, 0.25] {
                                let b = Blend {
                                    a: &out.table,
                                    b: &hy_t,
                                    w,
                                    geo: true,
                                };
                                let e = truth.errors_of(&b).environment;
                                line += &format!(" {e:.3}");
                                errs.push(e);
                            }
                            eprintln!(
                                "   basis with basis + peak, geometric, basis weight .75/.5/.25:{line} (written {:.3})",
                                errs[0]
                            );
                            hybrids.push((rig.clone(), better, errs));
                        }
                        if let Some((_, lg)) =
                            out.alternatives.iter().find(|a| a.0 == Family::LambertGgx)
                        {
                            let (lg_t, _) = make_plausible(lg.as_ref(), None, &used, &ps);
                            let mut line = String::new();
                            let mut errs = Vec::new();
                            for geo in [false, true] {
                                let u = out.confidence.unseen_energy;
                                for w in
                                    [1.0, 1.0 - 0.25 * u, 1.0 - 0.5 * u, 1.0 - 0.75 * u, 1.0 - u]
                                {
                                    let b = Blend {
                                        a: &chosen_t,
                                        b: &lg_t,
                                        w,
                                        geo,
                                    };
                                    let e = truth.errors_of(&b).environment;
                                    line += &format!(" {e:.3}");
                                    errs.push(e);
                                }
                                line += " |";
                            }
                            eprintln!(
                                "   blend chosen {} unseen {:.2} w 1-c*u c 0/.25/.5/.75/1 arith | geo:{line}",
                                out.model.family, out.confidence.unseen_energy
                            );
                            blends.push((rig.clone(), better, errs));
                            if std::env::var("DIAG").is_ok() {
                                let fams: Vec<(String, &dyn Candidate)> =
                                    fams.iter().map(|(f, c)| (f.to_string(), *c)).collect();
                                let hedged =
                                    out.plausibility.hedge.map_or(0.0, |h| h.analytic_weight);
                                let errs = diagnose(&Diag {
                                    truth: &truth,
                                    net,
                                    table: &out.table,
                                    analytic: &lg_t,
                                    ggx: ggx_model.as_ref().map(|m| m as &dyn Candidate),
                                    families: &fams,
                                    used: &used,
                                    hedged,
                                });
                                locals.push((rig.clone(), better, errs));
                            }
                        }
                    }
                    let mut choices = Vec::new();
                    if let Some(l) = &out.ladder {
                        for (label, rule) in [
                            ("1se", ChoiceRule::OneStandardError),
                            ("paired", ChoiceRule::Paired),
                        ] {
                            if let Some((i, _)) = choose(&l.rungs, rule) {
                                choices.push((label.to_string(), l.rungs[i].family));
                            }
                        }
                        let best = l.rungs.iter().filter(|r| r.error.is_some()).min_by(|a, b| {
                            a.error.unwrap_or(1e9).total_cmp(&b.error.unwrap_or(1e9))
                        });
                        if let Some(b) = best {
                            choices.push(("min".to_string(), b.family));
                        }
                    }
                    let label = format!("{mesh_name} {name} {rig} {seed}");
                    eprintln!("{label}: better baseline {better:.3}");
                    for (f, errs) in &per_family {
                        eprintln!(
                            "   {:<18} {}",
                            f.to_string(),
                            errs.iter()
                                .map(|e| format!("{e:.3}"))
                                .collect::<Vec<_>>()
                                .join(" ")
                        );
                    }
                    eprintln!("   choices {choices:?}");
                    dump.push(serde_json::json!({
                        "scene": label,
                        "rig": rig,
                        "better_baseline": better,
                        "lambert": lam.map(|e| e.environment),
                        "lambert_ggx": ggx.map(|e| e.environment),
                        "families": per_family.iter().map(|(f, e)| serde_json::json!({"family": f, "env": e})).collect::<Vec<_>>(),
                        "ladder": out.ladder,
                        "confidence": out.confidence,
                    }));
                    std::fs::write(
                        root.join("study.json"),
                        serde_json::to_string_pretty(&serde_json::json!({
                            "variants": variants.iter().map(|v| v.0.clone()).collect::<Vec<_>>(),
                            "scenes": dump,
                        }))?,
                    )?;
                    rows.push((label, rig.clone(), better, per_family, choices));
                }
            }
        }
    }
    summary(
        &hybrids,
        "basis with basis + peak",
        "written, then basis weight .75/.5/.25",
    );
    summary(
        &locals,
        "cell-wise blends",
        "as written, then cell 5|10 x s .5,1 x n0 3,10,30",
    );
    summary(
        &blends,
        "blend",
        "w 1-c*u, c 0/.25/.5/.75/1, arithmetic then geometric",
    );
    // Geometric mean of better-baseline / ours, per (family, variant) and per (rule, variant).
    println!(
        "variants: {}",
        variants
            .iter()
            .map(|v| v.0.clone())
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let gm = |xs: &[f64]| (xs.iter().map(|x| x.ln()).sum::<f64>() / xs.len() as f64).exp();
    for rig in ["spread", "one-light", "all"] {
        let rs: Vec<_> = rows.iter().filter(|r| rig == "all" || r.1 == rig).collect();
        if rs.is_empty() {
            continue;
        }
        println!("== {rig} ({} scenes): gm ratio (min ratio)", rs.len());
        for fam in [
            Family::Lambert,
            Family::LambertGgx,
            Family::Basis,
            Family::Hybrid,
        ] {
            let mut line = format!("{:<18}", fam.to_string());
            for vi in 0..variants.len() {
                let ratios: Vec<f64> = rs
                    .iter()
                    .filter_map(|r| {
                        let e = r.3.iter().find(|x| x.0 == fam)?.1[vi];
                        Some(r.2 / e)
                    })
                    .collect();
                let min = ratios.iter().copied().fold(f64::INFINITY, f64::min);
                line += &format!(" {:.2}({:.2})", gm(&ratios), min);
            }
            println!("{line}");
        }
        for rule in ["1se", "paired", "min"] {
            let mut line = format!("rule {rule:<13}");
            for vi in 0..variants.len() {
                let ratios: Vec<f64> = rs
                    .iter()
                    .filter_map(|r| {
                        let f = r.4.iter().find(|c| c.0 == rule)?.1;
                        let e = r.3.iter().find(|x| x.0 == f)?.1[vi];
                        Some(r.2 / e)
                    })
                    .collect();
                let min = ratios.iter().copied().fold(f64::INFINITY, f64::min);
                line += &format!(" {:.2}({:.2})", gm(&ratios), min);
            }
            println!("{line}");
        }
    }
    Ok(())
}

/// `w` of table `a` and `1 - w` of table `b`, arithmetic or geometric.
struct Blend<'a> {
    a: &'a brdf_rig::brdf::merl::MerlTable,
    b: &'a brdf_rig::brdf::merl::MerlTable,
    w: f64,
    geo: bool,
}

impl brdf_rig::brdf::BinValues for Blend<'_> {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        let a = self.a.values_at(bins);
        let b = self.b.values_at(bins);
        a.iter()
            .zip(&b)
            .map(|(x, y)| {
                let mut o = [0.0; 3];
                for c in 0..3 {
                    o[c] = if self.geo {
                        let (p, q) = (x[c].max(1e-9), y[c].max(1e-9));
                        (self.w * p.ln() + (1.0 - self.w) * q.ln()).exp()
                    } else {
                        self.w * x[c] + (1.0 - self.w) * y[c]
                    };
                }
                o
            })
            .collect()
    }
}

/// What [`diagnose`] reads of one scene.
struct Diag<'a> {
    truth: &'a Truth,
    net: &'a dyn BinValues,
    /// The result as written.
    table: &'a MerlTable,
    /// Lambert + GGX, plausible (the hedge's partner).
    analytic: &'a MerlTable,
    ggx: Option<&'a dyn Candidate>,
    families: &'a [(String, &'a dyn Candidate)],
    used: &'a [&'a Observation],
    /// The hedge's weight already in `table`.
    hedged: f64,
}

/// `(theta_h, theta_d)` of a bin's centre, degrees (theta_h in MERL's square-root spacing).
fn angles_deg(bin: usize) -> Option<(f64, f64)> {
    let m = MerlBin::from_index(bin)?;
    let h = (m.theta_h as f64 + 0.5) / 90.0;
    Some((h * h * 90.0, m.theta_d as f64 + 0.5))
}

/// Cell of `cell x cell` (theta_h, theta_d) bins.
fn cell_of(bin: usize, cell: usize) -> Option<usize> {
    let m = MerlBin::from_index(bin)?;
    Some((m.theta_h / cell) * 90usize.div_ceil(cell) + m.theta_d / cell)
}

/// Pixels per cell.
fn counts(used: &[&Observation], cell: usize) -> Vec<usize> {
    let mut n = vec![0usize; 90usize.div_ceil(cell).pow(2)];
    for c in used.iter().filter_map(|o| cell_of(o.bin, cell)) {
        n[c] += 1;
    }
    n
}

/// Prints the diagnosis (see the module header); returns the environment errors of the table
/// as written and of the cell-wise blends, for the summary.
fn diagnose(d: &Diag) -> Vec<f64> {
    let env = |v: &dyn BinValues| d.truth.errors_of(v).environment;
    // 1. Where the error lies: each region set to the truth in turn.
    let ggx_values = d.ggx.map(CandidateValues);
    let h_ranges = [
        (0.0, 2.0),
        (2.0, 8.0),
        (8.0, 20.0),
        (20.0, 45.0),
        (45.0, 90.0),
    ];
    let d_ranges = [(0.0, 30.0), (30.0, 60.0), (60.0, 75.0), (75.0, 90.0)];
    eprintln!(
        "   error with one region set to the truth; theta_h {h_ranges:?} x theta_d {d_ranges:?}"
    );
    for (label, rec) in [
        ("ours", Some(d.table as &dyn BinValues)),
        ("L+GGX", ggx_values.as_ref().map(|v| v as &dyn BinValues)),
    ] {
        let Some(rec) = rec else { continue };
        let mut line = format!("   {label:<6} {:.3} |", env(rec));
        for &h in &h_ranges {
            for &dd in &d_ranges {
                let swapped = Swap {
                    rec,
                    truth: d.net,
                    h,
                    d: dd,
                };
                line += &format!(" {:.3}", env(&swapped));
            }
            line += " |";
        }
        eprintln!("{line}");
    }
    // 2. The pixels in the grazing peak (theta_h < 8, theta_d >= 55 degrees).
    let peak = |b: usize| angles_deg(b).is_some_and(|(h, dd)| h < 8.0 && dd >= 55.0);
    let bins: Vec<usize> = d.truth.bins.iter().copied().filter(|&b| peak(b)).collect();
    let mean = |v: Vec<[f64; 3]>| {
        v.iter().map(|x| x[0] + x[1] + x[2]).sum::<f64>() / v.len().max(1) as f64
    };
    eprintln!(
        "   {} pixels used, {} in the grazing peak; its mean f (r + g + b): truth {:.2}, ours {:.2}, L+GGX {:.2}",
        d.used.len(),
        d.used.iter().filter(|o| peak(o.bin)).count(),
        mean(d.net.values_at(&bins)),
        mean(d.table.values_at(&bins)),
        ggx_values
            .as_ref()
            .map_or(f64::NAN, |v| mean(v.values_at(&bins)))
    );
    // 3. The table times each cell's mean pixel / table ratio, shrunk by the cell's count.
    let pred = d
        .table
        .values_at(&d.used.iter().map(|o| o.bin).collect::<Vec<_>>());
    let mut line = "   residual correction:".to_string();
    for cell in [5usize, 10] {
        let mut sum = vec![[0.0f64; 3]; 90usize.div_ceil(cell).pow(2)];
        let mut cnt = vec![0usize; sum.len()];
        for (o, p) in d.used.iter().zip(&pred) {
            if let Some(c) = cell_of(o.bin, cell)
                && (0..3).all(|k| o.reflectance[k] > 0.0 && p[k] > 0.0)
            {
                for k in 0..3 {
                    sum[c][k] += (o.reflectance[k] / p[k]).ln();
                }
                cnt[c] += 1;
            }
        }
        for n0 in [10.0, 50.0, 200.0] {
            let c = Corrected {
                rec: d.table,
                cell,
                sum: &sum,
                cnt: &cnt,
                n0,
            };
            line += &format!(" cell {cell} n0 {n0}: {:.3}", env(&c));
        }
    }
    eprintln!("{line}");
    // 4. Training log error with each pixel weighted by (its cell's share of the Lambert +
    //    GGX render / the cell's pixels)^lambda: does it rank the families as the render does?
    if let Some(g) = d.ggx {
        let probe = brdf_rig::eval::probe();
        let vals = CandidateValues(g).values_at(probe.bins());
        let energy = |v: &[[f64; 3]]| -> f64 {
            probe
                .render_values(v)
                .environment
                .iter()
                .flatten()
                .map(|x| x.max(0.0))
                .sum()
        };
        let total = energy(&vals);
        let cnt = counts(d.used, 10);
        let share: Vec<f64> = (0..cnt.len())
            .map(|c| {
                let masked: Vec<[f64; 3]> = probe
                    .bins()
                    .iter()
                    .zip(&vals)
                    .map(|(&b, v)| {
                        if cell_of(b, 10) == Some(c) {
                            *v
                        } else {
                            [0.0; 3]
                        }
                    })
                    .collect();
                energy(&masked) / total
            })
            .collect();
        let mut radiance: Vec<f64> = d
            .used
            .iter()
            .map(|o| o.radiance.iter().sum::<f64>() / 3.0)
            .collect();
        radiance.sort_by(f64::total_cmp);
        let scale = radiance
            .get(radiance.len() / 2)
            .copied()
            .unwrap_or(1.0)
            .max(1e-12);
        let mut line = "   render-weighted training error:".to_string();
        for lambda in [0.0, 0.5, 1.0] {
            line += &format!(" lambda {lambda}:");
            for (name, c) in d.families {
                let (mut num, mut den) = (0.0, 0.0);
                for o in d.used {
                    let Some(cc) = cell_of(o.bin, 10) else {
                        continue;
                    };
                    let w = (share[cc] / cnt[cc] as f64).powf(lambda);
                    let f = c.eval_bin(o.bin);
                    #[allow(clippy::needless_range_loop)] // three parallel channel arrays
                    for ch in 0..3 {
                        let a = (1.0 + (f[ch] * o.irradiance[ch] * o.cos_theta_i).max(0.0) / scale)
                            .ln();
                        let b = (1.0 + o.radiance[ch].max(0.0) / scale).ln();
                        if a.is_finite() && b.is_finite() {
                            num += w * (a - b) * (a - b);
                            den += w * b * b;
                        }
                    }
                }
                line += &format!(" {name} {:.4}", num / den);
            }
        }
        eprintln!("{line}");
        let envs: Vec<String> = d
            .families
            .iter()
            .map(|(name, c)| format!("{name} {:.3}", d.truth.errors_of_candidate(*c).environment))
            .collect();
        eprintln!("   rendered: {}", envs.join(", "));
    }
    // 5. Cell-wise blends: weight max(hedged, s n0 / (n + n0)) of Lambert + GGX per cell.
    let mut errs = vec![env(d.table)];
    let mut line = "   cell-wise blends (cell 5|10; s .5,1 x n0 3,10,30):".to_string();
    for cell in [5usize, 10] {
        let cnt = counts(d.used, cell);
        for s in [0.5, 1.0] {
            for n0 in [3.0, 10.0, 30.0] {
                let b = CellBlend {
                    a: d.table,
                    b: d.analytic,
                    cell,
                    cnt: &cnt,
                    s,
                    n0,
                    hedged: d.hedged,
                };
                let e = env(&b);
                line += &format!(" {e:.3}");
                errs.push(e);
            }
        }
        line += " |";
    }
    eprintln!("{line}");
    errs
}

/// `rec` with the bins whose (theta_h, theta_d) lie in `h` x `d` (degrees) from the truth.
struct Swap<'a> {
    rec: &'a dyn BinValues,
    truth: &'a dyn BinValues,
    h: (f64, f64),
    d: (f64, f64),
}

impl BinValues for Swap<'_> {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        let a = self.rec.values_at(bins);
        let t = self.truth.values_at(bins);
        bins.iter()
            .enumerate()
            .map(|(i, &b)| match angles_deg(b) {
                Some((h, d)) if h >= self.h.0 && h < self.h.1 && d >= self.d.0 && d < self.d.1 => {
                    t[i]
                }
                _ => a[i],
            })
            .collect()
    }
}

/// `rec` times each cell's mean pixel / table ratio (log space), shrunk by `n / (n + n0)`.
struct Corrected<'a> {
    rec: &'a MerlTable,
    cell: usize,
    sum: &'a [[f64; 3]],
    cnt: &'a [usize],
    n0: f64,
}

impl BinValues for Corrected<'_> {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        let a = self.rec.values_at(bins);
        bins.iter()
            .zip(a)
            .map(|(&b, v)| {
                let Some(c) = cell_of(b, self.cell).filter(|&c| self.cnt[c] > 0) else {
                    return v;
                };
                let n = self.cnt[c] as f64;
                let s = n / (n + self.n0);
                [0, 1, 2].map(|k| v[k] * (s * self.sum[c][k] / n).exp())
            })
            .collect()
    }
}

/// `a` leaning (geometrically) to `b` per cell by `max(hedged, s n0 / (n + n0))`, `n` the
/// cell's pixels; `a` already carries `hedged` of `b`.
struct CellBlend<'a> {
    a: &'a MerlTable,
    b: &'a MerlTable,
    cell: usize,
    cnt: &'a [usize],
    s: f64,
    n0: f64,
    hedged: f64,
}

impl BinValues for CellBlend<'_> {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        let a = self.a.values_at(bins);
        let b = self.b.values_at(bins);
        bins.iter()
            .zip(a.iter().zip(&b))
            .map(|(&bin, (x, y))| {
                let n = cell_of(bin, self.cell).map_or(0.0, |c| self.cnt[c] as f64);
                let w = (self.s * self.n0 / (n + self.n0)).max(self.hedged);
                let extra = ((w - self.hedged) / (1.0 - self.hedged)).clamp(0.0, 1.0);
                [0, 1, 2].map(|c| {
                    let (p, q) = (x[c].max(1e-12), y[c].max(1e-12));
                    ((1.0 - extra) * p.ln() + extra * q.ln()).exp()
                })
            })
            .collect()
    }
}

/// Per rig: the better baseline's error over each variant's, geometric mean (min, scenes worse
/// by more than 10 %), for rows of (rig, better baseline's error, the variants' errors).
fn summary(rows: &[(String, f64, Vec<f64>)], what: &str, variants: &str) {
    for rig in ["spread", "one-light", "all"] {
        let rs: Vec<_> = rows.iter().filter(|b| rig == "all" || b.0 == rig).collect();
        let Some(first) = rs.first() else { continue };
        let mut line = format!("{what} {rig}, {} scenes ({variants}):", rs.len());
        for i in 0..first.2.len() {
            let r: Vec<f64> = rs.iter().map(|b| b.1 / b.2[i]).collect();
            let g = (r.iter().map(|x| x.ln()).sum::<f64>() / r.len() as f64).exp();
            let min = r.iter().copied().fold(f64::INFINITY, f64::min);
            let worse = r.iter().filter(|x| **x < 1.0 / 1.1).count();
            line += &format!(" {g:.3}({min:.2},{worse})");
        }
        println!("{line}");
    }
}
