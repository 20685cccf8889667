//! Knot insertion and refinement, degree elevation, splitting, reversing, reparametrisation
//! of curves. Every operation keeps the shape exactly (up to rounding); periodic curves stay
//! periodic in the stored unclamped form.

use super::hcurve::{HCurve, Op, H};
use super::{NurbsCurve, NurbsError, Result};
use crate::P3;

/// Clamped knot vector on [0, 1] with uniform interior knots for `n` control points.
pub(crate) fn clamped_uniform_knots(degree: usize, n: usize) -> Vec<f64> {
    let mut k = vec![0.0; degree + 1];
    let inner = n - degree - 1;
    for i in 1..=inner {
        k.push(i as f64 / (inner + 1) as f64);
    }
    k.extend(std::iter::repeat_n(1.0, degree + 1));
    k
}

impl NurbsCurve {
    pub(crate) fn to_h(&self) -> HCurve {
        let pw = self
            .points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let w = self.weight(i);
                H::new(w * p.x, w * p.y, w * p.z, w)
            })
            .collect();
        HCurve {
            p: self.degree,
            knots: self.knots.clone(),
            pw,
        }
    }

    pub(crate) fn from_h(h: HCurve, rational: bool, periodic: bool) -> NurbsCurve {
        let points =
            h.pw.iter()
                .map(|q| P3::new(q.x / q.w, q.y / q.w, q.z / q.w))
                .collect();
        let weights = rational.then(|| h.pw.iter().map(|q| q.w).collect());
        NurbsCurve {
            degree: h.p,
            knots: h.knots,
            points,
            weights,
            periodic,
        }
    }

    fn apply_op(&self, op: &Op) -> NurbsCurve {
        let h = self.to_h().apply(op, self.periodic);
        NurbsCurve::from_h(h, self.weights.is_some(), self.periodic)
    }

    fn check_in_domain(&self, u: f64) -> Result<()> {
        let (a, b) = self.domain();
        if !(u.is_finite() && u >= a && u <= b) {
            return Err(NurbsError::Invalid {
                what: "curve",
                reason: format!("knot {u} lies outside the domain [{a}, {b}]"),
            });
        }
        Ok(())
    }

    /// Insert knot `u` `r` times (multiplicity is capped at the degree). The shape is
    /// unchanged; more control points give more freedom to later edits.
    pub fn insert_knot(&self, u: f64, r: usize) -> Result<NurbsCurve> {
        self.check_in_domain(u)?;
        if self.periodic {
            Ok(self.apply_op(&Op::Refine(vec![u; r])))
        } else {
            let h = self.to_h().insert(u, r);
            Ok(NurbsCurve::from_h(h, self.weights.is_some(), false))
        }
    }

    /// Insert many knots at once (any order; each inside the domain). For a periodic curve a
    /// knot at the domain end is the same as one at the start.
    pub fn refine_knots(&self, x: &[f64]) -> Result<NurbsCurve> {
        for &u in x {
            self.check_in_domain(u)?;
        }
        let x = self.sanitize_knots(x);
        if x.is_empty() {
            return Ok(self.clone());
        }
        Ok(self.apply_op(&Op::Refine(x)))
    }

    /// Sorted knots to insert, without those that would add nothing (at the ends of an open
    /// curve) or raise a multiplicity above the degree (periodic: the domain end is the start).
    pub(crate) fn sanitize_knots(&self, x: &[f64]) -> Vec<f64> {
        let (a, b) = self.domain();
        let p = self.degree;
        let mut x: Vec<f64> = x
            .iter()
            .map(|&u| {
                if self.periodic {
                    self.normalize_param(u)
                } else {
                    u
                }
            })
            .filter(|&u| self.periodic || (u > a && u < b))
            .collect();
        x.sort_by(|a, b| a.total_cmp(b));
        let mut out: Vec<f64> = Vec::with_capacity(x.len());
        let mut i = 0;
        while i < x.len() {
            let v = x[i];
            let mut j = i;
            while j < x.len() && x[j] == v {
                j += 1;
            }
            let have = self.knots[p..self.points.len()]
                .iter()
                .filter(|&&k| k == v)
                .count();
            let room = p.saturating_sub(have);
            out.extend(std::iter::repeat_n(v, (j - i).min(room)));
            i = j;
        }
        out
    }

    /// Raise the degree by `t`. An open curve comes back clamped.
    pub fn elevate_degree(&self, t: usize) -> NurbsCurve {
        if t == 0 {
            return self.clone();
        }
        self.apply_op(&Op::Elevate(t))
    }

    /// The same shape as an open clamped curve on the same domain (a periodic curve is cut at
    /// its domain start).
    pub fn to_clamped(&self) -> NurbsCurve {
        let h = self.to_h().clamp();
        NurbsCurve::from_h(h, self.weights.is_some(), false)
    }

    /// Split an open curve at `u` strictly inside the domain into two clamped curves over
    /// [a, u] and [u, b]. A periodic curve is first cut at its domain start.
    pub fn split(&self, u: f64) -> Result<(NurbsCurve, NurbsCurve)> {
        let c = if self.periodic {
            self.to_clamped()
        } else {
            self.to_clamped_if_needed()
        };
        let (a, b) = c.domain();
        if !(u > a && u < b) {
            return Err(NurbsError::Invalid {
                what: "curve split",
                reason: format!("parameter {u} must lie strictly inside the domain ({a}, {b})"),
            });
        }
        let p = c.degree;
        let h = c.to_h().insert(u, p);
        let f = h.knots.iter().position(|&k| k == u).unwrap();
        // Knots u occupy f..f+p; the curve passes through point f - 1 at u.
        let mut k1 = h.knots[..f + p].to_vec();
        k1.push(u);
        let left = HCurve {
            p,
            knots: k1,
            pw: h.pw[..f].to_vec(),
        };
        let mut k2 = vec![u];
        k2.extend_from_slice(&h.knots[f..]);
        let right = HCurve {
            p,
            knots: k2,
            pw: h.pw[f - 1..].to_vec(),
        };
        let rat = self.weights.is_some();
        Ok((
            NurbsCurve::from_h(left, rat, false),
            NurbsCurve::from_h(right, rat, false),
        ))
    }

    fn to_clamped_if_needed(&self) -> NurbsCurve {
        let p = self.degree;
        let n = self.points.len();
        let ok = self.knots[..=p].iter().all(|&k| k == self.knots[0])
            && self.knots[n..].iter().all(|&k| k == self.knots[n]);
        if ok {
            self.clone()
        } else {
            self.to_clamped()
        }
    }

    /// The same curve run backwards over the same domain: C'(u) = C(a + b - u).
    pub fn reversed(&self) -> NurbsCurve {
        let (a, b) = self.domain();
        let knots = self.knots.iter().rev().map(|&k| a + b - k).collect();
        let points = self.points.iter().rev().copied().collect();
        let weights = self
            .weights
            .as_ref()
            .map(|w| w.iter().rev().copied().collect());
        NurbsCurve {
            degree: self.degree,
            knots,
            points,
            weights,
            periodic: self.periodic,
        }
    }

    /// The same curve on the domain [s, e] (an affine change of parameter).
    pub fn reparametrized(&self, s: f64, e: f64) -> NurbsCurve {
        let (a, b) = self.domain();
        let f = (e - s) / (b - a);
        let mut c = self.clone();
        for k in c.knots.iter_mut() {
            *k = s + (*k - a) * f;
        }
        // Pin the domain ends exactly.
        for i in 0..c.knots.len() {
            if self.knots[i] == a {
                c.knots[i] = s;
            }
            if self.knots[i] == b {
                c.knots[i] = e;
            }
        }
        c
    }

    /// The same curve on [0, 1].
    pub fn reparametrized_unit(&self) -> NurbsCurve {
        self.reparametrized(0.0, 1.0)
    }

    /// Move the start of a periodic curve to parameter `u` (the result is periodic with
    /// domain [u, u + period]); useful to align the seams of closed sections.
    pub fn with_seam_at(&self, u: f64) -> Result<NurbsCurve> {
        if !self.periodic {
            return Err(NurbsError::Invalid {
                what: "curve seam",
                reason: "only a periodic curve has a movable seam".into(),
            });
        }
        let (a, b) = self.domain();
        let u = self.normalize_param(u);
        if u == a {
            return Ok(self.clone());
        }
        // Insert u, then rotate the period list so it starts at u.
        let c = self.refine_knots(&[u])?;
        let p = c.degree;
        let nu = c.points.len() - p;
        let t = b - a;
        let period: Vec<f64> = c.knots[p..p + nu].to_vec();
        let s = period.iter().position(|&k| k == u).unwrap();
        let new_period: Vec<f64> = (0..nu)
            .map(|i| {
                if s + i < nu {
                    period[s + i]
                } else {
                    period[s + i - nu] + t
                }
            })
            .collect();
        let knots: Vec<f64> = (0..(nu + 2 * p + 1) as isize)
            .map(|i| {
                let j = i - p as isize;
                new_period[j.rem_euclid(nu as isize) as usize]
                    + j.div_euclid(nu as isize) as f64 * t
            })
            .collect();
        // Point index i in the old numbering belongs to knot span... the new point k is old
        // point (k + s) mod nu, since basis function i starts at knot i.
        let idx = |k: usize| (k + s) % nu;
        let points: Vec<P3> = (0..nu + p).map(|k| c.points[idx(k % nu)]).collect();
        let weights = c
            .weights
            .as_ref()
            .map(|w| (0..nu + p).map(|k| w[idx(k % nu)]).collect());
        Ok(NurbsCurve {
            degree: p,
            knots,
            points,
            weights,
            periodic: true,
        })
    }
}
