//! Whole captures on the simulated rig through the real binary: the serial stack to the
//! simulated firmware on a pty, the simulated camera rendering what the firmware reports.

use std::collections::HashSet;

use brdf_rig::capture::session::{Manifest, read_journal};
use brdf_rig::capture::{ShotKind, verify_session};
use brdf_rig::imageio::decode_exr;

use crate::capture_util::{capture_unattended, fast_profile, run, s, text, tiny_plan};

fn mean(img: &brdf_rig::render::image::LinearImage) -> f64 {
    img.data().iter().map(|&v| f64::from(v)).sum::<f64>() / img.data().len() as f64
}

#[test]
fn a_full_simulated_capture_takes_every_planned_shot_of_the_scene() {
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    let plan = tiny_plan(tmp.path(), 6);
    let out = tmp.path().join("session");
    let o = capture_unattended(&profile, &plan, &out);
    assert!(o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("theta_d covered: 10.0 .. 55.0 deg"), "{err}");

    let v = run(&["session", "verify", s(&out)]);
    assert!(v.status.success(), "{}", text(&v));

    let m: Manifest =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(m.status, "complete");
    // 6 ambient + 2 views x 3 channels x 2 exposures + (sphere + white) x 3 channels x 2
    assert_eq!(m.shots.len(), 6 + 12 + 12);
    assert_eq!(m.header.planned_shots, m.shots.len());
    let ids: HashSet<_> = m.shots.iter().map(|r| r.id.clone()).collect();
    assert_eq!(ids.len(), m.shots.len());
    for r in &m.shots {
        // the turntable reached the angle the shot asked for
        let d = (r.measured_angle_deg - r.angle_deg).rem_euclid(360.0);
        assert!(
            d.min(360.0 - d) < 0.1,
            "{}: {} vs {}",
            r.id,
            r.measured_angle_deg,
            r.angle_deg
        );
        assert_eq!((r.width, r.height), (64, 48));
        assert_eq!(r.channel.is_some(), r.kind != ShotKind::Ambient);
    }
    let img = |file: &str| decode_exr(&std::fs::read(out.join(file)).unwrap()).unwrap();
    // room light lights the backdrop; under a single light the backdrop is black
    let ambient = img("ambient/v000_e0.exr");
    let light_short = img("light/v000_ch1_e0.exr");
    let light_long = img("light/v000_ch1_e1.exr");
    assert!(ambient.get(0, 0)[0] > 0.01, "{:?}", ambient.get(0, 0));
    assert!(light_short.get(0, 0)[0] < 0.01);
    // 4x the exposure, about 4x the signal (below saturation)
    let ratio = mean(&light_long) / mean(&light_short);
    assert!(ratio > 3.0 && ratio < 4.5, "{ratio}");
    // the white reference is evenly lit; the sphere has a small bright highlight
    let white = img("calib/white_ch0_e0.exr");
    assert!(white.get(32, 24)[1] > 0.05, "{:?}", white.get(32, 24));
    let sphere = img("calib/sphere_ch0_e0.exr");
    // (a grey backdrop stands behind the sphere: count what outshines it)
    let backdrop = sphere.get(0, 0)[1];
    let bright = sphere
        .data()
        .iter()
        .filter(|&&v| v > 0.5 && v > 1.2 * backdrop)
        .count();
    assert!(
        bright > 0 && bright < 200,
        "{bright} above the backdrop {backdrop}"
    );
    // what photogrammetry would give: one pose per ambient view, and the truth
    let images = std::fs::read_to_string(out.join("sim/colmap/images.txt")).unwrap();
    assert_eq!(
        images.lines().filter(|l| l.contains("ambient/v")).count(),
        6
    );
    for f in [
        "sim/truth.json",
        "sim/mesh_true.ply",
        "sim/mesh_sfm.ply",
        "profile.toml",
        "plan.toml",
    ] {
        assert!(out.join(f).exists(), "{f}");
    }
    let (sfm, _) = brdf_rig::geometry::mesh_io::load_mesh(&out.join("sim/mesh_sfm.ply")).unwrap();
    let (truth_mesh, _) =
        brdf_rig::geometry::mesh_io::load_mesh(&out.join("sim/mesh_true.ply")).unwrap();
    assert_eq!(sfm.faces().len(), truth_mesh.faces().len());
    assert_ne!(sfm.positions(), truth_mesh.positions());
    let truth = std::fs::read_to_string(out.join("sim/truth.json")).unwrap();
    assert!(truth.contains("not measured MERL data"));
}

#[test]
fn verify_catches_a_corrupted_image() {
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    let plan = tiny_plan(tmp.path(), 3);
    let out = tmp.path().join("session");
    let o = capture_unattended(&profile, &plan, &out);
    assert!(o.status.success(), "{}", text(&o));
    let file = out.join("light/v000_ch2_e1.exr");
    let mut bytes = std::fs::read(&file).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x01; // one bit
    std::fs::write(&file, &bytes).unwrap();
    let v = run(&["session", "verify", s(&out)]);
    assert_eq!(v.status.code(), Some(2), "{}", text(&v));
    let stdout = String::from_utf8_lossy(&v.stdout);
    assert!(
        stdout.contains("light/v000_ch2_e1.exr: checksum mismatch"),
        "{stdout}"
    );
    // a missing file too
    std::fs::remove_file(out.join("ambient/v001_e0.exr")).unwrap();
    let report = verify_session(&out).unwrap();
    assert_eq!(report.problems.len(), 2, "{:?}", report.problems);
}

#[test]
fn a_missing_serial_port_is_a_clear_error_before_anything_moves_or_is_written() {
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    let text_p = std::fs::read_to_string(&profile)
        .unwrap()
        .replace("port = \"sim\"", "port = \"/dev/brdf-rig-no-such-port\"");
    // a real-rig profile still needs a camera: keep the simulated one, which must then refuse
    std::fs::write(&profile, text_p).unwrap();
    let out = tmp.path().join("session");
    let o = capture_unattended(&profile, &tiny_plan(tmp.path(), 3), &out);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("/dev/brdf-rig-no-such-port"), "{err}");
    assert!(err.contains("nothing has moved"), "{err}");
    assert!(
        !out.exists(),
        "no session folder for a capture that never started"
    );
}

#[test]
fn guided_mode_refuses_when_stdin_is_not_a_terminal() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("session");
    let o = run(&[
        "capture",
        "--profile",
        s(&fast_profile(tmp.path())),
        "--plan",
        s(&tiny_plan(tmp.path(), 3)),
        "--out",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("standard input is not a terminal") && err.contains("--unattended"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn the_plan_must_fit_the_rig_and_the_folder_must_be_new() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = tiny_plan(tmp.path(), 3);
    let t = std::fs::read_to_string(&plan)
        .unwrap()
        .replace("channels = [0, 1, 2]", "channels = [0, 5]");
    std::fs::write(&plan, t).unwrap();
    let out = tmp.path().join("session");
    let o = capture_unattended(&fast_profile(tmp.path()), &plan, &out);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("contains 5, but the light reports 3"),
        "{}",
        text(&o)
    );
    assert!(!out.exists());
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    let o = capture_unattended(&fast_profile(tmp.path()), &tiny_plan(tmp.path(), 3), &out);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("not empty"),
        "{}",
        text(&o)
    );
    // and journal of nothing: nothing was written there
    assert!(
        read_journal(&out.join("journal.jsonl"))
            .unwrap()
            .0
            .is_empty()
    );
}

#[test]
fn ctrl_c_stops_cleanly_and_the_session_resumes() {
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    let plan = tiny_plan(tmp.path(), 30);
    let out = tmp.path().join("session");
    let o = crate::capture_util::interrupt_after_first_shot(&profile, &plan, &out);
    assert_eq!(o.status.code(), Some(130), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("the light is off") && err.contains("--resume"),
        "{err}"
    );
    let report = verify_session(&out).unwrap();
    assert!(report.intact() && !report.complete());
    let m: Manifest =
        serde_json::from_slice(&std::fs::read(out.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(m.status, "in_progress");
    assert_eq!(
        m.shots.len(),
        report.checked,
        "the snapshot matches the journal"
    );
    let o = run(&["capture", "--resume", s(&out), "--unattended"]);
    assert!(o.status.success(), "{}", text(&o));
    let report = verify_session(&out).unwrap();
    assert!(report.intact() && report.complete());
}

/// Guided mode on a real terminal (a pty as standard input): the capture prints what the
/// operator must do, waits for Enter before going on (no shot is taken while it waits), and with
/// Enter at every prompt finishes the whole plan.
#[test]
fn guided_capture_on_a_terminal_waits_for_enter_at_each_prompt() {
    use std::io::{BufRead, BufReader, Write};
    use std::process::Stdio;
    use std::time::{Duration, Instant};

    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    let plan = tiny_plan(tmp.path(), 6);
    let out = tmp.path().join("session");
    let (mut master, slave) = brdf_rig::sim::runner::pty_pair().unwrap();
    let tty = serialport::SerialPort::name(&slave).expect("the pty's path");
    let stdin = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(&tty)
        .unwrap();
    let mut child = crate::capture_util::brdf_rig(&[
        "capture",
        "--profile",
        s(&profile),
        "--plan",
        s(&plan),
        "--out",
        s(&out),
    ])
    .stdin(Stdio::from(stdin))
    .stdout(Stdio::null())
    .stderr(Stdio::piped())
    .spawn()
    .unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    let stderr = child.stderr.take().unwrap();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    let journal_lines = || {
        std::fs::read_to_string(out.join("journal.jsonl"))
            .map(|t| t.lines().count())
            .unwrap_or(0)
    };
    let start = Instant::now();
    let (mut prompts, mut steps, mut log) = (0, Vec::new(), String::new());
    while start.elapsed() < Duration::from_secs(120) {
        match rx.recv_timeout(Duration::from_millis(200)) {
            Ok(line) => {
                log += &line;
                log.push('\n');
                if let Some(step) = line.trim().strip_prefix(">>> ") {
                    steps.push(step.to_string());
                }
                if line.contains("Press Enter") {
                    prompts += 1;
                    if prompts == 1 {
                        // nothing moves on while the operator has not confirmed
                        let before = journal_lines();
                        std::thread::sleep(Duration::from_millis(1500));
                        assert_eq!(journal_lines(), before, "a shot was taken during a prompt");
                        assert!(child.try_wait().unwrap().is_none(), "{log}");
                    }
                    master.write_all(b"\n").unwrap();
                }
            }
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => {
                if child.try_wait().unwrap().is_some() {
                    break;
                }
            }
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => break,
        }
    }
    let status = child.wait().unwrap();
    assert!(status.success(), "{log}");
    // object + room light, sphere, white reference, lights off: several distinct prompts
    assert!(prompts >= 3, "{prompts} prompts\n{log}");
    assert!(
        steps.iter().any(|s| s.contains("black glossy sphere")),
        "{steps:?}"
    );
    assert!(
        steps.iter().any(|s| s.contains("white reference")),
        "{steps:?}"
    );
    let v = run(&["session", "verify", s(&out)]);
    assert!(v.status.success(), "{}", text(&v));
}
