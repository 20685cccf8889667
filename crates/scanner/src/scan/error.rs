//! Why a scan failed, and which device fault it was when a device failed: typed, so callers
//! (the daemon's device status) never read it out of the message text.

use crate::pipeline::{BoxError, PipelineError};
pub use footscan_hal::{DeviceFault, FaultKind};
use std::path::PathBuf;

/// Which of the scanner's devices.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DeviceRole {
    Camera,
    Slider,
}

impl std::fmt::Display for DeviceRole {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            DeviceRole::Camera => "camera",
            DeviceRole::Slider => "slider",
        })
    }
}

/// A device fault of a scan: which device (role and driver name) and what kind.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ScanFault {
    pub role: DeviceRole,
    pub fault: DeviceFault,
}

/// An error of one of the scan's devices, labelled with its role and fault where the error is
/// one. Displays as the role; the device's own message is its source.
#[derive(Debug, thiserror::Error)]
#[error("{role}")]
pub struct DeviceError {
    pub role: DeviceRole,
    pub fault: Option<DeviceFault>,
    #[source]
    pub source: BoxError,
}

impl DeviceError {
    /// A HAL error of the device in `role`, with the fault it means.
    pub fn hal(role: DeviceRole, e: footscan_hal::HalError) -> Self {
        DeviceError {
            role,
            fault: e.fault(),
            source: Box::new(e),
        }
    }

    /// The fault as the scan reports it.
    pub fn scan_fault(&self) -> Option<ScanFault> {
        self.fault.clone().map(|fault| ScanFault {
            role: self.role,
            fault,
        })
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ScanError {
    #[error("{0}")]
    Config(String),
    #[error("cannot use scan directory {path}")]
    OutDir {
        path: PathBuf,
        source: std::io::Error,
    },
    /// The message is the setup error's own (it has no cause of its own to chain).
    #[error("scanner setup failed: {0}")]
    Setup(SetupError),
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    #[error("writing {path}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// Why the scanner could not be set up: the message, and the device fault when opening a
/// device failed with one.
#[derive(Debug, thiserror::Error)]
#[error("{message}")]
pub struct SetupError {
    pub message: String,
    pub fault: Option<ScanFault>,
}

impl From<String> for SetupError {
    fn from(message: String) -> Self {
        SetupError {
            message,
            fault: None,
        }
    }
}

impl ScanError {
    /// The device fault that ended the scan, if a device failed.
    pub fn fault(&self) -> Option<ScanFault> {
        match self {
            ScanError::Setup(s) => s.fault.clone(),
            ScanError::Pipeline(PipelineError::Stage { source, .. }) => source
                .downcast_ref::<DeviceError>()
                .and_then(DeviceError::scan_fault),
            _ => None,
        }
    }
}
