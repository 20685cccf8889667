//! The plantar surface model (docs/method.md section 7): the Bezier network of the plantar
//! scanner paper and the comparators of its Table 1 (section 7.5).
//!
//! - [`BezierNetwork`]: segments of 4 x 4 grid points (stride 3) storing C_ij = W_ij P_ij for
//!   x, y and z; it interpolates every grid point, evaluates at any (s, t), over a regular
//!   (x, y) grid ([`BezierNetwork::eval_heightmap`]) and gives normals.
//! - Continuity, honestly: every basis function has zero derivative at t = 0 and t = 1, so the
//!   first derivative across a segment edge vanishes and the surface's tangent plane there is
//!   set by second derivatives, which differ from side to side:
//!   [`BezierNetwork::continuity`] measures the normal-angle jump.

// Index loops read as the matrix algebra they implement.
#![allow(clippy::needless_range_loop)]

mod basis;
pub mod bspline;
pub mod compare;
mod export;
mod mesh;
pub(crate) mod network;
pub mod ops;
mod point_grid;
pub mod poly;
pub mod solid;

pub use basis::{basis, basis_d1, basis_d2, interpolation_matrix};

/// A surface's point and first derivatives at (s, t): what Newton's inversion of (x, y)
/// needs ([`bspline::BSplineSurface::eval_d1`], [`poly::PolySurface::eval_d1`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Jet {
    pub p: footscan_geom::P3,
    pub du: footscan_geom::V3,
    pub dv: footscan_geom::V3,
}

impl From<[[f64; 3]; 3]> for Jet {
    /// Rows [p, p_s, p_t], as the evaluators accumulate them.
    fn from(r: [[f64; 3]; 3]) -> Self {
        Jet {
            p: r[0].into(),
            du: r[1].into(),
            dv: r[2].into(),
        }
    }
}
pub use export::build_scan_model;
pub use mesh::closed_from_heightmap;
pub use network::{BezierNetwork, Continuity, HeightFill, Segment};
pub use point_grid::{PointGrid, Subsample};

/// Errors building a surface model.
#[derive(Debug, thiserror::Error)]
pub enum SurfaceError {
    #[error("grid of {nu} x {nv} points: a surface model needs at least 2 x 2")]
    GridTooSmall { nu: usize, nv: usize },
    #[error("the grid has too few valid points to model")]
    Empty,
    #[error("a tensor-product fit needs a complete grid: fill the missing points first")]
    Incomplete,
    #[error("the least-squares system is singular (too few points for the basis)")]
    Singular,
    #[error("cell_mm = {0}: must be positive")]
    BadCell(f64),
    #[error("cell_mm = {cell_mm}: {nx} x {ny} grid nodes, more than {max}: use a larger cell")]
    TooManyCells {
        cell_mm: f64,
        nx: usize,
        ny: usize,
        max: usize,
    },
    #[error("the model's boundary is inconsistent: {0}")]
    Topology(String),
    #[error("writing {path}")]
    Write {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
}
