//! The network of a scan: grid to network, timed. The foot model written from it (the closed
//! solid in the foot frame, STL and STEP) is `crate::cad`, shared by the `model.bezier` stage
//! and `footscan model`.

use super::{BezierNetwork, PointGrid, SurfaceError};
use crate::scandata::ScanGrid;
use std::time::Instant;

/// Build the network of a scan grid (u = frame, v = row), timing the build.
pub fn build_scan_model(grid: &ScanGrid) -> Result<(BezierNetwork, f64), SurfaceError> {
    let g = PointGrid::from_scan(grid);
    if g.valid_count() == 0 {
        return Err(SurfaceError::Empty);
    }
    let t = Instant::now();
    let net = BezierNetwork::build(&g)?;
    Ok((net, t.elapsed().as_secs_f64() * 1e3))
}
