//! Curve derivatives, tangent, curvature, closest point and length.

use super::basis::{binomial, ders_basis_funs, find_span};
use super::NurbsCurve;
use crate::{P3, V3};

/// The foot of a point on a curve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestPoint {
    pub u: f64,
    pub point: P3,
    pub distance: f64,
}

/// Gauss-Legendre nodes and weights on [-1, 1], 8 points.
const GL8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (-0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_47),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_26),
];

impl NurbsCurve {
    /// Derivatives C^(k)(u) for k = 0..=d (index 0 is the point as a vector). Rational
    /// curves use the quotient rule on the homogeneous derivatives.
    pub fn derivatives(&self, u: f64, d: usize) -> Vec<V3> {
        let p = self.degree;
        let u = self.normalize_param(u);
        let n = self.points.len() - 1;
        let span = find_span(n, p, u, &self.knots);
        let nd = ders_basis_funs(span, u, p, d.min(p), &self.knots);
        let mut aders = vec![V3::zeros(); d + 1];
        let mut wders = vec![0.0; d + 1];
        for k in 0..=d.min(p) {
            for j in 0..=p {
                let i = span - p + j;
                let w = self.weight(i);
                aders[k] += nd[k][j] * w * self.points[i].coords;
                wders[k] += nd[k][j] * w;
            }
        }
        if self.weights.is_none() {
            return aders;
        }
        let mut ck = vec![V3::zeros(); d + 1];
        for k in 0..=d {
            let mut v = aders[k];
            for i in 1..=k {
                v -= binomial(k, i) * wders[i] * ck[k - i];
            }
            ck[k] = v / wders[0];
        }
        ck
    }

    /// First derivative C'(u).
    pub fn derivative(&self, u: f64) -> V3 {
        self.derivatives(u, 1)[1]
    }

    /// Unit tangent at `u` (zero vector where the derivative vanishes).
    pub fn tangent(&self, u: f64) -> V3 {
        let d = self.derivative(u);
        let n = d.norm();
        if n > 0.0 {
            d / n
        } else {
            d
        }
    }

    /// Curvature |C' x C''| / |C'|^3 (1/mm).
    pub fn curvature(&self, u: f64) -> f64 {
        let d = self.derivatives(u, 2);
        let s = d[1].norm();
        if s == 0.0 {
            return 0.0;
        }
        d[1].cross(&d[2]).norm() / (s * s * s)
    }

    /// Curvature vector: points to the centre of curvature, length = curvature.
    pub fn curvature_vector(&self, u: f64) -> V3 {
        let d = self.derivatives(u, 2);
        let s2 = d[1].norm_squared();
        if s2 == 0.0 {
            return V3::zeros();
        }
        let t = d[1] / s2.sqrt();
        (d[2] - d[2].dot(&t) * t) / s2
    }

    /// Distinct knot values inside the domain, ends included (the curve is polynomial or
    /// rational-polynomial between consecutive ones).
    pub fn span_breaks(&self) -> Vec<f64> {
        let (a, b) = self.domain();
        let mut v: Vec<f64> = vec![a];
        for &k in &self.knots {
            if k > *v.last().unwrap() && k <= b {
                v.push(k);
            }
        }
        v
    }

    /// Arc length between parameters `u0 <= u1` (Gauss-Legendre on each knot span, split in
    /// two halves).
    pub fn length_between(&self, u0: f64, u1: f64) -> f64 {
        let mut brk: Vec<f64> = vec![u0];
        for k in self.span_breaks() {
            if k > u0 && k < u1 {
                brk.push(k);
            }
        }
        brk.push(u1);
        let mut len = 0.0;
        for w in brk.windows(2) {
            let (a, b) = (w[0], w[1]);
            let m = 0.5 * (a + b);
            for (s, e) in [(a, m), (m, b)] {
                let h = 0.5 * (e - s);
                let c = 0.5 * (e + s);
                for (x, wt) in GL8 {
                    len += wt * h * self.derivative(c + h * x).norm();
                }
            }
        }
        len
    }

    /// Total arc length over the domain.
    pub fn length(&self) -> f64 {
        let (a, b) = self.domain();
        self.length_between(a, b)
    }

    /// Closest point on the curve to `q`: the nearest of a coarse sampling (8 samples per knot
    /// span), refined by Newton's method on C'(u) . (C(u) - q) = 0.
    pub fn closest_point(&self, q: &P3) -> ClosestPoint {
        let (a, b) = self.domain();
        let brk = self.span_breaks();
        let mut best = (a, f64::INFINITY);
        for w in brk.windows(2) {
            for s in 0..8 {
                let u = w[0] + (w[1] - w[0]) * s as f64 / 8.0;
                let d = (self.point(u) - q).norm_squared();
                if d < best.1 {
                    best = (u, d);
                }
            }
        }
        let d = (self.point(b) - q).norm_squared();
        if d < best.1 {
            best = (b, d);
        }
        let mut u = best.0;
        let tol = 1e-14 * (b - a);
        for _ in 0..30 {
            let ds = self.derivatives(u, 2);
            let r = ds[0] - q.coords;
            let f = ds[1].dot(&r);
            let fp = ds[2].dot(&r) + ds[1].norm_squared();
            if fp <= 0.0 {
                break;
            }
            let mut un = u - f / fp;
            un = self.normalize_param(un);
            if (un - u).abs() <= tol {
                u = un;
                break;
            }
            u = un;
        }
        let mut point = self.point(u);
        let mut distance = (point - q).norm();
        // Newton may leave a worse point than the coarse start near cusps or ends.
        if distance * distance > best.1 {
            u = best.0;
            point = self.point(u);
            distance = (point - q).norm();
        }
        ClosestPoint { u, point, distance }
    }
}
