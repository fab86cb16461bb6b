//! Serves the simulated firmware on a pseudo-terminal, on its own thread, so the host's real
//! serial stack (driver, link, codec) runs against it unchanged.
//!
//! The port the host opens is a symlink (`SimRig::port_path`) to the pty's slave side; pulling
//! the port closes the pty and later re-points the symlink at a new one, which is what a USB
//! serial adapter that drops off the bus looks like to a driver that re-opens by path.
//! Faults (lost and corrupted frames, lost bytes, delayed replies, firmware resets, unplugging)
//! are injected on command through [`FaultControl`]; they act on whole frames (split at the
//! `0x00` delimiters) in both directions, with a seeded RNG so runs repeat.
//!
//! Shared state: [`SimHandle`] lets the simulated camera and tests see the platter angle and
//! the lit channels at any instant, and the list of motions the firmware executed.
//!
//! Must not be used by the library's non-simulated paths; it owns threads, ptys and the clock.

use std::collections::VecDeque;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serialport::{SerialPort, TTYPort};

use super::firmware::{FirmwareConfig, FirmwareStats, MoveRecord, SimFirmware, SimSnapshot};

/// `TTYPort::pair()` is not safe to call from parallel threads (serialport's own tests say so),
/// so every pty this process creates is made under this lock.
static PTY_LOCK: Mutex<()> = Mutex::new(());

/// Link faults, applied per frame in both directions.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LinkFaults {
    /// Probability that a whole frame is lost.
    pub drop_rate: f64,
    /// Probability that one bit of a frame is flipped.
    pub corrupt_rate: f64,
    /// Probability that any single byte is lost.
    pub byte_drop_rate: f64,
    /// Extra delay before every reply leaves the firmware.
    pub reply_delay: Duration,
}

/// What to simulate.
#[derive(Clone, Debug)]
pub struct SimConfig {
    pub firmware: FirmwareConfig,
    pub faults: LinkFaults,
    /// Seed of the fault RNG.
    pub seed: u64,
    /// When a host first opens the port after the board started, and after the port came back
    /// from an unplug, the board ignores what it receives for this long, as an Arduino's
    /// bootloader holds the UART after the reset that opening its port causes. The window runs
    /// from the host's open, however late the host comes.
    pub boot_delay: Duration,
    /// Where to put the port symlink; a fresh temporary directory when `None`.
    pub link_path: Option<PathBuf>,
}

impl Default for SimConfig {
    fn default() -> SimConfig {
        SimConfig {
            firmware: FirmwareConfig::default(),
            faults: LinkFaults::default(),
            seed: 1,
            boot_delay: Duration::ZERO,
            link_path: None,
        }
    }
}

/// The simulated rig's state, shared with the simulated camera and tests. Cheap to clone.
#[derive(Clone)]
pub struct SimHandle {
    fw: Arc<Mutex<SimFirmware>>,
    epoch: Instant,
}

impl SimHandle {
    fn now_us(&self) -> u64 {
        self.epoch.elapsed().as_micros() as u64
    }

    fn lock(&self) -> MutexGuard<'_, SimFirmware> {
        // A panic while holding the lock leaves the firmware state as consistent as it was
        // between two requests; keep serving.
        self.fw.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// The rig now: platter angle, lit channels, boot counter.
    pub fn snapshot(&self) -> SimSnapshot {
        let now = self.now_us();
        self.lock().snapshot(now)
    }

    /// Every motion the firmware executed, in order.
    pub fn moves(&self) -> Vec<MoveRecord> {
        self.lock().moves().to_vec()
    }

    pub fn stats(&self) -> FirmwareStats {
        self.lock().stats()
    }

    /// Resets the firmware now (boot counter + 1, not homed, lights off).
    pub fn reset(&self) {
        let now = self.now_us();
        self.lock().reset(now);
    }
}

#[derive(Default)]
struct FaultState {
    link: LinkFaults,
    unplug: Option<Duration>,
    unplugged: bool,
    frames_dropped: u64,
    frames_corrupted: u64,
}

/// Fault injection on command. Cheap to clone.
#[derive(Clone)]
pub struct FaultControl {
    state: Arc<Mutex<FaultState>>,
    sim: SimHandle,
}

impl FaultControl {
    fn lock(&self) -> MutexGuard<'_, FaultState> {
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    pub fn set(&self, faults: LinkFaults) {
        self.lock().link = faults;
    }

    pub fn get(&self) -> LinkFaults {
        self.lock().link.clone()
    }

    /// Resets the firmware (as a power glitch would).
    pub fn reset(&self) {
        self.sim.reset();
    }

    /// Pulls the port: the pty closes and the path disappears; after `gone_for` a new pty
    /// appears at the same path. Returns at once.
    pub fn unplug(&self, gone_for: Duration) {
        let mut s = self.lock();
        s.unplug = Some(gone_for);
        s.unplugged = true;
    }

    /// True from `unplug` until the port is back.
    pub fn is_unplugged(&self) -> bool {
        self.lock().unplugged
    }

    /// Frames the link lost and corrupted so far.
    pub fn counts(&self) -> (u64, u64) {
        let s = self.lock();
        (s.frames_dropped, s.frames_corrupted)
    }
}

/// A simulated rig served on a pty. Dropping it stops the thread and removes the port.
pub struct SimRig {
    /// The path the host opens (a symlink to the current pty).
    pub port_path: PathBuf,
    pub state: SimHandle,
    pub faults: FaultControl,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    _dir: Option<tempfile::TempDir>,
}

/// The master side of one pty. The runner does not keep the slave open: reading the master
/// fails (EIO) while no host has the port open, which is how the board sees the host open the
/// port and starts its bootloader then, as the reset that opening an Arduino's port causes.
struct Pty {
    master: TTYPort,
}

/// A bare pty pair `(master, slave)`, made under the same lock as the runner's (for tests that
/// need a port where nothing answers, or their own fake).
pub fn pty_pair() -> std::io::Result<(TTYPort, TTYPort)> {
    let _guard = PTY_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    TTYPort::pair().map_err(std::io::Error::other)
}

fn open_pty(link: &Path) -> std::io::Result<Pty> {
    let _guard = PTY_LOCK.lock().unwrap_or_else(|p| p.into_inner());
    let (mut master, slave) = TTYPort::pair().map_err(std::io::Error::other)?;
    master
        .set_timeout(Duration::from_millis(1))
        .map_err(std::io::Error::other)?;
    let target = slave
        .name()
        .ok_or_else(|| std::io::Error::other("pty without a name"))?;
    // Re-point the symlink atomically: create beside it, rename over it.
    let tmp = link.with_extension("new");
    let _ = std::fs::remove_file(&tmp);
    std::os::unix::fs::symlink(&target, &tmp)?;
    std::fs::rename(&tmp, link)?;
    drop(slave);
    Ok(Pty { master })
}

impl SimRig {
    /// Boots the simulated firmware and serves it on a new pty.
    pub fn spawn(config: SimConfig) -> std::io::Result<SimRig> {
        let (dir, port_path) = match &config.link_path {
            Some(p) => (None, p.clone()),
            None => {
                let d = super::port_dir::create()?;
                let p = d.path().join("tty");
                (Some(d), p)
            }
        };
        let epoch = Instant::now();
        let state = SimHandle {
            fw: Arc::new(Mutex::new(SimFirmware::new(config.firmware.clone(), 0))),
            epoch,
        };
        let faults = FaultControl {
            state: Arc::new(Mutex::new(FaultState {
                link: config.faults.clone(),
                ..FaultState::default()
            })),
            sim: state.clone(),
        };
        let pty = open_pty(&port_path)?;
        let stop = Arc::new(AtomicBool::new(false));
        let mut server = Server {
            pty: Some(pty),
            link: port_path.clone(),
            sim: state.clone(),
            faults: faults.clone(),
            stop: stop.clone(),
            rng: ChaCha8Rng::seed_from_u64(config.seed),
            rx: Vec::new(),
            outbox: VecDeque::new(),
            boot_delay: config.boot_delay,
            booted_at: Instant::now(),
            host_open: false,
            boot_pending: true,
        };
        let thread = std::thread::Builder::new()
            .name("brdf-sim-firmware".into())
            .spawn(move || server.run())?;
        Ok(SimRig {
            port_path,
            state,
            faults,
            stop,
            thread: Some(thread),
            _dir: dir,
        })
    }
}

impl Drop for SimRig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        if self._dir.is_none() {
            let _ = std::fs::remove_file(&self.port_path);
        }
    }
}

struct Server {
    pty: Option<Pty>,
    link: PathBuf,
    sim: SimHandle,
    faults: FaultControl,
    stop: Arc<AtomicBool>,
    rng: ChaCha8Rng,
    /// Host -> firmware bytes not yet ended by a delimiter.
    rx: Vec<u8>,
    /// Replies waiting for their delay, with the time they leave.
    outbox: VecDeque<(Instant, Vec<u8>)>,
    boot_delay: Duration,
    /// Until then the bootloader runs: received bytes are discarded.
    booted_at: Instant,
    /// Whether a host has the port open (the master's reads do not fail).
    host_open: bool,
    /// The board has started (or come back from an unplug) and boots when a host opens it.
    boot_pending: bool,
}

impl Server {
    fn run(&mut self) {
        let mut buf = [0u8; 512];
        while !self.stop.load(Ordering::SeqCst) {
            let unplug = self.faults.lock().unplug.take();
            if let Some(gone_for) = unplug {
                self.unplug(gone_for);
                continue;
            }
            let Some(pty) = self.pty.as_mut() else {
                return;
            };
            let n = match pty.master.read(&mut buf) {
                Ok(n) => Some(n),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => Some(0),
                Err(_) => None,
            };
            let Some(n) = n else {
                // No host has the port open: nothing to read, nothing to answer, and the
                // firmware keeps running (watchdog, motion).
                self.host_open = false;
                self.outbox.clear();
                let now = self.sim.now_us();
                self.sim.lock().advance(now);
                std::thread::sleep(Duration::from_millis(1));
                continue;
            };
            if !self.host_open {
                self.host_open = true;
                if self.boot_pending {
                    // Opening the port resets the board: its bootloader holds the UART from now.
                    self.boot_pending = false;
                    self.booted_at = Instant::now() + self.boot_delay;
                }
            }
            if Instant::now() < self.booted_at {
                // The bootloader reads the UART and finds no programmer: the bytes are gone.
                continue;
            }
            self.rx.extend_from_slice(&buf[..n]);
            let mut to_fw = Vec::new();
            while let Some(pos) = self.rx.iter().position(|&b| b == 0) {
                let frame: Vec<u8> = self.rx.drain(..=pos).collect();
                to_fw.extend(self.damage(frame));
            }
            if self.rx.len() > 256 {
                // Long garbage without delimiters passes through; the firmware discards it.
                to_fw.append(&mut self.rx);
            }
            let now = self.sim.now_us();
            let out = self.sim.lock().receive(&to_fw, now);
            let delay = self.faults.lock().link.reply_delay;
            let mut rest = out.as_slice();
            while let Some(pos) = rest.iter().position(|&b| b == 0) {
                let frame = rest[..=pos].to_vec();
                rest = &rest[pos + 1..];
                let frame = self.damage(frame);
                if !frame.is_empty() {
                    self.outbox.push_back((Instant::now() + delay, frame));
                }
            }
            self.flush_due();
        }
    }

    fn flush_due(&mut self) {
        let now = Instant::now();
        while let Some((due, _)) = self.outbox.front() {
            if *due > now {
                break;
            }
            if let Some((_, bytes)) = self.outbox.pop_front()
                && let Some(pty) = self.pty.as_mut()
            {
                // A full buffer (no host reading) loses the bytes, as a UART would.
                let _ = pty.master.write_all(&bytes);
            }
        }
    }

    /// Applies the link faults to one frame (with its delimiter).
    fn damage(&mut self, mut frame: Vec<u8>) -> Vec<u8> {
        let f = self.faults.lock().link.clone();
        if f.drop_rate > 0.0 && self.rng.gen_bool(f.drop_rate.min(1.0)) {
            self.faults.lock().frames_dropped += 1;
            return Vec::new();
        }
        if f.corrupt_rate > 0.0 && self.rng.gen_bool(f.corrupt_rate.min(1.0)) && frame.len() > 1 {
            let i = self.rng.gen_range(0..frame.len() - 1);
            frame[i] ^= 1 << self.rng.gen_range(0..8);
            self.faults.lock().frames_corrupted += 1;
        }
        if f.byte_drop_rate > 0.0 {
            let p = f.byte_drop_rate.min(1.0);
            frame.retain(|_| !self.rng.gen_bool(p));
        }
        frame
    }

    fn unplug(&mut self, gone_for: Duration) {
        let _ = std::fs::remove_file(&self.link);
        self.pty = None;
        self.rx.clear();
        self.outbox.clear();
        let back_at = Instant::now() + gone_for;
        while Instant::now() < back_at {
            if self.stop.load(Ordering::SeqCst) {
                return;
            }
            // The firmware keeps running while its port is gone (watchdog, motion).
            let now = self.sim.now_us();
            self.sim.lock().advance(now);
            std::thread::sleep(Duration::from_millis(1));
        }
        // If the pty cannot be made again, stay unplugged: the host sees a port that never
        // came back, which is a case it must handle anyway.
        for _ in 0..50 {
            if let Ok(pty) = open_pty(&self.link) {
                self.pty = Some(pty);
                break;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        self.host_open = false;
        self.boot_pending = true;
        self.faults.lock().unplugged = false;
    }
}
