//! Outlines: the landmark rules shared by foot and last bottom, the foot's sole envelope,
//! arc-length correspondence between two outlines, and contour smoothing.

use super::side::Side;
use footscan_geom::polygon::convex_hull;
use footscan_geom::{dist_by_hypot, quarter_turn, P2, V2};

/// Signed area (counterclockwise positive).
pub fn signed_area(p: &[P2]) -> f64 {
    let n = p.len();
    let o = p.first().copied().unwrap_or(P2::origin());
    (0..n)
        .map(|i| (p[i] - o).perp(&(p[(i + 1) % n] - o)))
        .sum::<f64>()
        / 2.0
}

/// Makes `p` counterclockwise.
pub fn make_ccw(p: &mut [P2]) {
    if signed_area(p) < 0.0 {
        p.reverse();
    }
}

/// Perimeter of a closed outline.
pub fn perimeter(p: &[P2]) -> f64 {
    let n = p.len();
    (0..n).map(|i| dist_by_hypot(&p[i], &p[(i + 1) % n])).sum()
}

/// `n` points at equal arc-length steps around the closed outline, starting at vertex 0.
/// A fixed count (not a fixed step) keeps the result exactly similar under scaling.
pub fn resample_closed(p: &[P2], n: usize) -> Vec<P2> {
    let m = p.len();
    let total = perimeter(p);
    let mut out = Vec::with_capacity(n);
    let (mut k, mut acc) = (0usize, 0.0);
    for q in 0..n {
        let target = total * q as f64 / n as f64;
        while k < m {
            let l = dist_by_hypot(&p[k], &p[(k + 1) % m]);
            if acc + l >= target || k == m - 1 {
                let t = if l > 0.0 {
                    ((target - acc) / l).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let (a, b) = (p[k], p[(k + 1) % m]);
                out.push(a + (b - a) * t);
                break;
            }
            acc += l;
            k += 1;
        }
    }
    out
}

/// Area, area centroid and principal (long) axis of the region a closed outline bounds.
pub fn moments(p: &[P2]) -> (f64, P2, V2) {
    let n = p.len();
    let o = p[0];
    let (mut a2, mut cx, mut cy, mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for i in 0..n {
        let (a, b) = (p[i] - o, p[(i + 1) % n] - o);
        let w = a.perp(&b);
        a2 += w;
        cx += (a.x + b.x) * w;
        cy += (a.y + b.y) * w;
        sxx += (a.x * a.x + a.x * b.x + b.x * b.x) * w;
        syy += (a.y * a.y + a.y * b.y + b.y * b.y) * w;
        sxy += (a.x * b.y + 2.0 * a.x * a.y + 2.0 * b.x * b.y + b.x * a.y) * w;
    }
    let area = a2 / 2.0;
    let (mx, my) = (cx / (3.0 * a2), cy / (3.0 * a2));
    // Second moments about the centroid.
    let ixx = sxx / 12.0 - area * mx * mx;
    let iyy = syy / 12.0 - area * my * my;
    let ixy = sxy / 24.0 - area * mx * my;
    let angle = 0.5 * (2.0 * ixy).atan2(ixx - iyy);
    (area, o + V2::new(mx, my), V2::new(angle.cos(), angle.sin()))
}

/// Landmarks of an outline by the operational rules used for foot and last bottom alike.
///
/// Axis: the principal axis of the bounded region through its centroid, pointing the way
/// `forward` points (heel to toe). Heel point / toe tip: rearmost / foremost outline points
/// along the axis. Ball points: the widest points (farthest from the axis on each side) in
/// the front 60 % of the length. Medial side: the side whose ball point lies further
/// forward (the first metatarsal head is ahead of the fifth), unless `side` is given.
/// Waist points: the outline points nearest the axis on each side between 20 % of the
/// length and that side's ball point. Every rule is a vertex extreme, so the landmarks of
/// a scaled, moved copy of an outline are the scaled, moved landmarks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutlineLandmarks {
    pub centre: P2,
    pub axis: V2,
    pub length: f64,
    pub side: Side,
    pub heel: P2,
    pub toe: P2,
    pub ball_medial: P2,
    pub ball_lateral: P2,
    pub waist_medial: P2,
    pub waist_lateral: P2,
}

impl OutlineLandmarks {
    /// The landmarks in the order used for correspondence and reports.
    pub fn named(&self) -> [(&'static str, P2); 6] {
        [
            ("heel point", self.heel),
            ("toe tip", self.toe),
            ("MT1 / medial ball", self.ball_medial),
            ("MT5 / lateral ball", self.ball_lateral),
            ("inner waist", self.waist_medial),
            ("outer waist", self.waist_lateral),
        ]
    }
}

pub fn outline_landmarks(
    p: &[P2],
    forward: V2,
    side: Option<Side>,
) -> Result<OutlineLandmarks, String> {
    if p.len() < 8 {
        return Err(format!("{} outline points; need at least 8", p.len()));
    }
    let (area, c, mut u) = moments(p);
    if area.abs().is_nan() || area.abs() <= 100.0 {
        return Err(format!("outline area {:.1} mm^2 is too small", area.abs()));
    }
    if u.dot(&forward) < 0.0 {
        u = -u;
    }
    let v = quarter_turn(&u);
    let s = |q: P2| (q - c).dot(&u);
    let t = |q: P2| (q - c).dot(&v);
    let arg = |keep: &dyn Fn(P2) -> bool, key: &dyn Fn(P2) -> f64| -> Option<P2> {
        p.iter()
            .copied()
            .filter(|&q| keep(q))
            .max_by(|a, b| key(*a).total_cmp(&key(*b)))
    };
    let heel = arg(&|_| true, &|q| -s(q)).unwrap();
    let toe = arg(&|_| true, &|q| s(q)).unwrap();
    let (s0, length) = (s(heel), s(toe) - s(heel));
    let fore = |q: P2| s(q) - s0 >= 0.4 * length;
    let left = arg(&fore, &|q| t(q)).ok_or("no forepart outline point")?;
    let right = arg(&fore, &|q| -t(q)).ok_or("no forepart outline point")?;
    let side = side.unwrap_or(if s(left) >= s(right) {
        Side::Right
    } else {
        Side::Left
    });
    // A right foot has its medial side to the left of the heel-to-toe axis.
    let (ball_medial, ball_lateral, sign) = match side {
        Side::Right => (left, right, 1.0),
        Side::Left => (right, left, -1.0),
    };
    let waist = |ball: P2, sgn: f64| {
        arg(
            &|q| sgn * t(q) > 0.0 && s(q) - s0 >= 0.2 * length && s(q) <= s(ball),
            &|q| -sgn * t(q),
        )
    };
    let waist_medial = waist(ball_medial, sign).ok_or("no inner waist point")?;
    let waist_lateral = waist(ball_lateral, -sign).ok_or("no outer waist point")?;
    Ok(OutlineLandmarks {
        centre: c,
        axis: u,
        length,
        side,
        heel,
        toe,
        ball_medial,
        ball_lateral,
        waist_medial,
        waist_lateral,
    })
}

/// The sole outline a last bottom must cover: the foot's body outline behind `cut` (an
/// axis position, e.g. the rearmost ball point), and in front of it the convex hull of the
/// body's forepart and the toe pads, which closes the gaps between the toes the way a last
/// bottom does. Counterclockwise.
pub fn sole_envelope(body: &[P2], toes: &[Vec<P2>], axis: V2, cut_point: P2) -> Vec<P2> {
    let mut body = body.to_vec();
    make_ccw(&mut body);
    if toes.iter().all(|t| t.is_empty()) {
        return body;
    }
    let cut = cut_point.coords.dot(&axis);
    let front: Vec<P2> = body
        .iter()
        .chain(toes.iter().flatten())
        .filter(|q| q.coords.dot(&axis) >= cut)
        .copied()
        .collect();
    let hull = convex_hull(&front).points;
    let n = body.len();
    let behind = |q: P2| q.coords.dot(&axis) < cut;
    // The rear chain: from the first vertex after the forepart run to the last before it.
    let Some(start) = (0..n).find(|&i| behind(body[i]) && !behind(body[(i + n - 1) % n])) else {
        return body;
    };
    let mut out = Vec::with_capacity(n + hull.len());
    let mut i = start;
    while behind(body[i]) {
        out.push(body[i]);
        i = (i + 1) % n;
        if i == start {
            break;
        }
    }
    // The front: the hull counterclockwise from where the body enters the forepart (the
    // first body vertex after the rear chain) to where it leaves it (the last before the
    // chain). Both are the body's widest points at the cut, so hull vertices or next to one.
    // (Every hull point is in front of the cut, so the cut cannot be found on the hull.)
    let (entry, exit) = (body[i], body[(start + n - 1) % n]);
    let h = hull.len();
    let nearest = |q: P2| {
        (0..h)
            .min_by(|&a, &b| dist_by_hypot(&hull[a], &q).total_cmp(&dist_by_hypot(&hull[b], &q)))
            .unwrap_or(0)
    };
    if h > 0 {
        let (ke, kx) = (nearest(entry), nearest(exit));
        let mut k = ke;
        loop {
            out.push(hull[k]);
            if k == kx {
                break;
            }
            k = (k + 1) % h;
        }
    }
    out
}

/// Nearest point of the closed outline to `q`: (point, edge index, position along the edge
/// in [0, 1], distance).
pub fn closest_on(p: &[P2], q: P2) -> (P2, usize, f64, f64) {
    let n = p.len();
    let mut best = (p[0], 0, 0.0, f64::INFINITY);
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        let ab = b - a;
        let l2 = ab.dot(&ab);
        let t = if l2 > 0.0 {
            ((q - a).dot(&ab) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let x = a + ab * t;
        let d = dist_by_hypot(&x, &q);
        if d < best.3 {
            best = (x, i, t, d);
        }
    }
    best
}

/// Distance from `q` to the closed outline.
pub fn distance_to(p: &[P2], q: P2) -> f64 {
    closest_on(p, q).3
}

/// Cumulative arc length at each vertex (entry n = perimeter).
fn cumulative(p: &[P2]) -> Vec<f64> {
    let n = p.len();
    let mut c = Vec::with_capacity(n + 1);
    c.push(0.0);
    for i in 0..n {
        c.push(c[i] + dist_by_hypot(&p[i], &p[(i + 1) % n]));
    }
    c
}

/// Arc-length position of the point nearest `q` on the outline.
pub fn arc_position(p: &[P2], cum: &[f64], q: P2) -> f64 {
    let (_, i, t, _) = closest_on(p, q);
    cum[i] + t * (cum[i + 1] - cum[i])
}

/// The outline point at arc-length position `a` (taken modulo the perimeter).
pub fn point_at(p: &[P2], cum: &[f64], a: f64) -> P2 {
    let n = p.len();
    let total = cum[n];
    let a = a.rem_euclid(total);
    let i = match cum.binary_search_by(|x| x.total_cmp(&a)) {
        Ok(i) => i.min(n - 1),
        Err(i) => i.saturating_sub(1).min(n - 1),
    };
    let l = cum[i + 1] - cum[i];
    let t = if l > 0.0 { (a - cum[i]) / l } else { 0.0 };
    let (x, y) = (p[i], p[(i + 1) % n]);
    x + (y - x) * t
}

/// Corresponding points on two closed outlines: both are cut at matching landmarks (given
/// in the same order on each), and every piece between two landmarks is sampled at the same
/// arc-length fractions, about `spacing` mm apart on `b`. Returns (points on `a`, points on
/// `b`, index of each landmark in the lists). Fails when the landmarks do not come in the
/// same cyclic order on both outlines.
/// Matched points on two outlines and the index of each landmark among them.
pub type Correspondence = (Vec<P2>, Vec<P2>, Vec<usize>);

pub fn correspond(
    a: &[P2],
    la: &[P2],
    b: &[P2],
    lb: &[P2],
    spacing: f64,
) -> Result<Correspondence, String> {
    let (ca, cb) = (cumulative(a), cumulative(b));
    let pa: Vec<f64> = la.iter().map(|&q| arc_position(a, &ca, q)).collect();
    let pb: Vec<f64> = lb.iter().map(|&q| arc_position(b, &cb, q)).collect();
    let order = |pos: &[f64]| {
        let mut o: Vec<usize> = (0..pos.len()).collect();
        o.sort_by(|&x, &y| pos[x].total_cmp(&pos[y]));
        o
    };
    let (oa, ob) = (order(&pa), order(&pb));
    // Same cyclic order: ob is a rotation of oa.
    let r = ob.iter().position(|&k| k == oa[0]).unwrap();
    let rotated: Vec<usize> = (0..ob.len()).map(|k| ob[(k + r) % ob.len()]).collect();
    if rotated != oa {
        return Err(format!(
            "the landmarks run around the two outlines in different orders ({oa:?} and {ob:?})"
        ));
    }
    let (ta, tb) = (ca[a.len()], cb[b.len()]);
    let (mut xa, mut xb, mut idx) = (Vec::new(), Vec::new(), vec![0; la.len()]);
    let m = oa.len();
    for k in 0..m {
        let (l0, l1) = (oa[k], oa[(k + 1) % m]);
        let (a0, mut a1) = (pa[l0], pa[l1]);
        let (b0, mut b1) = (pb[l0], pb[l1]);
        if a1 <= a0 {
            a1 += ta;
        }
        if b1 <= b0 {
            b1 += tb;
        }
        let pieces = (((b1 - b0) / spacing).round() as usize).max(1);
        idx[l0] = xa.len();
        for q in 0..pieces {
            let f = q as f64 / pieces as f64;
            xa.push(point_at(a, &ca, a0 + f * (a1 - a0)));
            xb.push(point_at(b, &cb, b0 + f * (b1 - b0)));
        }
    }
    Ok((xa, xb, idx))
}

/// Taubin's lambda/mu smoothing of a closed point loop: a shrinking Laplacian step (lambda)
/// then an inflating one (mu < -lambda), which removes short wiggles without the steady
/// shrinkage of plain Laplacian averaging. `pinned` points do not move. The loop is of
/// vectors: displacements, or positions from the origin.
pub fn taubin(p: &mut [V2], pinned: &[bool], iterations: usize, lambda: f64, mu: f64) {
    let n = p.len();
    let mut next = p.to_vec();
    for _ in 0..iterations {
        for f in [lambda, mu] {
            for i in 0..n {
                if pinned[i] {
                    continue;
                }
                let (a, b) = (p[(i + n - 1) % n], p[(i + 1) % n]);
                let lap = (a + b) * 0.5 - p[i];
                next[i] = p[i] + lap * f;
            }
            p.copy_from_slice(&next);
        }
    }
}

/// The plantar scanner paper's contour smoothing, each point replaced by the mean of its two
/// neighbours (y_i = (y_(i-1) + y_(i+1)) / 2), applied to both coordinates, `iterations`
/// times (Jacobi). Kept to measure its shrinkage.
pub fn neighbour_mean(p: &mut [V2], iterations: usize) {
    let n = p.len();
    for _ in 0..iterations {
        let prev = p.to_vec();
        for i in 0..n {
            p[i] = (prev[(i + n - 1) % n] + prev[(i + 1) % n]) * 0.5;
        }
    }
}

/// Largest positive parameter t at which the ray `c + t d` crosses the closed outline.
pub fn ray_exit(p: &[P2], c: P2, d: V2) -> Option<f64> {
    let n = p.len();
    let mut best: Option<f64> = None;
    for i in 0..n {
        let (a, b) = (p[i], p[(i + 1) % n]);
        let e = b - a;
        let den = d.perp(&e);
        if den.abs() < 1e-15 {
            continue;
        }
        let ac = a - c;
        let t = ac.perp(&e) / den;
        let s = ac.perp(&d) / den;
        if (0.0..=1.0).contains(&s) && t > 0.0 && best.is_none_or(|b| t > b) {
            best = Some(t);
        }
    }
    best
}

/// For each grid row, the cells whose centres are inside the closed outline (even-odd rule
/// on the row's crossings): a mask over `nx * ny` cells.
pub fn inside_mask(p: &[P2], x0: f64, y0: f64, cell: f64, nx: usize, ny: usize) -> Vec<bool> {
    let mut mask = vec![false; nx * ny];
    let n = p.len();
    let mut xs = Vec::new();
    for j in 0..ny {
        let y = y0 + j as f64 * cell;
        xs.clear();
        for i in 0..n {
            let (a, b) = (p[i], p[(i + 1) % n]);
            if (a.y <= y) != (b.y <= y) {
                xs.push(a.x + (y - a.y) / (b.y - a.y) * (b.x - a.x));
            }
        }
        xs.sort_by(f64::total_cmp);
        for pair in xs.chunks_exact(2) {
            let i0 = ((pair[0] - x0) / cell).ceil().max(0.0) as usize;
            let i1 = ((pair[1] - x0) / cell).floor();
            if i1 < 0.0 {
                continue;
            }
            for i in i0..=(i1 as usize).min(nx.saturating_sub(1)) {
                mask[j * nx + i] = true;
            }
        }
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(r: f64, n: usize) -> Vec<P2> {
        (0..n)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                P2::new(r * a.cos(), r * a.sin())
            })
            .collect()
    }

    /// A foot-like body (an ellipse, heel at x = 0, toe-less front at x = 200) with five
    /// separate toe pads in front of it, as the scanner measures them: the envelope keeps the
    /// body behind the cut and closes over the pads in front, and every pad lies inside it.
    #[test]
    fn sole_envelope_closes_over_separate_toe_pads() {
        let body: Vec<P2> = circle(1.0, 400)
            .iter()
            .map(|q| P2::new(100.0 + 100.0 * q.x, 40.0 * q.y))
            .collect();
        let pads: Vec<Vec<P2>> = (0..5)
            .map(|k| {
                let c = V2::new(215.0 - 6.0 * k as f64, 25.0 - 12.0 * k as f64);
                circle(5.0, 40).iter().map(|q| q + c).collect()
            })
            .collect();
        let env = sole_envelope(&body, &pads, V2::x(), P2::new(160.0, 35.0));
        assert!(signed_area(&env) > signed_area(&body), "the pads add area");
        let xmax = env.iter().map(|p| p.x).fold(f64::MIN, f64::max);
        assert!(
            (xmax - 220.0).abs() < 0.1,
            "front at the hallux pad's tip: {xmax}"
        );
        let poly = footscan_geom::polygon::Polygon::new(env.clone());
        for q in pads.iter().flatten().chain(body.iter()) {
            assert!(
                poly.contains(q) || distance_to(&env, *q) < 1e-9,
                "{q:?} outside the envelope"
            );
        }
        // Behind the cut the envelope is the body itself.
        for p in env.iter().filter(|p| p.x < 150.0) {
            assert!(distance_to(&body, *p) < 1e-9);
        }
    }

    #[test]
    fn moments_of_a_rotated_rectangle() {
        let a = 0.3f64;
        let (u, v) = (V2::new(a.cos(), a.sin()), V2::new(-a.sin(), a.cos()));
        let c0 = P2::new(5.0, 7.0);
        let p: Vec<P2> = [[-50.0, -10.0], [50.0, -10.0], [50.0, 10.0], [-50.0, 10.0]]
            .iter()
            .map(|q| c0 + (u * q[0] + v * q[1]))
            .collect();
        let (area, c, axis) = moments(&p);
        assert!((area - 2000.0).abs() < 1e-9);
        assert!(dist_by_hypot(&c, &c0) < 1e-9);
        assert!(axis.perp(&u).abs() < 1e-12);
    }

    #[test]
    fn taubin_keeps_a_circle_where_the_neighbour_mean_shrinks_it() {
        let r = 50.0;
        let mut a: Vec<V2> = circle(r, 100).iter().map(|p| p.coords).collect();
        let mut b = a.clone();
        neighbour_mean(&mut a, 10);
        taubin(&mut b, &[false; 100], 10, 0.5, -0.53);
        let ra = a.iter().map(|q| q.x.hypot(q.y)).sum::<f64>() / 100.0;
        let rb = b.iter().map(|q| q.x.hypot(q.y)).sum::<f64>() / 100.0;
        // Each pass multiplies the radius by cos(2 pi / n).
        let expect = r * (std::f64::consts::TAU / 100.0).cos().powi(10);
        assert!((ra - expect).abs() < 1e-9, "{ra} {expect}");
        assert!(r - ra > 0.97, "neighbour mean shrinks by {}", r - ra);
        assert!(
            (r - rb).abs() < 0.05,
            "taubin changes the radius by {}",
            r - rb
        );
    }

    #[test]
    fn inside_mask_counts_a_disc() {
        let c = circle(10.0, 400);
        let m = inside_mask(&c, -12.0, -12.0, 0.1, 241, 241);
        let area = m.iter().filter(|&&b| b).count() as f64 * 0.01;
        assert!((area - std::f64::consts::PI * 100.0).abs() < 0.5, "{area}");
    }
}
