//! Calibration: the camera/laser model that turns a line position into a 3D point, the TOML
//! file that records it, and the ways to obtain it (docs/method.md sections 5 and 6):
//!
//! - [`insystem`]: the scanner calibrates itself from the line on a plate at known heights and
//!   a staircase gauge block (closed forms of eq. 20-21, then a Levenberg-Marquardt fit of the
//!   general model, with uncertainties);
//! - [`bezier_depth`]: the Bezier depth network of eq. 13-16 as a second height mapping;
//! - `opencv` (cargo feature `opencv`): the checkerboard reference a user would otherwise use.
//!
//! The model is the scanner's own implementation of docs/method.md section 2.3, written
//! independently of the simulator's renderer so that comparing the two is a real check. Data
//! come through a [`acquire::CalibrationRig`]: the scanner's own camera and slider with an
//! operator placing the targets (the same code for hardware and simulator), or frames rendered
//! directly.

pub mod acquire;
pub mod bezier_depth;
pub mod closed_form;
mod data;
mod error;
mod file;
mod gauge;
pub mod guided;
pub mod insystem;
pub mod lm;
mod model;
#[cfg(feature = "opencv")]
pub mod opencv;
pub mod plan;
pub mod run;
pub mod stair;
pub mod uncertainty;
pub mod verify;

pub use error::CalibError;
pub use file::{Calibration, CalibrationError, ParseError};
pub use gauge::{untilted_equivalent, UntiltedError};
pub use model::{CameraModel, ModelError, Triangulator};
pub use plan::CalibrationPlan;
pub use run::{Calibrated, Method};
