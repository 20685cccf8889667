//! B-spline and NURBS curves and tensor-product surfaces.
//!
//! Conventions shared by every module that uses these types (fitting, skinning, export):
//! - Knot vectors are stored in full (m + 1 = n + p + 2 knots for n + 1 control points of
//!   degree p), non-decreasing. Open (clamped) curves have p + 1 equal knots at each end.
//! - A periodic curve is stored in its unclamped form with the first p control points repeated
//!   at the end (and weights likewise) and `periodic = true`; its domain is
//!   [knots[p], knots[n + 1]]. Evaluation needs no special case; export may write the flag.
//! - `weights == None` is a non-rational B-spline (all weights 1). Control points are stored
//!   in Euclidean form (not pre-multiplied by the weight).
//! - Surfaces store control points row-major with u the slow index: `points[i * nv + j]` is
//!   P_ij, i = 0..nu along u, j = 0..nv along v (the order of footscan's scan grid too).

/// A B-spline or NURBS curve in 3D.
#[derive(Debug, Clone, PartialEq)]
pub struct NurbsCurve {
    pub degree: usize,
    pub knots: Vec<f64>,
    pub points: Vec<crate::P3>,
    pub weights: Option<Vec<f64>>,
    pub periodic: bool,
}

/// A tensor-product B-spline or NURBS surface in 3D.
#[derive(Debug, Clone, PartialEq)]
pub struct NurbsSurface {
    pub degree_u: usize,
    pub degree_v: usize,
    pub knots_u: Vec<f64>,
    pub knots_v: Vec<f64>,
    /// Number of control points along u and along v.
    pub nu: usize,
    pub nv: usize,
    /// `points[i * nv + j]`.
    pub points: Vec<crate::P3>,
    pub weights: Option<Vec<f64>>,
    pub periodic_u: bool,
    pub periodic_v: bool,
}
