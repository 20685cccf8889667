//! The scan's data, independent of how it was acquired: where and when each frame was taken,
//! the line found in each of its rows, the 3D points, and the grid (frame x row) they fill,
//! saved as `grid.bin`. The scan orchestrator produces it; the models and measurements read it.

mod dir;
mod scan_grid;
pub mod stored;

pub use dir::{ScanDir, ScanDirError};
pub use scan_grid::ScanGrid;

use crate::detect::LinePeak;
use footscan_geom::P3;
use footscan_hal::Timestamp;

/// Where and when a frame was taken.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FrameMeta {
    /// Position in the scan (0, 1, 2, ... over accepted frames).
    pub index: u64,
    /// Camera sequence number.
    pub seq: u64,
    pub timestamp: Timestamp,
    /// Slider position reported by the controller, interpolated at the capture time (mm).
    pub x_mm: f64,
}

pub struct FrameLines {
    pub meta: FrameMeta,
    pub lines: Vec<LinePeak>,
}

pub struct FramePoints {
    pub meta: FrameMeta,
    pub lines: Vec<LinePeak>,
    /// One per row; NaN where the row has no line.
    pub points: Vec<P3>,
}
