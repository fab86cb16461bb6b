//! `brdf-rig bench external`: the reconstruction on scenes rendered by an independent renderer
//! (`scripts/render_recon_scenes.py`), against least-squares Lambert and Lambert + GGX fits to
//! the same pixels; writes external.md and external.json under `--out`. Thin over
//! `eval::external`.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::Args;

use brdf_rig::brdf::basis::BasisSettings;
use brdf_rig::brdf::{basis_cache, nbrdf};
use brdf_rig::eval::external;
use brdf_rig::reconstruct::Settings;
use brdf_rig::reconstruct::ladder::HeldOutMetric;

#[derive(Args, Debug)]
pub struct BenchExternalArgs {
    /// A scene set written by scripts/render_recon_scenes.py (holds index.json).
    #[arg(long)]
    pub scenes: PathBuf,
    /// Job variants to run (mesh given to the reconstruction).
    #[arg(long, value_delimiter = ',', default_value = "exact,realistic,poor")]
    pub jobs: Vec<String>,
    /// Errors over every N-th MERL bin.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=1000))]
    pub bin_step: u64,
    /// Basis cache folder (default: $BRDF_RIG_CACHE or ~/.cache/brdf-rig).
    #[arg(long)]
    pub basis_cache: Option<PathBuf>,
    /// Output folder for external.md and external.json.
    #[arg(long, default_value = "docs/eval")]
    pub out: PathBuf,
    /// Reconstruct with the normals refined from the images (`reconstruct --refine-normals`).
    #[arg(long)]
    pub refine_normals: bool,
    /// Reconstruction seeds (trials and held-out folds): each job runs once per seed.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    pub seeds: Vec<u64>,
    /// How the reported trial is chosen (`reconstruct --choose`).
    #[arg(long, value_parser = super::reconstruct::parse_choice, default_value = "similarity")]
    pub choose: brdf_rig::reconstruct::core::TrialChoice,
    /// Study knob: how far (a factor) the result may stray from the Lambert + GGX prior where
    /// no pixel was observed (`PlausibleSettings::prior_ratio_limit`; default: the library's).
    #[arg(long, value_parser = clap::value_parser!(f64))]
    pub prior_ratio: Option<f64>,
    /// Study knob: the held-out error the ladder's choice reads: `pareto` (the default: the
    /// richer of the linear and the log choice unless it does worse in the other space),
    /// `pareto-patches` (the same with patch sums in place of pixels), `patches`, `both` (a
    /// richer model must win beyond noise in each), `log` or `linear`.
    #[arg(long, value_parser = parse_metric)]
    pub held_out: Option<HeldOutMetric>,
}

/// The `--held-out` word for a metric (what [`parse_metric`] reads).
pub(crate) fn metric_name(m: HeldOutMetric) -> &'static str {
    match m {
        HeldOutMetric::Log => "log",
        HeldOutMetric::Linear => "linear",
        HeldOutMetric::Both => "both",
        HeldOutMetric::Pareto => "pareto",
        HeldOutMetric::Patches => "patches",
        HeldOutMetric::ParetoPatches => "pareto-patches",
    }
}

pub(crate) fn parse_metric(s: &str) -> Result<HeldOutMetric, String> {
    match s {
        "log" => Ok(HeldOutMetric::Log),
        "linear" => Ok(HeldOutMetric::Linear),
        "both" => Ok(HeldOutMetric::Both),
        "pareto" => Ok(HeldOutMetric::Pareto),
        "patches" => Ok(HeldOutMetric::Patches),
        "pareto-patches" => Ok(HeldOutMetric::ParetoPatches),
        _ => Err(format!(
            "{s:?}: expected log, linear, both, pareto, patches or pareto-patches"
        )),
    }
}

pub fn run(a: BenchExternalArgs) -> anyhow::Result<ExitCode> {
    let mut settings = Settings {
        refine: a
            .refine_normals
            .then(brdf_rig::reconstruct::refine::RefineSettings::default),
        ..Settings::default()
    };
    settings.core.choose = a.choose;
    if let Some(r) = a.prior_ratio {
        anyhow::ensure!(
            r.is_finite() && r >= 1.0,
            "--prior-ratio must be a finite factor >= 1, got {r}"
        );
        settings.core.plausible.prior_ratio_limit = r;
    }
    if let Some(m) = a.held_out {
        settings.core.ladder.metric = m;
    }
    let materials = nbrdf::load_dir(&settings.nbrdf_dir).with_context(|| {
        format!(
            "loading the neural MERL fits from {}",
            settings.nbrdf_dir.display()
        )
    })?;
    let cache = a
        .basis_cache
        .clone()
        .unwrap_or_else(basis_cache::default_cache_dir);
    let (basis, _) = basis_cache::load_or_build(&BasisSettings::default(), &materials, &cache)
        .context("loading the basis")?;
    let command = format!(
        "cargo run --release -- bench external --scenes {} --jobs {} --seeds {} --bin-step {}{}{}{}{} --out {}",
        a.scenes.display(),
        a.jobs.join(","),
        a.seeds
            .iter()
            .map(|s| s.to_string())
            .collect::<Vec<_>>()
            .join(","),
        a.bin_step,
        if a.refine_normals {
            " --refine-normals"
        } else {
            ""
        },
        match a.choose {
            brdf_rig::reconstruct::core::TrialChoice::Similarity => "",
            brdf_rig::reconstruct::core::TrialChoice::PixelError => " --choose pixel-error",
            brdf_rig::reconstruct::core::TrialChoice::Mean => " --choose mean",
        },
        a.prior_ratio
            .map_or(String::new(), |r| format!(" --prior-ratio {r}")),
        a.held_out
            .map_or(String::new(), |m| format!(" --held-out {}", metric_name(m))),
        a.out.display()
    );
    let machine = brdf_rig::eval::host::machine();
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let start = std::time::Instant::now();
    let out_dir = a.out.clone();
    let write = |results: &[external::ExternalResult]| -> anyhow::Result<()> {
        let md = external::markdown(results, &command, &machine);
        let md_path = out_dir.join("external.md");
        std::fs::write(&md_path, &md).with_context(|| format!("writing {}", md_path.display()))?;
        let json =
            serde_json::json!({ "command": command, "machine": machine, "results": results });
        let json_path = out_dir.join("external.json");
        std::fs::write(&json_path, serde_json::to_string_pretty(&json)?)
            .with_context(|| format!("writing {}", json_path.display()))?;
        Ok(())
    };
    let mut done = Vec::new();
    let mut write_err = None;
    let results = external::run(
        &a.scenes,
        &a.jobs,
        &a.seeds,
        &settings,
        &basis,
        a.bin_step as usize,
        &mut |line| eprintln!("[{:7.1} s] {line}", start.elapsed().as_secs_f64()),
        &mut |r| {
            eprintln!(
                "  {} {}: ours env {}, ratio {}",
                r.scene,
                r.job,
                r.ours
                    .as_ref()
                    .map_or_else(|e| e.clone(), |e| format!("{:.3}", e.environment)),
                r.ratio().map_or("-".to_string(), |x| format!("{x:.2}"))
            );
            done.push(r.clone());
            if let Err(e) = write(&done) {
                write_err = Some(e);
            }
        },
    )
    .with_context(|| format!("running the scenes of {}", a.scenes.display()))?;
    if let Some(e) = write_err {
        return Err(e);
    }
    write(&results)?;
    println!("{}", external::markdown(&results, &command, &machine));
    Ok(ExitCode::SUCCESS)
}
