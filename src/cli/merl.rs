//! `brdf-rig merl ...`: look at BRDF files from the command line.
//!
//! `eval FILE THETA_IN PHI_IN THETA_OUT PHI_OUT` prints f_r (1/sr, R G B) for one pair of
//! directions given in degrees (spherical angles in the local frame, normal = +z). FILE is a MERL
//! `.binary` table, or a neural MERL fit (`.f32`, evaluated at the exact angles).
//! `tabulate NBRDF OUT` writes the full MERL table of a neural fit (a smooth approximation of the
//! MERL measurement, not measured data).
//! `compare REFERENCE CANDIDATE` scores a BRDF against a reference as an image sees it: the
//! errors of docs/error-metrics.md (a sphere rendered under the standard environment and novel
//! lights, the solid-angle weighted table error, the log-space error, the old peak-dominated
//! cosine-weighted error), for a user who has a reference (a gonioreflectometer table, or the
//! truth of a rendered scene).

use anyhow::{Context, bail};
use brdf_rig::brdf::Brdf;
use brdf_rig::brdf::merl::MerlTable;
use brdf_rig::brdf::nbrdf::Nbrdf;
use clap::{Args, Subcommand};
use nalgebra::Vector3;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Args, Debug)]
pub struct MerlArgs {
    #[command(subcommand)]
    pub command: MerlCommand,
}

#[derive(Subcommand, Debug)]
pub enum MerlCommand {
    /// Print f_r (1/sr, R G B) of a MERL .binary or neural .f32 file for one direction pair.
    #[command(allow_negative_numbers = true)]
    Eval {
        file: PathBuf,
        /// Polar angle of the light direction, degrees from the normal.
        theta_in: f64,
        /// Azimuth of the light direction, degrees.
        phi_in: f64,
        /// Polar angle of the view direction, degrees from the normal.
        theta_out: f64,
        /// Azimuth of the view direction, degrees.
        phi_out: f64,
    },
    /// Write the full MERL table of a neural fit (.f32) to a .binary file.
    Tabulate { nbrdf: PathBuf, out: PathBuf },
    /// Score a BRDF against a reference as images see it (docs/error-metrics.md).
    Compare {
        /// The reference: a MERL .binary table or a neural .f32 fit.
        reference: PathBuf,
        /// The BRDF to score: a MERL .binary table or a neural .f32 fit.
        candidate: PathBuf,
        /// Table errors over every N-th MERL bin (1: all 1.46 million).
        #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u64).range(1..=1000))]
        bin_step: u64,
    },
}

fn direction(theta_deg: f64, phi_deg: f64, what: &str) -> anyhow::Result<Vector3<f64>> {
    if !theta_deg.is_finite() || !phi_deg.is_finite() || !(0.0..=90.0).contains(&theta_deg) {
        bail!(
            "{what}: theta must be within 0..=90 degrees and angles finite, got {theta_deg}, {phi_deg}"
        );
    }
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    Ok(Vector3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos()))
}

impl brdf_rig::brdf::BinValues for Loaded {
    fn values_at(&self, bins: &[usize]) -> Vec<[f64; 3]> {
        match self {
            Loaded::Neural(n) => n.values_at(bins),
            Loaded::Table(t) => t.values_at(bins),
        }
    }
}

/// A BRDF file: a neural fit (evaluated exactly) or a MERL table (nearest bin, may lack data).
enum Loaded {
    Neural(Nbrdf),
    Table(MerlTable),
}

impl Loaded {
    fn as_merl(&self) -> Option<&MerlTable> {
        match self {
            Loaded::Table(t) => Some(t),
            Loaded::Neural(_) => None,
        }
    }

    fn eval_local(&self, wi: &Vector3<f64>, wo: &Vector3<f64>) -> [f64; 3] {
        match self {
            Loaded::Neural(n) => n.eval_local(wi, wo),
            Loaded::Table(t) => t.eval_local(wi, wo),
        }
    }
}

fn load(file: &Path) -> anyhow::Result<Loaded> {
    if file.extension().is_some_and(|e| e == "f32") {
        Ok(Loaded::Neural(Nbrdf::load(file)?))
    } else {
        Ok(Loaded::Table(MerlTable::read(file)?))
    }
}

pub fn run(args: MerlArgs) -> anyhow::Result<ExitCode> {
    match args.command {
        MerlCommand::Eval {
            file,
            theta_in,
            phi_in,
            theta_out,
            phi_out,
        } => {
            let wi = direction(theta_in, phi_in, "light direction")?;
            let wo = direction(theta_out, phi_out, "view direction")?;
            let brdf = load(&file).with_context(|| format!("loading BRDF {}", file.display()))?;
            if let Some(table) = brdf.as_merl()
                && table
                    .lookup(&brdf_rig::brdf::coords::HalfDiff::from_directions(&wi, &wo))
                    .is_none()
            {
                errln!(
                    "warning: {}: the table has no data (a negative value) in the bin of these \
                     directions; f_r is given as 0",
                    file.display()
                );
            }
            let [r, g, b] = brdf.eval_local(&wi, &wo);
            outln!("{r:.9e} {g:.9e} {b:.9e}");
        }
        MerlCommand::Tabulate { nbrdf, out } => {
            let net = Nbrdf::load(&nbrdf)?;
            net.tabulate()
                .write(&out)
                .with_context(|| format!("tabulating {}", nbrdf.display()))?;
        }
        MerlCommand::Compare {
            reference,
            candidate,
            bin_step,
        } => {
            let r = load(&reference)
                .with_context(|| format!("loading the reference {}", reference.display()))?;
            let c = load(&candidate)
                .with_context(|| format!("loading the candidate {}", candidate.display()))?;
            let truth = brdf_rig::eval::Truth::new(&r, bin_step as usize);
            let e = truth.errors_of(&c);
            outln!(
                "environment (relative L2 of the rendered sphere): {:.4}",
                e.environment
            );
            outln!(
                "environment PSNR (tone-mapped): {:.2} dB",
                e.environment_psnr_db
            );
            outln!("novel lights (relative L2): {:.4}", e.lights);
            outln!("table, solid-angle weighted: {:.4}", e.solid_angle);
            outln!("table, log space: {:.4}", e.log);
            outln!(
                "table, cosine weighted (peak-dominated): {:.4}",
                e.cosine_weighted
            );
        }
    }
    Ok(ExitCode::SUCCESS)
}
