//! `brdf-rig bench external`: the reconstruction on scenes rendered by an independent renderer
//! (`scripts/render_recon_scenes.py`), against least-squares Lambert and Lambert + GGX fits to
//! the same pixels (a scene of several materials, from the script's `--split`: with
//! `--materials auto`, the count, the labels' agreement and each material's ratio); writes
//! external.md and external.json under `--out`. Thin over
//! `eval::bench::external`: parses the arguments into its options and prints.

use std::path::PathBuf;
use std::process::ExitCode;

use clap::Args;

use brdf_rig::eval::bench::external::{self, ExternalBenchOptions};
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
    /// Reconstruct with the normals refined from the images, as `reconstruct` does by default
    /// (`--no-refine-normals`: not).
    #[command(flatten)]
    pub refine: super::reconstruct::RefineSwitch,
    /// When the normals are refined: what the refinement moves (`reconstruct --refine-unknowns`).
    #[arg(long, value_enum, default_value = "depth")]
    pub refine_unknowns: super::reconstruct::RefineUnknownsArg,
    /// Study knob: leave out of the normal refinement the pixels of another material's colour
    /// near the labels' boundary (`reconstruct --refine-colour-rule`).
    #[arg(long)]
    pub refine_colour_rule: bool,
    /// Study knob: every scene reconstructed with `--materials auto` (as the scenes of several
    /// materials are) with this many passes moving the labels' boundary
    /// (`reconstruct --relabel-passes`).
    #[arg(long, value_parser = super::ranges::int_in(0usize, 10))]
    pub relabel_passes: Option<usize>,
    /// Reconstruction seeds (trials and held-out folds): each job runs once per seed.
    #[arg(long, value_delimiter = ',', default_value = "1")]
    pub seeds: Vec<u64>,
    /// Study knob: how far (a factor) the result may stray from the Lambert + GGX prior where
    /// no pixel was observed (`PlausibleSettings::prior_ratio_limit`; default: the library's).
    #[arg(long, value_parser = clap::value_parser!(f64))]
    pub prior_ratio: Option<f64>,
    /// Study knob: the held-out error the ladder's choice reads: `log` (the default),
    /// `pareto` (the richer of the linear and the log choice unless it does worse in the other
    /// space; the default of sessions 15-20),
    /// `pareto-patches` (the same with patch sums in place of pixels), `front` (`pareto` among
    /// the rungs no rung of another family beats beyond noise in one space without losing in
    /// the other), `patches`, `both` (a richer model must win beyond noise in each) or
    /// `linear`.
    #[arg(long, value_parser = parse_metric)]
    pub held_out: Option<HeldOutMetric>,
    #[command(flatten)]
    pub knobs: super::bench_knobs::FitKnobs,
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
        HeldOutMetric::Front => "front",
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
        "front" => Ok(HeldOutMetric::Front),
        _ => Err(format!(
            "{s:?}: expected log, linear, both, pareto, patches, pareto-patches or front"
        )),
    }
}

pub fn run(a: BenchExternalArgs) -> anyhow::Result<ExitCode> {
    let mut settings = Settings {
        refine: a
            .refine_unknowns
            .settings(a.refine.on(), a.refine_colour_rule),
        ..Settings::default()
    };
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
    if let Some(passes) = a.relabel_passes {
        settings.materials = Some(segment_settings(passes));
    }
    a.knobs.overrides().apply(&mut settings.core);
    let command = format!(
        "cargo run --release -- bench external --scenes {} --jobs {} --seeds {} --bin-step {}{}{}{}{}{} --out {}",
        a.scenes.display(),
        a.jobs.join(","),
        a.seeds
            .iter()
            .map(|s| s.to_string())
            .collect::<Vec<_>>()
            .join(","),
        a.bin_step,
        a.refine_unknowns
            .command_args(a.refine.on(), a.refine_colour_rule),
        a.prior_ratio
            .map_or(String::new(), |r| format!(" --prior-ratio {r}")),
        a.held_out
            .map_or(String::new(), |m| format!(" --held-out {}", metric_name(m))),
        a.knobs.args(),
        a.relabel_passes
            .map_or(String::new(), |r| format!(" --relabel-passes {r}")),
        a.out.display()
    );
    let options = ExternalBenchOptions {
        scenes: a.scenes.clone(),
        jobs: a.jobs.clone(),
        seeds: a.seeds.clone(),
        bin_step: a.bin_step as usize,
        settings,
        basis_cache: a.basis_cache.clone(),
        out: a.out.clone(),
        command,
    };
    let bench = external::run(&options, &mut super::bench_notes::printer())?;
    outln!("{}", bench.markdown);
    Ok(ExitCode::SUCCESS)
}

/// The default segmentation with `passes` of the boundary's relabelling.
fn segment_settings(passes: usize) -> brdf_rig::reconstruct::segment::SegmentSettings {
    brdf_rig::reconstruct::segment::SegmentSettings {
        relabel_passes: passes,
        ..Default::default()
    }
}
