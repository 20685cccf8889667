//! Hardware abstraction for footscan.
//!
//! The pipeline knows hardware only through the [`Camera`] and [`Slider`] traits defined here;
//! real drivers (V4L2, GRBL) and the simulator are interchangeable backends behind them.
//! Every timestamp is on the monotonic clock ([`Timestamp`]), the clock V4L2 stamps buffers
//! with, so slider positions can be interpolated at a frame's capture time.

mod camera;
mod channel;
mod error;
mod frame;
mod slider;
mod time;

pub use camera::{Camera, CameraInfo};
pub use channel::{Channel, CHANNEL_NAMES};
pub use error::{DeviceFault, FaultKind, HalError, HalResult};
pub use frame::{Frame, FramePool, PixelFormat, Pixels};
pub use slider::{Slider, SliderInfo, SliderSettings, SliderState, SliderStatus};
pub use time::Timestamp;
