//! `brdf-rig firmware flash`: the avrdude command that writes the reference firmware
//! (`firmware-protocol/firmware/`) to an Arduino Mega 2560 through its stk500v2 bootloader.
//! Prints the command; runs it only with `--run` and when avrdude is on PATH.

use anyhow::{Context, bail};
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode};

/// Where `make -C firmware-protocol/firmware` puts the board build.
pub const DEFAULT_HEX: &str = "firmware-protocol/firmware/build/firmware.hex";
/// The Mega 2560's USB serial (16U2) on Linux.
pub const DEFAULT_PORT: &str = "/dev/ttyACM0";

#[derive(Subcommand, Debug)]
pub enum FirmwareCommand {
    /// Print (or with --run, execute) the avrdude command that flashes a Mega 2560.
    Flash(FlashArgs),
}

#[derive(Args, Debug)]
pub struct FlashArgs {
    /// Serial port of the board.
    #[arg(long, default_value = DEFAULT_PORT)]
    pub port: String,
    /// Intel-hex image to write (built by `make -C firmware-protocol/firmware`).
    #[arg(long, default_value = DEFAULT_HEX)]
    pub hex: PathBuf,
    /// Run the command (needs avrdude on PATH) instead of only printing it.
    #[arg(long)]
    pub run: bool,
}

pub fn run(command: FirmwareCommand) -> anyhow::Result<ExitCode> {
    match command {
        FirmwareCommand::Flash(args) => flash(args),
    }
}

/// The avrdude arguments for a Mega 2560: `-c wiring` is the stk500v2 bootloader's protocol
/// with the DTR reset Arduino boards need; `-D` skips the chip erase the bootloader cannot do.
pub fn avrdude_args(port: &str, hex: &Path) -> anyhow::Result<Vec<String>> {
    if port.trim().is_empty() {
        bail!("the serial port is empty; give one with --port (e.g. {DEFAULT_PORT})");
    }
    let hex_str = hex
        .to_str()
        .with_context(|| format!("the hex path {} is not valid UTF-8", hex.display()))?;
    if hex_str.contains(':') {
        // avrdude splits `-U memtype:op:file:format` at colons.
        bail!(
            "the hex path {hex_str} contains ':', which avrdude's -U option cannot take; \
             copy the file to a path without one"
        );
    }
    Ok([
        "-p",
        "atmega2560",
        "-c",
        "wiring",
        "-P",
        port,
        "-b",
        "115200",
        "-D",
        "-U",
        &format!("flash:w:{hex_str}:i"),
    ]
    .iter()
    .map(|s| s.to_string())
    .collect())
}

/// The command line as a user would type it (arguments with shell metacharacters quoted).
pub fn render(program: &str, args: &[String]) -> String {
    std::iter::once(program.to_string())
        .chain(args.iter().map(|a| shell_quote(a)))
        .collect::<Vec<_>>()
        .join(" ")
}

fn shell_quote(arg: &str) -> String {
    let plain = !arg.is_empty()
        && arg
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./:=@%+,".contains(c));
    if plain {
        arg.to_string()
    } else {
        format!("'{}'", arg.replace('\'', r"'\''"))
    }
}

/// The first `avrdude` among the PATH entries.
fn find_on_path(program: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH")?;
    std::env::split_paths(&path)
        .map(|dir| dir.join(program))
        .find(|candidate| candidate.is_file())
}

fn flash(args: FlashArgs) -> anyhow::Result<ExitCode> {
    let avr_args = avrdude_args(&args.port, &args.hex)?;
    outln!("{}", render("avrdude", &avr_args));
    if !args.run {
        return Ok(ExitCode::SUCCESS);
    }
    if !args.hex.is_file() {
        bail!(
            "the firmware image {} does not exist; build it with `make -C firmware-protocol/firmware`",
            args.hex.display()
        );
    }
    let avrdude = find_on_path("avrdude").context(
        "avrdude is not on PATH; install it (Debian: apt-get install avrdude) or run the \
         printed command on a machine that has it",
    )?;
    let status = Command::new(&avrdude)
        .args(&avr_args)
        .status()
        .with_context(|| format!("could not start {}", avrdude.display()))?;
    if !status.success() {
        bail!(
            "avrdude failed ({status}) flashing {} on {}; check the port and that nothing else \
             holds it open",
            args.hex.display(),
            args.port
        );
    }
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builds_the_mega_2560_command() {
        let args = avrdude_args("/dev/ttyACM1", Path::new("build/firmware.hex")).expect("valid");
        assert_eq!(
            render("avrdude", &args),
            "avrdude -p atmega2560 -c wiring -P /dev/ttyACM1 -b 115200 -D \
             -U flash:w:build/firmware.hex:i"
        );
    }

    #[test]
    fn quotes_paths_with_spaces() {
        let args = avrdude_args("/dev/ttyACM0", Path::new("my dir/fw.hex")).expect("valid");
        assert_eq!(
            args.last().map(String::as_str),
            Some("flash:w:my dir/fw.hex:i")
        );
        assert!(render("avrdude", &args).ends_with("-U 'flash:w:my dir/fw.hex:i'"));
    }

    #[test]
    fn refuses_what_avrdude_would_misread() {
        let err = avrdude_args("/dev/ttyACM0", Path::new("a:b.hex")).expect_err("colon");
        assert!(err.to_string().contains("contains ':'"), "{err}");
        let err = avrdude_args(" ", Path::new("fw.hex")).expect_err("empty port");
        assert!(err.to_string().contains("--port"), "{err}");
    }
}
