//! Harness for the C reference firmware (`firmware-protocol/firmware`) under QEMU: builds the
//! QEMU variant once with make, starts `qemu-system-avr -M mega2560` on a pseudo-terminal and
//! kills it when the guard drops. Missing tools fail the test with a pointer to
//! `scripts/setup.sh`; they never make it pass silently.
//!
//! QEMU's AVR timers run slower than the wall clock (each timer period is stretched by the host's
//! scheduling delay, more on a loaded machine), so waits here poll with generous wall deadlines.

#![allow(dead_code)]

use brdf_rig::protocol::{self, Decoder};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::sync::{Mutex, MutexGuard};
use std::time::Duration;

/// The firmware sources.
pub fn firmware_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("firmware-protocol/firmware")
}

fn require_tool(program: &str) {
    let found = Command::new(program)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .map(|s| s.success())
        .unwrap_or(false);
    assert!(
        found,
        "{program} is not installed: the firmware tests need gcc-avr, avr-libc, binutils-avr and \
         qemu-system-misc; run scripts/setup.sh"
    );
}

/// Builds the QEMU variant (`make qemu`) into the test's target directory, once per test run.
pub fn qemu_elf() -> PathBuf {
    qemu_elf_with(&[])
}

/// Builds the QEMU variant with extra `make` settings (e.g. `("BOOT_DELAY_MS", "1000")`) into
/// its own folder, once per test run and settings.
pub fn qemu_elf_with(settings: &[(&str, &str)]) -> PathBuf {
    static BUILT: Mutex<Vec<(String, Result<PathBuf, String>)>> = Mutex::new(Vec::new());
    let key: String = settings.iter().map(|(k, v)| format!("-{k}={v}")).collect();
    let mut built = BUILT.lock().unwrap_or_else(|p| p.into_inner());
    if !built.iter().any(|(k, _)| *k == key) {
        let result = build_qemu(&key, settings);
        built.push((key.clone(), result));
    }
    match built.iter().find(|(k, _)| *k == key).map(|(_, r)| r) {
        Some(Ok(p)) => p.clone(),
        Some(Err(e)) => panic!("{e}"),
        None => unreachable!("inserted above"),
    }
}

fn build_qemu(key: &str, settings: &[(&str, &str)]) -> Result<PathBuf, String> {
    require_tool("avr-gcc");
    require_tool("make");
    let build = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(format!("firmware-qemu{key}"));
    let out = Command::new("make")
        .arg("-C")
        .arg(firmware_dir())
        .arg("qemu")
        .arg(format!("BUILD={}", build.display()))
        .args(settings.iter().map(|(k, v)| format!("{k}={v}")))
        .output()
        .map_err(|e| format!("could not run make: {e}"))?;
    if !out.status.success() {
        return Err(format!(
            "make qemu failed:\n{}\n{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        ));
    }
    Ok(build.join("firmware.elf"))
}

/// One QEMU at a time: on a 2-core machine parallel emulators slow each other's timers down.
fn exclusive() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// A running emulator; dropping it kills QEMU.
pub struct Qemu {
    child: Child,
    pub pty: PathBuf,
    _turn: MutexGuard<'static, ()>,
}

impl Qemu {
    /// Boots the QEMU build of the firmware and finds its serial pseudo-terminal.
    pub fn start() -> Qemu {
        Qemu::start_elf(&qemu_elf())
    }

    /// Boots a given firmware image (see [`qemu_elf_with`]).
    pub fn start_elf(elf: &Path) -> Qemu {
        require_tool("qemu-system-avr");
        let turn = exclusive();
        let mut child = Command::new("qemu-system-avr")
            .args(["-M", "mega2560", "-bios"])
            .arg(elf)
            .args(["-serial", "pty", "-nographic", "-monitor", "none"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| {
                panic!("could not start qemu-system-avr: {e}; run scripts/setup.sh")
            });
        let (tx, rx) = mpsc::channel();
        for stream in [
            child
                .stdout
                .take()
                .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
            child
                .stderr
                .take()
                .map(|s| Box::new(s) as Box<dyn std::io::Read + Send>),
        ]
        .into_iter()
        .flatten()
        {
            let tx = tx.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    let _ = tx.send(line);
                }
            });
        }
        let mut qemu = Qemu {
            child,
            pty: PathBuf::new(),
            _turn: turn,
        };
        let mut seen = Vec::new();
        loop {
            match rx.recv_timeout(Duration::from_secs(10)) {
                Ok(line) => {
                    // "char device redirected to /dev/pts/N (label serial0)"
                    if let Some(rest) = line.split("redirected to ").nth(1) {
                        let path = rest.split_whitespace().next().unwrap_or_default();
                        qemu.pty = PathBuf::from(path);
                        break;
                    }
                    seen.push(line);
                }
                Err(_) => panic!(
                    "qemu-system-avr did not report its serial pty within 10 s; it said: {seen:?}"
                ),
            }
        }
        assert!(
            qemu.pty.starts_with("/dev/"),
            "unexpected pty path {:?}",
            qemu.pty
        );
        qemu
    }

    pub fn pty(&self) -> &Path {
        &self.pty
    }
}

impl Drop for Qemu {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Frames at the byte level, for what a driver deliberately cannot do (re-send a request with
/// the same id, send bodies of the wrong length or unknown kinds). Framing is the crate's codec
/// (`protocol::frame`); the bytes inside are written by hand.
pub struct RawLink {
    port: Box<dyn serialport::SerialPort>,
    decoder: Decoder,
}

/// A decoded reply: kind, id, body.
#[derive(Debug, Clone, PartialEq)]
pub struct RawFrame {
    pub kind: u8,
    pub id: u16,
    pub body: Vec<u8>,
}

/// Wire bytes of a request with any kind and body.
pub fn frame(kind: u8, id: u16, body: &[u8]) -> Vec<u8> {
    let mut payload = vec![kind];
    payload.extend_from_slice(&id.to_le_bytes());
    payload.extend_from_slice(body);
    protocol::frame::encode_payload(&payload)
}

impl RawLink {
    pub fn open(pty: &Path) -> RawLink {
        let port = serialport::new(pty.to_string_lossy(), 115_200)
            .timeout(Duration::from_millis(50))
            .open()
            .unwrap_or_else(|e| panic!("cannot open {}: {e}", pty.display()));
        RawLink {
            port,
            decoder: Decoder::new(),
        }
    }

    pub fn write(&mut self, bytes: &[u8]) {
        self.port
            .write_all(bytes)
            .unwrap_or_else(|e| panic!("write to the firmware failed: {e}"));
    }

    pub fn send(&mut self, kind: u8, id: u16, body: &[u8]) {
        self.write(&frame(kind, id, body));
    }

    /// The next valid frame, or None after `timeout` of wall time. Frames the decoder drops
    /// (which the firmware never sends) are skipped.
    pub fn recv(&mut self, timeout: Duration) -> Option<RawFrame> {
        let deadline = std::time::Instant::now() + timeout;
        loop {
            while let Some(frame) = self.decoder.next_frame() {
                let Ok(packet) = frame else { continue };
                let payload = packet
                    .to_payload()
                    .unwrap_or_else(|e| panic!("cannot re-encode {packet:?}: {e}"));
                return Some(RawFrame {
                    kind: payload[0],
                    id: packet.id,
                    body: payload[3..].to_vec(),
                });
            }
            if std::time::Instant::now() >= deadline {
                return None;
            }
            let mut chunk = [0u8; 256];
            match self.port.read(&mut chunk) {
                Ok(n) => self.decoder.push(&chunk[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) => panic!("read from the firmware failed: {e}"),
            }
        }
    }

    /// Sends a request and returns the reply to it (replies to other ids are skipped).
    pub fn request(&mut self, kind: u8, id: u16, body: &[u8]) -> RawFrame {
        self.send(kind, id, body);
        let deadline = std::time::Instant::now() + Duration::from_secs(5);
        while std::time::Instant::now() < deadline {
            if let Some(f) = self.recv(Duration::from_secs(5))
                && f.id == id
            {
                return f;
            }
        }
        panic!("no reply from the firmware to kind 0x{kind:02x} id {id} within 5 s");
    }
}

/// STATUS_REPLY body fields.
#[derive(Debug, Clone, Copy)]
pub struct RawStatus {
    pub angle: i32,
    pub target: i32,
    pub moving: bool,
    pub homed: bool,
    pub enabled: bool,
    pub faults: u16,
    pub boot: u32,
    pub uptime_ms: u32,
}

pub fn parse_status(f: &RawFrame) -> RawStatus {
    assert_eq!(f.kind, 0x83, "expected STATUS_REPLY, got {f:?}");
    assert_eq!(f.body.len(), 19, "STATUS_REPLY body length");
    let b = &f.body;
    let i32_at = |o: usize| i32::from_le_bytes([b[o], b[o + 1], b[o + 2], b[o + 3]]);
    RawStatus {
        angle: i32_at(0),
        target: i32_at(4),
        moving: b[8] & 1 != 0,
        homed: b[8] & 2 != 0,
        enabled: b[8] & 4 != 0,
        faults: u16::from_le_bytes([b[9], b[10]]),
        boot: i32_at(11) as u32,
        uptime_ms: i32_at(15) as u32,
    }
}
