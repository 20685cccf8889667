//! Calibration targets (docs/method.md section 13): the staircase gauge block as a height field
//! the frame renderer can image, and checkerboard images for the OpenCV reference calibration.
//! A flat plate at a known height is [`crate::render::Scene::Plate`].

pub mod checkerboard;
pub mod staircase;

pub use checkerboard::{BoardPose, BoardRenderer, BoardShot, Checkerboard, Lighting, LinePoint};
pub use staircase::{Placement, Staircase, StaircaseGeometry};
