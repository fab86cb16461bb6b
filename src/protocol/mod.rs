//! The wire protocol between host and rig firmware (`firmware-protocol/PROTOCOL.md`, version 1.0):
//! COBS framing with CRC-16/CCITT-FALSE, requests and replies, their canonical text form.
//!
//! Pure and I/O-free: this module is fed bytes and gives bytes back. It must not depend on
//! ports, threads, clocks or the rest of the crate; the serial link (`devices::serial`) and the
//! simulated firmware (`sim::firmware`) own those. One file per concern: `cobs`, `crc`, `frame`
//! (framing and the resynchronising decoder), `messages` (kinds, bodies, text form), `error`.

pub mod cobs;
pub mod crc;
pub mod error;
pub mod frame;
pub mod messages;
pub mod vectors;

#[cfg(test)]
mod proptests;

pub use error::{CobsError, EncodeError, Reject};
pub use frame::Decoder;
pub use messages::{
    Body, ChannelState, HelloInfo, NakCode, Packet, Reply, Request, StatusInfo, caps, faults, kind,
};
