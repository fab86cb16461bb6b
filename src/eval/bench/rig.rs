//! `brdf-rig bench rig`: STATUS round trip and controller overhead per step over a pty to the
//! simulated firmware ([`crate::eval::rig`]), as a markdown page.

use std::path::PathBuf;

use super::{BenchError, Note, write_file};
use crate::eval::rig::{self as bench, RigBenchOptions};
use crate::profile::Profile;

/// The options of `bench rig`.
#[derive(Clone, Debug)]
pub struct RigPageOptions {
    /// A profile with `port = "sim"` (`None`: the built-in simulated rig).
    pub profile: Option<PathBuf>,
    pub bench: RigBenchOptions,
    /// Where the page is written, besides being returned.
    pub write: Option<PathBuf>,
    /// The command as typed, quoted by the page.
    pub command: String,
}

/// Runs the benchmark; notes the steps much slower than the median; returns the page.
pub fn run(o: &RigPageOptions, note: &mut dyn FnMut(Note<'_>)) -> Result<String, BenchError> {
    let profile = match &o.profile {
        Some(p) => Profile::load(p),
        None => Profile::simulated(),
    }?;
    if !profile.is_simulated() {
        return Err(BenchError::Invalid(format!(
            "{}: bench rig needs a profile with port = \"sim\"",
            profile.origin
        )));
    }
    let machine = crate::eval::host::machine();
    let report = bench::run(&profile, &o.bench)
        .map_err(|e| BenchError::step("running the rig benchmark", e))?;
    for (i, w) in report.walls.iter().enumerate() {
        if *w > report.step_wall[0] * 3 / 2 {
            note(Note::Detail(&format!(
                "note: step {} took {:.1} ms (median {:.1} ms)",
                i + 1,
                w.as_secs_f64() * 1e3,
                report.step_wall[0].as_secs_f64() * 1e3
            )));
        }
    }
    let md = report.markdown(&o.command, &machine);
    if let Some(w) = &o.write {
        write_file(w, &md)?;
    }
    Ok(md)
}
