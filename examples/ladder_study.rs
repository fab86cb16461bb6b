//! The model ladder and the plausibility step, studied against the truth (investigation tool,
//! not a benchmark): for each simulated scene, every family's final fit is made plausible
//! with several shrink settings and scored by the rendered environment error, and the ladder's
//! held-out scores are read with each choice rule. Neural MERL fits as truth (approximations of
//! MERL, not measured MERL data).
//!
//! `cargo run --release --example ladder_study -- [MATERIALS] [MESHES] [RIGS] [SEEDS]`
//! (comma lists; defaults: the paper's six, spot,bunny, spread,one-light, 1). Scenes are
//! written once to `$STUDY_DIR` (default /tmp/ladder-study) and reused.

use brdf_rig::brdf::basis::{BasisSettings, GridStride};
use brdf_rig::brdf::basis_cache::{default_cache_dir, load_or_build};
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
use brdf_rig::reconstruct::prior::Candidate;
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
                        let spec = match rig.as_str() {
                            "one-light" => SceneSpec::one_light(30.0),
                            _ => SceneSpec::default(),
                        };
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
    for rig in ["spread", "one-light", "all"] {
        let bs: Vec<_> = blends
            .iter()
            .filter(|b| rig == "all" || b.0 == rig)
            .collect();
        if bs.is_empty() {
            continue;
        }
        let mut line = format!("blend {rig}:");
        for i in 0..10 {
            let r: Vec<f64> = bs.iter().map(|b| b.1 / b.2[i]).collect();
            let g = (r.iter().map(|x| x.ln()).sum::<f64>() / r.len() as f64).exp();
            let min = r.iter().copied().fold(f64::INFINITY, f64::min);
            let worse = r.iter().filter(|x| **x < 1.0 / 1.1).count();
            line += &format!(" {g:.3}({min:.2},{worse})");
        }
        println!("{line}");
    }
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
