//! The Table-1 comparison on one set of data: every method is a parametric surface over the
//! same grid parameters (s = frame, t = row), built from the same sub-grid of a scan, then
//!
//! - model accuracy: RMS of z(x, y) - z_measured at held-out scan points (scan points that are
//!   not nodes of the sub-grid), each method inverted at the point's (x, y) by Newton's method
//!   from the point's fractional sub-grid index;
//! - representation accuracy: RMS of z - h_true(x, y) over the evaluated points, the same
//!   (s, t) for every method: a fixed (u, v) pattern in every modelled network segment;
//! - operations per evaluated point: the z evaluation run on [`super::ops::Counted`].
//!
//! Only where the network has segments (all 16 points present) are points compared, so every
//! method is judged on the same region.

use super::bspline::{self, BSplineSurface};
use super::network::BezierNetwork;
use super::ops::{Counted, OpCount};
use super::point_grid::{PointGrid, Subsample};
use super::poly::PolySurface;
use super::SurfaceError;
use footscan_geom::P3;
use serde::Serialize;

/// The methods of the comparison.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Method {
    /// The paper's method.
    BezierNetwork,
    /// Global polynomial surface of the given total degree (the paper's "least squares").
    LeastSquares { degree: usize },
    /// Least-squares bicubic B-spline, one span per network segment (3 grid intervals).
    BSplineApprox,
    /// Rational bicubic with curvature weights ([`bspline::curvature_weights`]), same spans.
    Nurbs,
    /// C2 bicubic B-spline through every grid point.
    BSplineInterp,
}

impl Method {
    pub fn name(&self) -> String {
        match self {
            Method::BezierNetwork => "Bezier network".into(),
            Method::LeastSquares { degree } => format!("least squares (deg {degree})"),
            Method::BSplineApprox => "B-spline approx".into(),
            Method::Nurbs => "NURBS".into(),
            Method::BSplineInterp => "B-spline interp C2".into(),
        }
    }

    /// All five, the least-squares polynomial of total degree 12.
    pub fn all() -> [Method; 5] {
        [
            Method::BezierNetwork,
            Method::LeastSquares { degree: 12 },
            Method::BSplineApprox,
            Method::Nurbs,
            Method::BSplineInterp,
        ]
    }
}

/// A built model of any method.
pub enum Fitted {
    Network(BezierNetwork),
    Spline(BSplineSurface),
    Poly(PolySurface),
}

impl Fitted {
    /// Build `method` from `grid`. The spline methods need a complete rectangle and fill the
    /// missing points first ([`PointGrid::filled`]); the fill is part of their build.
    pub fn build(method: Method, grid: &PointGrid) -> Result<Fitted, SurfaceError> {
        let spans = [(grid.nu - 1).div_ceil(3), (grid.nv - 1).div_ceil(3)];
        Ok(match method {
            Method::BezierNetwork => Fitted::Network(BezierNetwork::build(grid)?),
            Method::LeastSquares { degree } => Fitted::Poly(PolySurface::fit(grid, degree)?),
            Method::BSplineApprox => {
                let f = grid.filled().ok_or(SurfaceError::Empty)?;
                Fitted::Spline(bspline::fit(&f, spans, None)?)
            }
            Method::Nurbs => {
                let f = grid.filled().ok_or(SurfaceError::Empty)?;
                let (a, b) = bspline::curvature_weights(&f, spans);
                Fitted::Spline(bspline::fit(&f, spans, Some((&a, &b)))?)
            }
            Method::BSplineInterp => {
                let f = grid.filled().ok_or(SurfaceError::Empty)?;
                Fitted::Spline(bspline::interpolate(&f)?)
            }
        })
    }

    /// (x, y, z) at global (s, t); None where the network has no segment.
    pub fn eval(&self, s: f64, t: f64) -> Option<P3> {
        match self {
            Fitted::Network(n) => n.eval(s, t),
            Fitted::Spline(b) => Some(b.eval(s, t)),
            Fitted::Poly(p) => Some(p.eval(s, t)),
        }
    }

    /// z over world (x, y), starting Newton's method at (s0, t0) (the network locates its
    /// segment itself).
    pub fn height_at(&self, x: f64, y: f64, s0: f64, t0: f64) -> Option<f64> {
        match self {
            Fitted::Network(n) => n.height_at(x, y),
            Fitted::Spline(b) => newton(|s, t| b.eval_d1(s, t), b.domain(), x, y, s0, t0),
            Fitted::Poly(p) => newton(|s, t| p.eval_d1(s, t), p.domain(), x, y, s0, t0),
        }
    }

    /// Operations to evaluate z at (s, t).
    pub fn z_ops(&self, s: f64, t: f64) -> OpCount {
        match self {
            Fitted::Network(n) => {
                let Some((seg, u, v)) = n.locate_param(s, t) else {
                    return OpCount::default();
                };
                Counted::take();
                let _ = seg.eval_coord_generic(2, Counted(u), Counted(v));
                Counted::take()
            }
            Fitted::Spline(b) => b.z_ops(s, t),
            Fitted::Poly(p) => p.z_ops(s, t),
        }
    }

    pub fn bytes(&self) -> usize {
        match self {
            Fitted::Network(n) => n.bytes(),
            Fitted::Spline(b) => b.bytes(),
            Fitted::Poly(p) => p.bytes(),
        }
    }

    /// Patches: network segments, spline spans, 1 for the global polynomial.
    pub fn patches(&self) -> usize {
        match self {
            Fitted::Network(n) => n.segments().len(),
            Fitted::Spline(b) => b.patches(),
            Fitted::Poly(_) => 1,
        }
    }
}

/// Newton's method for (x, y)(s, t) = (x, y), clamped to the domain; z at the solution.
fn newton(
    f: impl Fn(f64, f64) -> super::Jet,
    max: [f64; 2],
    x: f64,
    y: f64,
    s0: f64,
    t0: f64,
) -> Option<f64> {
    let (mut s, mut t) = (s0, t0);
    for _ in 0..30 {
        let d = f(s, t);
        let (rx, ry) = (d.p.x - x, d.p.y - y);
        if rx.abs().max(ry.abs()) < 1e-7 {
            return Some(d.p.z);
        }
        let det = d.du.x * d.dv.y - d.dv.x * d.du.y;
        if det.abs() < 1e-300 {
            return None;
        }
        s = (s - (rx * d.dv.y - ry * d.dv.x) / det).clamp(0.0, max[0]);
        t = (t - (d.du.x * ry - d.du.y * rx) / det).clamp(0.0, max[1]);
    }
    None
}

/// A scan point held out of the sub-grid, with its fractional sub-grid index.
#[derive(Clone, Copy, Debug)]
pub struct HeldOut {
    pub p: P3,
    pub s0: f64,
    pub t0: f64,
}

/// Fractional position of `i` in the sorted index list `at` (None outside it).
fn frac_index(at: &[usize], i: usize) -> Option<f64> {
    let k = at.partition_point(|&a| a <= i);
    if k == 0 {
        return None;
    }
    let lo = at[k - 1];
    if lo == i {
        return Some((k - 1) as f64);
    }
    let hi = *at.get(k)?;
    Some((k - 1) as f64 + (i - lo) as f64 / (hi - lo) as f64)
}

/// Valid scan points of `full` that are not nodes of `sub`, inside a modelled segment of
/// `net` (built on `sub`) and at least one sub-grid step from its border, every `stride`-th.
pub fn held_out(
    full: &PointGrid,
    sub: &Subsample,
    net: &BezierNetwork,
    stride: usize,
) -> Vec<HeldOut> {
    let mut out = Vec::new();
    let mut k = 0usize;
    for i in 0..full.nu {
        let Some(s0) = frac_index(&sub.frames, i) else {
            continue;
        };
        let node_frame = sub.frames.binary_search(&i).is_ok();
        for j in 0..full.nv {
            if !full.is_valid(i, j) || (node_frame && sub.rows.binary_search(&j).is_ok()) {
                continue;
            }
            let Some(t0) = frac_index(&sub.rows, j) else {
                continue;
            };
            // Away from the sub-grid's border, where an approximating surface need not reach.
            let inner = s0 >= 1.0
                && t0 >= 1.0
                && s0 <= (sub.frames.len() - 2) as f64
                && t0 <= (sub.rows.len() - 2) as f64;
            if !inner || net.locate_param(s0, t0).is_none() {
                continue;
            }
            k += 1;
            if k.is_multiple_of(stride.max(1)) {
                out.push(HeldOut {
                    p: P3::from(full.get(i, j)),
                    s0,
                    t0,
                });
            }
        }
    }
    out
}

/// The evaluated points: local (u, v) at the centres of an `nu x nv` pattern in every
/// modelled segment of `net`, as global (s, t).
pub fn eval_params(net: &BezierNetwork, nu: usize, nv: usize) -> Vec<(f64, f64)> {
    let (gu, gv) = net.grid_size();
    let mut out = Vec::with_capacity(net.segments().len() * nu * nv);
    for seg in net.segments() {
        let (a, b) = (seg.a as usize, seg.b as usize);
        let ku = ((gu - 1) - 3 * a).min(3) as f64;
        let kv = ((gv - 1) - 3 * b).min(3) as f64;
        for p in 0..nu {
            for q in 0..nv {
                let u = (p as f64 + 0.5) / nu as f64;
                let v = (q as f64 + 0.5) / nv as f64;
                out.push((3.0 * a as f64 + u * ku, 3.0 * b as f64 + v * kv));
            }
        }
    }
    out
}

/// RMS of a list of errors (NaN if empty).
pub fn rms(e: &[f64]) -> f64 {
    (e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64).sqrt()
}

/// z - measured z at the held-out points where the model inverts.
pub fn model_errors(m: &Fitted, pts: &[HeldOut]) -> Vec<f64> {
    pts.iter()
        .filter_map(|h| Some(m.height_at(h.p[0], h.p[1], h.s0, h.t0)? - h.p[2]))
        .collect()
}

/// z - h_true(x, y) at the evaluated (s, t) where the truth has a surface.
pub fn representation_errors(
    m: &Fitted,
    params: &[(f64, f64)],
    truth: &dyn Fn(f64, f64) -> Option<f64>,
) -> Vec<f64> {
    params
        .iter()
        .filter_map(|&(s, t)| {
            let p = m.eval(s, t)?;
            Some(p.z - truth(p.x, p.y)?)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fractional_index() {
        let at = [2, 5, 9];
        assert_eq!(frac_index(&at, 1), None);
        assert_eq!(frac_index(&at, 2), Some(0.0));
        assert_eq!(frac_index(&at, 7), Some(1.5));
        assert_eq!(frac_index(&at, 9), Some(2.0));
        assert_eq!(frac_index(&at, 10), None);
    }

    /// A dome z = f(x, y) on a grid with a missing corner: every method recovers the
    /// held-out points and the analytic surface, the interpolants best.
    #[test]
    fn every_method_models_a_smooth_dome() {
        let f = |x: f64, y: f64| 10.0 - 0.002 * (x - 30.0).powi(2) - 0.01 * (y - 12.0).powi(2);
        let (nu, nv) = (121, 97);
        let mut pts = Vec::new();
        for i in 0..nu {
            for j in 0..nv {
                let (x, y) = (i as f64 * 0.5, j as f64 * 0.25);
                pts.push(if i < 10 && j < 10 {
                    [f64::NAN; 3]
                } else {
                    [x, y, f(x, y)]
                });
            }
        }
        let full = PointGrid::new(nu, nv, pts.into_iter().map(P3::from).collect());
        let sub = full.even_subsample(41, 33).unwrap();
        let g = full.subsample(&sub);
        let net = BezierNetwork::build(&g).unwrap();
        assert!(net.skipped() > 0);
        let held = held_out(&full, &sub, &net, 7);
        assert!(held.len() > 500);
        let params = eval_params(&net, 4, 8);
        assert_eq!(params.len(), net.segments().len() * 32);
        let truth = |x: f64, y: f64| Some(f(x, y));
        for m in Method::all() {
            let fit = Fitted::build(m, &g).unwrap();
            let me = model_errors(&fit, &held);
            assert!(
                me.len() as f64 > 0.99 * held.len() as f64,
                "{m:?} {} of {}",
                me.len(),
                held.len()
            );
            let re = representation_errors(&fit, &params, &truth);
            assert_eq!(re.len(), params.len());
            let bound = match m {
                Method::BezierNetwork | Method::BSplineInterp => 2e-3,
                _ => 2e-2,
            };
            assert!(
                rms(&me) < bound && rms(&re) < bound,
                "{m:?}: {} {}",
                rms(&me),
                rms(&re)
            );
            assert!(fit.z_ops(10.2, 10.7).total() > 20);
            assert!(fit.bytes() > 0 && fit.patches() > 0);
        }
    }
}
