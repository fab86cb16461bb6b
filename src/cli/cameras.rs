//! `brdf-rig cameras`: what each camera backend finds attached.

use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

use brdf_rig::devices::cameras::list_all;

#[derive(Args, Debug)]
pub struct CamerasArgs {
    /// The gphoto2 program used for DSLRs.
    #[arg(long, default_value = "gphoto2")]
    pub gphoto2: PathBuf,
}

pub fn run(args: CamerasArgs) -> anyhow::Result<ExitCode> {
    for listing in list_all(&args.gphoto2) {
        outln!("{}:", listing.backend);
        if let Some(why) = &listing.unavailable {
            outln!("  unavailable: {why}");
        } else if listing.cameras.is_empty() {
            outln!("  none found");
        }
        for (id, name) in &listing.cameras {
            outln!("  {id}  {name}");
        }
    }
    Ok(ExitCode::SUCCESS)
}
