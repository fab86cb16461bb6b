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
}

pub fn run(a: BenchExternalArgs) -> anyhow::Result<ExitCode> {
    let settings = Settings {
        refine: a
            .refine_normals
            .then(brdf_rig::reconstruct::refine::RefineSettings::default),
        ..Settings::default()
    };
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
        "cargo run --release -- bench external --scenes {} --jobs {} --bin-step {}{} --out {}",
        a.scenes.display(),
        a.jobs.join(","),
        a.bin_step,
        if a.refine_normals {
            " --refine-normals"
        } else {
            ""
        },
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
