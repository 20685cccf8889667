//! footscan-geom: the geometry every last stage stands on.
//!
//! One job: exact, fast geometry on f64 millimetres. It depends on nothing else in footscan
//! (only nalgebra and thiserror), so the scanner, the simulator and the last stages can all use
//! it, and it sits at the bottom of the layer map in ARCHITECTURE.md.
//!
//! - [`plane`], [`polyline`], [`polygon`], [`bbox`]: planes, open and closed polylines, planar
//!   polygons (area, containment, offsets), axis-aligned boxes.
//! - [`mesh`]: indexed triangle meshes: STL (binary and ASCII), PLY and OBJ in and out,
//!   validation (closed, 2-manifold, oriented, no degenerate faces), units, plane sections
//!   into closed ordered polylines, signed point-to-mesh distance on a bounding-volume tree.
//! - [`nurbs`]: B-spline and NURBS curves and tensor-product surfaces of any degree: evaluation
//!   with derivatives, curvature, knot insertion and refinement, degree elevation,
//!   interpolation, least-squares approximation, skinning.
//! - [`export`]: curves and surfaces to IGES 5.3 and STEP AP214.

pub mod bbox;
pub mod export;
pub mod mesh;
pub mod nurbs;
pub mod plane;
pub mod polygon;
pub mod polyline;

/// A point in millimetres.
pub type P3 = nalgebra::Point3<f64>;
/// A vector in millimetres.
pub type V3 = nalgebra::Vector3<f64>;
/// A point in a plane, millimetres.
pub type P2 = nalgebra::Point2<f64>;
/// A vector in a plane, millimetres.
pub type V2 = nalgebra::Vector2<f64>;
