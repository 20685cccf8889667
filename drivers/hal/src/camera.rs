use crate::{Frame, HalResult, PixelFormat};
use std::time::Duration;

#[derive(Clone, Debug, PartialEq)]
pub struct CameraInfo {
    /// Device path or backend name, used in error messages.
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub format: PixelFormat,
    /// Nominal frame rate.
    pub fps: f64,
}

/// A streaming grayscale camera.
///
/// `next_frame` blocks until a frame arrives or `timeout` passes (then [`crate::HalError::Timeout`]);
/// it never hangs. Sequence numbers come from the device: a gap means dropped frames.
pub trait Camera: Send {
    fn info(&self) -> CameraInfo;
    fn start(&mut self) -> HalResult<()>;
    fn stop(&mut self) -> HalResult<()>;
    fn next_frame(&mut self, timeout: Duration) -> HalResult<Frame>;
    /// Exposure time in microseconds (manual exposure; auto exposure is off).
    fn exposure_us(&self) -> u32;
    fn set_exposure_us(&mut self, us: u32) -> HalResult<()>;
    /// Analogue gain, device units.
    fn gain(&self) -> f64;
    fn set_gain(&mut self, gain: f64) -> HalResult<()>;
}
