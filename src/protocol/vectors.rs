//! The shared test vectors of `firmware-protocol/vectors/` (PROTOCOL.md section 10): their
//! generator (from this codec) and a checker any Rust test can run on the committed files.
//!
//! Pure: works on strings; reading and writing the files is the tests' job. The generated
//! frames are hand-checked in `frame.rs` tests, so the vectors are not only self-consistent.

use super::crc::crc16;
use super::error::{EncodeError, Reject};
use super::frame::{self, Decoder};
use super::messages::{
    ChannelState, HelloInfo, NakCode, Packet, Reply, Request, StatusInfo, caps, faults, kind,
};

/// One line of a vector file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Vector {
    /// Wire bytes of one frame (with its `0x00`) and its canonical text or `REJECT <reason>`.
    Frame { wire: Vec<u8>, text: String },
    /// A byte stream and the texts of the frames a receiver must extract from it, in order.
    Stream { wire: Vec<u8>, texts: Vec<String> },
}

/// A line of a vector file that is not a vector; `line` is 1-based.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VectorFileError {
    #[error("line {line}: bad hex: {source}")]
    Hex {
        line: usize,
        #[source]
        source: hex::FromHexError,
    },
    #[error("line {line}: expected 2 or 3 TAB-separated fields")]
    Fields { line: usize },
}

/// How a vector disagrees with this codec.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VectorError {
    #[error("wire bytes must end with 00")]
    NoDelimiter,
    #[error("decoded to {got:?}, expected {expected:?}")]
    Decoded { got: String, expected: String },
    /// A frame whose text says it is valid does not parse.
    #[error(transparent)]
    Rejected(#[from] Reject),
    #[error(transparent)]
    Encode(#[from] EncodeError),
    /// The hex of the bytes the decoded packet encodes to.
    #[error("re-encodes to {0}")]
    ReEncoded(String),
    #[error("extracted {got:?}, expected {expected:?}")]
    Extracted {
        got: Vec<String>,
        expected: Vec<String>,
    },
}

fn hex_line(wire: &[u8], text: &str) -> String {
    format!("{}\t{}\n", hex::encode(wire), text)
}

fn valid_packets() -> Vec<Packet> {
    let sim_hello = HelloInfo {
        major: 1,
        minor: 0,
        caps: 31,
        boot: 5,
        channels: 3,
        min_angle: -3_600_000,
        max_angle: 3_600_000,
        max_speed: 90_000,
        max_accel: 180_000,
        watchdog_ms: 2000,
        name: "brdf-sim".into(),
    };
    vec![
        Packet::request(1, Request::Hello),
        Packet::request(0, Request::Hello),
        Packet::request(2, Request::Heartbeat),
        Packet::request(3, Request::SetWatchdog { timeout_ms: 2000 }),
        Packet::request(
            4,
            Request::SetLimits {
                max_speed: 90_000,
                max_accel: 180_000,
            },
        ),
        Packet::request(5, Request::Home),
        Packet::request(7, Request::MoveAbs { angle: 90_000 }),
        Packet::request(8, Request::MoveAbs { angle: -3_600_000 }),
        Packet::request(0x0100, Request::MoveAbs { angle: 0 }),
        Packet::request(10, Request::MoveRel { delta: 1000 }),
        Packet::request(11, Request::MoveRel { delta: -1 }),
        Packet::request(12, Request::Stop),
        Packet::request(65535, Request::Status),
        Packet::request(
            9,
            Request::LightOn {
                channel: 0,
                level: 65535,
                exclusive: true,
            },
        ),
        Packet::request(
            13,
            Request::LightOn {
                channel: 2,
                level: 256,
                exclusive: false,
            },
        ),
        Packet::request(14, Request::LightOff { channel: 1 }),
        Packet::request(15, Request::LightOff { channel: 0xFF }),
        Packet::request(16, Request::LightStatus),
        Packet::reply(2, Reply::Ack),
        Packet::reply(9, Reply::nak(NakCode::BadChannel, 2)),
        Packet::reply(7, Reply::nak(NakCode::NotHomed, 0)),
        Packet::reply(6, Reply::nak(NakCode::BadLength, 4)),
        Packet::reply(7, Reply::nak(NakCode::Busy, 0)),
        Packet::reply(1, Reply::Hello(sim_hello.clone())),
        Packet::reply(
            0,
            Reply::Hello(HelloInfo {
                caps: caps::TURNTABLE | caps::LIGHT,
                boot: 0xFFFF_FFFF,
                channels: 1,
                min_angle: 0,
                max_angle: 360_000,
                watchdog_ms: 100,
                name: "ATmega2560-rig-1".into(),
                ..sim_hello.clone()
            }),
        ),
        Packet::reply(
            1,
            Reply::Hello(HelloInfo {
                name: String::new(),
                ..sim_hello
            }),
        ),
        Packet::reply(
            3,
            Reply::Status(StatusInfo {
                angle: 90_000,
                target: 90_000,
                moving: false,
                homed: true,
                enabled: true,
                faults: 0,
                boot: 5,
                uptime_ms: 1234,
            }),
        ),
        Packet::reply(
            17,
            Reply::Status(StatusInfo {
                angle: -1500,
                target: -45_000,
                moving: true,
                homed: true,
                enabled: true,
                faults: faults::WATCHDOG | faults::RX_OVERFLOW,
                boot: 6,
                uptime_ms: 4_000_000_000,
            }),
        ),
        Packet::reply(
            4,
            Reply::LightStatus(vec![
                ChannelState {
                    level: 65535,
                    stable: true,
                },
                ChannelState {
                    level: 0,
                    stable: false,
                },
            ]),
        ),
        Packet::reply(18, Reply::LightStatus(vec![])),
    ]
}

/// Wire bytes for an arbitrary payload with a correct CRC (used to build frames the message
/// layer must reject).
fn raw(payload: &[u8]) -> Vec<u8> {
    frame::encode_payload(payload)
}

/// `frames.txt`: valid frames of every kind and streams with garbage between frames.
pub fn frames_file() -> String {
    let mut s = String::from(
        "# brdf-rig protocol 1.0 test vectors: valid frames (PROTOCOL.md section 10).\n\
         # Generated by the Rust codec (`BRDF_RIG_BLESS_VECTORS=1 cargo test rig_vectors`);\n\
         # <wire hex including the final 00> TAB <canonical text form>\n",
    );
    for p in valid_packets() {
        // Every packet above fits the protocol's limits, so encoding cannot fail.
        let Ok(wire) = frame::encode(&p) else {
            continue;
        };
        s += &hex_line(&wire, &p.to_string());
    }
    s += "# streams: stream TAB <bytes> TAB <frames a receiver extracts, separated by |>\n";
    for (wire, texts) in streams() {
        s += &format!("stream\t{}\t{}\n", hex::encode(wire), texts.join("|"));
    }
    s
}

fn streams() -> Vec<(Vec<u8>, Vec<String>)> {
    let enc = |p: &Packet| frame::encode(p).unwrap_or_default();
    let a = Packet::request(20, Request::Status);
    let b = Packet::request(21, Request::MoveAbs { angle: 45_000 });
    let c = Packet::reply(21, Reply::Ack);
    let mut out = Vec::new();

    // Garbage, a flushing 0x00, a frame, an empty frame, another frame.
    let mut w = vec![0x42, 0x17, 0xFF, 0x00];
    w.extend(enc(&a));
    w.push(0x00);
    w.extend(enc(&b));
    out.push((w, vec![a.to_string(), b.to_string()]));

    // A frame with a flipped bit between two good ones: only the good ones come out.
    let mut bad = enc(&b);
    bad[2] ^= 0x10;
    let mut w = enc(&a);
    w.extend(bad);
    w.extend(enc(&c));
    out.push((w, vec![a.to_string(), c.to_string()]));

    // More than 64 bytes without a delimiter: discarded up to the next 0x00; the frame after
    // that survives.
    let mut w = vec![0x55; 80];
    w.push(0x00);
    w.extend(enc(&c));
    out.push((w, vec![c.to_string()]));

    // A frame truncated by a lost tail, then a good frame: the truncated bytes and the good
    // frame run together up to its 0x00 and fail, so nothing comes out until the next frame.
    let full = enc(&a);
    let mut w = full[..4].to_vec();
    w.extend(enc(&b));
    w.extend(enc(&c));
    out.push((w, vec![c.to_string()]));
    out
}

/// `reject.txt`: frames every receiver must drop (or, for `kind` and `length`, answer with a
/// NAK when it is a firmware and the frame is a request).
pub fn reject_file() -> String {
    let mut s = String::from(
        "# brdf-rig protocol 1.0 test vectors: frames that must be rejected (PROTOCOL.md\n\
         # section 10). Generated by the Rust codec; <wire hex> TAB REJECT <reason>\n",
    );
    let mut line = |wire: Vec<u8>, reason: &str| {
        s += &hex_line(&wire, &format!("REJECT {reason}"));
    };
    // cobs: a code byte pointing past the end of the frame.
    line(vec![0x05, 0x11, 0x22, 0x00], "cobs");
    line(vec![0x09, 0x01, 0x01, 0x03, 0x9D, 0xC8, 0x00], "cobs");
    // crc: a good frame with one bit flipped, and one with the CRC bytes swapped.
    let mut w =
        frame::encode(&Packet::request(7, Request::MoveAbs { angle: 90_000 })).unwrap_or_default();
    if w.len() > 4 {
        w[4] ^= 0x01;
    }
    line(w, "crc");
    let payload = [kind::STATUS, 0x22, 0x00];
    let c = crc16(&payload).to_be_bytes();
    let mut r = payload.to_vec();
    r.extend_from_slice(&c);
    let mut w = super::cobs::encode(&r);
    w.push(0);
    line(w, "crc");
    // short: fewer than 5 decoded bytes (a 2-byte payload with a correct CRC; a lone byte).
    line(raw(&[kind::HELLO, 0x01]), "short");
    line(vec![0x02, 0x01, 0x00], "short");
    // long: 63 decoded bytes (61-byte payload, correct CRC); 64 wire bytes before the 0x00, so
    // the buffer rule (more than 64) does not apply and the length check must.
    let mut p = vec![kind::HEARTBEAT, 0x01, 0x00];
    p.extend(std::iter::repeat_n(0xAA, 58));
    line(raw(&p), "long");
    // long: 65 bytes before the 0x00, dropped by the buffer rule before any decoding.
    let mut p = vec![kind::HEARTBEAT, 0x02, 0x00];
    p.extend(std::iter::repeat_n(0xAA, 60));
    line(raw(&p), "long");
    // kind: unknown request and reply kinds with correct CRCs.
    line(raw(&[0x05, 0x30, 0x00]), "kind");
    line(raw(&[0x7F, 0x31, 0x00, 0x01]), "kind");
    line(raw(&[0x85, 0x32, 0x00]), "kind");
    // length: bodies of the wrong length for their kind.
    line(
        raw(&[kind::MOVE_ABS, 0x40, 0x00, 0x10, 0x27, 0x00]),
        "length",
    );
    line(raw(&[kind::HELLO, 0x41, 0x00, 0x00]), "length");
    line(
        raw(&[kind::LIGHT_ON, 0x42, 0x00, 0x00, 0xFF, 0xFF]),
        "length",
    );
    line(raw(&[kind::ACK, 0x43, 0x00, 0x00]), "length");
    line(
        raw(&[kind::LIGHT_STATUS_REPLY, 0x44, 0x00, 0x02, 0xFF, 0xFF, 0x01]),
        "length",
    );
    s
}

/// Parses a vector file; errors name the 1-based line.
pub fn parse_file(text: &str) -> Result<Vec<(usize, Vector)>, VectorFileError> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let n = i + 1;
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split('\t').collect();
        let bad_hex = |source| VectorFileError::Hex { line: n, source };
        match fields.as_slice() {
            ["stream", hex, texts] => out.push((
                n,
                Vector::Stream {
                    wire: hex::decode(hex).map_err(bad_hex)?,
                    texts: texts.split('|').map(str::to_owned).collect(),
                },
            )),
            [hex, text] => out.push((
                n,
                Vector::Frame {
                    wire: hex::decode(hex).map_err(bad_hex)?,
                    text: (*text).to_owned(),
                },
            )),
            _ => return Err(VectorFileError::Fields { line: n }),
        }
    }
    Ok(out)
}

/// What this codec makes of one frame's wire bytes: its text, or `REJECT <reason>`.
pub fn decode_to_text(wire: &[u8]) -> String {
    let mut d = Decoder::new();
    d.push(wire);
    match d.next_frame() {
        Some(Ok(p)) => p.to_string(),
        Some(Err(r)) => format!("REJECT {}", r.reason()),
        None => "REJECT incomplete".into(),
    }
}

/// Checks one vector against this codec: the decoded text matches, and for a valid frame,
/// re-encoding gives the same bytes.
pub fn check(v: &Vector) -> Result<(), VectorError> {
    match v {
        Vector::Frame { wire, text } => {
            if wire.last() != Some(&0) {
                return Err(VectorError::NoDelimiter);
            }
            let got = decode_to_text(wire);
            if &got != text {
                return Err(VectorError::Decoded {
                    got,
                    expected: text.clone(),
                });
            }
            if !text.starts_with("REJECT") {
                let p = frame::parse(&wire[..wire.len() - 1])?;
                let again = frame::encode(&p)?;
                if &again != wire {
                    return Err(VectorError::ReEncoded(hex::encode(again)));
                }
            }
            Ok(())
        }
        Vector::Stream { wire, texts } => {
            let mut d = Decoder::new();
            d.push(wire);
            let mut got = Vec::new();
            while let Some(r) = d.next_frame() {
                if let Ok(p) = r {
                    got.push(p.to_string());
                }
            }
            if &got != texts {
                return Err(VectorError::Extracted {
                    got,
                    expected: texts.clone(),
                });
            }
            Ok(())
        }
    }
}

/// Reasons a `Reject` may carry in the vectors.
pub fn is_vector_reason(r: &Reject) -> bool {
    matches!(
        r.reason(),
        "cobs" | "crc" | "short" | "long" | "kind" | "length"
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bad_vector_line_is_named() {
        let e = parse_file("# header\n\n0011\tHELLO\tx\tmore\n").unwrap_err();
        assert_eq!(e, VectorFileError::Fields { line: 3 });
        assert_eq!(
            e.to_string(),
            "line 3: expected 2 or 3 TAB-separated fields"
        );
        let e = parse_file("zz\tHELLO\n").unwrap_err();
        assert!(matches!(e, VectorFileError::Hex { line: 1, .. }), "{e}");
        assert!(e.to_string().starts_with("line 1: bad hex: "), "{e}");
    }

    #[test]
    fn a_wrong_text_says_what_it_decoded_to() {
        let v = Vector::Frame {
            wire: vec![0x01, 0x01],
            text: "HELLO".into(),
        };
        assert_eq!(check(&v), Err(VectorError::NoDelimiter));
        let v = Vector::Frame {
            wire: vec![0x01, 0x00],
            text: "HELLO".into(),
        };
        let e = check(&v).unwrap_err().to_string();
        assert!(e.starts_with("decoded to \"REJECT "), "{e}");
    }
}
