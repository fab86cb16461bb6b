//! The `brdf-rig` binary's rig commands, run the way a user runs them, on the built-in
//! simulated rig (each invocation spawns its own simulated firmware on a pty).

#![allow(clippy::unwrap_used)] // a panic in a test is a failed test

use assert_cmd::Command;
use serialport::SerialPort;

use crate::util;

fn brdf_rig() -> Command {
    let mut c = Command::new(util::bin());
    c.env_remove("BRDF_RIG_PROFILE");
    c
}

fn stdout_of(args: &[&str]) -> String {
    let out = brdf_rig().args(args).output().unwrap();
    assert!(
        out.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn rig_check_prints_the_handshake() {
    let out = stdout_of(&["rig", "check"]);
    assert!(out.contains("firmware:   brdf-sim"), "{out}");
    assert!(out.contains("protocol:   1.0"), "{out}");
    assert!(out.contains("boot:       1"), "{out}");
    assert!(out.contains("speed 90 deg/s"), "{out}");
    assert!(out.contains("light 2:    far"), "{out}");
}

#[test]
fn rig_check_fails_when_nothing_answers() {
    // A pty where no firmware listens: `--port` without a profile is a real board, so the
    // handshake waits out the boot window, then times out.
    let (_master, slave) = brdf_rig::sim::runner::pty_pair().unwrap();
    let path = slave.name().unwrap();
    drop(slave);
    let out = brdf_rig()
        .args(["rig", "check", "--port", &path])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no reply"), "{err}");
    assert!(err.contains(&path), "{err}");
    assert!(err.contains("2500 ms boot window"), "{err}");
}

#[test]
fn turntable_move_homes_first_and_lands_on_the_angle() {
    let out = stdout_of(&["turntable", "move", "-42.5"]);
    assert_eq!(
        out.trim(),
        "angle -42.500 deg, target -42.500 deg, homed, at rest"
    );
    let out = stdout_of(&["turntable", "move", "30", "--relative"]);
    assert!(out.starts_with("angle 30.000 deg"), "{out}");
}

#[test]
fn light_on_waits_for_a_stable_channel() {
    let out = stdout_of(&["light", "on", "1", "--level", "0.5"]);
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines.len(), 3, "{out}");
    assert!(lines[1].contains("level 0.500 stable"), "{out}");
    assert!(
        lines[0].contains("off") && lines[2].contains("off"),
        "{out}"
    );
}

#[test]
fn limits_and_bad_profiles_give_clear_errors() {
    // A level no light has is refused when the command line is parsed...
    let out = brdf_rig()
        .args(["light", "on", "0", "--level", "1.5"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("must be a finite number in (0, 1]"), "{err}");
    // ... and one above the channel's max_level by the driver, before anything is sent.
    let dir = tempfile::tempdir().unwrap();
    let capped = dir.path().join("capped.toml");
    let text = brdf_rig::profile::SIMULATED.replacen(
        "name = \"near\"\nmax_level = 1.0",
        "name = \"near\"\nmax_level = 0.5",
        1,
    );
    assert_ne!(text, brdf_rig::profile::SIMULATED);
    std::fs::write(&capped, &text).unwrap();
    let out = brdf_rig()
        .args(["light", "on", "0", "--level", "0.8"])
        .args(["--profile", capped.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("outside the limits") && err.contains("(0, 0.5]"),
        "{err}"
    );

    let p = dir.path().join("typo.toml");
    let text = brdf_rig::profile::SIMULATED.replace("retries = 5", "retrys = 5");
    std::fs::write(&p, &text).unwrap();
    let line = text.lines().position(|l| l.starts_with("retrys")).unwrap() + 1;
    let out = brdf_rig()
        .args(["rig", "check", "--profile", p.to_str().unwrap()])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(&format!("typo.toml:{line}: serial.retrys: unknown field")),
        "{err}"
    );
}

/// The standalone simulated firmware keeps its state between CLI invocations and takes fault
/// commands on stdin.
#[test]
fn standalone_simulated_firmware_serves_several_invocations() {
    use std::io::{BufRead, BufReader, Write};
    use std::process::{Command as Std, Stdio};

    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("rig");
    /// Kills the program if the test fails half-way (it serves until killed).
    struct Reap(std::process::Child);
    impl Drop for Reap {
        fn drop(&mut self) {
            let _ = self.0.kill();
            let _ = self.0.wait();
        }
    }
    let child = Std::new(env!("CARGO_BIN_EXE_brdf-rig-simfw"))
        .arg("--link")
        .arg(&link)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut child = Reap(child);
    let mut out = BufReader::new(child.0.stdout.take().unwrap());
    let mut first = String::new();
    out.read_line(&mut first).unwrap();
    assert_eq!(first.trim(), link.to_str().unwrap());
    let port = link.to_str().unwrap();

    let moved = stdout_of(&["turntable", "move", "45", "--port", port]);
    assert!(moved.starts_with("angle 45.000 deg"), "{moved}");
    let again = stdout_of(&["turntable", "status", "--port", port]);
    assert!(
        again.starts_with("angle 45.000 deg"),
        "state persists: {again}"
    );
    assert!(again.contains(" homed"), "{again}");

    let mut stdin = child.0.stdin.take().unwrap();
    writeln!(stdin, "reset").unwrap();
    stdin.flush().unwrap();
    let t = std::time::Instant::now();
    let check = loop {
        let c = stdout_of(&["rig", "check", "--port", port]);
        if c.contains("boot:       2") || t.elapsed() > std::time::Duration::from_secs(5) {
            break c;
        }
    };
    assert!(check.contains("boot:       2"), "{check}");
    assert!(check.contains("not homed"), "{check}");
    writeln!(stdin, "quit").unwrap();
    drop(stdin);
    let status = child.0.wait().unwrap();
    assert!(status.success());
}
