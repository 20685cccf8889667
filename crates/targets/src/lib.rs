//! footscan-targets: what a calibration target is.
//!
//! One job: describe the calibration targets as their drawings give them (the staircase gauge
//! block's steps, the printed checkerboard's squares) and where one stands (a block's placement,
//! a board's pose), with the checks that say whether a description is possible. The
//! calibration (`footscan::calib`) reads these descriptions; the simulator (`footscan-sim`)
//! renders them. Neither owns them, so the algorithm never depends on the simulator for what a
//! target is, and the simulator's ground truth does not come from the algorithm it checks.
//!
//! May depend on: `footscan-geom` (the world's rotation convention), serde, thiserror; nothing
//! that renders, acquires or calibrates. The geometry is in docs/method.md section 13.

pub mod checkerboard;
pub mod staircase;

pub use checkerboard::{BoardPose, Checkerboard};
pub use staircase::{Placement, StaircaseGeometry};

/// A description that cannot be a real target.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TargetError {
    /// A parameter is outside its valid range (the same wording as the simulator's
    /// parameter errors, which carry these on unchanged).
    #[error("invalid parameter `{key}` = {value}: expected {expected}")]
    InvalidParameter {
        key: String,
        value: String,
        expected: String,
    },
}

impl TargetError {
    fn invalid(key: &str, value: impl std::fmt::Display, expected: &str) -> Self {
        TargetError::InvalidParameter {
            key: key.to_string(),
            value: value.to_string(),
            expected: expected.to_string(),
        }
    }
}

/// Check `lo <= v <= hi` (and finite), naming the key in the error.
fn check_range(key: &str, v: f64, lo: f64, hi: f64) -> Result<(), TargetError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(TargetError::invalid(
            key,
            v,
            &format!("a number in [{lo}, {hi}]"),
        ))
    }
}
