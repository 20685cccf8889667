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
//!   `Disconnected`; lines GRBL would never send are counted ([`GrblStats`]) and reported as
//!   `BadData` when they are all a wait received.
//! - `home`: a failed cycle is its `ALARM:N` (6 to 9); one still running at the timeout is
//!   aborted with a soft reset, so the machine does not keep seeking.
//! - `read_settings`: `$$` as [`GrblSettings`]; `build_info`: `$I` as [`BuildInfo`].
//! - `poll_status`: `?` at `GrblConfig::poll_interval` on absolute slots, each report stamped.
//! - lost answers: a timeout is followed by a `$G` sync (its `[GC:...]` marks every earlier
//!   unanswered line as lost), so a dropped `ok` never shifts the counting of later lines.
//! - a corrupted status report is asked again (3 times) before `BadData`.
//! - `jog_to` / `jog_cancel` (0x85), `feed_hold` (`!`) / `resume` (`~`, after the hold
//!   completes), `stop` (jog cancel, or hold then reset, so no position is lost).
//! - `reconnect(wait)`: reopen a port that comes back (a `/dev/serial/by-id/` path), bring a
//!   controller that kept moving to rest before the reset; never unlocks (`$X`) on its own.
//!
//! Layers, each depending only on the ones before it:
//! - `link`: the serial port, its receive buffer split into lines, arrival times on
//!   CLOCK_MONOTONIC; port failures become `Disconnected`.
//! - `tracker`: which sent line each `ok`/`error:N` answers (character counting), what an
//!   alarm, a reset or a `$G` resync means for the lines in flight, and what the controller
//!   reported about itself. A pure state machine without I/O, unit-tested on byte strings.
//! - `exchange`: a line sent and its answer awaited under a named wait policy (how long,
//!   patient while the machine moves or not, resync after a timeout or not); status queries;
//!   streaming.
//! - `slider`: [`GrblSlider`], the scanner's view: connect, home, move, jog, hold, stop, laser
//!   on/off ([`LaserOutput`]).
//!
//! `message`, `codes` and `settings` parse what GRBL sends and name its codes.

mod codes;
mod exchange;
mod link;
mod message;
mod settings;
mod slider;
mod tracker;
mod wait;

pub use codes::{alarm_message, error_message};
pub use message::{banner_version, parse_line, parse_status, Message, StatusReport};
pub use settings::{BuildInfo, GrblSettings};
pub use slider::{GrblConfig, GrblSlider, LaserOutput};
pub use tracker::GrblStats;
