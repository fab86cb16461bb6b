//! A capture killed with SIGKILL at random points, then resumed, ends with exactly the planned
//! shots and valid checksums: nothing lost, nothing taken twice. Kills come two ways: after a
//! random delay (anywhere: start-up, homing, a move, a render, a write), and through the
//! binary's `BRDF_RIG_TEST_KILL_AT=N:phase` hook at the exact seams of a shot (before the image
//! is written, after the image but before its journal record, after the record). Killed
//! processes leave no simulated port folders behind: the next run sweeps them.

use std::os::unix::process::ExitStatusExt;
use std::time::Duration;

use rand::{Rng, SeedableRng};

use brdf_rig::capture::plan::load_plan;
use brdf_rig::capture::session::read_journal;
use brdf_rig::capture::verify_session;

use crate::capture_util::{brdf_rig, fast_profile, s, text, tiny_plan};

const PHASES: [&str; 3] = ["before-image", "after-image", "after-journal"];

#[test]
fn sigkill_at_random_points_then_resume_gives_exactly_the_planned_shots() {
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    let plan_path = tiny_plan(tmp.path(), 9); // 9 + 3x3x2 + 12 = 39 shots
    // the children's temporary directory, where their simulated rigs' port folders go
    let ports = tmp.path().join("tmp");
    std::fs::create_dir(&ports).unwrap();
    let planned: Vec<String> = load_plan(&plan_path)
        .unwrap()
        .shots()
        .into_iter()
        .map(|s| s.id)
        .collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(20261127);
    let mut kills = 0;
    let mut sessions = 0;
    let mut hook_kills = 0;
    while kills < 24 {
        sessions += 1;
        let out = tmp.path().join(format!("session-{sessions}"));
        let mut runs = 0;
        loop {
            runs += 1;
            assert!(runs < 200, "no progress in {}", out.display());
            let mut args = vec!["capture", "--profile", s(&profile), "--unattended"];
            let started = out.join("session.json").exists();
            let plan_s = s(&plan_path).to_string();
            let out_s = s(&out).to_string();
            if started {
                args.extend(["--resume", &out_s]);
            } else {
                args.extend(["--plan", &plan_s, "--out", &out_s]);
            }
            let mut cmd = brdf_rig(&args);
            cmd.env("TMPDIR", &ports);
            let use_hook = kills < 24 && rng.gen_bool(0.5);
            if use_hook {
                let n = rng.gen_range(0..4);
                let phase = PHASES[rng.gen_range(0..3)];
                cmd.env("BRDF_RIG_TEST_KILL_AT", format!("{n}:{phase}"));
            }
            let mut child = cmd
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap();
            if !use_hook && kills < 24 {
                std::thread::sleep(Duration::from_millis(rng.gen_range(5..400)));
                let _ = child.kill(); // SIGKILL
            }
            let o = child.wait_with_output().unwrap();
            if o.status.signal() == Some(9) {
                kills += 1;
                if use_hook {
                    hook_kills += 1;
                }
                // After every kill: whatever is journaled is intact.
                if out.join("session.json").exists() {
                    let report = verify_session(&out).unwrap();
                    assert!(report.intact(), "after kill {kills}: {:?}", report.problems);
                } else {
                    assert!(!out.exists() || std::fs::read_dir(&out).unwrap().next().is_none());
                }
                continue;
            }
            assert!(o.status.success(), "{}", text(&o));
            eprintln!("{}: complete after {runs} runs", out.display());
            break;
        }
        let (records, _) = read_journal(&out.join("journal.jsonl")).unwrap();
        let ids: Vec<String> = records.iter().map(|r| r.id.clone()).collect();
        assert_eq!(
            ids, planned,
            "exactly the planned shots, once each, in plan order"
        );
        let report = verify_session(&out).unwrap();
        assert!(
            report.intact() && report.complete(),
            "{:?} {:?}",
            report.problems,
            report.not_taken
        );
        let v = brdf_rig(&["session", "verify", s(&out)]).output().unwrap();
        assert!(v.status.success(), "{}", text(&v));
        // no stray temporaries
        for sub in ["ambient", "light", "calib"] {
            for e in std::fs::read_dir(out.join(sub)).unwrap() {
                let name = e.unwrap().file_name().to_string_lossy().into_owned();
                assert!(name.ends_with(".exr") && !name.starts_with('.'), "{name}");
            }
        }
    }
    eprintln!("{kills} SIGKILLs ({hook_kills} at shot seams) over {sessions} session(s)");
    // each killed run's port folder was swept by a later run; the last run removed its own
    let left: Vec<String> = std::fs::read_dir(&ports)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(brdf_rig::sim::port_dir::PREFIX))
        .collect();
    assert!(left.is_empty(), "port folders left behind: {left:?}");
    assert!(
        kills >= 20 && hook_kills >= 5,
        "{kills} kills, {hook_kills} at shot seams"
    );
}
