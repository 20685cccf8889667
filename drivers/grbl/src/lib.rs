//! GRBL 1.1 slider driver for footscan.
//!
//! [`GrblSlider`] implements [`footscan_hal::Slider`] over a serial port (the `serialport`
//! crate): `/dev/ttyUSB0` for a real controller, or the pseudo-terminal of
//! `footscan_sim::grbl::GrblEmulator`, opened the same way.
//!
//! - `connect`: open, soft reset (0x18), wait for the `Grbl 1.x` banner, read `$I` (RX buffer
//!   size for character counting) and a first status report.
//! - `move_to`: `G90G21G1X..F..`, answered when the block is queued (GRBL's `ok`), not when it
//!   completes; `error:N` → [`HalError::Rejected`](footscan_hal::HalError::Rejected) with the
//!   code's meaning, `ALARM:N` → [`HalError::Alarm`](footscan_hal::HalError::Alarm).
//! - `status`: `?` → `<State|MPos:...|FS:...>`, timestamped at the midpoint of query and answer
//!   on the monotonic clock.
//! - a silent controller gives `Timeout` (every wait has a deadline), a hung-up port
//!   `Disconnected`, lines GRBL would never send `BadData`.

mod codes;
mod message;
mod settings;
mod slider;

pub use codes::{alarm_message, error_message};
pub use message::{banner_version, parse_line, parse_status, Message, StatusReport};
pub use settings::{BuildInfo, GrblSettings};
pub use slider::{GrblConfig, GrblSlider, GrblStats};
