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
//!
//! Submodules: [`basis`] (basis functions), `curve` and `surface` (evaluation, derivatives,
//! curvature, closest point, length), `edit` (knot insertion and refinement, degree elevation,
//! splitting, reversing, reparametrisation), [`fit`] (interpolation and least squares),
//! [`skin`] (compatible curves, skinning, grid interpolation).

// The algorithms follow published index recurrences; index loops read closer to them.
#![allow(
    clippy::needless_range_loop,
    clippy::manual_memcpy,
    clippy::explicit_counter_loop
)]

pub mod basis;
mod curve;
mod edit;
pub mod fit;
mod hcurve;
pub mod skin;
mod surface;

pub use curve::ClosestPoint;
pub use fit::{FitOptions, FitReport, Param};
pub use surface::{make_surfaces_compatible, SurfaceCurvature};

use crate::P3;

/// What is wrong with a curve or surface definition, or why a construction failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NurbsError {
    #[error("{what}: degree must be at least 1, got {degree}")]
    Degree { what: &'static str, degree: usize },
    #[error("{what}: degree {degree} needs at least {need} control points, got {got}")]
    TooFewPoints {
        what: &'static str,
        degree: usize,
        need: usize,
        got: usize,
    },
    #[error(
        "{what}: {points} control points of degree {degree} need {expected} knots \
         (points + degree + 1), got {got}"
    )]
    KnotCount {
        what: &'static str,
        points: usize,
        degree: usize,
        expected: usize,
        got: usize,
    },
    #[error("{what}: knots must be non-decreasing, but knot {index} = {value} < knot {prev_index} = {prev}", prev_index = index - 1)]
    KnotsDecreasing {
        what: &'static str,
        index: usize,
        prev: f64,
        value: f64,
    },
    #[error("{what}: knot {index} is not finite ({value})")]
    KnotNotFinite {
        what: &'static str,
        index: usize,
        value: f64,
    },
    #[error("{what}: the domain [{start}, {end}] is empty")]
    EmptyDomain {
        what: &'static str,
        start: f64,
        end: f64,
    },
    #[error("{what}: a knot of multiplicity {multiplicity} at {value} exceeds degree + 1 = {max}")]
    KnotMultiplicity {
        what: &'static str,
        value: f64,
        multiplicity: usize,
        max: usize,
    },
    #[error("{what}: control point {index} is not finite")]
    PointNotFinite { what: &'static str, index: usize },
    #[error("{what}: {got} weights for {expected} control points")]
    WeightCount {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("{what}: weight {index} is {value}; weights must be finite and > 0")]
    WeightNotPositive {
        what: &'static str,
        index: usize,
        value: f64,
    },
    #[error("{what}: {got} control points for a {nu} x {nv} grid (expected {expected})")]
    GridSize {
        what: &'static str,
        nu: usize,
        nv: usize,
        expected: usize,
        got: usize,
    },
    #[error(
        "{what}: periodic, so control point {index} must repeat control point {index_first} \
         (the last degree points wrap the first)"
    )]
    PeriodicWrap {
        what: &'static str,
        index: usize,
        index_first: usize,
    },
    #[error(
        "{what}: periodic, so knot spacing must repeat with period {period}: knot {index} \
         breaks it"
    )]
    PeriodicKnots {
        what: &'static str,
        index: usize,
        period: f64,
    },
    #[error("{what}: {reason}")]
    Invalid { what: &'static str, reason: String },
    #[error("{what}: the linear system is singular ({reason})")]
    Singular { what: &'static str, reason: String },
    #[error("{what}: curves are not compatible ({reason})")]
    Incompatible { what: &'static str, reason: String },
}

pub type Result<T> = std::result::Result<T, NurbsError>;

/// Relative tolerance for the periodic wrap checks (points and knot spacing).
const WRAP_TOL: f64 = 1e-9;

fn check_knots(what: &'static str, degree: usize, npts: usize, knots: &[f64]) -> Result<()> {
    if degree == 0 {
        return Err(NurbsError::Degree { what, degree });
    }
    if npts < degree + 1 {
        return Err(NurbsError::TooFewPoints {
            what,
            degree,
            need: degree + 1,
            got: npts,
        });
    }
    let expected = npts + degree + 1;
    if knots.len() != expected {
        return Err(NurbsError::KnotCount {
            what,
            points: npts,
            degree,
            expected,
            got: knots.len(),
        });
    }
    for (i, &k) in knots.iter().enumerate() {
        if !k.is_finite() {
            return Err(NurbsError::KnotNotFinite {
                what,
                index: i,
                value: k,
            });
        }
        if i > 0 && k < knots[i - 1] {
            return Err(NurbsError::KnotsDecreasing {
                what,
                index: i,
                prev: knots[i - 1],
                value: k,
            });
        }
    }
    // Interior multiplicity may reach degree (C0); ends may reach degree + 1.
    let mut i = 0;
    while i < knots.len() {
        let mut j = i;
        while j + 1 < knots.len() && knots[j + 1] == knots[i] {
            j += 1;
        }
        let mult = j - i + 1;
        if mult > degree + 1 {
            return Err(NurbsError::KnotMultiplicity {
                what,
                value: knots[i],
                multiplicity: mult,
                max: degree + 1,
            });
        }
        i = j + 1;
    }
    let (start, end) = (knots[degree], knots[npts]);
    if end <= start {
        return Err(NurbsError::EmptyDomain { what, start, end });
    }
    Ok(())
}

fn check_points(what: &'static str, points: &[P3], weights: Option<&[f64]>) -> Result<()> {
    for (i, p) in points.iter().enumerate() {
        if !(p.x.is_finite() && p.y.is_finite() && p.z.is_finite()) {
            return Err(NurbsError::PointNotFinite { what, index: i });
        }
    }
    if let Some(w) = weights {
        if w.len() != points.len() {
            return Err(NurbsError::WeightCount {
                what,
                expected: points.len(),
                got: w.len(),
            });
        }
        for (i, &x) in w.iter().enumerate() {
            if !(x.is_finite() && x > 0.0) {
                return Err(NurbsError::WeightNotPositive {
                    what,
                    index: i,
                    value: x,
                });
            }
        }
    }
    Ok(())
}

/// Check that a stored unclamped periodic knot vector repeats its spacing with the period.
fn check_periodic_knots(
    what: &'static str,
    degree: usize,
    npts: usize,
    knots: &[f64],
) -> Result<()> {
    let n_unique = npts - degree;
    let period = knots[npts] - knots[degree];
    let tol = WRAP_TOL * period.abs().max(1.0);
    for i in 0..knots.len() - n_unique {
        if ((knots[i + n_unique] - knots[i]) - period).abs() > tol {
            return Err(NurbsError::PeriodicKnots {
                what,
                index: i + n_unique,
                period,
            });
        }
    }
    Ok(())
}

fn points_scale(points: &[P3]) -> f64 {
    points.iter().map(|p| p.coords.amax()).fold(1.0, f64::max)
}

impl NurbsCurve {
    /// An open (non-periodic) curve; `weights = None` for a non-rational B-spline.
    pub fn new(
        degree: usize,
        knots: Vec<f64>,
        points: Vec<P3>,
        weights: Option<Vec<f64>>,
    ) -> Result<Self> {
        let c = NurbsCurve {
            degree,
            knots,
            points,
            weights,
            periodic: false,
        };
        c.validate()?;
        Ok(c)
    }

    /// A periodic curve in the stored unclamped form: the last `degree` control points (and
    /// weights) repeat the first ones and the knot spacing repeats with the period.
    pub fn new_periodic(
        degree: usize,
        knots: Vec<f64>,
        points: Vec<P3>,
        weights: Option<Vec<f64>>,
    ) -> Result<Self> {
        let c = NurbsCurve {
            degree,
            knots,
            points,
            weights,
            periodic: true,
        };
        c.validate()?;
        Ok(c)
    }

    /// A clamped B-spline with uniform interior knots on [0, 1].
    pub fn clamped_uniform(degree: usize, points: Vec<P3>) -> Result<Self> {
        if degree == 0 {
            return Err(NurbsError::Degree {
                what: "curve",
                degree,
            });
        }
        if points.len() < degree + 1 {
            return Err(NurbsError::TooFewPoints {
                what: "curve",
                degree,
                need: degree + 1,
                got: points.len(),
            });
        }
        let knots = edit::clamped_uniform_knots(degree, points.len());
        Self::new(degree, knots, points, None)
    }

    /// Check every invariant of the stored form (fields are public, so a caller that edits
    /// them can re-check).
    pub fn validate(&self) -> Result<()> {
        let what = "curve";
        check_knots(what, self.degree, self.points.len(), &self.knots)?;
        check_points(what, &self.points, self.weights.as_deref())?;
        if self.periodic {
            let p = self.degree;
            let n = self.points.len();
            if n < 2 * p + 1 {
                return Err(NurbsError::TooFewPoints {
                    what,
                    degree: p,
                    need: 2 * p + 1,
                    got: n,
                });
            }
            let tol = WRAP_TOL * points_scale(&self.points);
            for k in 0..p {
                let (a, b) = (k, n - p + k);
                let wrong_w = self
                    .weights
                    .as_ref()
                    .is_some_and(|w| (w[a] - w[b]).abs() > WRAP_TOL * w[a].max(1.0));
                if (self.points[a] - self.points[b]).amax() > tol || wrong_w {
                    return Err(NurbsError::PeriodicWrap {
                        what,
                        index: b,
                        index_first: a,
                    });
                }
            }
            check_periodic_knots(what, p, n, &self.knots)?;
        }
        Ok(())
    }

    /// Number of control points (including the wrapped ones of a periodic curve).
    pub fn n_points(&self) -> usize {
        self.points.len()
    }

    /// True when the curve has weights that are not all equal.
    pub fn is_rational(&self) -> bool {
        self.weights
            .as_ref()
            .is_some_and(|w| w.iter().any(|&x| (x - w[0]).abs() > 1e-14 * w[0]))
    }

    /// Weight of control point `i` (1 when non-rational).
    pub fn weight(&self, i: usize) -> f64 {
        self.weights.as_ref().map_or(1.0, |w| w[i])
    }

    /// Parameter domain [knots[p], knots[n + 1]].
    pub fn domain(&self) -> (f64, f64) {
        (self.knots[self.degree], self.knots[self.points.len()])
    }

    /// Bring `u` into the domain: wrapped for a periodic curve, clamped otherwise.
    pub fn normalize_param(&self, u: f64) -> f64 {
        let (a, b) = self.domain();
        if self.periodic {
            let t = b - a;
            let w = a + (u - a).rem_euclid(t);
            if w >= b {
                a
            } else {
                w
            }
        } else {
            u.clamp(a, b)
        }
    }

    /// The point at parameter `u` (wrapped into the domain if periodic, clamped otherwise).
    pub fn point(&self, u: f64) -> P3 {
        let p = self.degree;
        let u = self.normalize_param(u);
        let n = self.points.len() - 1;
        // A clamped end is its end control point exactly (the basis recurrence could be off
        // by a rounding there, and fits promise their fixed ends exactly).
        if !self.periodic {
            if u == self.knots[p] && self.knots[0] == self.knots[p] {
                return self.points[0];
            }
            if u == self.knots[n + 1] && self.knots[n + 1] == self.knots[n + p + 1] {
                return self.points[n];
            }
        }
        let span = basis::find_span(n, p, u, &self.knots);
        let mut b = [0.0f64; 32];
        let mut heap;
        let b: &mut [f64] = if p < 32 {
            &mut b[..=p]
        } else {
            heap = vec![0.0; p + 1];
            &mut heap
        };
        basis::basis_funs(span, u, p, &self.knots, b);
        let mut acc = crate::V3::zeros();
        match &self.weights {
            None => {
                for (j, &bj) in b.iter().enumerate() {
                    acc += bj * self.points[span - p + j].coords;
                }
                P3::from(acc)
            }
            Some(w) => {
                let mut ws = 0.0;
                for (j, &bj) in b.iter().enumerate() {
                    let i = span - p + j;
                    acc += bj * w[i] * self.points[i].coords;
                    ws += bj * w[i];
                }
                P3::from(acc / ws)
            }
        }
    }
}

impl NurbsSurface {
    /// An open surface in both directions (`periodic_u = periodic_v = false`); see
    /// [`NurbsSurface::with_periodic`] to mark periodic directions.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        degree_u: usize,
        degree_v: usize,
        knots_u: Vec<f64>,
        knots_v: Vec<f64>,
        nu: usize,
        nv: usize,
        points: Vec<P3>,
        weights: Option<Vec<f64>>,
    ) -> Result<Self> {
        let s = NurbsSurface {
            degree_u,
            degree_v,
            knots_u,
            knots_v,
            nu,
            nv,
            points,
            weights,
            periodic_u: false,
            periodic_v: false,
        };
        s.validate()?;
        Ok(s)
    }

    /// Mark directions periodic (stored unclamped with wrapped rows/columns) and re-validate.
    pub fn with_periodic(mut self, periodic_u: bool, periodic_v: bool) -> Result<Self> {
        self.periodic_u = periodic_u;
        self.periodic_v = periodic_v;
        self.validate()?;
        Ok(self)
    }

    /// Check every invariant of the stored form.
    pub fn validate(&self) -> Result<()> {
        let expected = self.nu * self.nv;
        if self.points.len() != expected {
            return Err(NurbsError::GridSize {
                what: "surface",
                nu: self.nu,
                nv: self.nv,
                expected,
                got: self.points.len(),
            });
        }
        check_knots("surface u", self.degree_u, self.nu, &self.knots_u)?;
        check_knots("surface v", self.degree_v, self.nv, &self.knots_v)?;
        check_points("surface", &self.points, self.weights.as_deref())?;
        let tol = WRAP_TOL * points_scale(&self.points);
        let wtol = |a: f64| WRAP_TOL * a.max(1.0);
        if self.periodic_u {
            let (p, n) = (self.degree_u, self.nu);
            if n < 2 * p + 1 {
                return Err(NurbsError::TooFewPoints {
                    what: "surface u",
                    degree: p,
                    need: 2 * p + 1,
                    got: n,
                });
            }
            for k in 0..p {
                for j in 0..self.nv {
                    let (a, b) = (k * self.nv + j, (n - p + k) * self.nv + j);
                    let bad_w = self
                        .weights
                        .as_ref()
                        .is_some_and(|w| (w[a] - w[b]).abs() > wtol(w[a]));
                    if (self.points[a] - self.points[b]).amax() > tol || bad_w {
                        return Err(NurbsError::PeriodicWrap {
                            what: "surface u",
                            index: b,
                            index_first: a,
                        });
                    }
                }
            }
            check_periodic_knots("surface u", p, n, &self.knots_u)?;
        }
        if self.periodic_v {
            let (p, n) = (self.degree_v, self.nv);
            if n < 2 * p + 1 {
                return Err(NurbsError::TooFewPoints {
                    what: "surface v",
                    degree: p,
                    need: 2 * p + 1,
                    got: n,
                });
            }
            for i in 0..self.nu {
                for k in 0..p {
                    let (a, b) = (i * self.nv + k, i * self.nv + n - p + k);
                    let bad_w = self
                        .weights
                        .as_ref()
                        .is_some_and(|w| (w[a] - w[b]).abs() > wtol(w[a]));
                    if (self.points[a] - self.points[b]).amax() > tol || bad_w {
                        return Err(NurbsError::PeriodicWrap {
                            what: "surface v",
                            index: b,
                            index_first: a,
                        });
                    }
                }
            }
            check_periodic_knots("surface v", p, n, &self.knots_v)?;
        }
        Ok(())
    }

    /// Control point P_ij.
    pub fn point_ij(&self, i: usize, j: usize) -> P3 {
        self.points[i * self.nv + j]
    }

    /// Weight of P_ij (1 when non-rational).
    pub fn weight_ij(&self, i: usize, j: usize) -> f64 {
        self.weights.as_ref().map_or(1.0, |w| w[i * self.nv + j])
    }

    /// Domain in u: [knots_u[p], knots_u[nu]].
    pub fn domain_u(&self) -> (f64, f64) {
        (self.knots_u[self.degree_u], self.knots_u[self.nu])
    }

    /// Domain in v: [knots_v[q], knots_v[nv]].
    pub fn domain_v(&self) -> (f64, f64) {
        (self.knots_v[self.degree_v], self.knots_v[self.nv])
    }

    fn norm_u(&self, u: f64) -> f64 {
        norm_param(u, self.domain_u(), self.periodic_u)
    }

    fn norm_v(&self, v: f64) -> f64 {
        norm_param(v, self.domain_v(), self.periodic_v)
    }

    /// The point at (u, v) (each wrapped if periodic in that direction, clamped otherwise).
    pub fn point(&self, u: f64, v: f64) -> P3 {
        let (p, q) = (self.degree_u, self.degree_v);
        let (u, v) = (self.norm_u(u), self.norm_v(v));
        let su = basis::find_span(self.nu - 1, p, u, &self.knots_u);
        let sv = basis::find_span(self.nv - 1, q, v, &self.knots_v);
        let mut bu = vec![0.0; p + 1];
        let mut bv = vec![0.0; q + 1];
        basis::basis_funs(su, u, p, &self.knots_u, &mut bu);
        basis::basis_funs(sv, v, q, &self.knots_v, &mut bv);
        let mut acc = crate::V3::zeros();
        let mut ws = 0.0;
        for (a, &nu_a) in bu.iter().enumerate() {
            let row = (su - p + a) * self.nv + sv - q;
            for (b, &nv_b) in bv.iter().enumerate() {
                let idx = row + b;
                let w = self.weights.as_ref().map_or(1.0, |w| w[idx]);
                let f = nu_a * nv_b * w;
                acc += f * self.points[idx].coords;
                ws += f;
            }
        }
        P3::from(acc / ws)
    }
}

pub(crate) fn norm_param(u: f64, (a, b): (f64, f64), periodic: bool) -> f64 {
    if periodic {
        let w = a + (u - a).rem_euclid(b - a);
        if w >= b {
            a
        } else {
            w
        }
    } else {
        u.clamp(a, b)
    }
}

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
