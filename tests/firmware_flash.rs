//! `brdf-rig firmware flash`: the avrdude command for a Mega 2560, printed, and run with `--run`
//! (here against a stand-in avrdude on PATH that records its arguments).

use crate::util::bin;
use std::process::Command;

#[test]
fn firmware_flash_prints_the_avrdude_command() {
    let out = Command::new(bin())
        .args([
            "firmware",
            "flash",
            "--port",
            "/dev/ttyUSB3",
            "--hex",
            "fw/firmware.hex",
        ])
        .output()
        .expect("run brdf-rig");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        String::from_utf8_lossy(&out.stdout).trim(),
        "avrdude -p atmega2560 -c wiring -P /dev/ttyUSB3 -b 115200 -D -U flash:w:fw/firmware.hex:i"
    );
}

#[test]
fn firmware_flash_run_calls_avrdude_from_path() {
    let dir = tempfile::tempdir().expect("temp dir");
    let log = dir.path().join("args.txt");
    let fake = dir.path().join("avrdude");
    std::fs::write(
        &fake,
        format!("#!/bin/sh\nprintf '%s\\n' \"$@\" > '{}'\n", log.display()),
    )
    .expect("write the stand-in avrdude");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&fake, std::fs::Permissions::from_mode(0o755))
            .expect("make the stand-in executable");
    }
    let hex = dir.path().join("firmware.hex");
    std::fs::write(&hex, ":00000001FF\n").expect("write a hex file");
    let out = Command::new(bin())
        .args(["firmware", "flash", "--run", "--hex"])
        .arg(&hex)
        .env("PATH", dir.path())
        .output()
        .expect("run brdf-rig");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let args = std::fs::read_to_string(&log).expect("the stand-in avrdude ran");
    let want = format!(
        "-p\natmega2560\n-c\nwiring\n-P\n/dev/ttyACM0\n-b\n115200\n-D\n-U\nflash:w:{}:i\n",
        hex.display()
    );
    assert_eq!(args, want);
}

#[test]
fn firmware_flash_run_without_avrdude_says_what_to_do() {
    let dir = tempfile::tempdir().expect("temp dir");
    let hex = dir.path().join("firmware.hex");
    std::fs::write(&hex, ":00000001FF\n").expect("write a hex file");
    let out = Command::new(bin())
        .args(["firmware", "flash", "--run", "--hex"])
        .arg(&hex)
        .env("PATH", dir.path())
        .output()
        .expect("run brdf-rig");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("avrdude is not on PATH"), "{err}");
}
