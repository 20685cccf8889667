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
    #[error("{device}")]
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

/// What a device fault means for the device's state, whatever the driver's words for it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FaultKind {
    /// The device is gone (unplugged, port closed, no such device).
    Disconnected,
    /// The controller is in an alarm state with this code.
    Alarm(u32),
    /// The device stopped answering in time.
    Timeout,
    /// The device answered with something that cannot be understood.
    BadData,
}

/// A device fault: the device as its driver names it (a port or a device node) and what kind.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceFault {
    pub device: String,
    pub kind: FaultKind,
}

impl HalError {
    /// The device the error is about, as its driver names it.
    pub fn device(&self) -> &str {
        match self {
            HalError::Timeout { device, .. }
            | HalError::Disconnected { device, .. }
            | HalError::Alarm { device, .. }
            | HalError::BadData { device, .. }
            | HalError::Rejected { device, .. }
            | HalError::InvalidArgument { device, .. }
            | HalError::NotStreaming { device }
            | HalError::Io { device, .. } => device,
        }
    }

    /// The device fault this error means, if it is one (a rejected command or an invalid
    /// argument is the caller's mistake, not the device's state). An I/O error counts as a
    /// disconnect when the OS says the device is gone (ENODEV, ENXIO).
    pub fn fault(&self) -> Option<DeviceFault> {
        const ENXIO: i32 = 6;
        const ENODEV: i32 = 19;
        let kind = match self {
            HalError::Timeout { .. } => FaultKind::Timeout,
            HalError::Disconnected { .. } => FaultKind::Disconnected,
            HalError::Alarm { code, .. } => FaultKind::Alarm(*code),
            HalError::BadData { .. } => FaultKind::BadData,
            HalError::Io { source, .. }
                if matches!(source.raw_os_error(), Some(ENXIO | ENODEV))
                    || source.kind() == std::io::ErrorKind::BrokenPipe =>
            {
                FaultKind::Disconnected
            }
            _ => return None,
        };
        Some(DeviceFault {
            device: self.device().to_string(),
            kind,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faults_by_variant() {
        let dev = |kind| {
            Some(DeviceFault {
                device: "/dev/ttyUSB0".into(),
                kind,
            })
        };
        let alarm = HalError::Alarm {
            device: "/dev/ttyUSB0".into(),
            code: 2,
            message: "soft limit".into(),
        };
        assert_eq!(alarm.fault(), dev(FaultKind::Alarm(2)));
        let gone = HalError::Disconnected {
            device: "/dev/ttyUSB0".into(),
            reason: "read returned 0".into(),
        };
        assert_eq!(gone.fault(), dev(FaultKind::Disconnected));
        let nodev = HalError::Io {
            device: "/dev/ttyUSB0".into(),
            source: std::io::Error::from_raw_os_error(19),
        };
        assert_eq!(nodev.fault(), dev(FaultKind::Disconnected));
        let rejected = HalError::Rejected {
            device: "/dev/ttyUSB0".into(),
            code: 20,
            message: "unsupported command".into(),
        };
        assert_eq!(rejected.fault(), None);
        assert_eq!(rejected.device(), "/dev/ttyUSB0");
    }
}
