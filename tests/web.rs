//! The lab page (`brdf-rig serve`) in a real headless Chromium, on the simulated rig: a whole
//! guided capture driven by clicks, a browser closed mid-capture (the light goes off, a new page
//! resumes with nothing lost or duplicated), a page cut off from the network, a second browser
//! that is read-only, and the token beyond localhost.

use std::collections::HashSet;
use std::path::Path;
use std::time::{Duration, Instant};

use serde_json::{Value, json};

use brdf_rig::capture::session::{JOURNAL_FILE, Manifest, read_journal};

use crate::capture_util::{fast_profile, run, s, text};
use crate::web_util::{Browser, Driver, Serve, one_at_a_time, silent_page};

/// A plan of 6 ambient views at `size`, single-light shots on views 0 and 3 under three
/// channels with a two-step bracket, both calibration targets: 30 shots. `light_millis` slows
/// each light change so a test can act while a light is on.
fn plan(dir: &Path, size: &str, light_millis: u64) -> std::path::PathBuf {
    let (w, h) = size.split_once('x').unwrap();
    let plans = dir.join("plans");
    std::fs::create_dir_all(&plans).unwrap();
    std::fs::write(
        plans.join("web.toml"),
        format!(
            "name = \"web test\"\n\
             [camera]\nwidth = {w}\nheight = {h}\ngain = 1.0\n\
             [ambient]\nviews = 6\nexposures_secs = [0.02]\n\
             [single_light]\nevery = 3\nchannels = [0, 1, 2]\nexposures_secs = [0.004, 0.016]\n\
             [calibration]\nsphere = true\nwhite = true\n\
             [settle]\nturntable_millis = 0\nlight_millis = {light_millis}\n"
        ),
    )
    .unwrap();
    plans
}

const PLANNED: usize = 30;

/// The whole journal of a session: every planned shot exactly once, none taken twice.
fn assert_exactly_the_planned_shots(session: &Path) {
    let (records, _) = read_journal(&session.join(JOURNAL_FILE)).unwrap();
    let ids: HashSet<_> = records.iter().map(|r| r.id.clone()).collect();
    assert_eq!(records.len(), PLANNED, "journal lines");
    assert_eq!(ids.len(), PLANNED, "distinct shots");
    assert!(records.iter().all(|r| r.retake.is_none()), "no re-take");
    let m: Manifest =
        serde_json::from_slice(&std::fs::read(session.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(m.status, "complete");
    let v = run(&["session", "verify", s(session)]);
    assert!(v.status.success(), "{}", text(&v));
}

/// `BRDF_RIG_WRITE_SCREENSHOT=1`: the guided test writes docs/web-page.png (and the page at
/// the end to target/web-page-end.png).
fn write_screenshots() -> bool {
    std::env::var_os("BRDF_RIG_WRITE_SCREENSHOT").is_some()
}

fn take_control(b: &Browser, name: &str) {
    b.fill("#client-name", name);
    b.click("#take-control");
    b.wait(
        "this page controls",
        10,
        "return document.body.dataset.controlling === 'true'",
    );
}

fn start(b: &Browser, session: &str, mode: &str) {
    b.select("#plan", "web.toml");
    b.fill("#session-name", session);
    b.select("#mode", mode);
    b.click("#btn-start");
}

fn journal_lines(session: &Path) -> usize {
    std::fs::read_to_string(session.join(JOURNAL_FILE))
        .map(|t| t.lines().count())
        .unwrap_or(0)
}

#[test]
fn a_guided_capture_runs_to_the_end_from_clicks_in_headless_chromium() {
    let _one = one_at_a_time();
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    let plans = plan(tmp.path(), "160x120", 0);
    let sessions = tmp.path().join("sessions");
    let serve = Serve::start(&[
        "--profile",
        s(&profile),
        "--plans",
        s(&plans),
        "--sessions",
        s(&sessions),
    ]);
    let driver = Driver::start();
    let b = Browser::open(&driver, &format!("{}/", serve.base));
    // the page shows the rig and the plan with its theta_d coverage before anything runs
    b.wait(
        "the rig state",
        10,
        "return document.querySelector('#rig-connected').textContent.includes('connected')",
    );
    assert!(b.text("#lights").contains("near"), "{}", b.text("#lights"));
    take_control(&b, "bench");
    b.select("#plan", "web.toml");
    let summary = b.text("#plan-summary");
    assert!(
        summary.contains("30 shots") && summary.contains("theta_d covered 10.0–55.0°"),
        "{summary}"
    );
    // a live preview at 640x480 with its histogram, before the capture
    b.wait("a live frame", 20, "return lab.frames > 0");
    assert!(
        b.text("#preview-source").contains("live, 640x480"),
        "{}",
        b.text("#preview-source")
    );
    start(&b, "s1", "guided");

    let session = sessions.join("s1");
    let t0 = Instant::now();
    let mut answered = HashSet::new();
    let mut steps: Vec<String> = Vec::new();
    let mut shot_taken = false;
    loop {
        assert!(
            t0.elapsed() < Duration::from_secs(120),
            "the capture did not end: {}",
            b.text("#phase")
        );
        let page = b.eval(
            "return {phase: document.body.dataset.phase,
                     waiting: !document.querySelector('#instruction').hidden,
                     seq: document.querySelector('#btn-continue').dataset.seq || null,
                     steps: [...document.querySelectorAll('#instruction-steps li')].map(l => l.textContent)}",
        );
        match page["phase"].as_str().unwrap() {
            "complete" => break,
            p @ ("failed" | "paused" | "aborted") => {
                panic!(
                    "capture {p}: {} {}",
                    b.text("#stop-reason"),
                    b.text("#error")
                )
            }
            _ => {}
        }
        let seq = page["seq"].as_str().unwrap_or("").to_string();
        if page["waiting"] == Value::Bool(true) && !answered.contains(&seq) {
            for st in page["steps"].as_array().unwrap() {
                steps.push(st.as_str().unwrap().to_string());
            }
            if answered.is_empty() {
                // nothing is shot while the operator has not confirmed
                let before = journal_lines(&session);
                std::thread::sleep(Duration::from_millis(800));
                assert_eq!(
                    journal_lines(&session),
                    before,
                    "a shot was taken during an instruction"
                );
            } else if !shot_taken {
                shot_taken = journal_lines(&session) > 0;
            }
            let now_steps = page["steps"].to_string();
            if now_steps.contains("room lights OFF") {
                // the 6 ambient shots are done; the sessions list shows the run's own count
                b.wait(
                    "the session being captured in the list",
                    10,
                    "return document.querySelector('#sessions').textContent.includes('6 / 30capturing')",
                );
            }
            if now_steps.contains("room lights OFF") && write_screenshots() {
                // docs/web-page.png: the page asking for the room light to go off, the object
                // still lit by it in the live preview (see docs/web.md)
                b.wait(
                    "a live frame of the object",
                    10,
                    "return document.querySelector('#preview-source').textContent.startsWith('live')",
                );
                std::fs::write(
                    Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/web-page.png"),
                    b.screenshot(),
                )
                .unwrap();
            }
            b.click("#btn-continue");
            answered.insert(seq);
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    // object with room light, room light off, the sphere, the white board
    assert_eq!(answered.len(), 4, "{steps:?}");
    for want in [
        "Place the object",
        "room lights OFF",
        "black glossy sphere",
        "white reference",
    ] {
        assert!(steps.iter().any(|s| s.contains(want)), "{want}: {steps:?}");
    }
    assert!(shot_taken);
    assert_eq!(
        b.text("#progress-text"),
        format!("{PLANNED} / {PLANNED} shots")
    );
    assert_eq!(
        b.eval("const p = document.querySelector('#progress-bar'); return p.value === p.max"),
        Value::Bool(true)
    );
    let verify = b.text("#verify");
    assert!(
        verify.contains(&format!("all {PLANNED} images intact")),
        "{verify}"
    );
    // shots were previewed as they were taken
    assert!(b.eval("return lab.frames").as_u64().unwrap() > 1);
    let href = b.eval("return document.querySelector('#report-link').getAttribute('href')");
    assert_eq!(href, json!("/sessions/s1/report"));
    let (status, html) = serve.get("/sessions/s1/report");
    assert_eq!(status, 200);
    assert!(
        html.contains("<html") && html.contains("all intact"),
        "{}",
        &html[..html.len().min(300)]
    );

    // what the page shows is the browser's own rendering, and not blank
    let png = b.screenshot();
    if write_screenshots() {
        std::fs::write(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("target/web-page-end.png"),
            &png,
        )
        .unwrap();
    }
    let shot = image::load_from_memory(&png).unwrap().to_rgb8();
    let mut colours: Vec<[u8; 3]> = shot.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() > 100,
        "screenshot has {} colours",
        colours.len()
    );
    b.close();
    assert_exactly_the_planned_shots(&session);
}

#[test]
fn closing_the_browser_mid_capture_pauses_with_the_light_off_and_a_new_page_resumes() {
    let _one = one_at_a_time();
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    // 150 ms per light change: the single-light stage lasts long enough to close the browser
    // while a light is on
    let plans = plan(tmp.path(), "64x48", 150);
    let sessions = tmp.path().join("sessions");
    let serve = Serve::start(&[
        "--profile",
        s(&profile),
        "--plans",
        s(&plans),
        "--sessions",
        s(&sessions),
        "--preview-size",
        "160x120",
    ]);
    let watchdog_ms = serve.state()["rig"]["watchdog_ms"].as_u64().unwrap();
    assert_eq!(watchdog_ms, 2000);
    let driver = Driver::start();
    let b = Browser::open(&driver, &format!("{}/", serve.base));
    take_control(&b, "first page");
    start(&b, "s2", "unattended");
    let lit = |s: &Value| {
        s["rig"]["sim"]["levels"]
            .as_array()
            .is_some_and(|l| l.iter().any(|v| v.as_f64().unwrap() > 0.0))
    };
    let st = serve.wait_state("a single-light shot with the light on", 60, |s| {
        s["capture"]["last_shot"]["kind"] == "SingleLight" && lit(s)
    });
    let done_then = st["capture"]["done"].as_u64().unwrap() as usize;
    assert!(done_then < PLANNED);

    let t = Instant::now();
    b.close();
    // the simulated board itself (read beside the serial link) has the light off
    let st = serve.wait_state("the light off", 10, |s| {
        !lit(s) && s["capture"]["phase"] == "paused"
    });
    let dark_after = t.elapsed();
    assert!(
        dark_after < Duration::from_millis(watchdog_ms),
        "the light went off {dark_after:?} after the browser closed (watchdog {watchdog_ms} ms)"
    );
    let reason = st["capture"]["stop_reason"].as_str().unwrap();
    assert!(reason.contains("controlling page"), "{reason}");
    assert_eq!(st["capture"]["verify"]["intact"], true);
    let paused_at = st["capture"]["done"].as_u64().unwrap() as usize;
    assert!(paused_at < PLANNED, "paused with {paused_at} shots");
    let session = sessions.join("s2");
    assert_eq!(journal_lines(&session), paused_at);
    // the terminal way to continue is offered too
    assert!(
        st["capture"]["resume_command"]
            .as_str()
            .unwrap()
            .contains("capture --resume"),
        "{}",
        st["capture"]
    );

    // a new page takes control and resumes the session from the list
    let b2 = Browser::open(&driver, &format!("{}/", serve.base));
    take_control(&b2, "second page");
    b2.wait(
        "the session is listed",
        10,
        "return document.querySelector('.resume-btn[data-session=\"s2\"]') !== null",
    );
    b2.select("#mode", "unattended");
    b2.click(".resume-btn[data-session=\"s2\"]");
    b2.wait(
        "the resumed capture completes",
        90,
        "return document.body.dataset.phase === 'complete'",
    );
    assert_eq!(
        b2.text("#progress-text"),
        format!("{PLANNED} / {PLANNED} shots")
    );
    assert!(
        b2.text("#verify")
            .contains(&format!("all {PLANNED} images intact"))
    );
    b2.close();
    assert_exactly_the_planned_shots(&session);
}

#[test]
fn a_page_cut_off_from_the_network_pauses_its_capture() {
    let _one = one_at_a_time();
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    // The page is silent from the start, so taking control and starting must both happen
    // within `--lost-after` of its connecting: 0.5 s was too short on a loaded machine (the
    // page was lost before the start, which then ran to the end). 2 s, and shots slow enough
    // (300 ms per light change) that the capture is still running when the loss is seen.
    let plans = plan(tmp.path(), "64x48", 300);
    let sessions = tmp.path().join("sessions");
    let serve = Serve::start(&[
        "--profile",
        s(&profile),
        "--plans",
        s(&plans),
        "--sessions",
        s(&sessions),
        "--lost-after",
        "2",
    ]);
    // The rig connected and answering (the simulated board's boot is over), so the start below
    // is not queued behind it while the silent page's clock runs.
    serve.wait_state("the rig polled", 60, |s| s["rig"]["polled"] == true);
    // a page that connects, takes control, starts a capture, then neither reads nor answers
    let (socket, key) = silent_page(serve.port);
    let client = [("x-client", key.as_str())];
    let (st, body) = serve.post("/api/control", &client, &json!({"name": "laptop"}));
    assert_eq!(st, 200, "{body}");
    let (st, body) = serve.post(
        "/api/capture/start",
        &client,
        &json!({"plan": "web.toml", "session": "s3", "mode": "unattended"}),
    );
    assert_eq!(st, 200, "{body}");
    let st = serve.wait_state("the capture pauses", 30, |s| {
        s["capture"]["phase"] == "paused"
    });
    let reason = st["capture"]["stop_reason"].as_str().unwrap();
    assert!(
        reason.contains("stopped answering") || reason.contains("stopped reading"),
        "{reason}"
    );
    assert!(st["capture"]["done"].as_u64().unwrap() < PLANNED as u64);
    assert!(
        st["control"]["controller"].is_null(),
        "control was released"
    );
    drop(socket);
    // The board's own light levels (read beside the serial link, on their own timer) go dark,
    // and the server polls the idle rig again over the link (every 400 ms; on a loaded
    // machine that can come after the levels are seen, so both are waited for).
    serve.wait_state("the light off and the idle rig polled again", 15, |s| {
        s["rig"]["polled"] == true
            && s["rig"]["sim"]["levels"]
                .as_array()
                .is_some_and(|l| l.iter().all(|v| v.as_f64().unwrap() == 0.0))
    });
    // and the terminal can continue it (the server holds no lock on it)
    let o = run(&[
        "capture",
        "--resume",
        s(&sessions.join("s3")),
        "--unattended",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert_exactly_the_planned_shots(&sessions.join("s3"));
}

#[test]
fn a_second_browser_is_read_only_and_beyond_localhost_actions_need_the_token() {
    let _one = one_at_a_time();
    let tmp = tempfile::tempdir().unwrap();
    let profile = fast_profile(tmp.path());
    let plans = plan(tmp.path(), "64x48", 0);
    let sessions = tmp.path().join("sessions");
    // beyond localhost without a token: refused before anything opens
    let o = run(&["serve", "--bind", "0.0.0.0:0", "--profile", s(&profile)]);
    assert!(!o.status.success());
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("--token-file"),
        "{}",
        text(&o)
    );

    let token = "open-sesame-7f3a9c21";
    let token_file = tmp.path().join("token");
    std::fs::write(&token_file, format!("{token}\n")).unwrap();
    let serve = Serve::start(&[
        "--bind",
        "0.0.0.0:0",
        "--token-file",
        s(&token_file),
        "--profile",
        s(&profile),
        "--plans",
        s(&plans),
        "--sessions",
        s(&sessions),
        "--preview-size",
        "160x120",
    ]);
    // reading stays open; acting without the token is refused with 401
    assert_eq!(serve.get("/").0, 200);
    assert_eq!(serve.state()["server"]["token_required"], true);
    for (path, body) in [
        ("/api/control", json!({"name": "intruder"})),
        ("/api/light", json!({"on": true, "channel": 0})),
        ("/api/turntable", json!({"action": "home"})),
        (
            "/api/capture/start",
            json!({"plan": "web.toml", "session": "x", "mode": "unattended"}),
        ),
        ("/api/capture/continue", json!({"seq": 1})),
        ("/api/capture/abort", json!({})),
    ] {
        let (st, answer) = serve.post(path, &[], &body);
        assert_eq!(st, 401, "{path}: {answer}");
        let (st, _) = serve.post(path, &[("authorization", "Bearer wrong-token-123")], &body);
        assert_eq!(st, 401, "{path} with a wrong token");
    }
    let (st, _) = request_with_token(&serve, "/api/light", None, &json!({"on": false}), token);
    assert_eq!(
        st, 403,
        "the token alone does not make a page the controller"
    );

    let driver = Driver::start();
    let url = format!("{}/#token={token}", serve.base);
    let a = Browser::open(&driver, &url);
    take_control(&a, "bench PC");
    // the controller acts: a light on, seen on the simulated board
    a.select("#light-channel", "1");
    a.fill("#light-level", "0.5");
    a.click("#btn-light-on");
    // (levels travel as 16-bit fractions: 0.5 arrives as 32768/65535)
    let half = |s: &Value| (s["rig"]["sim"]["levels"][1].as_f64().unwrap() - 0.5).abs() < 1e-3;
    serve.wait_state("channel 1 on at half", 10, half);
    a.wait(
        "the page shows channel 1 on",
        10,
        "return document.querySelector('#light-1').textContent.includes('on, stable')",
    );

    let b = Browser::open(&driver, &url);
    b.wait("the second page sees who controls", 10, "return document.querySelector('#control-status').textContent.startsWith('Read-only: bench PC')");
    assert_eq!(
        b.eval("return document.body.dataset.controlling"),
        json!("false")
    );
    for button in [
        "#take-control",
        "#btn-start",
        "#btn-light-off",
        "#btn-home",
        "#preview-apply",
    ] {
        assert!(
            b.is_disabled(button),
            "{button} is enabled on the read-only page"
        );
    }
    // the read-only page's own requests are refused by the server, not only greyed out
    let answer = b.eval(
        "return (async () => {
            const h = {'Content-Type': 'application/json', 'X-Client': lab.client,
                       'Authorization': 'Bearer ' + document.querySelector('#token').value};
            const off = await fetch('/api/light', {method: 'POST', headers: h, body: JSON.stringify({on: false})});
            const take = await fetch('/api/control', {method: 'POST', headers: h, body: JSON.stringify({name: 'b'})});
            return [off.status, take.status, (await take.json()).error];
        })()",
    );
    assert_eq!(answer[0], 403, "{answer}");
    assert_eq!(answer[1], 403, "{answer}");
    assert!(answer[2].as_str().unwrap().contains("bench PC"), "{answer}");
    assert!(half(&serve.state()), "the light is still on");

    // the controller leaves: its light goes off, and the other page may take control
    a.close();
    serve.wait_state("the light off after the controller left", 10, |s| {
        s["rig"]["sim"]["levels"][1] == 0.0
    });
    b.wait(
        "control is free",
        10,
        "return !document.querySelector('#take-control').disabled",
    );
    take_control(&b, "tablet");
    b.close();
}

/// POST with the token and an optional client key.
fn request_with_token(
    serve: &Serve,
    path: &str,
    client: Option<&str>,
    body: &Value,
    token: &str,
) -> (u16, Value) {
    let auth = format!("Bearer {token}");
    let mut headers = vec![("authorization", auth.as_str())];
    if let Some(c) = client {
        headers.push(("x-client", c));
    }
    serve.post(path, &headers, body)
}
