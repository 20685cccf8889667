//! The two gap-filling operators on slices: the linear morph between two boundary slices and
//! the discrete G1/G2 extension of a part past its last slice.
//!
//! A slice is a planar loop (or open curve) of points; all slices of a part carry the same
//! number of points, point i of one slice corresponding to point i of the next. The
//! extension takes a part's last three slices O, P, Q, equally spaced by d, and builds the
//! slice R at d/2 past Q (from a discrete tangent-plane condition) and S at d past Q (from a
//! discrete curvature condition), each point as close as possible to the previous slice on
//! the line of points that satisfy the condition. Neither depends on the step lengths.

use footscan_geom::{P3, V3};

/// The slices R (half a step past Q) and S (a whole step past Q) that extend O, P, Q.
#[derive(Debug, Clone)]
pub struct Extension {
    pub r: Vec<P3>,
    pub s: Vec<P3>,
    /// Points where the closed forms do not hold (the ends of an open slice, points whose
    /// neighbours coincide, and points the closed forms throw off, see [`extend`]).
    pub by_curve: usize,
    /// Which points were extended along their own curve (R and S both on it).
    pub on_curve: Vec<bool>,
}

/// Neighbour differences below this (mm) leave the direction along the slice undefined.
const TINY: f64 = 1e-9;

/// Farthest R_i may lie from Q_i, in steps |Q_i - P_i| (S_i twice as far) before the
/// closed forms are taken as broken at that point.
const REACH: f64 = 2.0;

/// Extend the slices `o`, `p`, `q` (in the order they run towards the gap, equally spaced)
/// by R and S. `closed` slices wrap around; open ones get their two end points by extending
/// the curve through O_i, P_i, Q_i.
///
/// R_i and S_i come from the closed forms (eq. 4-8). R_i (eq. 4) is the linear extension of
/// P_i Q_i: its chord from Q_i is the part's last chord, the discrete tangent condition, but it
/// falls short of a curved part by 3/8 of the second difference, and S_i, built on it to carry
/// the curvature, makes up for it: the slices Q, R, S, R', S', ... of repeated steps zig-zag
/// (the second differences of a parabola's extension alternate 0.5, -0.25, 0.125). The fill
/// keeps eq. 4's R in its first step, where the tangent condition holds the seam, and takes
/// [`Extension::r_on_quadratic`] after it.
///
/// Where the closed forms break at a point of a closed slice (R_i more than two steps from
/// Q_i, S_i more than four; the neighbours crowd or the slice kinks), the point moves by the
/// displacement of the nearest good points either side, interpolated by index: its own curve
/// extension lay millimetres from its neighbours' closed forms (dimples at the top of the
/// RoundTip fill). With no good point at all, and at the ends of an open slice, points are
/// extended along their own curve (R and S both on it).
pub fn extend(o: &[P3], p: &[P3], q: &[P3], closed: bool) -> Extension {
    let n = q.len();
    assert!(
        n >= 3 && o.len() == n && p.len() == n,
        "slices of unequal length"
    );
    let mut r = vec![P3::origin(); n];
    let mut s = vec![P3::origin(); n];
    let mut good = vec![false; n];
    let idx = |i: isize| -> Option<usize> {
        if closed {
            Some(i.rem_euclid(n as isize) as usize)
        } else if i < 0 || i >= n as isize {
            None
        } else {
            Some(i as usize)
        }
    };
    for i in 0..n {
        let (im, ip) = (idx(i as isize - 1), idx(i as isize + 1));
        let closed_form = match (im, ip) {
            (Some(im), Some(ip)) => {
                point_closed_form((&o[i], &p[i], &q[i]), (&p[im], &p[ip]), (&q[im], &q[ip]))
            }
            _ => None,
        };
        (r[i], s[i]) = closed_form.unwrap_or_else(|| by_curve_extension(&o[i], &p[i], &q[i]));
        good[i] = closed_form.is_some();
    }
    let by_curve = good.iter().filter(|&&g| !g).count();
    // Points extended along their own curve: R is already on that curve.
    let mut on_curve: Vec<bool> = good.iter().map(|&g| !g).collect();
    if closed && by_curve > 0 && by_curve < n {
        on_curve.fill(false);
        let (r0, s0) = (r.clone(), s.clone());
        for i in (0..n).filter(|&i| !good[i]) {
            let a = (1..n).find(|&a| good[(i + n - a) % n]).unwrap_or(n);
            let b = (1..n).find(|&b| good[(i + b) % n]).unwrap_or(n);
            let (j, k) = ((i + n - a) % n, (i + b) % n);
            let t = a as f64 / (a + b) as f64;
            r[i] = q[i] + (r0[j] - q[j]) * (1.0 - t) + (r0[k] - q[k]) * t;
            s[i] = q[i] + (s0[j] - q[j]) * (1.0 - t) + (s0[k] - q[k]) * t;
        }
    }
    Extension {
        r,
        s,
        by_curve,
        on_curve,
    }
}

impl Extension {
    /// R taken on the quadratic through P_i, Q_i and S_i, halfway between Q_i and S_i:
    /// (3 S_i + 6 Q_i - P_i) / 8 (points extended along their own curve keep their R, which
    /// is on it already). See [`extend`] for why the fill uses it after its first step.
    pub fn r_on_quadratic(&self, p: &[P3], q: &[P3]) -> Vec<P3> {
        (0..q.len())
            .map(|i| {
                if self.on_curve[i] {
                    self.r[i]
                } else {
                    P3::from((3.0 * self.s[i].coords + 6.0 * q[i].coords - p[i].coords) / 8.0)
                }
            })
            .collect()
    }
}

/// R_i and S_i from the closed forms, or None where Q's neighbours coincide.
///
/// Tangent condition: R_i - Q_i = (Q_i - P_i)/2 - gamma' b with b = Q_(i+1) - Q_(i-1) (the
/// step across the slices plus any slide along the slice); gamma' puts R_i nearest Q_i.
/// Curvature condition: S_i + a = eta' b, a collecting the second differences across the
/// slices, the mixed difference and the second difference along Q; eta' puts S_i nearest R_i.
fn point_closed_form(
    (o, p, q): (&P3, &P3, &P3),
    (pm, pp): (&P3, &P3),
    (qm, qp): (&P3, &P3),
) -> Option<(P3, P3)> {
    let b: V3 = qp - qm;
    let bb = b.norm_squared();
    if bb < TINY * TINY {
        return None;
    }
    let gamma = (q - p).dot(&b) / (2.0 * bb);
    let r = P3::from((3.0 * q.coords - p.coords) / 2.0 - gamma * b);
    let second_across = (o.coords + q.coords - 2.0 * p.coords) / 4.0;
    let mixed = (pp - pm - (qp - qm)) / 2.0;
    let along = qp.coords + qm.coords - 2.0 * q.coords;
    let a: V3 =
        (q.coords - 2.0 * r.coords) - second_across - gamma * mixed - 4.0 * gamma * gamma * along;
    let eta = (a + r.coords).dot(&b) / bb;
    let s = P3::from(eta * b - a);
    // A smooth part puts R about half a step and S about a step past Q. Where Q's
    // neighbours sit much closer than the step across the slices (the resampling crowds
    // points between near crossings, a blended slice carries a kink), the gamma'^2 term
    // divides by |b|^2 and the closed forms throw the point off by orders of magnitude,
    // which the next extension amplifies again; such a point is extended along its curve.
    let step = (q - p).norm();
    if (r - q).norm() > REACH * step || (s - q).norm() > 2.0 * REACH * step {
        return None;
    }
    Some((r, s))
}

/// R_i and S_i by extending the quadratic Bezier curve through O_i, P_i, Q_i (at parameters
/// 0, 1/2, 1) to the planes half a step and a whole step past Q_i.
///
/// With equal steps the curve's distance along the slice normal is linear in the parameter,
/// so the planes are met at parameters 5/4 and 3/2.
pub fn by_curve_extension(o: &P3, p: &P3, q: &P3) -> (P3, P3) {
    let b1 = P3::from(2.0 * p.coords - 0.5 * (o.coords + q.coords));
    let at = |t: f64| {
        let s = 1.0 - t;
        P3::from(s * s * o.coords + 2.0 * s * t * b1.coords + t * t * q.coords)
    };
    (at(1.25), at(1.5))
}

/// The point correspondence of the linear morph: the index shift k such that point i of
/// slice `a` goes with point (i + k) of slice `b`. An extreme point of `a` (the farthest
/// along `dir`) is matched to its nearest neighbour on `b`.
pub fn morph_shift(a: &[P3], b: &[P3], dir: &V3) -> usize {
    let ia = (0..a.len())
        .max_by(|&i, &j| a[i].coords.dot(dir).total_cmp(&a[j].coords.dot(dir)))
        .unwrap_or(0);
    let ib = (0..b.len())
        .min_by(|&i, &j| (b[i] - a[ia]).norm().total_cmp(&(b[j] - a[ia]).norm()))
        .unwrap_or(0);
    (ib + b.len() - ia) % b.len().max(1)
}

/// The linear morph between slices `a` (at position `za` along the slice normal) and `b`
/// (at `zb`), point by point, at position `z`: each segment A_i B_i cut by the plane at z.
pub fn morph(a: &[P3], za: f64, b: &[P3], zb: f64, z: f64) -> Vec<P3> {
    let t = (z - za) / (zb - za);
    a.iter().zip(b).map(|(pa, pb)| pa + (pb - pa) * t).collect()
}

/// `w` times `m` plus (1 - `w`) times `e`, point by point.
pub fn mix(m: &[P3], e: &[P3], w: f64) -> Vec<P3> {
    m.iter()
        .zip(e)
        .map(|(pm, pe)| P3::from(pm.coords * w + pe.coords * (1.0 - w)))
        .collect()
}
