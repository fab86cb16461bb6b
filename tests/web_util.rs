//! Shared by the lab page tests: the real `brdf-rig serve` binary on the simulated rig, plain
//! HTTP requests to it, and headless Chromium driven through chromedriver (WebDriver) the way a
//! person uses the page: real clicks on real buttons.
//!
//! Chromium and chromedriver are Debian's (`scripts/setup.sh`); nothing is downloaded and
//! nothing leaves this machine: the browser starts with a fresh profile and without background
//! networking, and talks only to the server on 127.0.0.1.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Mutex, MutexGuard};
use std::time::{Duration, Instant};

use fantoccini::{Client, ClientBuilder, Locator};
use serde_json::{Value, json};

use crate::util;

/// The browser tests run one at a time: each starts Chromium, and on a 2-core machine two
/// browsers and two simulated captures at once would only make each slower.
pub fn one_at_a_time() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|p| p.into_inner())
}

/// `brdf-rig serve` on a free port; killed (SIGTERM, then SIGKILL) when dropped.
pub struct Serve {
    child: Child,
    /// `http://127.0.0.1:PORT`
    pub base: String,
    pub port: u16,
    stderr: std::sync::Arc<Mutex<String>>,
}

impl Serve {
    /// Starts `brdf-rig serve ARGS` (add `--bind`; default 127.0.0.1:0) and waits for its URL.
    pub fn start(args: &[&str]) -> Serve {
        let mut cmd = Command::new(util::bin());
        cmd.arg("serve");
        if !args.contains(&"--bind") {
            cmd.args(["--bind", "127.0.0.1:0"]);
        }
        cmd.args(args)
            .env_remove("BRDF_RIG_PROFILE")
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped());
        let mut child = cmd.spawn().unwrap();
        let stderr = std::sync::Arc::new(Mutex::new(String::new()));
        let err_pipe = child.stderr.take().unwrap();
        let sink = stderr.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(err_pipe).lines().map_while(Result::ok) {
                let mut s = sink.lock().unwrap();
                s.push_str(&line);
                s.push('\n');
            }
        });
        let mut first = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut first)
            .unwrap();
        let port: u16 = first
            .trim()
            .trim_end_matches('/')
            .rsplit(':')
            .next()
            .and_then(|p| p.parse().ok())
            .unwrap_or_else(|| {
                let _ = child.kill();
                let _ = child.wait();
                panic!(
                    "serve printed no URL: {first:?}\n{}",
                    stderr.lock().unwrap()
                )
            });
        Serve {
            child,
            base: format!("http://127.0.0.1:{port}"),
            port,
            stderr,
        }
    }

    pub fn stderr(&self) -> String {
        self.stderr.lock().unwrap().clone()
    }

    pub fn get(&self, path: &str) -> (u16, String) {
        request("GET", &format!("{}{path}", self.base), &[], None)
    }

    pub fn post(&self, path: &str, headers: &[(&str, &str)], body: &Value) -> (u16, Value) {
        let (status, text) = request(
            "POST",
            &format!("{}{path}", self.base),
            headers,
            Some(&body.to_string()),
        );
        (status, serde_json::from_str(&text).unwrap_or(Value::Null))
    }

    pub fn state(&self) -> Value {
        let (status, text) = self.get("/api/state");
        assert_eq!(status, 200, "{text}");
        serde_json::from_str(&text).unwrap()
    }

    /// Polls the state until `pred` holds; panics with the last state after `secs`.
    pub fn wait_state(&self, what: &str, secs: u64, pred: impl Fn(&Value) -> bool) -> Value {
        let t = Instant::now();
        loop {
            let s = self.state();
            if pred(&s) {
                return s;
            }
            if t.elapsed() > Duration::from_secs(secs) {
                panic!(
                    "{what}: not within {secs} s; capture: {}\nlog: {}\nserver stderr:\n{}",
                    s["capture"],
                    s["log"],
                    self.stderr()
                );
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Stops the server as Ctrl-C would (SIGTERM) and waits for it.
    pub fn stop(&mut self) -> std::process::ExitStatus {
        let _ = Command::new("kill")
            .args(["-TERM", &self.child.id().to_string()])
            .status();
        let t = Instant::now();
        loop {
            if let Some(st) = self.child.try_wait().unwrap() {
                return st;
            }
            if t.elapsed() > Duration::from_secs(20) {
                let _ = self.child.kill();
                return self.child.wait().unwrap();
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        if self.child.try_wait().ok().flatten().is_none() {
            self.stop();
        }
    }
}

/// One HTTP request; `(status, body)`. Any status is an answer (no error for 4xx/5xx).
pub fn request(
    method: &str,
    url: &str,
    headers: &[(&str, &str)],
    body: Option<&str>,
) -> (u16, String) {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .build()
        .into();
    let response = match (method, body) {
        ("GET", _) => {
            let mut r = agent.get(url);
            for (k, v) in headers {
                r = r.header(*k, *v);
            }
            r.call()
        }
        (_, body) => {
            let mut r = agent.post(url).header("content-type", "application/json");
            for (k, v) in headers {
                r = r.header(*k, *v);
            }
            r.send(body.unwrap_or("{}"))
        }
    };
    let mut response = response.unwrap_or_else(|e| panic!("{method} {url}: {e}"));
    let status = response.status().as_u16();
    let text = response.body_mut().read_to_string().unwrap_or_default();
    (status, text)
}

fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

fn find_program(candidates: &[&str], package: &str) -> PathBuf {
    for c in candidates {
        if Path::new(c).is_file() {
            return PathBuf::from(c);
        }
    }
    panic!(
        "{} is not installed: run scripts/setup.sh (it installs Debian's {package})",
        candidates[0]
    );
}

/// chromedriver on a free port; killed when dropped.
pub struct Driver {
    child: Child,
    pub url: String,
}

impl Driver {
    pub fn start() -> Driver {
        let exe = find_program(
            &["/usr/bin/chromedriver", "/usr/lib/chromium/chromedriver"],
            "chromium-driver",
        );
        let port = free_port();
        let child = Command::new(exe)
            .arg(format!("--port={port}"))
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let t = Instant::now();
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(
                t.elapsed() < Duration::from_secs(20),
                "chromedriver did not start"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
        Driver {
            child,
            url: format!("http://127.0.0.1:{port}"),
        }
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One headless Chromium with a fresh profile, showing one page.
pub struct Browser {
    rt: tokio::runtime::Runtime,
    client: Option<Client>,
    _profile: tempfile::TempDir,
}

impl Browser {
    pub fn open(driver: &Driver, url: &str) -> Browser {
        let chromium = find_program(
            &["/usr/bin/chromium", "/usr/bin/chromium-browser"],
            "chromium",
        );
        let profile = tempfile::tempdir().unwrap();
        let rt = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .unwrap();
        let mut caps = serde_json::Map::new();
        caps.insert(
            "goog:chromeOptions".into(),
            json!({
                "binary": chromium,
                "args": [
                    "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
                    "--no-first-run", "--disable-background-networking",
                    "--disable-component-update", "--disable-sync",
                    "--window-size=1280,1000",
                    format!("--user-data-dir={}", profile.path().display()),
                ]
            }),
        );
        let client = rt
            .block_on(async {
                let c =
                    ClientBuilder::new(hyper_util::client::legacy::connect::HttpConnector::new())
                        .capabilities(caps)
                        .connect(&driver.url)
                        .await?;
                c.goto(url).await?;
                Ok::<_, Box<dyn std::error::Error>>(c)
            })
            .unwrap_or_else(|e| panic!("opening {url} in headless Chromium: {e}"));
        let b = Browser {
            rt,
            client: Some(client),
            _profile: profile,
        };
        b.wait(
            "the page connects",
            30,
            "return window.lab && window.lab.client !== null && window.lab.state !== null",
        );
        b
    }

    fn client(&self) -> &Client {
        self.client.as_ref().unwrap()
    }

    /// Runs `js` (a function body) in the page and returns its value.
    pub fn eval(&self, js: &str) -> Value {
        self.rt
            .block_on(self.client().execute(js, vec![]))
            .unwrap_or_else(|e| panic!("{js}: {e}"))
    }

    /// Waits until `js` returns true.
    pub fn wait(&self, what: &str, secs: u64, js: &str) {
        let t = Instant::now();
        while self.eval(js) != Value::Bool(true) {
            if t.elapsed() > Duration::from_secs(secs) {
                panic!(
                    "{what}: not within {secs} s; page error {:?}, capture {}",
                    self.text("#error"),
                    self.eval("return lab.state ? lab.state.capture : null")
                );
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// A real click on the element (WebDriver moves the pointer there and clicks).
    pub fn click(&self, css: &str) {
        self.rt
            .block_on(async { self.client().find(Locator::Css(css)).await?.click().await })
            .unwrap_or_else(|e| panic!("clicking {css}: {e}"));
    }

    /// Types `text` into an input (after clearing it).
    pub fn fill(&self, css: &str, text: &str) {
        self.rt
            .block_on(async {
                let e = self.client().find(Locator::Css(css)).await?;
                e.clear().await?;
                e.send_keys(text).await
            })
            .unwrap_or_else(|e| panic!("typing into {css}: {e}"));
    }

    pub fn select(&self, css: &str, value: &str) {
        self.rt
            .block_on(async {
                self.client()
                    .find(Locator::Css(css))
                    .await?
                    .select_by_value(value)
                    .await
            })
            .unwrap_or_else(|e| panic!("choosing {value} in {css}: {e}"));
    }

    pub fn text(&self, css: &str) -> String {
        self.eval(&format!(
            "const e = document.querySelector({}); return e ? e.textContent : null",
            json!(css)
        ))
        .as_str()
        .unwrap_or("")
        .to_string()
    }

    pub fn is_disabled(&self, css: &str) -> bool {
        self.eval(&format!(
            "return document.querySelector({}).disabled",
            json!(css)
        )) == Value::Bool(true)
    }

    pub fn screenshot(&self) -> Vec<u8> {
        self.rt.block_on(self.client().screenshot()).unwrap()
    }

    /// Quits the browser (WebDriver ends the session: Chromium exits, its connections close).
    pub fn close(mut self) {
        if let Some(c) = self.client.take() {
            let _ = self.rt.block_on(c.close());
        }
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        if let Some(c) = self.client.take() {
            let _ = self.rt.block_on(c.close());
        }
    }
}

/// A page's event stream opened by hand, that then goes silent: it never reads and never
/// answers a ping, as a browser behind a pulled network cable. Returns the socket (keep it
/// open) and the client key the server sent.
pub fn silent_page(port: u16) -> (TcpStream, String) {
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    write!(
        s,
        "GET /api/ws HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
         Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
    )
    .unwrap();
    // the 101 answer, up to its blank line
    let mut head = Vec::new();
    let mut byte = [0u8; 1];
    while !head.ends_with(b"\r\n\r\n") {
        s.read_exact(&mut byte).unwrap();
        head.push(byte[0]);
    }
    assert!(
        head.starts_with(b"HTTP/1.1 101"),
        "{}",
        String::from_utf8_lossy(&head)
    );
    // the first frame: the hello text (short, unmasked from a server)
    let mut h = [0u8; 2];
    s.read_exact(&mut h).unwrap();
    assert_eq!(h[0], 0x81, "a text frame");
    let len = match h[1] & 0x7f {
        126 => {
            let mut l = [0u8; 2];
            s.read_exact(&mut l).unwrap();
            usize::from(u16::from_be_bytes(l))
        }
        n => usize::from(n),
    };
    let mut payload = vec![0u8; len];
    s.read_exact(&mut payload).unwrap();
    let hello: Value = serde_json::from_slice(&payload).unwrap();
    assert_eq!(hello["type"], "hello");
    (s, hello["client"].as_str().unwrap().to_string())
}
