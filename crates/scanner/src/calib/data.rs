//! What the in-system calibration fits: the line on the plate at known heights and the frames
//! of the staircase pass. Acquisition produces these; the fits and the Bezier depth network
//! read them.

use footscan_targets::StaircaseGeometry;

/// The line on the plate at one height, averaged over repeated frames.
#[derive(Clone, Debug, PartialEq)]
pub struct PlateObservation {
    pub height_mm: f64,
    pub frames: usize,
    /// Mean column per image row; NaN where fewer than 3/4 of the frames found the line.
    pub col: Vec<f64>,
    /// Standard deviation of the column over the frames, per row (px).
    pub std: Vec<f64>,
}

/// One frame of the staircase pass.
#[derive(Clone, Debug, PartialEq)]
pub struct StairFrame {
    /// Slider position as the controller reports it.
    pub x_mm: f64,
    /// Column per row, NaN where no line.
    pub col: Vec<f64>,
}

/// Everything the in-system calibration fits.
#[derive(Clone, Debug, PartialEq)]
pub struct InsystemData {
    pub width: u32,
    pub height: u32,
    pub plates: Vec<PlateObservation>,
    pub stair: Vec<StairFrame>,
    pub staircase: StaircaseGeometry,
}
