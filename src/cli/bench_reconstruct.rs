//! `brdf-rig bench reconstruct`: time and peak memory of a paper-scale reconstruction (11
//! single-light images of the Stanford Bunny, cached basis), and optionally the accuracy study
//! (the paper's six materials: with the three assumptions, with none, each one off, and the
//! Lambert and Lambert+GGX baselines). Every number comes from the neural MERL fits (smooth
//! approximations of MERL, not measured data), and the page says so.
//!
//! The timed run is a child process (`brdf-rig reconstruct`), so its VmHWM is the
//! reconstruction's alone, not the scene rendering's or the basis build's.

use super::ranges::int_in;
use anyhow::{Context, bail};
use brdf_rig::brdf::BinValues;
use brdf_rig::brdf::basis::{Basis, GridStride};
use brdf_rig::brdf::basis_cache::{default_cache_dir, load_or_build};
use brdf_rig::brdf::merl::MerlTable;
use brdf_rig::brdf::metrics::{ErrorReport, compare};
use brdf_rig::brdf::nbrdf::{Nbrdf, default_dir, load_dir};
use brdf_rig::eval::PAPER_MATERIALS;
use brdf_rig::geometry::mesh_io::load_mesh;
use brdf_rig::geometry::sfm_like::{SfmLikeParams, sfm_like};
use brdf_rig::reconstruct::baselines::fit_baselines;
use brdf_rig::reconstruct::reliable::ReliableSettings;
use brdf_rig::reconstruct::report_file;
use brdf_rig::reconstruct::{Job, Settings, reconstruct_with_basis};
use brdf_rig::sim::job_scene::{SceneSpec, write_scene};
use clap::Args;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

#[derive(Args, Debug)]
pub struct BenchReconstructArgs {
    /// Mesh to render (default: the Stanford Bunny in the data folder).
    #[arg(long)]
    pub mesh: Option<PathBuf>,
    /// Material of the timed run (always left out of its basis).
    #[arg(long, default_value = "alum-bronze")]
    pub material: String,
    #[arg(long, default_value_t = 11, value_parser = int_in(1usize, 360))]
    pub views: usize,
    #[arg(long, default_value_t = 640, value_parser = int_in(8usize, 8192))]
    pub width: usize,
    #[arg(long, default_value_t = 480, value_parser = int_in(8usize, 8192))]
    pub height: usize,
    /// Basis grid stride (theta_h, theta_d, phi_d).
    #[arg(
        long,
        value_delimiter = ',',
        default_values_t = [1usize, 2, 2],
        value_parser = int_in(1usize, 90)
    )]
    pub basis_stride: Vec<usize>,
    #[arg(long, default_value_t = 80, value_parser = int_in(1usize, 300))]
    pub basis_components: usize,
    /// Also run the accuracy study over these materials (comma-separated; `paper` = the six).
    #[arg(long, value_delimiter = ',')]
    pub study: Vec<String>,
    /// Image size of the study's scenes (smaller than the timed run: 6 materials x 5 runs).
    #[arg(
        long,
        value_delimiter = ',',
        default_values_t = [320usize, 240],
        value_parser = int_in(8usize, 8192)
    )]
    pub study_size: Vec<usize>,
    /// Write the markdown page here (e.g. docs/benchmarks-reconstruct.md).
    #[arg(long)]
    pub write: Option<PathBuf>,
    /// Keep the scene folders here instead of a temporary directory.
    #[arg(long)]
    pub keep: Option<PathBuf>,
    /// Time the reconstruction with `--refine-normals` (the normal refinement's cost).
    #[arg(long)]
    pub refine_normals: bool,
    /// Time the reconstruction with `--all-pixels` (no reduction of redundant pixels).
    #[arg(long)]
    pub all_pixels: bool,
    /// Seed of the timed run's trials (the spread over seeds is the run-to-run noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

fn stride(v: &[usize]) -> GridStride {
    GridStride {
        theta_h: v.first().copied().unwrap_or(1),
        theta_d: v.get(1).copied().unwrap_or(2),
        phi_d: v.get(2).copied().unwrap_or(2),
    }
}

fn settings_for(a: &BenchReconstructArgs, target: &str) -> Settings {
    let mut s = Settings::default();
    s.basis.stride = stride(&a.basis_stride);
    s.basis.basis_components = a.basis_components;
    s.basis.exclude = vec![target.to_string()];
    s
}

fn scene(
    dir: &Path,
    mesh_path: &Path,
    truth: &Nbrdf,
    views: usize,
    width: usize,
    height: usize,
) -> anyhow::Result<Job> {
    let (mesh, _) = load_mesh(mesh_path)?;
    let job_mesh = sfm_like(&mesh, &SfmLikeParams::default());
    let spec = SceneSpec {
        views,
        width,
        height,
        ..SceneSpec::default()
    };
    write_scene(dir, &mesh, &job_mesh, truth, &spec)
        .with_context(|| format!("writing the simulated scene in {}", dir.display()))
}

fn basis_for(s: &Settings, mats: &[(String, Nbrdf)]) -> anyhow::Result<Basis> {
    let dir = s.basis_cache.clone().unwrap_or_else(default_cache_dir);
    Ok(load_or_build(&s.basis, mats, &dir)?.0)
}

/// Every 3rd MERL bin (the metric skips bins below the horizon).
fn eval_bins() -> Vec<usize> {
    (0..90 * 90 * 180).step_by(3).collect()
}

fn err(bins: &[usize], truth: &dyn BinValues, rec: &dyn BinValues) -> ErrorReport {
    compare(bins, truth, rec)
}

pub fn run(a: BenchReconstructArgs) -> anyhow::Result<ExitCode> {
    anyhow::ensure!(
        a.basis_stride.len() == 3 && a.study_size.len() == 2,
        "--basis-stride takes three numbers and --study-size two"
    );
    let mesh_path = a
        .mesh
        .clone()
        .unwrap_or_else(|| brdf_rig::data::data_dir().join("meshes/stanford-bunny.obj"));
    let mats = load_dir(&default_dir())?;
    let truth_of = |name: &str| -> anyhow::Result<&Nbrdf> {
        match mats.iter().find(|(n, _)| n == name) {
            Some((_, m)) => Ok(m),
            None => bail!("no neural fit named {name} in {}", default_dir().display()),
        }
    };
    let tmp = tempfile::tempdir()?;
    let root = a.keep.clone().unwrap_or_else(|| tmp.path().to_path_buf());
    let bins = eval_bins();

    // --- timed run: a child process on a cached basis -------------------------------------
    let settings = settings_for(&a, &a.material);
    eprintln!("basis without {} (built once, then cached)", a.material);
    let t = Instant::now();
    drop(basis_for(&settings, &mats)?);
    let basis_secs = t.elapsed().as_secs_f64();
    eprintln!(
        "rendering the scene: {} views at {}x{}",
        a.views, a.width, a.height
    );
    let dir = root.join(format!("bench-{}", a.material));
    let job = scene(
        &dir,
        &mesh_path,
        truth_of(&a.material)?,
        a.views,
        a.width,
        a.height,
    )?;
    let out_dir = dir.join("out");
    let s = &a.basis_stride;
    let mut cmd_args: Vec<String> = vec![
        "reconstruct".into(),
        job.source.display().to_string(),
        "--out".into(),
        out_dir.display().to_string(),
        "--exclude".into(),
        a.material.clone(),
        "--basis-stride".into(),
        format!("{},{},{}", s[0], s[1], s[2]),
        "--basis-components".into(),
        a.basis_components.to_string(),
    ];
    if a.refine_normals {
        cmd_args.push("--refine-normals".into());
    }
    if a.all_pixels {
        cmd_args.push("--all-pixels".into());
    }
    if a.seed != 1 {
        cmd_args.extend(["--seed".into(), a.seed.to_string()]);
    }
    let uptime = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    eprintln!("timed: brdf-rig {}", cmd_args.join(" "));
    let t = Instant::now();
    let status = std::process::Command::new(std::env::current_exe()?)
        .args(&cmd_args)
        .status()?;
    let wall = t.elapsed().as_secs_f64();
    if !status.success() {
        bail!("the timed reconstruction failed");
    }
    let report = report_file::read(&out_dir)?;
    let table = MerlTable::read(&out_dir.join(report_file::BRDF_FILE))?;
    let e = err(&bins, truth_of(&a.material)?, &table);
    eprintln!("rendered error: the sphere probe under the standard environment");
    let env = brdf_rig::eval::Truth::new(truth_of(&a.material)?, 3)
        .errors_of(&table)
        .environment;

    let mut md = String::new();
    let mut command = format!(
        "cargo run --release -- bench reconstruct --material {} --views {} --width {} --height {} --basis-stride {},{},{} --basis-components {}",
        a.material, a.views, a.width, a.height, s[0], s[1], s[2], a.basis_components
    );
    if !a.study.is_empty() {
        command += &format!(
            " --study {} --study-size {},{}",
            a.study.join(","),
            a.study_size[0],
            a.study_size[1]
        );
    }
    if a.refine_normals {
        command += " --refine-normals";
    }
    if a.all_pixels {
        command += " --all-pixels";
    }
    if a.seed != 1 {
        command += &format!(" --seed {}", a.seed);
    }
    if let Some(w) = &a.write {
        command += &format!(" --write {}", w.display());
    }
    writeln!(md, "# Reconstruction benchmark\n")?;
    writeln!(
        md,
        "Made by `{command}` on {}.\n\nGround truth and basis: neural fits of the MERL materials (Sztrajman et al. 2021), smooth approximations of the measurements, **not measured MERL data**. The target material is always left out of the basis.\n",
        brdf_rig::eval::host::machine()
    )?;
    writeln!(md, "## Time and memory (paper scale)\n")?;
    writeln!(
        md,
        "Stanford Bunny ({} single-light images at {}x{}, SfM-like mesh: Taubin smoothing + normal noise, `geometry::sfm_like` defaults), material {}, basis stride {:?}, {} components, basis read from the cache (building it took {:.1} s in the bench process; cached afterwards). Child process `brdf-rig {}`: wall {:.2} s, peak memory (VmHWM) {:.0} MiB; load average before it (/proc/loadavg) {}.\n",
        a.views,
        a.width,
        a.height,
        a.material,
        [s[0], s[1], s[2]],
        a.basis_components,
        basis_secs,
        cmd_args
            .join(" ")
            .replace(&root.display().to_string(), "$SCENE"),
        wall,
        report.peak_memory_bytes.unwrap_or(0) as f64 / 1048576.0,
        uptime
            .split_whitespace()
            .take(3)
            .collect::<Vec<_>>()
            .join(" ")
    )?;
    writeln!(md, "| stage | seconds |\n|---|---:|")?;
    for t in &report.timings {
        writeln!(md, "| {} | {:.3} |", t.stage, t.seconds)?;
    }
    writeln!(
        md,
        "\nObserved pixels {}, reliable {}, k = {}, eta = {}, chosen trial {} of {}; rendered (environment) error {env:.4}; cosine-weighted relative error {:.4} (relative {:.4}, near-specular {:.4}).\n",
        report.observed_pixels,
        report.reliable_pixels,
        report.components.k,
        report.components.eta,
        report.chosen_trial + 1,
        report.trials.len(),
        e.cosine_weighted,
        e.relative,
        e.near_specular
    )?;

    // --- accuracy study ------------------------------------------------------------------
    let study: Vec<String> = if a.study.iter().any(|m| m == "paper") {
        PAPER_MATERIALS.iter().map(|s| s.to_string()).collect()
    } else {
        a.study.clone()
    };
    if !study.is_empty() {
        writeln!(md, "## Accuracy: assumptions, ablation, baselines\n")?;
        writeln!(
            md,
            "Bunny, {} views at {}x{}, SfM-like mesh; cosine-weighted relative error (docs/error-metrics.md) over every 3rd MERL bin above the horizon; baselines fitted to every observed pixel. Lower is better.\n",
            a.views, a.study_size[0], a.study_size[1]
        )?;
        writeln!(
            md,
            "| material | all three | none | no curvature | no monotonicity | no brightest | Lambert | Lambert+GGX | k, eta | best trial similarity |\n|---|---:|---:|---:|---:|---:|---:|---:|---|---:|"
        )?;
    }
    for m in &study {
        eprintln!("study: {m}");
        let truth = truth_of(m)?;
        let settings = settings_for(&a, m);
        let basis = basis_for(&settings, &mats)?;
        let dir = root.join(format!("study-{m}"));
        let job = scene(
            &dir,
            &mesh_path,
            truth,
            a.views,
            a.study_size[0],
            a.study_size[1],
        )?;
        let variants: [(&str, ReliableSettings); 5] = [
            ("all", ReliableSettings::default()),
            ("none", ReliableSettings::none()),
            (
                "no-curvature",
                ReliableSettings {
                    use_curvature: false,
                    ..Default::default()
                },
            ),
            (
                "no-monotonicity",
                ReliableSettings {
                    use_monotonicity: false,
                    ..Default::default()
                },
            ),
            (
                "no-brightest",
                ReliableSettings {
                    use_brightest: false,
                    ..Default::default()
                },
            ),
        ];
        let mut cells = Vec::new();
        let mut first = None;
        for (_, r) in variants {
            let mut s = settings.clone();
            s.core.reliable = r;
            let out = reconstruct_with_basis(&job, &s, &basis, &mut |_| {})?;
            cells.push(err(&bins, truth, &out.table).cosine_weighted);
            if first.is_none() {
                first = Some(out);
            }
        }
        let Some(out) = first else { continue };
        let (lambert, ggx) = fit_baselines(&out.observed.observations);
        let (Some(lambert), Some(ggx)) = (lambert, ggx) else {
            anyhow::bail!("{m}: the baselines could not be fitted to the observed pixels");
        };
        let el = err(&bins, truth, &MerlTable::tabulate(&lambert)).cosine_weighted;
        let eg = err(&bins, truth, &MerlTable::tabulate(&ggx)).cosine_weighted;
        let r = &out.report;
        writeln!(
            md,
            "| {m} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {el:.4} | {eg:.4} | {}, {} | {:.5} |",
            cells[0],
            cells[1],
            cells[2],
            cells[3],
            cells[4],
            r.components.k,
            r.components.eta,
            r.trials[r.chosen_trial].similarity
        )?;
        eprint!("{}", md.lines().last().unwrap_or_default());
        eprintln!();
    }
    print!("{md}");
    if let Some(w) = &a.write {
        std::fs::write(w, &md).with_context(|| format!("writing {}", w.display()))?;
    }
    Ok(ExitCode::SUCCESS)
}
