//! Errors of the codec. A rejected frame is not a failure of the program: the receiver drops
//! it (PROTOCOL.md section 2) and the sender's retry recovers. The reasons match the
//! `REJECT <reason>` words of the test vectors.

use thiserror::Error;

/// A COBS block that cannot be decoded.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum CobsError {
    #[error("zero byte inside a COBS block at offset {offset}")]
    ZeroByte { offset: usize },
    #[error("COBS code {code} at offset {offset} needs more bytes than the {available} left")]
    Truncated {
        offset: usize,
        code: u8,
        available: usize,
    },
}

/// Why a received frame was dropped (or, for `Kind` and `Length`, answered with a NAK: those
/// passed the CRC, so their request id can be trusted).
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum Reject {
    #[error("frame is not valid COBS: {0}")]
    Cobs(CobsError),
    #[error("frame too short: {len} decoded bytes (at least 5)")]
    Short { len: usize },
    #[error("frame too long: {len} decoded bytes (at most 62)")]
    Long { len: usize },
    #[error("CRC mismatch: computed {computed:#06x}, frame says {received:#06x}")]
    Crc { computed: u16, received: u16 },
    #[error("unknown kind {kind:#04x} (request id {id})")]
    Kind { id: u16, kind: u8 },
    #[error("kind {kind:#04x} (request id {id}): body of {got} bytes, expected {expected}")]
    Length {
        id: u16,
        kind: u8,
        got: usize,
        expected: usize,
    },
    #[error("kind {kind:#04x} (request id {id}): bad field: {reason}")]
    Field {
        id: u16,
        kind: u8,
        reason: &'static str,
    },
    #[error("more than 64 bytes without a frame delimiter; discarded until the next 0x00")]
    Overflow,
}

impl Reject {
    /// The reason word of PROTOCOL.md section 9 (`cobs`, `crc`, `short`, `long`, `kind`,
    /// `length`), plus `field`, which the vectors do not use. A frame dropped by the 64-byte
    /// buffer rule is `long` too: it was longer than any frame can be.
    pub fn reason(&self) -> &'static str {
        match self {
            Reject::Cobs(_) => "cobs",
            Reject::Short { .. } => "short",
            Reject::Long { .. } | Reject::Overflow => "long",
            Reject::Crc { .. } => "crc",
            Reject::Kind { .. } => "kind",
            Reject::Length { .. } => "length",
            Reject::Field { .. } => "field",
        }
    }
}

/// A message that cannot be put on the wire.
#[derive(Clone, Debug, Error, PartialEq, Eq)]
pub enum EncodeError {
    #[error("payload of {len} bytes exceeds the 60-byte maximum")]
    TooLong { len: usize },
    #[error("firmware name must be ASCII and at most 16 bytes: {name:?}")]
    BadName { name: String },
}
