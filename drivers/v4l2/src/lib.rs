//! V4L2 camera driver for footscan, on the `v4l` crate.
//!
//! - [`discover`]: the capture nodes, their capabilities, formats, sizes and rates.
//! - [`format`]: the accepted pixel formats (GREY, Y10, Y12, Y16, YUYV, MJPG) and their
//!   conversion to Gray8 / Gray16 frames.
//! - [`stream`]: mmap buffers queued and dequeued with poll(2) and a timeout; sequence numbers
//!   widened to 64 bits with gaps counted as dropped frames; buffer timestamps on
//!   CLOCK_MONOTONIC.
//! - [`controls`]: manual exposure and gain, raw integer/menu controls.
//! - [`dv`]: inputs, outputs and DV timings for HDMI-style sources.
//! - [`V4l2Camera`]: the HAL's [`footscan_hal::Camera`] over all of it.
//!
//! Errors: a device that disappears (ENODEV, or EIO from DQBUF) is
//! [`footscan_hal::HalError::Disconnected`]; a stream that delivers nothing within the timeout
//! is [`footscan_hal::HalError::Timeout`]; `next_frame` never blocks past its timeout.

mod camera;
pub mod controls;
pub mod discover;
pub mod dv;
pub mod format;
pub mod stream;
pub mod sys;

pub use camera::{io_error, StreamStats, V4l2Camera, V4l2Config};
pub use format::{ConvertError, Converter, SourceFormat};
pub use stream::{Direction, MmapQueue, SeqTracker, TimestampSource};
/// The `v4l` crate this driver is built on, for callers that need more of it.
pub use v4l;
