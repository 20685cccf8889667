//! Guide curves: one per crossing (bundle ray or sole point), running from the back part
//! through the gap into the toe part.
//!
//! A guide interpolates its crossing points on the network sections at the sections' common
//! v parameters and, inside the kept parts, also its crossing points on the mid sections
//! halfway between consecutive network sections. Those extra points lie on the original
//! lasts between the sections, so the guides carry shape the sections alone do not, and the
//! Gordon surface uses it. Across the gap the guide is the cubic spline through the points on
//! both sides: its tangent and curvature at the main sections come from the auxiliary
//! sections behind them, as last makers carry the lines of both lasts into the join.

use footscan_geom::nurbs::fit::interpolate_with;
use footscan_geom::nurbs::{NurbsCurve, NurbsError};
use footscan_geom::P3;

/// Data of one guide: points and their parameters (shared by every guide).
pub struct GuideData {
    pub params: Vec<f64>,
    /// `points[i]` for guide i, one per parameter.
    pub points: Vec<Vec<P3>>,
}

/// Interpolate every guide (cubic, at the shared parameters, so all guides have one knot
/// vector).
pub fn guide_curves(d: &GuideData) -> Result<Vec<NurbsCurve>, NurbsError> {
    d.points
        .iter()
        .map(|pts| interpolate_with(pts, &d.params, 3, None))
        .collect()
}

/// Chord-length parameters of a stack of aligned sections: the mean distance between
/// corresponding points of consecutive sections, normalised to [0, 1].
pub fn section_params(points: &[Vec<P3>]) -> Vec<f64> {
    let mut v = vec![0.0; points.len()];
    for k in 1..points.len() {
        let (a, b) = (&points[k - 1], &points[k]);
        let d: f64 = a.iter().zip(b).map(|(x, y)| (y - x).norm()).sum::<f64>() / a.len() as f64;
        v[k] = v[k - 1] + d;
    }
    let t = *v.last().unwrap();
    v.iter().map(|x| x / t).collect()
}
