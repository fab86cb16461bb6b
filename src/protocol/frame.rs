//! Framing (PROTOCOL.md section 2): `COBS(payload || crc16le(payload)) 0x00` on the wire, and a
//! receiver that finds frames in a byte stream and resynchronises after garbage.
//!
//! Split as in mini-redis: [`check`] says whether a whole frame is buffered (no frame yet is the
//! normal case, not an error), [`parse`] decodes one, and [`Decoder`] owns the receive buffer
//! and applies the discard rules. Pure: the decoder is fed bytes; it never sees a port.

use super::cobs;
use super::crc::crc16;
use super::error::{EncodeError, Reject};
use super::messages::Packet;

/// A receiver holding this many bytes without a delimiter discards them (section 2).
pub const MAX_BUFFERED: usize = 64;
/// Decoded frame bounds: payload 3..=60 bytes plus 2 CRC bytes.
pub const MIN_DECODED: usize = 5;
pub const MAX_DECODED: usize = 62;

/// Wire bytes of a payload: COBS of payload and CRC, then the `0x00` delimiter.
pub fn encode_payload(payload: &[u8]) -> Vec<u8> {
    let mut raw = Vec::with_capacity(payload.len() + 2);
    raw.extend_from_slice(payload);
    raw.extend_from_slice(&crc16(payload).to_le_bytes());
    let mut wire = cobs::encode(&raw);
    wire.push(0);
    wire
}

/// Wire bytes of a packet.
pub fn encode(packet: &Packet) -> Result<Vec<u8>, EncodeError> {
    Ok(encode_payload(&packet.to_payload()?))
}

/// Length of the first frame in `buf` including its `0x00`, or `None` when no delimiter has
/// arrived yet (read more).
pub fn check(buf: &[u8]) -> Option<usize> {
    buf.iter().position(|&b| b == 0).map(|p| p + 1)
}

/// Decodes the COBS bytes of one frame (without the delimiter) into the payload, checking
/// bounds and CRC, but not the message itself.
pub fn parse_payload(encoded: &[u8]) -> Result<Vec<u8>, Reject> {
    let mut raw = cobs::decode(encoded).map_err(Reject::Cobs)?;
    if raw.len() < MIN_DECODED {
        return Err(Reject::Short { len: raw.len() });
    }
    if raw.len() > MAX_DECODED {
        return Err(Reject::Long { len: raw.len() });
    }
    let n = raw.len() - 2;
    let received = u16::from_le_bytes([raw[n], raw[n + 1]]);
    let computed = crc16(&raw[..n]);
    if received != computed {
        return Err(Reject::Crc { computed, received });
    }
    raw.truncate(n);
    Ok(raw)
}

/// Decodes one frame (COBS bytes without the delimiter) into a packet.
pub fn parse(encoded: &[u8]) -> Result<Packet, Reject> {
    Packet::from_payload(&parse_payload(encoded)?)
}

/// A receive buffer that yields frames, or the reason one was dropped, in stream order.
#[derive(Debug, Default)]
pub struct Decoder {
    buf: Vec<u8>,
    /// Overflowed: drop everything up to and including the next `0x00`.
    discarding: bool,
}

impl Decoder {
    pub fn new() -> Decoder {
        Decoder::default()
    }

    /// Appends received bytes.
    pub fn push(&mut self, bytes: &[u8]) {
        self.buf.extend_from_slice(bytes);
    }

    /// Bytes buffered but not yet part of a complete frame.
    pub fn pending(&self) -> usize {
        self.buf.len()
    }

    /// Forgets buffered bytes (after a reconnect: what was buffered came from a dead port).
    pub fn clear(&mut self) {
        self.buf.clear();
        self.discarding = false;
    }

    /// The next frame, `Some(Err(..))` for a dropped one, `None` when more bytes are needed.
    /// Empty frames (two zeros in a row) are skipped silently.
    pub fn next_frame(&mut self) -> Option<Result<Packet, Reject>> {
        loop {
            let Some(n) = check(&self.buf) else {
                if self.buf.len() > MAX_BUFFERED {
                    self.buf.clear();
                    if !self.discarding {
                        self.discarding = true;
                        return Some(Err(Reject::Overflow));
                    }
                }
                return None;
            };
            let frame: Vec<u8> = self.buf.drain(..n).collect();
            let body = &frame[..n - 1];
            if self.discarding {
                self.discarding = false;
                continue;
            }
            if body.is_empty() {
                continue;
            }
            if body.len() > MAX_BUFFERED {
                return Some(Err(Reject::Overflow));
            }
            return Some(parse(body));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::protocol::messages::{Reply, Request};

    /// Frames worked out by hand (CRC with the bitwise algorithm on paper/python, COBS by
    /// hand), independent of this codec.
    #[test]
    fn frames_by_hand() {
        // HELLO id=1: payload 01 01 00, CRC 0xC89D (LE 9D C8).
        // COBS of 01 01 00 9D C8: block "01 01" ends at the zero -> code 03; "9D C8" -> code 03.
        let p = Packet::request(1, Request::Hello);
        assert_eq!(p.to_payload().unwrap(), [0x01, 0x01, 0x00]);
        let wire = encode(&p).unwrap();
        assert_eq!(wire, [0x03, 0x01, 0x01, 0x03, 0x9D, 0xC8, 0x00]);
        assert_eq!(parse(&wire[..wire.len() - 1]), Ok(p));

        // MOVE_ABS id=7 angle=90000 (0x00015F90): payload 11 07 00 90 5F 01 00, CRC 0x31C4.
        let p = Packet::request(7, Request::MoveAbs { angle: 90_000 });
        let wire = encode(&p).unwrap();
        assert_eq!(
            wire,
            [
                0x03, 0x11, 0x07, 0x04, 0x90, 0x5F, 0x01, 0x03, 0xC4, 0x31, 0x00
            ]
        );
        assert_eq!(parse(&wire[..wire.len() - 1]), Ok(p));
    }

    #[test]
    fn decoder_resyncs_after_garbage_and_skips_empty_frames() {
        let a = encode(&Packet::request(5, Request::Status)).unwrap();
        let b = encode(&Packet::reply(5, Reply::Ack)).unwrap();
        let mut d = Decoder::new();
        d.push(&[0x42, 0x17, 0x00, 0x00]);
        d.push(&a);
        d.push(&[0x00]);
        d.push(&b[..3]);
        assert!(matches!(d.next_frame(), Some(Err(_))));
        assert_eq!(
            d.next_frame(),
            Some(Ok(Packet::request(5, Request::Status)))
        );
        assert_eq!(d.next_frame(), None);
        d.push(&b[3..]);
        assert_eq!(d.next_frame(), Some(Ok(Packet::reply(5, Reply::Ack))));
        assert_eq!(d.next_frame(), None);
    }

    #[test]
    fn overflow_discards_until_next_delimiter() {
        let a = encode(&Packet::request(9, Request::Home)).unwrap();
        let mut d = Decoder::new();
        d.push(&[0x11; 70]);
        assert_eq!(d.next_frame(), Some(Err(Reject::Overflow)));
        // The tail of the long garbage and its delimiter are dropped, the next frame survives.
        d.push(&[0x11, 0x12, 0x00]);
        d.push(&a);
        assert_eq!(d.next_frame(), Some(Ok(Packet::request(9, Request::Home))));
    }

    #[test]
    fn flipped_bit_fails_the_crc() {
        let wire = encode(&Packet::request(7, Request::MoveAbs { angle: 90_000 })).unwrap();
        let mut bad = wire.clone();
        bad[3] ^= 0x04;
        assert!(parse(&bad[..bad.len() - 1]).is_err());
    }
}
