//! Fairness: the variation of curvature (and, for reference, its magnitude) of a fill, on
//! its slice grid while a blend is searched, and on the skinned surface for the figures.
//!
//! Minimum variation (the integral of the squared derivative of curvature along the
//! direction it is measured in) is what a last maker's eye reads as a calm surface: it does
//! not mind a well-rounded toe, only changes of rounding. Minimum energy (the integral of
//! squared curvature) flattens instead, and is kept as the reference the fairing paper
//! compares with.

use footscan_geom::nurbs::NurbsSurface;
use footscan_geom::{P3, V3};

/// The functional a fairing minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Functional {
    /// Sum of squared curvature derivatives along the two directions.
    Variation,
    /// Sum of squared curvatures along the two directions.
    Energy,
}

/// Signed normal curvature of the polygon a, b, c at b (the discrete curvature vector
/// projected on `n`), and the local arc element.
fn curv(a: &P3, b: &P3, c: &P3, n: &V3) -> (f64, f64) {
    let (e0, e1) = (b - a, c - b);
    let (l0, l1) = (e0.norm(), e1.norm());
    if l0 < 1e-12 || l1 < 1e-12 {
        return (0.0, 0.5 * (l0 + l1));
    }
    let k = 2.0 * (e1 / l1 - e0 / l0) / (l0 + l1);
    (k.dot(n), 0.5 * (l0 + l1))
}

/// The functional on a grid of slices `g[l][k]` (slice l, point k around a closed slice),
/// over the slices `from..=to` (the curvature derivative needs one more slice each side, so
/// give those in `g`). Normal curvatures are taken along the slice and across the slices,
/// which on a last are close to its principal directions.
pub fn grid_functional(g: &[Vec<P3>], from: usize, to: usize, f: Functional) -> f64 {
    let nl = g.len();
    let n = g[0].len();
    let from = from.max(1);
    let to = to.min(nl - 2);
    if to < from {
        return 0.0;
    }
    // Curvatures along (ku) and across (kv), with arc elements, on slices from-1..=to+1.
    let lo = from.saturating_sub(1).max(1);
    let hi = (to + 1).min(nl - 2);
    let mut ku = vec![vec![0.0; n]; nl];
    let mut kv = vec![vec![0.0; n]; nl];
    let mut su = vec![vec![0.0; n]; nl];
    let mut sv = vec![vec![0.0; n]; nl];
    for l in lo..=hi {
        for k in 0..n {
            let (km, kp) = ((k + n - 1) % n, (k + 1) % n);
            let nrm = (g[l][kp] - g[l][km]).cross(&(g[l + 1][k] - g[l - 1][k]));
            let nn = nrm.norm();
            if nn < 1e-15 {
                continue;
            }
            let nrm = nrm / nn;
            let (a, da) = curv(&g[l][km], &g[l][k], &g[l][kp], &nrm);
            let (b, db) = curv(&g[l - 1][k], &g[l][k], &g[l + 1][k], &nrm);
            ku[l][k] = a;
            su[l][k] = da;
            kv[l][k] = b;
            sv[l][k] = db;
        }
    }
    let mut total = 0.0;
    for l in from..=to {
        for k in 0..n {
            let (km, kp) = ((k + n - 1) % n, (k + 1) % n);
            let da = su[l][k] * sv[l][k];
            let term = match f {
                Functional::Energy => ku[l][k].powi(2) + kv[l][k].powi(2),
                Functional::Variation => {
                    let du = (ku[l][kp] - ku[l][km]) / (2.0 * su[l][k]).max(1e-12);
                    let dv = if l > lo && l < hi {
                        (kv[l + 1][k] - kv[l - 1][k]) / (2.0 * sv[l][k]).max(1e-12)
                    } else {
                        0.0
                    };
                    du * du + dv * dv
                }
            };
            total += term * da;
        }
    }
    total
}

/// Minimise `cost` over `x` in [0, 1]^n by greedy coordinate steps: each coordinate moved by
/// +-h while that lowers the cost, h halved when no move helps, down to `h_min`. Returns the
/// point, its cost and the number of evaluations.
pub fn greedy(
    x0: Vec<f64>,
    h0: f64,
    h_min: f64,
    cost: &dyn Fn(&[f64]) -> f64,
) -> (Vec<f64>, f64, usize) {
    let mut x = x0;
    let mut best = cost(&x);
    let mut evals = 1;
    let mut h = h0;
    while h >= h_min {
        let mut improved = false;
        for i in 0..x.len() {
            for dir in [1.0, -1.0] {
                let old = x[i];
                let new = (old + dir * h).clamp(0.0, 1.0);
                if new == old {
                    continue;
                }
                x[i] = new;
                let c = cost(&x);
                evals += 1;
                if c < best {
                    best = c;
                    improved = true;
                    break;
                }
                x[i] = old;
            }
        }
        if !improved {
            h *= 0.5;
        }
    }
    (x, best, evals)
}

/// Integrals over a surface patch of the squared curvature variation along the principal
/// directions, (dk1/ds1)^2 + (dk2/ds2)^2, and of k1^2 + k2^2, on an `nu` x `nv` midpoint grid.
/// Each derivative is a central difference of the principal curvature a short step either
/// side along its own direction (mapped to the parameters through the surface's first
/// derivatives). Units: 1/mm^2 and 1 (mm^-2 integrated over mm^2).
pub fn surface_fairness(s: &NurbsSurface, nu: usize, nv: usize) -> (f64, f64) {
    let (u0, u1) = s.domain_u();
    let (v0, v1) = s.domain_v();
    let (du, dv) = ((u1 - u0) / nu as f64, (v1 - v0) / nv as f64);
    let mut var = 0.0;
    let mut energy = 0.0;
    for i in 0..nu {
        let u = u0 + (i as f64 + 0.5) * du;
        for j in 0..nv {
            let v = v0 + (j as f64 + 0.5) * dv;
            let (dvar, de) = fairness_at(s, u, v, du, dv);
            energy += de;
            if let Some(dvar) = dvar {
                var += dvar;
            }
        }
    }
    (var, energy)
}

/// [`surface_fairness`]'s two integrands at (u, v) over a cell of `du` x `dv` in the
/// parameters: the curvature variation (None where the tangents are parallel) and the
/// curvature energy.
pub fn fairness_at(s: &NurbsSurface, u: f64, v: f64, du: f64, dv: f64) -> (Option<f64>, f64) {
    let (v0, v1) = s.domain_v();
    let step = 0.5; // mm along a principal direction
    let d = s.derivatives(u, v, 1);
    let (su, sv) = (d[1][0], d[0][1]);
    let area = su.cross(&sv).norm() * du * dv;
    let c = s.curvature(u, v);
    let energy = (c.k1 * c.k1 + c.k2 * c.k2) * area;
    // Parameter direction of a 3D tangent t: solve [su sv] (a, b) = t.
    let (e, f, g) = (su.dot(&su), su.dot(&sv), sv.dot(&sv));
    let det = e * g - f * f;
    if det.abs() < 1e-18 {
        return (None, energy);
    }
    let mut dk2 = 0.0;
    for (which, t) in [(1, c.dir1), (2, c.dir2)] {
        let (tu, tv) = (t.dot(&su), t.dot(&sv));
        let a = (g * tu - f * tv) / det;
        let b = (e * tv - f * tu) / det;
        let (ua, va) = (u + step * a, (v + step * b).clamp(v0, v1));
        let (ub, vb) = (u - step * a, (v - step * b).clamp(v0, v1));
        let ds = (s.point(ua, va) - s.point(ub, vb)).norm();
        if ds < 1e-9 {
            continue;
        }
        let (ca, cb) = (s.curvature(ua, va), s.curvature(ub, vb));
        let (ka, kb) = if which == 1 {
            (ca.k1, cb.k1)
        } else {
            (ca.k2, cb.k2)
        };
        dk2 += ((ka - kb) / ds).powi(2);
    }
    (Some(dk2 * area), energy)
}
