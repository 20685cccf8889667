use crate::{HalResult, Timestamp};
use std::collections::BTreeMap;
use std::time::Duration;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SliderState {
    Idle,
    Run,
    Hold,
    Jog,
    Alarm,
    Door,
    Check,
    Home,
    Sleep,
}

impl SliderState {
    /// Parse GRBL's state word (`Hold:0` and `Door:1` carry a sub-state after the colon).
    pub fn parse(word: &str) -> Option<Self> {
        let head = word.split(':').next().unwrap_or("");
        Some(match head {
            "Idle" => SliderState::Idle,
            "Run" => SliderState::Run,
            "Hold" => SliderState::Hold,
            "Jog" => SliderState::Jog,
            "Alarm" => SliderState::Alarm,
            "Door" => SliderState::Door,
            "Check" => SliderState::Check,
            "Home" => SliderState::Home,
            "Sleep" => SliderState::Sleep,
            _ => return None,
        })
    }

    pub fn is_moving(self) -> bool {
        matches!(
            self,
            SliderState::Run | SliderState::Jog | SliderState::Home
        )
    }
}

/// One position report.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SliderStatus {
    pub state: SliderState,
    /// Machine position of the scan axis in mm.
    pub x_mm: f64,
    /// Current feed in mm/min as reported.
    pub feed_mm_min: f64,
    /// When the position was valid, on the monotonic clock (the driver's best estimate,
    /// e.g. the midpoint between query and answer).
    pub timestamp: Timestamp,
    /// How far `timestamp` may be off, in seconds: half the time between query and answer
    /// (an answer read late by a busy host widens it). 0 when the time is exact.
    pub uncertainty_s: f64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct SliderInfo {
    pub port: String,
    /// Firmware banner, e.g. `Grbl 1.1h ['$' for help]`.
    pub banner: String,
    /// GRBL's laser mode (`$32`) as read at connect: in it the spindle output is lit at rest
    /// only in a feed motion mode, which the driver takes care of; None where not reported.
    pub laser_mode: Option<bool>,
}

/// `$N=value` settings as reported by the controller.
pub type SliderSettings = BTreeMap<u32, f64>;

/// A single-axis motorised slider carrying the optical head.
pub trait Slider: Send {
    /// Open the port, reset the controller and wait for its banner.
    fn connect(&mut self) -> HalResult<SliderInfo>;
    /// Run the homing cycle; returns when homed (or errors with an alarm or timeout).
    fn home(&mut self, timeout: Duration) -> HalResult<()>;
    /// Queue a linear move of the scan axis to `x_mm` at `feed_mm_min`; returns once accepted.
    fn move_to(&mut self, x_mm: f64, feed_mm_min: f64) -> HalResult<()>;
    /// Query a fresh status report.
    fn status(&mut self) -> HalResult<SliderStatus>;
    /// Poll until the controller is idle (or alarm/timeout).
    fn wait_idle(&mut self, timeout: Duration) -> HalResult<SliderStatus>;
    fn feed_hold(&mut self) -> HalResult<()>;
    fn resume(&mut self) -> HalResult<()>;
    /// Stop motion now and discard queued moves (jog cancel / feed hold + soft reset).
    fn stop(&mut self) -> HalResult<()>;
    fn settings(&mut self) -> HalResult<SliderSettings>;
    /// Switch the laser (wired to a controller output) on or off; returns once the controller
    /// has accepted the command. Sliders without a laser output refuse.
    fn laser(&mut self, on: bool) -> HalResult<()> {
        let _ = on;
        Err(crate::HalError::InvalidArgument {
            device: "slider".into(),
            detail: "no laser output is configured on this slider".into(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_state_words() {
        assert_eq!(SliderState::parse("Idle"), Some(SliderState::Idle));
        assert_eq!(SliderState::parse("Hold:1"), Some(SliderState::Hold));
        assert_eq!(SliderState::parse("Door:0"), Some(SliderState::Door));
        assert_eq!(SliderState::parse("Bogus"), None);
        assert!(SliderState::Jog.is_moving());
        assert!(!SliderState::Alarm.is_moving());
    }
}
