//! `brdf-rig report DIR [--out FILE]`: a self-contained HTML page about a capture session folder
//! or a reconstruction output folder (capture summary, calibration, in-plane BRDF plot, sphere
//! renders, trials, timing, warnings). Prints the path written.

use anyhow::{Context, bail};
use brdf_rig::report::inplane::InPlaneSettings;
use brdf_rig::report::options::ReportOptions;
use clap::Args;
use std::path::PathBuf;

use super::ranges::{Open, real_in};
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// A session folder (manifest.json) or a reconstruction output folder (brdf.binary,
    /// report.json).
    pub dir: PathBuf,
    /// Where to write the page [default: DIR/report.html].
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
    /// Another BRDF to draw in the in-plane plot, as LABEL=PATH (a MERL .binary or a neural
    /// MERL fit .f32); repeatable.
    #[arg(long, value_name = "LABEL=PATH")]
    pub compare: Vec<String>,
    /// Linear f_r axis in the in-plane plot (default: logarithmic).
    #[arg(long)]
    pub linear: bool,
    /// Light angle of the in-plane plot, degrees from the +x axis (135 = theta_i 45 degrees, the
    /// paper's).
    /// Strictly between 0 and 180 (above the surface).
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 135.0,
        value_parser = real_in(Open(0.0), Open(180.0))
    )]
    pub light_deg: f64,
    /// Do not re-read session images to check their SHA-256 (faster on big sessions).
    #[arg(long)]
    pub no_verify: bool,
}

/// Raw arguments to a checked configuration, before any file is read.
fn options(a: &ReportArgs) -> anyhow::Result<ReportOptions> {
    let mut compare = Vec::new();
    for c in &a.compare {
        let Some((label, path)) = c.split_once('=') else {
            bail!(
                "--compare {c:?}: expected LABEL=PATH, e.g. truth=data/merl-nbrdf/alum-bronze.f32"
            );
        };
        if label.trim().is_empty() || path.trim().is_empty() {
            bail!("--compare {c:?}: both LABEL and PATH must be given");
        }
        compare.push((label.trim().to_string(), PathBuf::from(path.trim())));
    }
    Ok(ReportOptions {
        inplane: InPlaneSettings {
            light_alpha_deg: a.light_deg,
            ..InPlaneSettings::default()
        },
        log_y: !a.linear,
        compare,
        verify_checksums: !a.no_verify,
        ..ReportOptions::default()
    })
}

pub fn run(a: ReportArgs) -> anyhow::Result<ExitCode> {
    let opts = options(&a)?;
    let (path, data) = brdf_rig::report::write_report(&a.dir, a.out.as_deref(), &opts)
        .with_context(|| format!("making the report of {}", a.dir.display()))?;
    if let brdf_rig::report::avail::Avail::Yes(b) = &data.brdf {
        for m in &b.missing {
            errln!("warning: comparison not shown: {m}");
        }
    }
    outln!("{}", path.display());
    Ok(ExitCode::SUCCESS)
}
