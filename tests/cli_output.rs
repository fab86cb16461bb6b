//! The binary's output to a closed pipe (`brdf-rig ... | head` once `head` has gone): dropped,
//! never a panic, and the command's exit status is its own.

use crate::util;
use std::path::Path;
use std::process::{Command, Stdio};

#[test]
fn output_to_a_closed_pipe_is_dropped_without_a_panic() {
    let nbrdf = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/merl-nbrdf/alum-bronze.f32");
    let (reader, writer) = std::io::pipe().expect("pipe");
    // The reader has gone before the program writes: every write to stdout fails with EPIPE.
    drop(reader);
    let out = Command::new(util::bin())
        .args(["merl", "eval"])
        .arg(&nbrdf)
        .args(["30", "0", "30", "180"])
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .expect("run");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert!(out.status.success(), "{:?}: {err}", out.status);
    // The same command with a reader prints its line (the pipe, not the command, was the issue).
    let ok = Command::new(util::bin())
        .args(["merl", "eval"])
        .arg(&nbrdf)
        .args(["30", "0", "30", "180"])
        .output()
        .expect("run");
    assert!(ok.status.success());
    assert_eq!(
        String::from_utf8_lossy(&ok.stdout)
            .split_whitespace()
            .count(),
        3
    );
}
