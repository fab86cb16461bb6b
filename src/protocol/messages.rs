//! The messages of protocol 1.0 (PROTOCOL.md sections 3 to 6): requests, replies, their payload
//! layout and their canonical text form (section 9). Pure: no I/O, no framing (that is
//! `frame.rs`), no policy (retries and timeouts belong to the serial link in `devices`).
//!
//! Units are the wire's: millidegrees, millidegrees per second (squared), milliseconds, light
//! levels as u16. Integers are little-endian.

use std::fmt;

use super::error::{EncodeError, Reject};

pub const PROTOCOL_MAJOR: u8 = 1;
pub const PROTOCOL_MINOR: u8 = 0;
/// Largest payload (kind + id + body), section 2.
pub const MAX_PAYLOAD: usize = 60;
/// Longest firmware name in HELLO_REPLY.
pub const MAX_NAME: usize = 16;
/// Most light channels a LIGHT_STATUS_REPLY can carry within `MAX_PAYLOAD`.
pub const MAX_CHANNELS: usize = (MAX_PAYLOAD - 4) / 3;

/// Kind bytes.
pub mod kind {
    pub const HELLO: u8 = 0x01;
    pub const HEARTBEAT: u8 = 0x02;
    pub const SET_WATCHDOG: u8 = 0x03;
    pub const SET_LIMITS: u8 = 0x04;
    pub const HOME: u8 = 0x10;
    pub const MOVE_ABS: u8 = 0x11;
    pub const MOVE_REL: u8 = 0x12;
    pub const STOP: u8 = 0x13;
    pub const STATUS: u8 = 0x14;
    pub const LIGHT_ON: u8 = 0x20;
    pub const LIGHT_OFF: u8 = 0x21;
    pub const LIGHT_STATUS: u8 = 0x22;
    pub const ACK: u8 = 0x80;
    pub const NAK: u8 = 0x81;
    pub const HELLO_REPLY: u8 = 0x82;
    pub const STATUS_REPLY: u8 = 0x83;
    pub const LIGHT_STATUS_REPLY: u8 = 0x84;
}

/// Capability bits of HELLO_REPLY.
pub mod caps {
    pub const TURNTABLE: u16 = 1 << 0;
    pub const LIGHT: u16 = 1 << 1;
    pub const HOME_SWITCH: u16 = 1 << 2;
    pub const SIMULTANEOUS_CHANNELS: u16 = 1 << 3;
    pub const WARMUP_SENSING: u16 = 1 << 4;
}

/// Fault bits of STATUS_REPLY.
pub mod faults {
    pub const WATCHDOG: u16 = 1 << 0;
    pub const HOME_FAILED: u16 = 1 << 1;
    pub const STALL: u16 = 1 << 2;
    pub const BROWN_OUT: u16 = 1 << 3;
    pub const RX_OVERFLOW: u16 = 1 << 4;

    /// Names of the known bits set in `bits` (unknown bits are ignored, section 11).
    pub fn names(bits: u16) -> Vec<&'static str> {
        let all = [
            (WATCHDOG, "watchdog"),
            (HOME_FAILED, "home failed"),
            (STALL, "stall"),
            (BROWN_OUT, "brown-out"),
            (RX_OVERFLOW, "receive overflow"),
        ];
        all.iter()
            .filter(|(b, _)| bits & b != 0)
            .map(|(_, n)| *n)
            .collect()
    }
}

/// NAK error codes (section 6).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum NakCode {
    UnknownKind = 1,
    BadLength = 2,
    OutOfRange = 3,
    NotHomed = 4,
    Busy = 5,
    BadChannel = 6,
    Fault = 7,
}

impl NakCode {
    pub fn from_u8(code: u8) -> Option<NakCode> {
        Some(match code {
            1 => NakCode::UnknownKind,
            2 => NakCode::BadLength,
            3 => NakCode::OutOfRange,
            4 => NakCode::NotHomed,
            5 => NakCode::Busy,
            6 => NakCode::BadChannel,
            7 => NakCode::Fault,
            _ => return None,
        })
    }

    pub fn name(self) -> &'static str {
        match self {
            NakCode::UnknownKind => "UNKNOWN_KIND",
            NakCode::BadLength => "BAD_LENGTH",
            NakCode::OutOfRange => "OUT_OF_RANGE",
            NakCode::NotHomed => "NOT_HOMED",
            NakCode::Busy => "BUSY",
            NakCode::BadChannel => "BAD_CHANNEL",
            NakCode::Fault => "FAULT",
        }
    }
}

/// Host -> firmware.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Request {
    Hello,
    Heartbeat,
    SetWatchdog {
        timeout_ms: u16,
    },
    SetLimits {
        max_speed: u32,
        max_accel: u32,
    },
    Home,
    MoveAbs {
        angle: i32,
    },
    MoveRel {
        delta: i32,
    },
    Stop,
    Status,
    LightOn {
        channel: u8,
        level: u16,
        exclusive: bool,
    },
    LightOff {
        channel: u8,
    },
    LightStatus,
}

/// The handshake (HELLO_REPLY body).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HelloInfo {
    pub major: u8,
    pub minor: u8,
    pub caps: u16,
    pub boot: u32,
    pub channels: u8,
    pub min_angle: i32,
    pub max_angle: i32,
    pub max_speed: u32,
    pub max_accel: u32,
    pub watchdog_ms: u16,
    /// ASCII, at most 16 bytes.
    pub name: String,
}

/// STATUS_REPLY body.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct StatusInfo {
    pub angle: i32,
    pub target: i32,
    pub moving: bool,
    pub homed: bool,
    pub enabled: bool,
    pub faults: u16,
    pub boot: u32,
    pub uptime_ms: u32,
}

/// One channel of LIGHT_STATUS_REPLY.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ChannelState {
    pub level: u16,
    pub stable: bool,
}

/// Firmware -> host.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Reply {
    Ack,
    Nak { code: u8, detail: u8 },
    Hello(HelloInfo),
    Status(StatusInfo),
    LightStatus(Vec<ChannelState>),
}

#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Body {
    Request(Request),
    Reply(Reply),
}

/// A decoded payload: kind (implied by the body), request id, body.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Packet {
    pub id: u16,
    pub body: Body,
}

impl Packet {
    pub fn request(id: u16, r: Request) -> Packet {
        Packet {
            id,
            body: Body::Request(r),
        }
    }

    pub fn reply(id: u16, r: Reply) -> Packet {
        Packet {
            id,
            body: Body::Reply(r),
        }
    }

    pub fn kind(&self) -> u8 {
        match &self.body {
            Body::Request(r) => r.kind(),
            Body::Reply(r) => r.kind(),
        }
    }

    /// The payload bytes (kind, id, body), without CRC or framing.
    pub fn to_payload(&self) -> Result<Vec<u8>, EncodeError> {
        let mut p = Vec::with_capacity(16);
        p.push(self.kind());
        p.extend_from_slice(&self.id.to_le_bytes());
        match &self.body {
            Body::Request(r) => r.write_body(&mut p),
            Body::Reply(r) => r.write_body(&mut p)?,
        }
        if p.len() > MAX_PAYLOAD {
            return Err(EncodeError::TooLong { len: p.len() });
        }
        Ok(p)
    }

    /// Parses a payload whose CRC has already been checked (`payload.len() >= 3`).
    pub fn from_payload(payload: &[u8]) -> Result<Packet, Reject> {
        if payload.len() < 3 {
            return Err(Reject::Short {
                len: payload.len() + 2,
            });
        }
        let kind = payload[0];
        let id = u16::from_le_bytes([payload[1], payload[2]]);
        let body = &payload[3..];
        let mut r = Reader { body, pos: 0 };
        let fixed = |n: usize| -> Result<(), Reject> {
            if body.len() == n {
                Ok(())
            } else {
                Err(Reject::Length {
                    id,
                    kind,
                    got: body.len(),
                    expected: n,
                })
            }
        };
        use self::kind as k;
        let b = match kind {
            k::HELLO => fixed(0).map(|_| Body::Request(Request::Hello))?,
            k::HEARTBEAT => fixed(0).map(|_| Body::Request(Request::Heartbeat))?,
            k::SET_WATCHDOG => {
                fixed(2)?;
                Body::Request(Request::SetWatchdog {
                    timeout_ms: r.u16(),
                })
            }
            k::SET_LIMITS => {
                fixed(8)?;
                Body::Request(Request::SetLimits {
                    max_speed: r.u32(),
                    max_accel: r.u32(),
                })
            }
            k::HOME => fixed(0).map(|_| Body::Request(Request::Home))?,
            k::MOVE_ABS => {
                fixed(4)?;
                Body::Request(Request::MoveAbs { angle: r.i32() })
            }
            k::MOVE_REL => {
                fixed(4)?;
                Body::Request(Request::MoveRel { delta: r.i32() })
            }
            k::STOP => fixed(0).map(|_| Body::Request(Request::Stop))?,
            k::STATUS => fixed(0).map(|_| Body::Request(Request::Status))?,
            k::LIGHT_ON => {
                fixed(4)?;
                Body::Request(Request::LightOn {
                    channel: r.u8(),
                    level: r.u16(),
                    exclusive: r.u8() & 1 != 0,
                })
            }
            k::LIGHT_OFF => {
                fixed(1)?;
                Body::Request(Request::LightOff { channel: r.u8() })
            }
            k::LIGHT_STATUS => fixed(0).map(|_| Body::Request(Request::LightStatus))?,
            k::ACK => fixed(0).map(|_| Body::Reply(Reply::Ack))?,
            k::NAK => {
                fixed(2)?;
                Body::Reply(Reply::Nak {
                    code: r.u8(),
                    detail: r.u8(),
                })
            }
            k::HELLO_REPLY => {
                // Fixed part is 28 bytes, then the name's bytes.
                let name_len = body.get(27).map(|&n| n as usize).unwrap_or(0);
                fixed(28 + name_len)?;
                let info = HelloInfo {
                    major: r.u8(),
                    minor: r.u8(),
                    caps: r.u16(),
                    boot: r.u32(),
                    channels: r.u8(),
                    min_angle: r.i32(),
                    max_angle: r.i32(),
                    max_speed: r.u32(),
                    max_accel: r.u32(),
                    watchdog_ms: r.u16(),
                    name: {
                        let _ = r.u8();
                        let bytes = r.take(name_len);
                        if name_len > MAX_NAME || !bytes.iter().all(|b| b.is_ascii_graphic()) {
                            return Err(Reject::Field {
                                id,
                                kind,
                                reason: "firmware name must be 0..=16 printable ASCII bytes",
                            });
                        }
                        bytes.iter().map(|&b| b as char).collect()
                    },
                };
                Body::Reply(Reply::Hello(info))
            }
            k::STATUS_REPLY => {
                fixed(19)?;
                let angle = r.i32();
                let target = r.i32();
                let flags = r.u8();
                Body::Reply(Reply::Status(StatusInfo {
                    angle,
                    target,
                    moving: flags & 1 != 0,
                    homed: flags & 2 != 0,
                    enabled: flags & 4 != 0,
                    faults: r.u16(),
                    boot: r.u32(),
                    uptime_ms: r.u32(),
                }))
            }
            k::LIGHT_STATUS_REPLY => {
                let n = body.first().map(|&n| n as usize).unwrap_or(0);
                fixed(1 + 3 * n)?;
                let _ = r.u8();
                let chans = (0..n)
                    .map(|_| ChannelState {
                        level: r.u16(),
                        stable: r.u8() & 1 != 0,
                    })
                    .collect();
                Body::Reply(Reply::LightStatus(chans))
            }
            _ => return Err(Reject::Kind { id, kind }),
        };
        Ok(Packet { id, body: b })
    }
}

/// Reads little-endian fields from a body whose length was checked first, so reads never run
/// past the end (a short read would be a bug in the length table, and yields zeros, not a panic).
struct Reader<'a> {
    body: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> &[u8] {
        let start = self.pos.min(self.body.len());
        let end = (self.pos + n).min(self.body.len());
        self.pos += n;
        &self.body[start..end]
    }
    fn array<const N: usize>(&mut self) -> [u8; N] {
        let mut a = [0u8; N];
        let s = self.take(N);
        a[..s.len()].copy_from_slice(s);
        a
    }
    fn u8(&mut self) -> u8 {
        self.array::<1>()[0]
    }
    fn u16(&mut self) -> u16 {
        u16::from_le_bytes(self.array())
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.array())
    }
    fn i32(&mut self) -> i32 {
        i32::from_le_bytes(self.array())
    }
}

impl Request {
    pub fn kind(&self) -> u8 {
        use self::kind as k;
        match self {
            Request::Hello => k::HELLO,
            Request::Heartbeat => k::HEARTBEAT,
            Request::SetWatchdog { .. } => k::SET_WATCHDOG,
            Request::SetLimits { .. } => k::SET_LIMITS,
            Request::Home => k::HOME,
            Request::MoveAbs { .. } => k::MOVE_ABS,
            Request::MoveRel { .. } => k::MOVE_REL,
            Request::Stop => k::STOP,
            Request::Status => k::STATUS,
            Request::LightOn { .. } => k::LIGHT_ON,
            Request::LightOff { .. } => k::LIGHT_OFF,
            Request::LightStatus => k::LIGHT_STATUS,
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Request::Hello => "HELLO",
            Request::Heartbeat => "HEARTBEAT",
            Request::SetWatchdog { .. } => "SET_WATCHDOG",
            Request::SetLimits { .. } => "SET_LIMITS",
            Request::Home => "HOME",
            Request::MoveAbs { .. } => "MOVE_ABS",
            Request::MoveRel { .. } => "MOVE_REL",
            Request::Stop => "STOP",
            Request::Status => "STATUS",
            Request::LightOn { .. } => "LIGHT_ON",
            Request::LightOff { .. } => "LIGHT_OFF",
            Request::LightStatus => "LIGHT_STATUS",
        }
    }

    /// Body length the firmware expects for `kind`, if it is a request kind (the NAK
    /// BAD_LENGTH detail).
    pub fn body_len(kind: u8) -> Option<usize> {
        use self::kind as k;
        Some(match kind {
            k::HELLO | k::HEARTBEAT | k::HOME | k::STOP | k::STATUS | k::LIGHT_STATUS => 0,
            k::SET_WATCHDOG => 2,
            k::SET_LIMITS => 8,
            k::MOVE_ABS | k::MOVE_REL | k::LIGHT_ON => 4,
            k::LIGHT_OFF => 1,
            _ => return None,
        })
    }

    fn write_body(&self, p: &mut Vec<u8>) {
        match self {
            Request::Hello
            | Request::Heartbeat
            | Request::Home
            | Request::Stop
            | Request::Status
            | Request::LightStatus => {}
            Request::SetWatchdog { timeout_ms } => p.extend_from_slice(&timeout_ms.to_le_bytes()),
            Request::SetLimits {
                max_speed,
                max_accel,
            } => {
                p.extend_from_slice(&max_speed.to_le_bytes());
                p.extend_from_slice(&max_accel.to_le_bytes());
            }
            Request::MoveAbs { angle } => p.extend_from_slice(&angle.to_le_bytes()),
            Request::MoveRel { delta } => p.extend_from_slice(&delta.to_le_bytes()),
            Request::LightOn {
                channel,
                level,
                exclusive,
            } => {
                p.push(*channel);
                p.extend_from_slice(&level.to_le_bytes());
                p.push(*exclusive as u8);
            }
            Request::LightOff { channel } => p.push(*channel),
        }
    }
}

impl Reply {
    pub fn kind(&self) -> u8 {
        use self::kind as k;
        match self {
            Reply::Ack => k::ACK,
            Reply::Nak { .. } => k::NAK,
            Reply::Hello(_) => k::HELLO_REPLY,
            Reply::Status(_) => k::STATUS_REPLY,
            Reply::LightStatus(_) => k::LIGHT_STATUS_REPLY,
        }
    }

    pub fn name(&self) -> &'static str {
        match self {
            Reply::Ack => "ACK",
            Reply::Nak { .. } => "NAK",
            Reply::Hello(_) => "HELLO_REPLY",
            Reply::Status(_) => "STATUS_REPLY",
            Reply::LightStatus(_) => "LIGHT_STATUS_REPLY",
        }
    }

    pub fn nak(code: NakCode, detail: u8) -> Reply {
        Reply::Nak {
            code: code as u8,
            detail,
        }
    }

    fn write_body(&self, p: &mut Vec<u8>) -> Result<(), EncodeError> {
        match self {
            Reply::Ack => {}
            Reply::Nak { code, detail } => {
                p.push(*code);
                p.push(*detail);
            }
            Reply::Hello(h) => {
                if h.name.len() > MAX_NAME || !h.name.bytes().all(|b| b.is_ascii_graphic()) {
                    return Err(EncodeError::BadName {
                        name: h.name.clone(),
                    });
                }
                p.push(h.major);
                p.push(h.minor);
                p.extend_from_slice(&h.caps.to_le_bytes());
                p.extend_from_slice(&h.boot.to_le_bytes());
                p.push(h.channels);
                p.extend_from_slice(&h.min_angle.to_le_bytes());
                p.extend_from_slice(&h.max_angle.to_le_bytes());
                p.extend_from_slice(&h.max_speed.to_le_bytes());
                p.extend_from_slice(&h.max_accel.to_le_bytes());
                p.extend_from_slice(&h.watchdog_ms.to_le_bytes());
                p.push(h.name.len() as u8);
                p.extend_from_slice(h.name.as_bytes());
            }
            Reply::Status(s) => {
                p.extend_from_slice(&s.angle.to_le_bytes());
                p.extend_from_slice(&s.target.to_le_bytes());
                p.push(s.moving as u8 | (s.homed as u8) << 1 | (s.enabled as u8) << 2);
                p.extend_from_slice(&s.faults.to_le_bytes());
                p.extend_from_slice(&s.boot.to_le_bytes());
                p.extend_from_slice(&s.uptime_ms.to_le_bytes());
            }
            Reply::LightStatus(chans) => {
                if chans.len() > MAX_CHANNELS {
                    return Err(EncodeError::TooLong {
                        len: 4 + 3 * chans.len(),
                    });
                }
                p.push(chans.len() as u8);
                for c in chans {
                    p.extend_from_slice(&c.level.to_le_bytes());
                    p.push(c.stable as u8);
                }
            }
        }
        Ok(())
    }
}

/// The canonical text form of section 9, e.g. `MOVE_ABS id=7 angle=90000`.
impl fmt::Display for Packet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let id = self.id;
        match &self.body {
            Body::Request(r) => {
                write!(f, "{} id={id}", r.name())?;
                match r {
                    Request::SetWatchdog { timeout_ms } => write!(f, " timeout={timeout_ms}"),
                    Request::SetLimits {
                        max_speed,
                        max_accel,
                    } => write!(f, " max_speed={max_speed} max_accel={max_accel}"),
                    Request::MoveAbs { angle } => write!(f, " angle={angle}"),
                    Request::MoveRel { delta } => write!(f, " delta={delta}"),
                    Request::LightOn {
                        channel,
                        level,
                        exclusive,
                    } => write!(
                        f,
                        " channel={channel} level={level} exclusive={}",
                        *exclusive as u8
                    ),
                    Request::LightOff { channel } => write!(f, " channel={channel}"),
                    _ => Ok(()),
                }
            }
            Body::Reply(r) => {
                write!(f, "{} id={id}", r.name())?;
                match r {
                    Reply::Ack => Ok(()),
                    Reply::Nak { code, detail } => write!(f, " code={code} detail={detail}"),
                    Reply::Hello(h) => write!(
                        f,
                        " major={} minor={} caps={} boot={} channels={} min_angle={} \
                         max_angle={} max_speed={} max_accel={} watchdog={} name={}",
                        h.major,
                        h.minor,
                        h.caps,
                        h.boot,
                        h.channels,
                        h.min_angle,
                        h.max_angle,
                        h.max_speed,
                        h.max_accel,
                        h.watchdog_ms,
                        h.name
                    ),
                    Reply::Status(s) => write!(
                        f,
                        " angle={} target={} moving={} homed={} enabled={} faults={} boot={} \
                         uptime={}",
                        s.angle,
                        s.target,
                        s.moving as u8,
                        s.homed as u8,
                        s.enabled as u8,
                        s.faults,
                        s.boot,
                        s.uptime_ms
                    ),
                    Reply::LightStatus(chans) => {
                        write!(f, " channels={}", chans.len())?;
                        for (i, c) in chans.iter().enumerate() {
                            write!(f, " level{i}={} stable{i}={}", c.level, c.stable as u8)?;
                        }
                        Ok(())
                    }
                }
            }
        }
    }
}
