//! The shared protocol test vectors (`firmware-protocol/vectors/`): the committed files are
//! what the Rust codec generates, and every line decodes as it says. Regenerate with
//! `BRDF_RIG_BLESS_VECTORS=1 cargo test rig_vectors` after a deliberate protocol change.

#![allow(clippy::unwrap_used)] // a panic in a test is a failed test

use brdf_rig::protocol::vectors::{self, Vector};
use std::path::PathBuf;

fn dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("firmware-protocol/vectors")
}

fn committed_matches_generated(name: &str, generated: String) {
    let path = dir().join(name);
    if std::env::var_os("BRDF_RIG_BLESS_VECTORS").is_some() {
        std::fs::write(&path, &generated).unwrap();
    }
    let on_disk =
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(
        on_disk,
        generated,
        "{} differs from what the codec generates; bless with BRDF_RIG_BLESS_VECTORS=1 if the \
         change is deliberate",
        path.display()
    );
}

#[test]
fn frames_file_is_current() {
    committed_matches_generated("frames.txt", vectors::frames_file());
}

#[test]
fn reject_file_is_current() {
    committed_matches_generated("reject.txt", vectors::reject_file());
}

fn check_file(name: &str) -> Vec<Vector> {
    let path = dir().join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    let parsed = vectors::parse_file(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    for (line, v) in &parsed {
        if let Err(e) = vectors::check(v) {
            panic!("{}:{line}: {e}", path.display());
        }
    }
    parsed.into_iter().map(|(_, v)| v).collect()
}

#[test]
fn every_valid_vector_decodes_to_its_text() {
    let vs = check_file("frames.txt");
    let texts: Vec<&str> = vs
        .iter()
        .filter_map(|v| match v {
            Vector::Frame { text, .. } => Some(text.as_str()),
            _ => None,
        })
        .collect();
    // The examples of PROTOCOL.md section 9 are in the file verbatim.
    for example in [
        "HELLO id=1",
        "MOVE_ABS id=7 angle=90000",
        "LIGHT_ON id=9 channel=0 level=65535 exclusive=1",
        "NAK id=9 code=6 detail=2",
        "STATUS_REPLY id=3 angle=90000 target=90000 moving=0 homed=1 enabled=1 faults=0 boot=5 uptime=1234",
        "HELLO_REPLY id=1 major=1 minor=0 caps=31 boot=5 channels=3 min_angle=-3600000 max_angle=3600000 max_speed=90000 max_accel=180000 watchdog=2000 name=brdf-sim",
        "LIGHT_STATUS_REPLY id=4 channels=2 level0=65535 stable0=1 level1=0 stable1=0",
    ] {
        assert!(texts.contains(&example), "missing spec example {example:?}");
    }
    // Every kind of the protocol appears at least once.
    for name in [
        "HELLO ",
        "HEARTBEAT ",
        "SET_WATCHDOG ",
        "SET_LIMITS ",
        "HOME ",
        "MOVE_ABS ",
        "MOVE_REL ",
        "STOP ",
        "STATUS ",
        "LIGHT_ON ",
        "LIGHT_OFF ",
        "LIGHT_STATUS ",
        "ACK ",
        "NAK ",
        "HELLO_REPLY ",
        "STATUS_REPLY ",
        "LIGHT_STATUS_REPLY ",
    ] {
        assert!(texts.iter().any(|t| t.starts_with(name)), "no {name}vector");
    }
    assert!(vs.iter().any(|v| matches!(v, Vector::Stream { .. })));
}

#[test]
fn every_reject_vector_is_rejected_for_its_reason() {
    let vs = check_file("reject.txt");
    for reason in ["cobs", "crc", "short", "long", "kind", "length"] {
        let want = format!("REJECT {reason}");
        assert!(
            vs.iter()
                .any(|v| matches!(v, Vector::Frame { text, .. } if *text == want)),
            "no vector for {want}"
        );
    }
}

#[test]
fn a_vector_with_a_wrong_text_is_caught() {
    // The checker itself must be able to fail.
    let v = Vector::Frame {
        wire: hex::decode("0301010393c800").unwrap(),
        text: "HELLO id=1".into(),
    };
    assert!(vectors::check(&v).is_err());
    let v = Vector::Frame {
        wire: hex::decode("030101039dc800").unwrap(),
        text: "HELLO id=2".into(),
    };
    assert!(vectors::check(&v).is_err());
}
