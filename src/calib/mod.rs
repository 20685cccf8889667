//! Calibration: the camera/laser model that turns a line position into a 3D point, and the
//! TOML file that records it.
//!
//! This is the scanner's own implementation of SPEC section 2, written independently of the
//! simulator's renderer so that comparing the two is a real check.

mod file;
mod model;

pub use file::{Calibration, CalibrationError};
pub use model::{CameraModel, Triangulator};
