//! `brdf-rig-simfw`: the simulated rig firmware as a standalone program on a pseudo-terminal,
//! for trying the CLI against a rig whose state persists between commands, or for testing
//! another host implementation against the reference behaviour.
//!
//! It prints the port path (a symlink to the current pty) and runs until killed. Faults are
//! injected with flags at start and with commands on stdin, one per line:
//!
//! ```text
//! reset              firmware reset (boot counter + 1, not homed, lights off)
//! unplug MS          the port disappears for MS milliseconds, then comes back at the same path
//! drop RATE          probability that a frame is lost (each direction)
//! corrupt RATE       probability that a frame gets one bit flipped
//! bytes RATE         probability that any single byte is lost
//! delay MS           delay every reply by MS milliseconds
//! state              print angle, lights, boot counter, watchdog trips
//! moves              print every motion executed
//! quit               exit
//! ```

use std::io::BufRead;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::Parser;

use brdf_rig::profile::Profile;
use brdf_rig::rig_factory::sim_config;
use brdf_rig::sim::SimRig;

#[derive(Parser, Debug)]
#[command(
    name = "brdf-rig-simfw",
    about = "Simulated rig firmware on a pseudo-terminal (prints its port path, runs until killed)"
)]
struct Args {
    /// Rig profile the simulated board follows (channels, limits, `[sim]` faults); default: the
    /// built-in simulated profile.
    #[arg(long)]
    profile: Option<PathBuf>,
    /// Path of the port symlink (default: a new temporary directory).
    #[arg(long)]
    link: Option<PathBuf>,
    /// Probability that a frame is lost (each direction).
    #[arg(long)]
    drop_rate: Option<f64>,
    /// Probability that a frame has one bit flipped.
    #[arg(long)]
    corrupt_rate: Option<f64>,
    /// Probability that any single byte is lost.
    #[arg(long, default_value_t = 0.0)]
    byte_drop_rate: f64,
    /// Delay every reply by this many milliseconds.
    #[arg(long, default_value_t = 0)]
    delay_ms: u64,
    /// Seed of the fault generator.
    #[arg(long)]
    seed: Option<u64>,
    /// Ignore what arrives for this many milliseconds after start and after an unplug, as an
    /// Arduino's bootloader does after the reset that opening its port causes (default: the
    /// profile's `[sim] boot_delay_ms`).
    #[arg(long)]
    boot_delay_ms: Option<u64>,
}

fn rate(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(r) if (0.0..=1.0).contains(&r) => Ok(r),
        _ => Err(format!("not a probability in [0, 1]: {s:?}")),
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    let profile = match &args.profile {
        Some(p) => Profile::load(p),
        None => Profile::simulated(),
    };
    let profile = match profile {
        Ok(p) => p,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let mut cfg = sim_config(&profile);
    cfg.link_path = args.link.clone();
    if let Some(r) = args.drop_rate {
        cfg.faults.drop_rate = r;
    }
    if let Some(r) = args.corrupt_rate {
        cfg.faults.corrupt_rate = r;
    }
    if let Some(s) = args.seed {
        cfg.seed = s;
    }
    cfg.faults.byte_drop_rate = args.byte_drop_rate;
    if let Some(ms) = args.boot_delay_ms {
        cfg.boot_delay = Duration::from_millis(ms);
    }
    cfg.faults.reply_delay = Duration::from_millis(args.delay_ms);
    for (name, r) in [
        ("--drop-rate", cfg.faults.drop_rate),
        ("--corrupt-rate", cfg.faults.corrupt_rate),
        ("--byte-drop-rate", cfg.faults.byte_drop_rate),
    ] {
        if !(0.0..=1.0).contains(&r) {
            eprintln!("error: {name} must be in [0, 1], got {r}");
            return ExitCode::from(2);
        }
    }
    let sim = match SimRig::spawn(cfg) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: cannot create the pseudo-terminal: {e}");
            return ExitCode::from(1);
        }
    };
    println!("{}", sim.port_path.display());
    eprintln!(
        "simulated firmware on {} (use: brdf-rig rig check --port {}); commands on stdin: \
         reset, unplug MS, drop RATE, corrupt RATE, bytes RATE, delay MS, state, moves, quit",
        sim.port_path.display(),
        sim.port_path.display()
    );
    let stdin = std::io::stdin();
    for line in stdin.lock().lines() {
        let Ok(line) = line else { break };
        let words: Vec<&str> = line.split_whitespace().collect();
        let mut f = sim.faults.get();
        let result: Result<(), String> = match words.as_slice() {
            [] => Ok(()),
            ["reset"] => {
                sim.faults.reset();
                Ok(())
            }
            ["unplug", ms] => ms
                .parse::<u64>()
                .map(|ms| sim.faults.unplug(Duration::from_millis(ms)))
                .map_err(|_| format!("not a number of milliseconds: {ms:?}")),
            ["drop", r] => rate(r).map(|r| f.drop_rate = r),
            ["corrupt", r] => rate(r).map(|r| f.corrupt_rate = r),
            ["bytes", r] => rate(r).map(|r| f.byte_drop_rate = r),
            ["delay", ms] => ms
                .parse::<u64>()
                .map(|ms| f.reply_delay = Duration::from_millis(ms))
                .map_err(|_| format!("not a number of milliseconds: {ms:?}")),
            ["state"] => {
                println!("{:?}", sim.state.snapshot());
                Ok(())
            }
            ["moves"] => {
                for m in sim.state.moves() {
                    println!("{m:?}");
                }
                Ok(())
            }
            ["quit"] => return ExitCode::SUCCESS,
            _ => Err(format!("unknown command: {line:?}")),
        };
        match result {
            Ok(()) => sim.faults.set(f),
            Err(e) => eprintln!("error: {e}"),
        }
    }
    // Stdin closed (e.g. started in the background): serve until killed.
    loop {
        std::thread::park();
    }
}
