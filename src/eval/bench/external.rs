//! `brdf-rig bench external`: the reconstruction on scenes rendered by an independent renderer
//! (`scripts/render_recon_scenes.py`) through [`crate::eval::external`], against least-squares
//! Lambert and Lambert + GGX fits to the same pixels; writes external.md and external.json under
//! the output folder (after every run).

use std::path::PathBuf;

use super::{BenchError, Note, create_dir, write_file};
use crate::brdf::basis::BasisSettings;
use crate::brdf::{basis_cache, nbrdf};
use crate::eval::external::{self, ExternalResult};
use crate::reconstruct::Settings;

/// The options of `bench external`.
#[derive(Clone, Debug)]
pub struct ExternalBenchOptions {
    /// A scene set (holds index.json).
    pub scenes: PathBuf,
    /// Job variants to run.
    pub jobs: Vec<String>,
    /// Reconstruction seeds: each job runs once per seed.
    pub seeds: Vec<u64>,
    /// Errors over every N-th MERL bin.
    pub bin_step: usize,
    /// The reconstruction's settings (its neural MERL fits build the basis).
    pub settings: Settings,
    /// The basis cache (`None`: [`basis_cache::default_cache_dir`]).
    pub basis_cache: Option<PathBuf>,
    /// Folder of external.md and external.json.
    pub out: PathBuf,
    /// The command as typed, quoted by the pages.
    pub command: String,
}

/// Every run, and the markdown page written.
pub struct ExternalBench {
    pub results: Vec<ExternalResult>,
    pub markdown: String,
}

/// One run's summary line.
pub fn run_summary(r: &ExternalResult) -> String {
    if let Some(x) = &r.split {
        let ratios: Vec<String> = x
            .materials
            .iter()
            .map(|m| {
                format!(
                    "{} {}",
                    m.truth,
                    m.ratio().map_or("-".to_string(), |v| format!("{v:.2}"))
                )
            })
            .collect();
        return format!(
            "  {} {}: {} materials found ({} true), agreement {:.3}, ratios {}",
            r.scene,
            r.job,
            x.count,
            x.truth_count,
            x.agreement,
            ratios.join(", ")
        );
    }
    format!(
        "  {} {}: ours env {}, ratio {}",
        r.scene,
        r.job,
        r.ours
            .as_ref()
            .map_or_else(|e| e.clone(), |e| format!("{:.3}", e.environment)),
        r.ratio().map_or("-".to_string(), |x| format!("{x:.2}"))
    )
}

pub fn run(
    o: &ExternalBenchOptions,
    note: &mut dyn FnMut(Note<'_>),
) -> Result<ExternalBench, BenchError> {
    let settings = &o.settings;
    let materials =
        nbrdf::load_dir(&settings.nbrdf_dir).map_err(|source| BenchError::Materials {
            dir: settings.nbrdf_dir.clone(),
            source,
        })?;
    let cache = o
        .basis_cache
        .clone()
        .unwrap_or_else(basis_cache::default_cache_dir);
    // One basis per list of left-out materials, built (or read from the cache) when a scene
    // first asks for it.
    let mut bases: std::collections::HashMap<Vec<String>, std::rc::Rc<crate::brdf::basis::Basis>> =
        std::collections::HashMap::new();
    let mut basis_for = |exclude: &[String]| {
        let key = exclude.to_vec();
        if let Some(b) = bases.get(&key) {
            return Ok(b.clone());
        }
        let basis_settings = BasisSettings {
            exclude: key.clone(),
            ..BasisSettings::default()
        };
        let (basis, _) = basis_cache::load_or_build(&basis_settings, &materials, &cache)?;
        let b = std::rc::Rc::new(basis);
        bases.insert(key, b.clone());
        Ok(b)
    };
    let command = &o.command;
    let machine = crate::eval::host::machine();
    create_dir(&o.out)?;
    let write = |results: &[ExternalResult]| -> Result<(), BenchError> {
        let md = external::markdown(results, command, &machine);
        write_file(&o.out.join("external.md"), &md)?;
        let json =
            serde_json::json!({ "command": command, "machine": machine, "results": results });
        write_file(
            &o.out.join("external.json"),
            serde_json::to_string_pretty(&json)?,
        )
    };
    let mut done = Vec::new();
    let mut write_err = None;
    // both callbacks report through `note`
    let note = std::cell::RefCell::new(note);
    let results = external::run(
        &o.scenes,
        &o.jobs,
        &o.seeds,
        settings,
        &mut basis_for,
        o.bin_step,
        &mut |line| (note.borrow_mut())(Note::Step(line)),
        &mut |r| {
            (note.borrow_mut())(Note::Detail(&run_summary(r)));
            done.push(r.clone());
            if let Err(e) = write(&done) {
                write_err = Some(e);
            }
        },
    )
    .map_err(|e| BenchError::step(format!("running the scenes of {}", o.scenes.display()), e))?;
    if let Some(e) = write_err {
        return Err(e);
    }
    write(&results)?;
    let markdown = external::markdown(&results, command, &machine);
    Ok(ExternalBench { results, markdown })
}
