use std::time::Duration;

/// Errors of camera and slider backends.
///
/// The variants are the distinctions a caller acts on: retry after a timeout, reconnect after a
/// disconnect, clear an alarm, or report a device that speaks nonsense.
#[derive(Debug, thiserror::Error)]
pub enum HalError {
    #[error("{device}: timed out after {after:?} waiting for {what}")]
    Timeout {
        device: String,
        what: String,
        after: Duration,
    },
    #[error("{device}: disconnected: {reason}")]
    Disconnected { device: String, reason: String },
    #[error("{device}: alarm {code}: {message}")]
    Alarm {
        device: String,
        code: u32,
        message: String,
    },
    #[error("{device}: bad data: {detail}")]
    BadData { device: String, detail: String },
    #[error("{device}: command rejected: error {code}: {message}")]
    Rejected {
        device: String,
        code: u32,
        message: String,
    },
    #[error("{device}: {detail}")]
    InvalidArgument { device: String, detail: String },
    #[error("{device}: not streaming (call start first)")]
    NotStreaming { device: String },
    #[error("{device}: {source}")]
    Io {
        device: String,
        #[source]
        source: std::io::Error,
    },
}

pub type HalResult<T> = Result<T, HalError>;

impl HalError {
    pub fn is_timeout(&self) -> bool {
        matches!(self, HalError::Timeout { .. })
    }
    pub fn is_disconnect(&self) -> bool {
        matches!(self, HalError::Disconnected { .. })
    }
    pub fn is_alarm(&self) -> bool {
        matches!(self, HalError::Alarm { .. })
    }
}
