//! The one place a scan opens its backend, whichever it is: the simulator ([`sim`]) or the
//! hardware ([`hardware`]), one file each. Both hand the pipeline a [`Devices`] behind the
//! HAL's `Camera` and `Slider` traits.

pub mod hardware;
pub mod sim;

use crate::calib::Calibration;
use crate::scan::config::{Backend, LoadedConfig};
use crate::scan::error::{DeviceRole, ScanError, ScanFault, SetupError};
use crate::scan::summary::TruthSource;
use footscan_hal::{Camera, Slider};
use footscan_sim::foot::Foot;
use std::path::Path;
use std::sync::Arc;

/// The camera and slider a scan drives, whatever backend they come from.
pub struct Devices {
    pub camera: Box<dyn Camera>,
    pub slider: Box<dyn Slider>,
}

/// What a scan keeps open next to its devices: the simulator's emulator and ground truth, or
/// nothing for hardware.
pub struct OpenBackend {
    /// The simulated foot (its truth.json is written next to the scan).
    pub foot: Option<Foot>,
    sim: Option<sim::SimBackend>,
}

impl OpenBackend {
    /// Ground truth per frame, for simulated scans only.
    pub fn truth_source(&self) -> Option<Arc<dyn TruthSource>> {
        self.sim.as_ref().map(sim::truth_source)
    }
}

/// A hardware device that could not be opened: with its fault when the driver's error is one.
fn setup_hardware(e: hardware::HardwareError) -> ScanError {
    let fault = match &e {
        hardware::HardwareError::Camera { source, .. } => source.fault().map(|fault| ScanFault {
            role: DeviceRole::Camera,
            fault,
        }),
        hardware::HardwareError::Slider { source, .. } => source.fault().map(|fault| ScanFault {
            role: DeviceRole::Slider,
            fault,
        }),
        hardware::HardwareError::SliderCheck(..) => None,
    };
    ScanError::Setup(SetupError {
        message: footscan_util::chain(&e),
        fault,
    })
}

/// Resolve the calibration (`--calibration`, then `scanner.calibration`, then the
/// simulator's true model; required for hardware) and open the configured backend.
pub fn open_backend(
    cfg: &LoadedConfig,
    calibration: Option<&Path>,
) -> Result<(Devices, OpenBackend, Calibration), ScanError> {
    let setup = |e: String| ScanError::Setup(e.into());
    let path = calibration
        .map(Path::to_path_buf)
        .or_else(|| cfg.calibration_path());
    let from = if calibration.is_some() {
        "--calibration".to_string()
    } else {
        format!("scanner.calibration in {}", cfg.path.display())
    };
    let loaded = match &path {
        Some(p) => Some(
            Calibration::load(p)
                .map_err(|e| setup(format!("{} (from {from})", footscan_util::Chain(&e))))?,
        ),
        None => None,
    };
    match cfg.config.scanner.backend {
        Backend::Sim => {
            let (devices, backend) =
                sim::open(&cfg.config).map_err(|e| setup(footscan_util::chain(&e)))?;
            let calibration = loaded.unwrap_or_else(|| sim::true_calibration(&cfg.config));
            let foot = backend.foot.clone();
            Ok((
                devices,
                OpenBackend {
                    foot,
                    sim: Some(backend),
                },
                calibration,
            ))
        }
        Backend::Hardware => {
            let Some(calibration) = loaded else {
                return Err(setup(format!(
                    "the hardware backend needs a calibration file: pass --calibration FILE or set scanner.calibration in {} (`footscan calibrate` writes one)",
                    cfg.path.display()
                )));
            };
            let hw = cfg
                .config
                .hardware
                .as_ref()
                .expect("validated: backend = \"hardware\" has a [hardware] section");
            let m = &calibration.model;
            if (m.width, m.height) != (hw.camera.width, hw.camera.height) {
                return Err(setup(format!(
                    "calibration {} is for a {}x{} camera, hardware.camera is {}x{}",
                    path.as_deref().unwrap_or(Path::new("?")).display(),
                    m.width,
                    m.height,
                    hw.camera.width,
                    hw.camera.height
                )));
            }
            let devices = hardware::open(&cfg.config).map_err(setup_hardware)?;
            Ok((
                devices,
                OpenBackend {
                    foot: None,
                    sim: None,
                },
                calibration,
            ))
        }
    }
}
