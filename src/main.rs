//! The `brdf-rig` binary: parse, run, print the error chain, return an exit code.

mod cli;

use clap::Parser;

fn main() -> std::process::ExitCode {
    let args = cli::Cli::parse();
    match cli::run(args) {
        Ok(code) => code,
        Err(err) => {
            cli::output::err(format_args!("error: {err}"), true);
            for cause in err.chain().skip(1) {
                cli::output::err(format_args!("  caused by: {cause}"), true);
            }
            std::process::ExitCode::from(1)
        }
    }
}
