//! Errors of device drivers. `is_retryable` tells a session runner whether trying again can help.

use thiserror::Error;

#[derive(Debug, Error)]
pub enum DeviceError {
    #[error("no reply from {device} after {attempts} attempts ({what})")]
    Timeout {
        device: String,
        attempts: u32,
        what: String,
    },
    #[error("{device} is not connected: {reason}")]
    Disconnected { device: String, reason: String },
    #[error("{device} refused {what}: {reason}")]
    Refused {
        device: String,
        what: String,
        reason: String,
    },
    #[error("{device}: {what} is outside the limits: {reason}")]
    Limit {
        device: String,
        what: String,
        reason: String,
    },
    #[error("{device} reports a fault: {reason}")]
    Fault { device: String, reason: String },
    #[error("{device}: protocol error: {reason}")]
    Protocol { device: String, reason: String },
    #[error("{device}: {reason}")]
    Other { device: String, reason: String },
}

impl DeviceError {
    /// True when the same request may succeed if tried again (a lost reply, a port that
    /// vanished and may come back); false when the device said no.
    pub fn is_retryable(&self) -> bool {
        matches!(
            self,
            DeviceError::Timeout { .. } | DeviceError::Disconnected { .. }
        )
    }
}
