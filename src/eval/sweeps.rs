//! Speed and stability sweeps: one knob at a time around the defaults, on one simulated scene.
//! Speed: error against reconstruction time (observe + core; the simulated rendering and the
//! basis build/cache read are not counted). Stability: error against the size of a
//! perturbation, over several seeds (mean and spread).

use super::{
    Errors, EvalError, Perturb, Truth, find_material, mean_sd, observe_case, run_core, write_case,
};
use crate::brdf::basis::{Basis, BasisSettings, GridStride};
use crate::brdf::basis_cache;
use crate::brdf::nbrdf::Nbrdf;
use crate::geometry::mesh::Mesh;
use crate::geometry::sfm_like::SfmLikeParams;
use crate::reconstruct::Job;
use crate::reconstruct::core::CoreSettings;
use crate::reconstruct::nielsen::NielsenSettings;
use crate::reconstruct::observe::ObserveSettings;
use crate::sim::job_scene::SceneSpec;
use serde::Serialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// One setting of one knob, as run.
#[derive(Clone, Debug)]
pub struct Setting {
    pub sweep: String,
    /// Numeric value of the knob (x axis).
    pub value: f64,
    pub label: String,
    pub material: String,
    pub scene: SceneSpec,
    pub sfm: SfmLikeParams,
    pub perturb: Perturb,
    pub core: CoreSettings,
    pub stride: GridStride,
    pub components: usize,
}

/// The outcome of one setting and seed.
#[derive(Clone, Debug, Serialize)]
pub struct Point {
    pub sweep: String,
    pub value: f64,
    pub label: String,
    pub material: String,
    pub seed: u64,
    pub errors: Option<Errors>,
    pub chosen_rank: Option<usize>,
    pub trials: usize,
    /// Why the run failed, when it did.
    pub failure: Option<String>,
    /// Errors of the mean of the fitted trials (diagnostic).
    pub trial_mean: Option<Errors>,
    /// Errors of the trial with the lowest pixel error (diagnostic).
    pub pixel_choice: Option<Errors>,
    /// The pipeline's own verdict on its result.
    pub confidence: Option<crate::reconstruct::confidence::Confidence>,
    /// Observe + core, seconds.
    pub seconds: f64,
}

/// Runs settings one after another, sharing scenes and bases between those that agree.
pub struct Runner<'a> {
    pub materials: &'a [(String, Nbrdf)],
    pub mesh: &'a Mesh,
    pub cache_dir: PathBuf,
    pub scratch: PathBuf,
    pub bin_step: usize,
    jobs: HashMap<String, Job>,
    bases: HashMap<String, Basis>,
    truths: HashMap<String, Truth>,
}

impl<'a> Runner<'a> {
    pub fn new(
        materials: &'a [(String, Nbrdf)],
        mesh: &'a Mesh,
        cache_dir: &Path,
        scratch: &Path,
        bin_step: usize,
    ) -> Self {
        Self {
            materials,
            mesh,
            cache_dir: cache_dir.to_path_buf(),
            scratch: scratch.to_path_buf(),
            bin_step,
            jobs: HashMap::new(),
            bases: HashMap::new(),
            truths: HashMap::new(),
        }
    }

    pub fn run(&mut self, s: &Setting) -> Result<Point, EvalError> {
        let brdf = find_material(self.materials, &s.material)?;
        let bkey = format!("{}-{:?}-{}", s.material, s.stride, s.components);
        if !self.bases.contains_key(&bkey) {
            let bs = BasisSettings {
                stride: s.stride,
                basis_components: s.components,
                exclude: vec![s.material.clone()],
            };
            let (b, _) = basis_cache::load_or_build(&bs, self.materials, &self.cache_dir)?;
            self.bases.insert(bkey.clone(), b);
        }
        if !self.truths.contains_key(&s.material) {
            self.truths
                .insert(s.material.clone(), Truth::new(brdf, self.bin_step));
        }
        let jkey = format!(
            "{}-{}x{}-{}-{}-{}-{}",
            s.material,
            s.scene.width,
            s.scene.height,
            s.scene.views,
            s.sfm.iterations,
            s.sfm.noise_rel,
            s.sfm.seed
        );
        if !self.jobs.contains_key(&jkey) {
            let dir = self.scratch.join(format!("scene-{}", self.jobs.len()));
            let job = write_case(&dir, self.mesh, &s.sfm, brdf, &s.scene)?;
            self.jobs.insert(jkey.clone(), job);
        }
        let (Some(job), Some(basis), Some(truth)) = (
            self.jobs.get(&jkey),
            self.bases.get(&bkey),
            self.truths.get(&s.material),
        ) else {
            unreachable!("inserted above")
        };
        let t = Instant::now();
        let result = observe_case(job, &ObserveSettings::default(), &s.perturb)
            .and_then(|obs| run_core(truth, &obs, basis, &s.core, NielsenSettings::default()));
        let seconds = t.elapsed().as_secs_f64();
        let (errors, chosen_rank, trials, failure, confidence, trial_mean, pixel_choice) =
            match result {
                Ok(r) => (
                    Some(r.chosen),
                    Some(r.chosen_rank),
                    r.trials.len(),
                    None,
                    Some(r.confidence),
                    r.trial_mean,
                    r.pixel_choice,
                ),
                Err(e) => (None, None, 0, Some(e.to_string()), None, None, None),
            };
        Ok(Point {
            sweep: s.sweep.clone(),
            value: s.value,
            label: s.label.clone(),
            material: s.material.clone(),
            seed: s.perturb.seed.max(s.sfm.seed),
            errors,
            chosen_rank,
            trials,
            failure,
            trial_mean,
            pixel_choice,
            confidence,
            seconds,
        })
    }
}

/// The default setting every sweep varies one knob of.
pub fn base_setting(material: &str) -> Setting {
    Setting {
        sweep: "default".to_string(),
        value: 0.0,
        label: "default".to_string(),
        material: material.to_string(),
        scene: SceneSpec::default(),
        sfm: SfmLikeParams {
            seed: 7,
            ..SfmLikeParams::default()
        },
        perturb: Perturb::default(),
        core: CoreSettings::default(),
        stride: GridStride::default(),
        components: 64,
    }
}

/// The speed sweep: image scale, samples, trials, components k, basis resolution; each setting
/// with `seeds` seeds (SfM-like noise and trials), as one seed is too noisy to rank settings.
pub fn speed_settings(base: &Setting, seeds: u64) -> Vec<Setting> {
    let mut out = Vec::new();
    for seed in 0..seeds.max(1) {
        let mut b = base.clone();
        b.sfm.seed = base.sfm.seed + seed;
        b.core.trials.seed = base.core.trials.seed + seed;
        out.extend(speed_settings_one(&b));
    }
    out
}

fn speed_settings_one(base: &Setting) -> Vec<Setting> {
    let mut out = Vec::new();
    let mut push = |sweep: &str, value: f64, label: String, f: &dyn Fn(&mut Setting)| {
        let mut s = base.clone();
        s.sweep = sweep.to_string();
        s.value = value;
        s.label = label;
        f(&mut s);
        out.push(s);
    };
    for (w, h) in [(64, 48), (128, 96), (256, 192)] {
        push("image size", w as f64, format!("{w}x{h}"), &|s| {
            s.scene.width = w;
            s.scene.height = h;
        });
    }
    for n in [20, 40, 80, 160] {
        push("samples", n as f64, format!("{n} samples"), &|s| {
            s.core.trials.samples = n
        });
    }
    for n in [1, 3, 10, 20] {
        push("trials", n as f64, format!("{n} trials"), &|s| {
            s.core.trials.trials = n
        });
    }
    for k in [5, 10, 20, 40] {
        push("components k", k as f64, format!("k = {k}"), &|s| {
            s.core.fixed_k = Some(k)
        });
    }
    for (stride, label) in [
        (
            GridStride {
                theta_h: 1,
                theta_d: 4,
                phi_d: 6,
            },
            "basis 1,4,6",
        ),
        (GridStride::default(), "basis 1,2,2"),
    ] {
        push(
            "basis stride",
            (stride.theta_d * stride.phi_d) as f64,
            label.to_string(),
            &|s| s.stride = stride,
        );
    }
    out
}

/// The stability sweeps, each with `seeds` seeds: (sweep, x-axis name, settings).
pub fn stability_settings(base: &Setting, seeds: u64, flat: &[String]) -> Vec<Setting> {
    let mut out = Vec::new();
    for seed in 0..seeds {
        let mut push = |sweep: &str, value: f64, label: String, f: &dyn Fn(&mut Setting)| {
            let mut s = base.clone();
            s.sweep = sweep.to_string();
            s.value = value;
            s.label = label;
            s.perturb.seed = seed;
            s.sfm.seed = 7 + seed;
            s.core.trials.seed = 1 + seed;
            f(&mut s);
            out.push(s);
        };
        for n in [0.0, 0.05, 0.2, 0.5] {
            push("normal noise (x mean edge)", n, format!("{n}"), &|s| {
                s.sfm.noise_rel = n
            });
        }
        push(
            "mesh",
            0.0,
            "exact (no smoothing, no noise)".to_string(),
            &|s| {
                s.sfm.iterations = 0;
                s.sfm.noise_rel = 0.0;
            },
        );
        for it in [0usize, 10, 40] {
            push(
                "SfM smoothing (Taubin iterations)",
                it as f64,
                format!("{it}"),
                &|s| s.sfm.iterations = it,
            );
        }
        for n in [0.0, 0.01, 0.03, 0.1] {
            push("image noise (x peak)", n, format!("{n}"), &|s| {
                s.perturb.image_noise = n
            });
        }
        for c in [1.0, 0.5, 0.2, 0.05] {
            push("clip level (x peak)", c, format!("{c}"), &|s| {
                s.perturb.clip_fraction = c
            });
        }
        for v in [11usize, 6, 3, 1] {
            push("single-light images", v as f64, format!("{v}"), &|s| {
                s.perturb.views = Some(v)
            });
        }
        for d in [0.0, 2.0, 5.0, 10.0] {
            push("light direction error (deg)", d, format!("{d}"), &|s| {
                s.perturb.light_error_deg = d
            });
        }
        for (i, m) in flat.iter().enumerate() {
            push("material", i as f64, m.clone(), &|s| s.material = m.clone());
        }
    }
    out
}

/// Mean and spread over seeds of the cosine-weighted error, per (sweep, value).
#[derive(Clone, Debug, Serialize)]
pub struct Summary {
    pub sweep: String,
    pub value: f64,
    pub label: String,
    pub runs: usize,
    pub failed: usize,
    pub mean: f64,
    pub sd: f64,
    pub mean_relative: f64,
    pub mean_rank: f64,
    pub mean_seconds: f64,
    /// Runs the pipeline itself called low / medium / high confidence.
    pub confidence_counts: [usize; 3],
    /// Mean trial disagreement (the confidence indicator closest to the error).
    pub mean_disagreement: f64,
}

pub fn summarise(points: &[Point]) -> Vec<Summary> {
    let mut keys: Vec<(String, f64, String)> = Vec::new();
    for p in points {
        if !keys
            .iter()
            .any(|(s, v, l)| *s == p.sweep && *v == p.value && *l == p.label)
        {
            keys.push((p.sweep.clone(), p.value, p.label.clone()));
        }
    }
    keys.into_iter()
        .map(|(sweep, value, label)| {
            let ps: Vec<&Point> = points
                .iter()
                .filter(|p| p.sweep == sweep && p.value == value && p.label == label)
                .collect();
            let ec: Vec<f64> = ps
                .iter()
                .filter_map(|p| p.errors.map(|e| e.cosine_weighted))
                .collect();
            let er: Vec<f64> = ps
                .iter()
                .filter_map(|p| p.errors.map(|e| e.relative))
                .collect();
            let rk: Vec<f64> = ps
                .iter()
                .filter_map(|p| p.chosen_rank.map(|r| r as f64))
                .collect();
            let secs: Vec<f64> = ps.iter().map(|p| p.seconds).collect();
            let mut confidence_counts = [0usize; 3];
            for c in ps.iter().filter_map(|p| p.confidence.as_ref()) {
                confidence_counts[c.level as usize] += 1;
            }
            let dis: Vec<f64> = ps
                .iter()
                .filter_map(|p| p.confidence.as_ref().and_then(|c| c.trial_disagreement))
                .collect();
            let (mean, sd) = mean_sd(&ec);
            Summary {
                sweep,
                value,
                label,
                runs: ps.len(),
                failed: ps.iter().filter(|p| p.failure.is_some()).count(),
                mean,
                sd,
                mean_relative: mean_sd(&er).0,
                mean_rank: mean_sd(&rk).0,
                mean_seconds: mean_sd(&secs).0,
                confidence_counts,
                mean_disagreement: mean_sd(&dis).0,
            }
        })
        .collect()
}
