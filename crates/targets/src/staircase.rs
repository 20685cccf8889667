//! The staircase gauge block as its drawing gives it, and where it stands.
//!
//! The step j face is at height `heights_mm[j]` over the rectangle `u in [U_j, U_j+1)`,
//! `w in [0, W]` of block coordinates, where `U_0 = 0`, `U_j+1 = U_j + lengths_mm[j]`; a
//! [`Placement`] puts the block's first corner (u = 0, w = 0) at world (x, y) with a yaw. How
//! the block looks to the camera is the simulator's (`footscan_sim::targets::Staircase`).

use crate::{check_range, TargetError};
use serde::{Deserialize, Serialize};

/// What the gauge block's drawing says: everything calibration may know about it.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StaircaseGeometry {
    /// Height of each step face above the glass, in order along the block (mm).
    pub heights_mm: Vec<f64>,
    /// Length of each step along the block (mm), same count as `heights_mm`.
    pub lengths_mm: Vec<f64>,
    /// Width of the block across its axis (mm).
    pub width_mm: f64,
}

impl StaircaseGeometry {
    /// Start of step `j` along the block (`u`), `U_0 = 0`; `j = len` gives the block's end.
    pub fn step_start(&self, j: usize) -> f64 {
        self.lengths_mm[..j].iter().sum()
    }

    /// Total length along the block.
    pub fn length(&self) -> f64 {
        self.lengths_mm.iter().sum()
    }

    pub fn validate(&self) -> Result<(), TargetError> {
        if self.heights_mm.is_empty() || self.heights_mm.len() != self.lengths_mm.len() {
            return Err(TargetError::invalid(
                "staircase.heights_mm",
                format!("{} steps", self.heights_mm.len()),
                &format!(
                    "at least one step and as many heights as lengths ({})",
                    self.lengths_mm.len()
                ),
            ));
        }
        for (j, (&h, &l)) in self.heights_mm.iter().zip(&self.lengths_mm).enumerate() {
            check_range(&format!("staircase.heights_mm[{j}]"), h, 0.0, 200.0)?;
            check_range(&format!("staircase.lengths_mm[{j}]"), l, 0.5, 1000.0)?;
        }
        check_range("staircase.width_mm", self.width_mm, 1.0, 1000.0)
    }
}

/// Where the block stands: its first corner (u = 0, w = 0) in world x, y and its yaw
/// (counterclockwise seen from above, degrees). The calibration does not know it: the
/// simulator stands the block there, and the in-system fit estimates it.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Placement {
    pub x_mm: f64,
    pub y_mm: f64,
    pub yaw_deg: f64,
}
