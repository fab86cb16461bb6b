//! `brdf-rig bench reconstruct`: time and peak memory of a paper-scale reconstruction (11
//! single-light images of the Stanford Bunny, cached basis), and optionally the accuracy study
//! (the paper's six materials: with the three assumptions, with none, each one off, and the
//! Lambert and Lambert+GGX baselines). Every number comes from the neural MERL fits (smooth
//! approximations of MERL, not measured data), and the page says so.
//!
//! The timed run is a child process (`brdf-rig reconstruct`, the binary the options name), so
//! its VmHWM is the reconstruction's alone, not the scene rendering's or the basis build's.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use super::{BenchError, Note, temp_dir, write_file};
use crate::brdf::BinValues;
use crate::brdf::basis::{Basis, GridStride};
use crate::brdf::basis_cache::{default_cache_dir, load_or_build};
use crate::brdf::merl::MerlTable;
use crate::brdf::metrics::{ErrorReport, compare};
use crate::brdf::nbrdf::{Nbrdf, default_dir, load_dir};
use crate::eval::PAPER_MATERIALS;
use crate::geometry::mesh_io::load_mesh;
use crate::geometry::sfm_like::{SfmLikeParams, sfm_like};
use crate::reconstruct::baselines::fit_baselines;
use crate::reconstruct::reliable::ReliableSettings;
use crate::reconstruct::report_file;
use crate::reconstruct::{Job, Settings, reconstruct_with_basis};
use crate::sim::job_scene::{SceneSpec, write_scene};

/// The options of `bench reconstruct`.
#[derive(Clone, Debug)]
pub struct ReconstructBenchOptions {
    /// Mesh to render (`None`: the Stanford Bunny in the data folder).
    pub mesh: Option<PathBuf>,
    /// Material of the timed run (always left out of its basis).
    pub material: String,
    pub views: usize,
    pub width: usize,
    pub height: usize,
    pub stride: GridStride,
    pub basis_components: usize,
    /// Materials of the accuracy study (`paper`: the six); empty: no study.
    pub study: Vec<String>,
    /// Image size of the study's scenes.
    pub study_size: (usize, usize),
    /// Where the page is written, besides being returned.
    pub write: Option<PathBuf>,
    /// Keep the scene folders here instead of a temporary folder.
    pub keep: Option<PathBuf>,
    pub refine_normals: bool,
    /// With `refine_normals`: `reconstruct --refine-unknowns` (None: its default).
    pub refine_unknowns: Option<String>,
    pub all_pixels: bool,
    /// What each basis fit is given (`None`: the default).
    pub basis_fit: Option<crate::reconstruct::trials::BasisFit>,
    /// Seed of the timed run's trials.
    pub seed: u64,
    /// The `brdf-rig` binary the timed child process runs.
    pub exe: PathBuf,
    /// The command as typed, quoted by the page.
    pub command: String,
}

fn settings_for(o: &ReconstructBenchOptions, target: &str) -> Settings {
    let mut s = Settings::default();
    s.basis.stride = o.stride;
    s.basis.basis_components = o.basis_components;
    s.basis.exclude = vec![target.to_string()];
    if let Some(f) = o.basis_fit {
        s.core.trials.basis_fit = f;
    }
    s
}

fn scene(
    dir: &Path,
    mesh_path: &Path,
    truth: &Nbrdf,
    views: usize,
    width: usize,
    height: usize,
) -> Result<Job, BenchError> {
    let (mesh, _) = load_mesh(mesh_path)?;
    let job_mesh = sfm_like(&mesh, &SfmLikeParams::default());
    let spec = SceneSpec {
        views,
        width,
        height,
        ..SceneSpec::default()
    };
    write_scene(dir, &mesh, &job_mesh, truth, &spec).map_err(|e| {
        BenchError::step(
            format!("writing the simulated scene in {}", dir.display()),
            e,
        )
    })
}

fn basis_for(s: &Settings, mats: &[(String, Nbrdf)]) -> Result<Basis, BenchError> {
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

/// Runs the timed reconstruction and the study; returns the markdown page (also written to
/// `o.write` when given).
pub fn run(
    o: &ReconstructBenchOptions,
    note: &mut dyn FnMut(Note<'_>),
) -> Result<String, BenchError> {
    let mut detail = |text: &str| note(Note::Detail(text));
    let mesh_path = o
        .mesh
        .clone()
        .unwrap_or_else(|| crate::data::data_dir().join("meshes/stanford-bunny.obj"));
    let mats = load_dir(&default_dir())?;
    let truth_of = |name: &str| -> Result<&Nbrdf, BenchError> {
        match mats.iter().find(|(n, _)| n == name) {
            Some((_, m)) => Ok(m),
            None => Err(BenchError::Invalid(format!(
                "no neural fit named {name} in {}",
                default_dir().display()
            ))),
        }
    };
    let tmp = temp_dir()?;
    let root = o.keep.clone().unwrap_or_else(|| tmp.path().to_path_buf());
    let bins = eval_bins();

    // --- timed run: a child process on a cached basis -------------------------------------
    let settings = settings_for(o, &o.material);
    detail(&format!(
        "basis without {} (built once, then cached)",
        o.material
    ));
    let t = Instant::now();
    drop(basis_for(&settings, &mats)?);
    let basis_secs = t.elapsed().as_secs_f64();
    detail(&format!(
        "rendering the scene: {} views at {}x{}",
        o.views, o.width, o.height
    ));
    let dir = root.join(format!("bench-{}", o.material));
    let job = scene(
        &dir,
        &mesh_path,
        truth_of(&o.material)?,
        o.views,
        o.width,
        o.height,
    )?;
    let out_dir = dir.join("out");
    let s = [o.stride.theta_h, o.stride.theta_d, o.stride.phi_d];
    let mut cmd_args: Vec<String> = vec![
        "reconstruct".into(),
        job.source.display().to_string(),
        "--out".into(),
        out_dir.display().to_string(),
        "--exclude".into(),
        o.material.clone(),
        "--basis-stride".into(),
        format!("{},{},{}", s[0], s[1], s[2]),
        "--basis-components".into(),
        o.basis_components.to_string(),
    ];
    if o.refine_normals {
        if let Some(u) = &o.refine_unknowns {
            cmd_args.push("--refine-unknowns".into());
            cmd_args.push(u.clone());
        }
    } else {
        cmd_args.push("--no-refine-normals".into());
    }
    if o.all_pixels {
        cmd_args.push("--all-pixels".into());
    }
    if let Some(f) = o.basis_fit {
        cmd_args.extend(["--basis-fit".into(), f.name().into()]);
    }
    if o.seed != 1 {
        cmd_args.extend(["--seed".into(), o.seed.to_string()]);
    }
    let uptime = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    detail(&format!("timed: brdf-rig {}", cmd_args.join(" ")));
    let t = Instant::now();
    let status = std::process::Command::new(&o.exe)
        .args(&cmd_args)
        .status()?;
    let wall = t.elapsed().as_secs_f64();
    if !status.success() {
        return Err(BenchError::Invalid(
            "the timed reconstruction failed".into(),
        ));
    }
    let report = report_file::read(&out_dir)?;
    let table = MerlTable::read(&out_dir.join(report_file::BRDF_FILE))?;
    let e = err(&bins, truth_of(&o.material)?, &table);
    detail("rendered error: the sphere probe under the standard environment");
    let env = crate::eval::Truth::new(truth_of(&o.material)?, 3)
        .errors_of(&table)
        .environment;

    let mut md = String::new();
    writeln!(md, "# Reconstruction benchmark\n")?;
    writeln!(
        md,
        "Made by `{}` on {}.\n\nGround truth and basis: neural fits of the MERL materials (Sztrajman et al. 2021), smooth approximations of the measurements, **not measured MERL data**. The target material is always left out of the basis.\n",
        o.command,
        crate::eval::host::machine()
    )?;
    writeln!(md, "## Time and memory (paper scale)\n")?;
    writeln!(
        md,
        "Stanford Bunny ({} single-light images at {}x{}, SfM-like mesh: Taubin smoothing + normal noise, `geometry::sfm_like` defaults), material {}, basis stride {:?}, {} components, basis read from the cache (building it took {:.1} s in the bench process; cached afterwards). Child process `brdf-rig {}`: wall {:.2} s, peak memory (VmHWM) {:.0} MiB; load average before it (/proc/loadavg) {}.\n",
        o.views,
        o.width,
        o.height,
        o.material,
        s,
        o.basis_components,
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
    let study: Vec<String> = if o.study.iter().any(|m| m == "paper") {
        PAPER_MATERIALS.iter().map(|s| s.to_string()).collect()
    } else {
        o.study.clone()
    };
    let (study_width, study_height) = o.study_size;
    if !study.is_empty() {
        writeln!(md, "## Accuracy: assumptions, ablation, baselines\n")?;
        writeln!(
            md,
            "Bunny, {} views at {}x{}, SfM-like mesh; cosine-weighted relative error (docs/error-metrics.md) over every 3rd MERL bin above the horizon; baselines fitted to every observed pixel. Lower is better.\n",
            o.views, study_width, study_height
        )?;
        writeln!(
            md,
            "| material | all three | none | no curvature | no monotonicity | no brightest | Lambert | Lambert+GGX | k, eta | best trial similarity |\n|---|---:|---:|---:|---:|---:|---:|---:|---|---:|"
        )?;
    }
    for m in &study {
        detail(&format!("study: {m}"));
        let truth = truth_of(m)?;
        let settings = settings_for(o, m);
        let basis = basis_for(&settings, &mats)?;
        let dir = root.join(format!("study-{m}"));
        let job = scene(&dir, &mesh_path, truth, o.views, study_width, study_height)?;
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
            return Err(BenchError::Invalid(format!(
                "{m}: the baselines could not be fitted to the observed pixels"
            )));
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
        detail(md.lines().last().unwrap_or_default());
    }
    if let Some(w) = &o.write {
        write_file(w, &md)?;
    }
    Ok(md)
}
