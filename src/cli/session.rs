//! `brdf-rig session verify DIR`: re-checks every image of a session against its checksum.

use anyhow::Context;
use clap::{Args, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

use brdf_rig::capture::verify_session;

#[derive(Args, Debug)]
pub struct SessionArgs {
    #[command(subcommand)]
    pub command: SessionCommand,
}

#[derive(Subcommand, Debug)]
pub enum SessionCommand {
    /// Re-check every image's SHA-256 and that the session holds exactly its planned shots;
    /// exits non-zero on any mismatch, missing file or missing shot.
    Verify {
        /// The session folder.
        dir: PathBuf,
    },
}

pub fn run(args: SessionArgs) -> anyhow::Result<ExitCode> {
    match args.command {
        SessionCommand::Verify { dir } => verify(dir),
    }
}

fn verify(dir: PathBuf) -> anyhow::Result<ExitCode> {
    let report = verify_session(&dir)
        .with_context(|| format!("verifying the session in {}", dir.display()))?;
    outln!(
        "session {} (plan `{}`, {}): {} of {} planned shots, {:.1} MiB checked",
        dir.display(),
        report.header.plan_name,
        report.header.camera_backend,
        report.checked,
        report.planned,
        report.bytes as f64 / (1024.0 * 1024.0)
    );
    for (id, retake) in &report.retaken {
        outln!(
            "  re-taken by a resume: {id} ({}{})",
            retake.reason,
            retake
                .set_aside
                .as_ref()
                .map(|f| format!("; the damaged file is {f}"))
                .unwrap_or_default()
        );
    }
    for p in &report.problems {
        outln!("  BAD  {p}");
    }
    if !report.complete() {
        outln!(
            "  INCOMPLETE: {} planned shot(s) not taken (first: {}); continue with `brdf-rig capture --resume {}`",
            report.not_taken.len(),
            report.not_taken[0],
            dir.display()
        );
    }
    if report.intact() && report.complete() {
        outln!("  OK: every checksum matches and every planned shot is present");
        Ok(ExitCode::SUCCESS)
    } else if !report.intact() {
        outln!("  FAILED: {} problem(s)", report.problems.len());
        Ok(ExitCode::from(2))
    } else {
        Ok(ExitCode::from(3))
    }
}
