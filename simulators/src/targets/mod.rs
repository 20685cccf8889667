//! Calibration targets (docs/method.md section 13): the staircase gauge block as a height field
//! the frame renderer can image, and checkerboard images for the OpenCV reference calibration.
//! A flat plate at a known height is [`crate::render::Scene::Plate`]. What the targets are
//! (`StaircaseGeometry`, `Placement`, `Checkerboard`, `BoardPose`) is `footscan_targets`'s:
//! calibration reads the same descriptions, and the simulator only renders them.

pub mod checkerboard;
pub mod staircase;

pub use checkerboard::{BoardRenderer, BoardShot, Lighting, LinePoint};
pub use staircase::Staircase;
