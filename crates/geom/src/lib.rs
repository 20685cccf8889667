//! footscan-geom: the geometry every last stage stands on.
//!
//! One job: exact, fast geometry on f64 millimetres. It depends on nothing else in footscan
//! (only nalgebra, thiserror, serde and serde_json), so the scanner, the simulator and the last stages can all use
//! it, and it sits at the bottom of the layer map in ARCHITECTURE.md.
//!
//! - [`bernstein`]: Bernstein polynomials in the shapes the detector, the calibration's depth
//!   network and the plantar model evaluate them (one implementation, held together by tests).
//! - [`plane`], [`polyline`], [`polygon`], [`bbox`]: planes, open and closed polylines, planar
//!   polygons (area, containment, offsets), axis-aligned boxes.
//! - [`mesh`]: indexed triangle meshes: STL (binary and ASCII), PLY and OBJ in and out, glTF
//!   binary (.glb) out,
//!   validation (closed, 2-manifold, oriented, no degenerate faces), units, plane sections
//!   into closed ordered polylines, signed point-to-mesh distance on a bounding-volume tree.
//! - [`nurbs`]: B-spline and NURBS curves and tensor-product surfaces of any degree: evaluation
//!   with derivatives, curvature, knot insertion and refinement, degree elevation,
//!   interpolation, least-squares approximation, skinning.
//! - [`rotation`]: the world's Euler-angle convention (camera tilt, calibration board poses).
//! - [`export`]: curves and surfaces to IGES 5.3 and STEP AP214.
//! - [`Side`], [`HeightMap`]: which foot, and heights on a regular (x, y) grid: the vocabulary the
//!   scanner, the simulator and the last stages share.
//!
//! Why written here rather than taken from a crate: curvo (NURBS) is on nalgebra 0.34 while the
//! workspace (and levenberg-marquardt) is on 0.33, and it has no least-squares fit with fixed
//! ends, no skinning at given parameters and no IGES/STEP; no maintained crate writes IGES;
//! truck-stepio writes STEP from truck's own topology types, a large tree to carry two entity
//! kinds (a B-spline curve and surface) that a few hundred lines write and OpenCASCADE reads
//! back in the tests; parry3d-f64 (on nalgebra 0.33) has a BVH and plane sections, but the
//! sections here must close exactly when vertices lie on the plane (and drop the zero-area
//! loops a tangent plane makes) and the signed distance needs angle-weighted pseudo-normals, so
//! the tree is ours too, at the meshes' size (2,000-17,000 triangles) a small one.

pub mod bbox;
pub mod bernstein;
pub mod export;
pub mod height_map;
pub mod mesh;
pub mod nurbs;
pub mod plane;
pub mod polygon;
pub mod polyline;
pub mod rotation;
pub mod side;

pub use height_map::HeightMap;
pub use side::Side;

/// A point in millimetres.
pub type P3 = nalgebra::Point3<f64>;
/// A vector in millimetres.
pub type V3 = nalgebra::Vector3<f64>;
/// A point in a plane, millimetres. Points and vectors serialise as `[x, y]` (`[x, y, z]`),
/// as the arrays they replaced did.
pub type P2 = nalgebra::Point2<f64>;
/// A vector in a plane, millimetres.
pub type V2 = nalgebra::Vector2<f64>;

/// `v` over its length as `hypot` gives it: the unit directions of the scanner's measurements
/// (hypot rounds differently from nalgebra's `normalize`, a square root of the sum of squares,
/// and the measurements' numbers are kept as they were).
pub fn unit_by_hypot(v: &V2) -> V2 {
    v / v.x.hypot(v.y)
}

/// The distance from `a` to `b` as `hypot` gives it, `(a.x - b.x).hypot(a.y - b.y)`: the
/// outlines' arc lengths and distances (see [`unit_by_hypot`] for why not nalgebra's
/// `distance`).
pub fn dist_by_hypot(a: &P2, b: &P2) -> f64 {
    (a.x - b.x).hypot(a.y - b.y)
}

/// `v` turned a quarter turn counterclockwise, `(-y, x)`: the left normal of a direction in
/// the plane (not nalgebra's `perp`, which is the scalar cross product of two vectors).
pub fn quarter_turn(v: &V2) -> V2 {
    V2::new(-v.y, v.x)
}
