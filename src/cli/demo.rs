//! `brdf-rig demo --out DIR`: the whole story on the simulated rig, as the README's main
//! command: a quick capture over the real serial stack (simulated firmware on a pseudo-terminal,
//! simulated camera), calibration of the session, reconstruction, and the HTML report. Each step
//! is the same subcommand a user would run by hand, called through the same parser, so the demo
//! cannot drift from the commands it shows.

use anyhow::{Context, Result, bail};
use clap::{Args, Parser};
use std::ffi::OsString;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// The quick plan, built in so the demo runs from anywhere.
const QUICK_PLAN: &str = include_str!("../../capture-plans/quick.toml");

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Folder for everything the demo makes (created; must be new or empty).
    #[arg(long)]
    pub out: PathBuf,
    /// Capture plan (default: the built-in quick plan, 320x240 images, capture-plans/quick.toml).
    #[arg(long)]
    pub plan: Option<PathBuf>,
}

fn step(name: &str, args: Vec<OsString>) -> Result<()> {
    errln!("\n=== {name}: brdf-rig {}", shown(&args));
    let mut argv = vec![OsString::from("brdf-rig")];
    argv.extend(args);
    let cli = super::Cli::try_parse_from(argv).with_context(|| format!("{name}: bad arguments"))?;
    let code = super::run(cli).with_context(|| format!("{name} failed"))?;
    if code != ExitCode::SUCCESS {
        bail!("{name} did not succeed");
    }
    Ok(())
}

fn shown(args: &[OsString]) -> String {
    args.iter()
        .map(|a| a.to_string_lossy().into_owned())
        .collect::<Vec<_>>()
        .join(" ")
}

fn os(s: impl AsRef<std::ffi::OsStr>) -> OsString {
    s.as_ref().to_os_string()
}

/// The simulated material (a neural MERL fit) from the session's ground truth.
fn truth_material(session: &Path) -> Result<String> {
    Ok(brdf_rig::sim::truth::read_truth(session)?.scene.material)
}

pub fn run(a: DemoArgs) -> Result<ExitCode> {
    let t0 = Instant::now();
    if a.out.exists()
        && std::fs::read_dir(&a.out)
            .with_context(|| format!("reading {}", a.out.display()))?
            .next()
            .is_some()
    {
        bail!(
            "{} is not empty: give a new folder, so the demo never mixes runs",
            a.out.display()
        );
    }
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let plan = match a.plan {
        Some(p) => p,
        None => {
            let p = a.out.join("quick-plan.toml");
            brdf_rig::atomic::write_atomic(&p, QUICK_PLAN.as_bytes())
                .with_context(|| format!("writing {}", p.display()))?;
            p
        }
    };
    let session = a.out.join("session");
    let recon = a.out.join("reconstruction");

    step(
        "capture",
        vec![
            os("capture"),
            os("--plan"),
            os(&plan),
            os("--out"),
            os(&session),
            os("--unattended"),
        ],
    )?;
    step("calibrate", vec![os("calibrate"), os(&session)])?;
    let material = truth_material(&session)?;
    step(
        "reconstruct",
        vec![
            os("reconstruct"),
            os(session.join(brdf_rig::reconstruct::job::JOB_FILE)),
            os("--out"),
            os(&recon),
            // the simulated material is the target: it must not be in the basis
            os("--exclude"),
            os(&material),
        ],
    )?;
    let truth = brdf_rig::brdf::nbrdf::default_dir().join(format!("{material}.f32"));
    let report = a.out.join("report.html");
    step(
        "report",
        vec![
            os("report"),
            os(&recon),
            os("--out"),
            os(&report),
            os("--compare"),
            os(format!(
                "truth ({material}, neural MERL fit)={}",
                truth.display()
            )),
        ],
    )?;
    errln!(
        "\ndemo finished in {:.0} s: session {}, BRDF {}, report {}",
        t0.elapsed().as_secs_f64(),
        session.display(),
        recon
            .join(brdf_rig::reconstruct::report_file::BRDF_FILE)
            .display(),
        report.display()
    );
    outln!("{}", report.display());
    Ok(ExitCode::SUCCESS)
}
