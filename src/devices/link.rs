//! The serial link to the rig firmware: owns the port and a read buffer, sends requests with
//! fresh ids, waits for the matching reply, retries with the *same* bytes (safe per the
//! protocol: the firmware answers a repeated id from memory, it never executes it twice), and
//! re-opens the port by path when it vanishes.
//!
//! Split as in mini-redis's `Connection`: the codec (`crate::protocol`) never sees the port; this
//! file never parses bytes itself. Blocking and synchronous: one request in flight at a time.
//! It knows nothing of turntables or lights (that is `devices::rig`).

use std::io::{Read, Write};
use std::path::PathBuf;
use std::time::{Duration, Instant};

use serialport::{ClearBuffer, SerialPort};

use super::DeviceError;
use crate::protocol::{Body, Decoder, Packet, Reply, Request, frame};

/// How to reach the firmware and how hard to try.
#[derive(Clone, Debug, PartialEq)]
pub struct LinkConfig {
    pub path: PathBuf,
    pub baud: u32,
    /// Wait for one reply before sending the request again.
    pub timeout: Duration,
    /// Re-sends after the first attempt when no reply comes.
    pub retries: u32,
    /// How long to keep trying to re-open a port that vanished.
    pub reconnect_timeout: Duration,
    /// After the port is opened (or re-opened), how long the board may stay silent while it
    /// boots: a request that gets no reply is re-sent every `timeout` until this has passed,
    /// and only then do `retries` start counting. Opening the port of an Arduino resets it
    /// (DTR), and its bootloader holds the UART for 1-2 s before the firmware runs.
    pub boot_window: Duration,
}

/// Counters, for tests, `rig check` and the bench.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    pub requests: u64,
    /// Requests sent again after a timeout or a reconnect.
    pub resends: u64,
    pub reconnects: u64,
    /// Frames dropped by the decoder (CRC, COBS, ...).
    pub rejected: u64,
    /// Replies whose id did not match the request in flight (late replies to earlier tries).
    pub stale: u64,
    /// Milliseconds from the last opening of the port to the first reply after it (the board's
    /// boot time as the host sees it, within one reply timeout).
    pub first_reply_ms: Option<u64>,
}

pub struct SerialLink {
    cfg: LinkConfig,
    port: Option<Box<dyn SerialPort>>,
    decoder: Decoder,
    next_id: u16,
    last_tx: Instant,
    stats: LinkStats,
    last_io_error: String,
    /// When the port was last opened (the boot window counts from here).
    opened_at: Instant,
}

/// The port cannot be opened (becomes the reason of a [`DeviceError::Disconnected`], which
/// carries text: a device error is shown or retried, never matched on its cause).
#[derive(Debug, thiserror::Error)]
#[error("cannot open {path}: {source}")]
struct OpenError {
    path: String,
    #[source]
    source: serialport::Error,
}

/// What went wrong while waiting for one reply.
enum Wait {
    Timeout,
    Io(String),
}

const DEVICE: &str = "rig firmware";

impl SerialLink {
    /// Opens the port (one attempt: a port missing at start-up is a configuration problem
    /// the user should see at once, not a glitch to wait out).
    pub fn open(cfg: LinkConfig) -> Result<SerialLink, DeviceError> {
        let mut link = SerialLink {
            cfg,
            port: None,
            decoder: Decoder::new(),
            // A random start: the firmware may still remember the last id of a previous
            // session, and a request that reuses it would be answered from memory. Every
            // session starts with HELLO, whose replay is harmless, and the random start makes
            // even that rare.
            next_id: rand::random::<u16>(),
            last_tx: Instant::now(),
            stats: LinkStats::default(),
            last_io_error: String::new(),
            opened_at: Instant::now(),
        };
        link.connect().map_err(|e| DeviceError::Disconnected {
            device: format!("{DEVICE} on {}", link.cfg.path.display()),
            reason: e.to_string(),
        })?;
        Ok(link)
    }

    pub fn config(&self) -> &LinkConfig {
        &self.cfg
    }

    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// When the last request left (for the heartbeat).
    pub fn last_tx(&self) -> Instant {
        self.last_tx
    }

    fn device(&self) -> String {
        format!("{DEVICE} on {}", self.cfg.path.display())
    }

    fn connect(&mut self) -> Result<(), OpenError> {
        let path = self.cfg.path.to_string_lossy().into_owned();
        let port = serialport::new(&path, self.cfg.baud)
            .timeout(self.cfg.timeout)
            .open()
            .map_err(|source| OpenError { path, source })?;
        // Whatever waits in the input queue was meant for an earlier connection.
        let _ = port.clear(ClearBuffer::Input);
        self.decoder.clear();
        self.port = Some(port);
        self.opened_at = Instant::now();
        self.stats.first_reply_ms = None;
        Ok(())
    }

    /// Re-opens the port by path with exponential backoff, for at most `reconnect_timeout`.
    fn reconnect(&mut self) -> Result<(), DeviceError> {
        self.port = None;
        let give_up = Instant::now() + self.cfg.reconnect_timeout;
        let mut backoff = Duration::from_millis(10);
        loop {
            match self.connect() {
                Ok(()) => {
                    self.stats.reconnects += 1;
                    return Ok(());
                }
                Err(reason) => {
                    let now = Instant::now();
                    if now >= give_up {
                        return Err(DeviceError::Disconnected {
                            device: self.device(),
                            reason: format!(
                                "lost the port ({}); {reason}; gave up after {} ms",
                                self.last_io_error,
                                self.cfg.reconnect_timeout.as_millis()
                            ),
                        });
                    }
                    std::thread::sleep(backoff.min(give_up - now));
                    backoff = (backoff * 2).min(Duration::from_millis(250));
                }
            }
        }
    }

    fn new_id(&mut self) -> u16 {
        self.next_id = self.next_id.wrapping_add(1);
        if self.next_id == 0 {
            self.next_id = 1;
        }
        self.next_id
    }

    /// Sends `req` and returns the firmware's reply (an ACK, a NAK, or data). Lost frames are
    /// retried with the same id; a vanished port is re-opened and the same id sent again. While
    /// the port's boot window is open, silence is the board booting: the request is re-sent
    /// without counting against `retries`.
    pub fn request(&mut self, req: Request) -> Result<Reply, DeviceError> {
        let id = self.new_id();
        let what = req.name();
        let packet = Packet::request(id, req);
        let mut wire = vec![0u8];
        wire.extend(frame::encode(&packet).map_err(|e| DeviceError::Protocol {
            device: self.device(),
            reason: e.to_string(),
        })?);
        self.stats.requests += 1;
        let mut timeouts = 0;
        let mut attempts = 0;
        let mut reconnects = 0;
        let mut first = true;
        loop {
            if self.port.is_none() {
                reconnects += 1;
                if reconnects > 8 {
                    return Err(DeviceError::Disconnected {
                        device: self.device(),
                        reason: format!("the port kept failing while sending {what}"),
                    });
                }
                self.reconnect()?;
            }
            if !first {
                self.stats.resends += 1;
            }
            first = false;
            match self.send_and_wait(&wire, id) {
                Ok(reply) => {
                    if self.stats.first_reply_ms.is_none() {
                        self.stats.first_reply_ms =
                            Some(self.opened_at.elapsed().as_millis() as u64);
                    }
                    return Ok(reply);
                }
                Err(Wait::Timeout) => {
                    attempts += 1;
                    if self.opened_at.elapsed() < self.cfg.boot_window {
                        continue;
                    }
                    timeouts += 1;
                    if timeouts > self.cfg.retries {
                        let boot = if self.cfg.boot_window.is_zero() {
                            String::new()
                        } else {
                            format!(
                                ", after a {} ms boot window from opening the port",
                                self.cfg.boot_window.as_millis()
                            )
                        };
                        return Err(DeviceError::Timeout {
                            device: self.device(),
                            attempts,
                            what: format!(
                                "{what} id {id}, {} ms per attempt{boot}",
                                self.cfg.timeout.as_millis()
                            ),
                        });
                    }
                }
                Err(Wait::Io(e)) => {
                    // The port vanished (USB unplugged, pty closed): reconnect and resend.
                    self.last_io_error = e;
                    self.port = None;
                }
            }
        }
    }

    fn send_and_wait(&mut self, wire: &[u8], id: u16) -> Result<Reply, Wait> {
        let Some(port) = self.port.as_mut() else {
            return Err(Wait::Io("not connected".into()));
        };
        // No flush: on a tty it is tcdrain, which has no timeout; the kernel sends anyway.
        port.write_all(wire).map_err(|e| Wait::Io(e.to_string()))?;
        self.last_tx = Instant::now();
        let deadline = self.last_tx + self.cfg.timeout;
        let mut buf = [0u8; 256];
        loop {
            while let Some(frame) = self.decoder.next_frame() {
                match frame {
                    Ok(Packet {
                        id: rid,
                        body: Body::Reply(r),
                    }) if rid == id => return Ok(r),
                    Ok(_) => self.stats.stale += 1,
                    Err(_) => self.stats.rejected += 1,
                }
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(Wait::Timeout);
            }
            let Some(port) = self.port.as_mut() else {
                return Err(Wait::Io("not connected".into()));
            };
            let _ = port.set_timeout(deadline - now);
            match port.read(&mut buf) {
                Ok(0) => return Err(Wait::Io("end of file".into())),
                Ok(n) => self.decoder.push(&buf[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(Wait::Io(e.to_string())),
            }
        }
    }
}
