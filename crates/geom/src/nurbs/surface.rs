//! Surface derivatives, normal and curvatures; knot refinement and degree elevation in u or
//! v; sums and differences of compatible surfaces.

use super::basis::{binomial, ders_basis_funs, find_span};
use super::hcurve::{HCurve, Op, H};
use super::{NurbsError, NurbsSurface, Result};
use crate::{P3, V3};

/// Curvatures at a surface point from the first and second fundamental forms.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceCurvature {
    /// Unit normal Su x Sv / |Su x Sv|; curvature signs follow it (positive when the surface
    /// bends towards the normal).
    pub normal: V3,
    pub gaussian: f64,
    pub mean: f64,
    /// Principal curvatures, k1 >= k2.
    pub k1: f64,
    pub k2: f64,
    /// Principal directions (unit, in 3D) for k1 and k2.
    pub dir1: V3,
    pub dir2: V3,
}

impl NurbsSurface {
    /// Partial derivatives: `d[k][l]` = d^(k+l) S / du^k dv^l for k + l <= `order`.
    pub fn derivatives(&self, u: f64, v: f64, order: usize) -> Vec<Vec<V3>> {
        let (p, q) = (self.degree_u, self.degree_v);
        let (u, v) = (
            super::norm_param(u, self.domain_u(), self.periodic_u),
            super::norm_param(v, self.domain_v(), self.periodic_v),
        );
        let su = find_span(self.nu - 1, p, u, &self.knots_u);
        let sv = find_span(self.nv - 1, q, v, &self.knots_v);
        let du = order.min(p);
        let dv = order.min(q);
        let nu_d = ders_basis_funs(su, u, p, du, &self.knots_u);
        let nv_d = ders_basis_funs(sv, v, q, dv, &self.knots_v);
        // Homogeneous derivatives A (w-weighted points) and weight derivatives.
        let mut a = vec![vec![V3::zeros(); order + 1]; order + 1];
        let mut w = vec![vec![0.0; order + 1]; order + 1];
        for k in 0..=du {
            // temp[s] = sum_r N^(k)_r(u) Pw_{r,s}
            let mut tmp = vec![H::zeros(); q + 1];
            for (s, t) in tmp.iter_mut().enumerate() {
                for r in 0..=p {
                    let idx = (su - p + r) * self.nv + sv - q + s;
                    let wt = self.weights.as_ref().map_or(1.0, |w| w[idx]);
                    let pt = self.points[idx];
                    *t += nu_d[k][r] * H::new(wt * pt.x, wt * pt.y, wt * pt.z, wt);
                }
            }
            for l in 0..=dv.min(order - k) {
                let mut acc = H::zeros();
                for (s, t) in tmp.iter().enumerate() {
                    acc += nv_d[l][s] * t;
                }
                a[k][l] = acc.xyz();
                w[k][l] = acc.w;
            }
        }
        if self.weights.is_none() {
            return a;
        }
        let mut skl = vec![vec![V3::zeros(); order + 1]; order + 1];
        for k in 0..=order {
            for l in 0..=(order - k) {
                let mut v = a[k][l];
                for j in 1..=l {
                    v -= binomial(l, j) * w[0][j] * skl[k][l - j];
                }
                for i in 1..=k {
                    v -= binomial(k, i) * w[i][0] * skl[k - i][l];
                    let mut v2 = V3::zeros();
                    for j in 1..=l {
                        v2 += binomial(l, j) * w[i][j] * skl[k - i][l - j];
                    }
                    v -= binomial(k, i) * v2;
                }
                skl[k][l] = v / w[0][0];
            }
        }
        skl
    }

    /// Unit normal Su x Sv normalised (zero at a degenerate point).
    pub fn normal(&self, u: f64, v: f64) -> V3 {
        let d = self.derivatives(u, v, 1);
        let n = d[1][0].cross(&d[0][1]);
        let l = n.norm();
        if l > 0.0 {
            n / l
        } else {
            n
        }
    }

    /// Gaussian, mean and principal curvatures with principal directions.
    pub fn curvature(&self, u: f64, v: f64) -> SurfaceCurvature {
        let d = self.derivatives(u, v, 2);
        let (su, sv) = (d[1][0], d[0][1]);
        let n = su.cross(&sv);
        let nl = n.norm();
        let n = if nl > 0.0 { n / nl } else { n };
        let (e, f, g) = (su.dot(&su), su.dot(&sv), sv.dot(&sv));
        let (l, m, nn) = (d[2][0].dot(&n), d[1][1].dot(&n), d[0][2].dot(&n));
        let det = e * g - f * f;
        if det <= 0.0 {
            return SurfaceCurvature {
                normal: n,
                gaussian: 0.0,
                mean: 0.0,
                k1: 0.0,
                k2: 0.0,
                dir1: V3::zeros(),
                dir2: V3::zeros(),
            };
        }
        let gaussian = (l * nn - m * m) / det;
        let mean = (e * nn - 2.0 * f * m + g * l) / (2.0 * det);
        let disc = (mean * mean - gaussian).max(0.0).sqrt();
        let (k1, k2) = (mean + disc, mean - disc);
        // Principal direction (du, dv) solves (L - k E) du + (M - k F) dv = 0, or the
        // second row when the first vanishes.
        let dir = |k: f64| -> V3 {
            let (a1, b1) = (l - k * e, m - k * f);
            let (a2, b2) = (m - k * f, nn - k * g);
            let (du, dv) = if a1.abs() + b1.abs() >= a2.abs() + b2.abs() {
                (b1, -a1)
            } else {
                (b2, -a2)
            };
            let t = su * du + sv * dv;
            let tl = t.norm();
            if tl > 1e-300 {
                t / tl
            } else {
                su.normalize()
            }
        };
        let dir1 = dir(k1);
        let mut dir2 = dir(k2);
        if disc < 1e-12 * (mean.abs() + 1e-300) || (dir1 - dir2).norm() < 1e-9 {
            // Umbilic: any direction is principal.
            dir2 = n.cross(&dir1);
        }
        SurfaceCurvature {
            normal: n,
            gaussian,
            mean,
            k1,
            k2,
            dir1,
            dir2,
        }
    }

    /// Normal curvature along the parameter direction (du, dv).
    pub fn normal_curvature_param(&self, u: f64, v: f64, du: f64, dv: f64) -> f64 {
        let d = self.derivatives(u, v, 2);
        let (su, sv) = (d[1][0], d[0][1]);
        let n = su.cross(&sv).normalize();
        let (e, f, g) = (su.dot(&su), su.dot(&sv), sv.dot(&sv));
        let (l, m, nn) = (d[2][0].dot(&n), d[1][1].dot(&n), d[0][2].dot(&n));
        (l * du * du + 2.0 * m * du * dv + nn * dv * dv)
            / (e * du * du + 2.0 * f * du * dv + g * dv * dv)
    }

    /// Normal curvature along a 3D tangent direction `t` (projected onto the tangent plane).
    pub fn normal_curvature(&self, u: f64, v: f64, t: &V3) -> f64 {
        let d = self.derivatives(u, v, 1);
        let (su, sv) = (d[1][0], d[0][1]);
        let (e, f, g) = (su.dot(&su), su.dot(&sv), sv.dot(&sv));
        let (bu, bv) = (t.dot(&su), t.dot(&sv));
        let det = e * g - f * f;
        let du = (g * bu - f * bv) / det;
        let dv = (e * bv - f * bu) / det;
        self.normal_curvature_param(u, v, du, dv)
    }

    fn column_h(&self, j: usize) -> HCurve {
        let pw = (0..self.nu)
            .map(|i| {
                let idx = i * self.nv + j;
                let w = self.weights.as_ref().map_or(1.0, |w| w[idx]);
                let p = self.points[idx];
                H::new(w * p.x, w * p.y, w * p.z, w)
            })
            .collect();
        HCurve {
            p: self.degree_u,
            knots: self.knots_u.clone(),
            pw,
        }
    }

    fn row_h(&self, i: usize) -> HCurve {
        let pw = (0..self.nv)
            .map(|j| {
                let idx = i * self.nv + j;
                let w = self.weights.as_ref().map_or(1.0, |w| w[idx]);
                let p = self.points[idx];
                H::new(w * p.x, w * p.y, w * p.z, w)
            })
            .collect();
        HCurve {
            p: self.degree_v,
            knots: self.knots_v.clone(),
            pw,
        }
    }

    /// Apply a knot-vector operation to every column (along u) or every row (along v).
    fn apply_dir(&self, op: &Op, in_u: bool) -> NurbsSurface {
        let rational = self.weights.is_some();
        if in_u {
            let cols: Vec<HCurve> = (0..self.nv)
                .map(|j| self.column_h(j).apply(op, self.periodic_u))
                .collect();
            let nu = cols[0].pw.len();
            let mut pw = vec![H::zeros(); nu * self.nv];
            for (j, c) in cols.iter().enumerate() {
                for i in 0..nu {
                    pw[i * self.nv + j] = c.pw[i];
                }
            }
            let mut s = self.clone();
            s.degree_u = cols[0].p;
            s.knots_u = cols[0].knots.clone();
            s.nu = nu;
            s.set_h(pw, rational);
            s
        } else {
            let rows: Vec<HCurve> = (0..self.nu)
                .map(|i| self.row_h(i).apply(op, self.periodic_v))
                .collect();
            let nv = rows[0].pw.len();
            let mut pw = Vec::with_capacity(self.nu * nv);
            for r in &rows {
                pw.extend_from_slice(&r.pw);
            }
            let mut s = self.clone();
            s.degree_v = rows[0].p;
            s.knots_v = rows[0].knots.clone();
            s.nv = nv;
            s.set_h(pw, rational);
            s
        }
    }

    fn set_h(&mut self, pw: Vec<H>, rational: bool) {
        self.points = pw
            .iter()
            .map(|q| P3::new(q.x / q.w, q.y / q.w, q.z / q.w))
            .collect();
        self.weights = rational.then(|| pw.iter().map(|q| q.w).collect());
    }

    /// Sorted knots worth inserting in one direction (see `NurbsCurve::sanitize_knots`).
    fn sanitize(&self, x: &[f64], in_u: bool) -> Vec<f64> {
        let (p, knots, n, periodic) = if in_u {
            (self.degree_u, &self.knots_u, self.nu, self.periodic_u)
        } else {
            (self.degree_v, &self.knots_v, self.nv, self.periodic_v)
        };
        let dummy = super::NurbsCurve {
            degree: p,
            knots: knots.clone(),
            points: vec![P3::origin(); n],
            weights: None,
            periodic,
        };
        dummy.sanitize_knots(x)
    }

    /// Insert knots in u (shape unchanged).
    pub fn refine_u(&self, x: &[f64]) -> NurbsSurface {
        let x = self.sanitize(x, true);
        if x.is_empty() {
            return self.clone();
        }
        self.apply_dir(&Op::Refine(x), true)
    }

    /// Insert knots in v (shape unchanged).
    pub fn refine_v(&self, x: &[f64]) -> NurbsSurface {
        let x = self.sanitize(x, false);
        if x.is_empty() {
            return self.clone();
        }
        self.apply_dir(&Op::Refine(x), false)
    }

    /// Insert knot `u` `r` times in u.
    pub fn insert_knot_u(&self, u: f64, r: usize) -> NurbsSurface {
        self.refine_u(&vec![u; r])
    }

    /// Insert knot `v` `r` times in v.
    pub fn insert_knot_v(&self, v: f64, r: usize) -> NurbsSurface {
        self.refine_v(&vec![v; r])
    }

    /// Raise the degree in u by `t` (an open direction comes back clamped).
    pub fn elevate_u(&self, t: usize) -> NurbsSurface {
        if t == 0 {
            return self.clone();
        }
        self.apply_dir(&Op::Elevate(t), true)
    }

    /// Raise the degree in v by `t`.
    pub fn elevate_v(&self, t: usize) -> NurbsSurface {
        if t == 0 {
            return self.clone();
        }
        self.apply_dir(&Op::Elevate(t), false)
    }

    /// The same surface with u and v exchanged: S'(u, v) = S(v, u).
    pub fn transposed(&self) -> NurbsSurface {
        let mut points = Vec::with_capacity(self.points.len());
        let mut weights = self
            .weights
            .as_ref()
            .map(|_| Vec::with_capacity(self.points.len()));
        for j in 0..self.nv {
            for i in 0..self.nu {
                points.push(self.points[i * self.nv + j]);
                if let (Some(w), Some(ws)) = (weights.as_mut(), self.weights.as_ref()) {
                    w.push(ws[i * self.nv + j]);
                }
            }
        }
        NurbsSurface {
            degree_u: self.degree_v,
            degree_v: self.degree_u,
            knots_u: self.knots_v.clone(),
            knots_v: self.knots_u.clone(),
            nu: self.nv,
            nv: self.nu,
            points,
            weights,
            periodic_u: self.periodic_v,
            periodic_v: self.periodic_u,
        }
    }

    /// The same surface with both domains mapped affinely to the given intervals.
    pub fn reparametrized(&self, (u0, u1): (f64, f64), (v0, v1): (f64, f64)) -> NurbsSurface {
        let mut s = self.clone();
        remap(&mut s.knots_u, self.domain_u(), (u0, u1));
        remap(&mut s.knots_v, self.domain_v(), (v0, v1));
        s
    }

    fn check_same_layout(&self, o: &NurbsSurface, what: &'static str) -> Result<()> {
        let bad = |reason: String| Err(NurbsError::Incompatible { what, reason });
        if self.weights.is_some() || o.weights.is_some() {
            return bad("both surfaces must be non-rational".into());
        }
        if (self.degree_u, self.degree_v) != (o.degree_u, o.degree_v) {
            return bad(format!(
                "degrees ({}, {}) and ({}, {})",
                self.degree_u, self.degree_v, o.degree_u, o.degree_v
            ));
        }
        if (self.nu, self.nv) != (o.nu, o.nv)
            || (self.periodic_u, self.periodic_v) != (o.periodic_u, o.periodic_v)
        {
            return bad(format!(
                "grids {}x{} and {}x{} (or periodic flags differ)",
                self.nu, self.nv, o.nu, o.nv
            ));
        }
        let same = |a: &[f64], b: &[f64]| {
            let scale = a.iter().chain(b).fold(1.0f64, |m, x| m.max(x.abs()));
            a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-10 * scale)
        };
        if !same(&self.knots_u, &o.knots_u) || !same(&self.knots_v, &o.knots_v) {
            return bad("knot vectors differ (bring them to common knots first)".into());
        }
        Ok(())
    }

    /// Control-point sum of two compatible non-rational surfaces (same degrees, knots and
    /// grid): the surface whose every point is S1(u, v) + S2(u, v), as a vector sum.
    pub fn try_add(&self, o: &NurbsSurface) -> Result<NurbsSurface> {
        self.check_same_layout(o, "surface sum")?;
        let mut s = self.clone();
        for (a, b) in s.points.iter_mut().zip(&o.points) {
            *a = P3::from(a.coords + b.coords);
        }
        Ok(s)
    }

    /// Control-point difference S1 - S2 of compatible non-rational surfaces.
    pub fn try_sub(&self, o: &NurbsSurface) -> Result<NurbsSurface> {
        self.check_same_layout(o, "surface difference")?;
        let mut s = self.clone();
        for (a, b) in s.points.iter_mut().zip(&o.points) {
            *a = P3::from(a.coords - b.coords);
        }
        Ok(s)
    }
}

pub(crate) fn remap(knots: &mut [f64], (a, b): (f64, f64), (s, e): (f64, f64)) {
    let f = (e - s) / (b - a);
    for k in knots.iter_mut() {
        *k = if *k == a {
            s
        } else if *k == b {
            e
        } else {
            s + (*k - a) * f
        };
    }
}

/// Bring surfaces to common degrees and knot vectors (degree elevation, then refinement
/// after mapping every domain to [0, 1]) so they can be added or subtracted. Periodic flags
/// must agree per direction.
pub fn make_surfaces_compatible(surfs: &[NurbsSurface]) -> Result<Vec<NurbsSurface>> {
    if surfs.is_empty() {
        return Ok(vec![]);
    }
    let (pu, pv) = (surfs[0].periodic_u, surfs[0].periodic_v);
    if surfs
        .iter()
        .any(|s| (s.periodic_u, s.periodic_v) != (pu, pv))
    {
        return Err(NurbsError::Incompatible {
            what: "surfaces",
            reason: "periodic flags differ between surfaces".into(),
        });
    }
    let du = surfs.iter().map(|s| s.degree_u).max().unwrap();
    let dv = surfs.iter().map(|s| s.degree_v).max().unwrap();
    let mut v: Vec<NurbsSurface> = surfs
        .iter()
        .map(|s| {
            s.reparametrized((0.0, 1.0), (0.0, 1.0))
                .elevate_u(du - s.degree_u)
                .elevate_v(dv - s.degree_v)
        })
        .collect();
    let ku = super::skin::merged_knots(v.iter().map(|s| (&s.knots_u[..], s.degree_u, s.nu, pu)));
    let kv = super::skin::merged_knots(v.iter().map(|s| (&s.knots_v[..], s.degree_v, s.nv, pv)));
    for s in v.iter_mut() {
        let xu = super::skin::missing_knots(
            &super::skin::inner_knots(&s.knots_u, s.degree_u, s.nu, pu),
            &ku,
        );
        let xv = super::skin::missing_knots(
            &super::skin::inner_knots(&s.knots_v, s.degree_v, s.nv, pv),
            &kv,
        );
        *s = s.refine_u(&xu).refine_v(&xv);
    }
    // Snap to one knot vector per direction (values that matched within the tolerance).
    let (k0u, k0v) = (v[0].knots_u.clone(), v[0].knots_v.clone());
    for (i, s) in v.iter_mut().enumerate() {
        if s.knots_u.len() != k0u.len() || s.knots_v.len() != k0v.len() {
            return Err(NurbsError::Incompatible {
                what: "surfaces",
                reason: format!("surface {i} ended with different knot counts than surface 0"),
            });
        }
        s.knots_u.clone_from(&k0u);
        s.knots_v.clone_from(&k0v);
    }
    Ok(v)
}
