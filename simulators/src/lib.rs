//! footscan simulator: what the scanner would see, with exact ground truth.
//!
//! Independent of the algorithms it checks: nothing here depends on the `footscan` crate.
//! - [`foot`]: the parametric foot (docs/method.md section 13) with analytic measurement truth;
//! - [`last`]: parametric shoe lasts (round, pointed, square toe; heel height; size) with the
//!   analytic truth of their bottom;
//! - [`mesh_scene`]: any closed triangle mesh placed on the glass as a scene;
//! - [`optics`]: the general optical model of docs/method.md section 2.3;
//! - [`render`]: frames and their per-row ground truth;
//! - [`camera`]: a [`footscan_hal::Camera`] that renders at the slider's true position;
//! - [`grbl`]: a GRBL 1.1 emulator on a pseudo-terminal;
//! - [`targets`]: calibration targets (staircase gauge block, checkerboard images).

pub mod camera;
pub mod foot;
pub mod grbl;
pub mod last;
pub mod mesh_scene;
pub mod optics;
pub mod render;
pub mod surface;
pub mod targets;

use footscan_hal::Timestamp;

/// Where the optical head physically is at a given instant.
///
/// The GRBL emulator implements this from its motion model (including slider scale error and
/// backlash, which the controller's own position report does not show); the simulated camera
/// asks it at each frame's capture time.
pub trait PositionSource: Send + Sync {
    fn physical_x(&self, at: Timestamp) -> f64;
}

/// Whether the laser shines at a given instant: the GRBL emulator's spindle or coolant output
/// when the laser is wired to one; the simulated camera renders no line while it is off.
pub trait LaserSource: Send + Sync {
    fn laser_on(&self, at: Timestamp) -> bool;
}

/// A head that never moves (tests, calibration targets imaged at fixed positions).
#[derive(Clone, Copy, Debug)]
pub struct FixedPosition(pub f64);

impl PositionSource for FixedPosition {
    fn physical_x(&self, _at: Timestamp) -> f64 {
        self.0
    }
}
