//! Planar polygons in 2D (outlines of footprints, last bottoms and sections).

use crate::{P2, V2};

/// Turning sense of a polygon.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Orientation {
    CounterClockwise,
    Clockwise,
    /// Zero signed area.
    Degenerate,
}

/// A closed polygon (the last vertex joins the first; it is not repeated).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Polygon {
    pub points: Vec<P2>,
}

impl Polygon {
    pub fn new(points: Vec<P2>) -> Polygon {
        Polygon { points }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Edge `i` from vertex i to vertex i + 1 (cyclically).
    pub fn edge(&self, i: usize) -> (P2, P2) {
        (self.points[i], self.points[(i + 1) % self.points.len()])
    }

    /// Signed area by the shoelace formula, counterclockwise positive. Coordinates are taken
    /// relative to the first vertex, which keeps the sum accurate far from the origin.
    pub fn signed_area(&self) -> f64 {
        let n = self.points.len();
        if n < 3 {
            return 0.0;
        }
        let o = self.points[0];
        let mut s = 0.0;
        for i in 1..n - 1 {
            let a = self.points[i] - o;
            let b = self.points[i + 1] - o;
            s += a.x * b.y - a.y * b.x;
        }
        s / 2.0
    }

    pub fn area(&self) -> f64 {
        self.signed_area().abs()
    }

    pub fn orientation(&self) -> Orientation {
        let a = self.signed_area();
        if a > 0.0 {
            Orientation::CounterClockwise
        } else if a < 0.0 {
            Orientation::Clockwise
        } else {
            Orientation::Degenerate
        }
    }

    pub fn is_ccw(&self) -> bool {
        self.signed_area() > 0.0
    }

    pub fn reverse(&mut self) {
        self.points.reverse();
    }

    /// Makes the polygon counterclockwise (reversing it if clockwise).
    pub fn make_ccw(&mut self) {
        if self.signed_area() < 0.0 {
            self.reverse();
        }
    }

    pub fn perimeter(&self) -> f64 {
        (0..self.points.len())
            .map(|i| {
                let (a, b) = self.edge(i);
                (b - a).norm()
            })
            .sum()
    }

    /// Area centroid (centre of mass of the enclosed region); the vertex mean for a polygon
    /// of zero area.
    pub fn centroid(&self) -> P2 {
        let n = self.points.len();
        let o = self.points[0];
        let (mut cx, mut cy, mut a2) = (0.0, 0.0, 0.0);
        for i in 1..n.saturating_sub(1) {
            let p = self.points[i] - o;
            let q = self.points[i + 1] - o;
            let c = p.x * q.y - q.x * p.y;
            a2 += c;
            cx += (p.x + q.x) * c;
            cy += (p.y + q.y) * c;
        }
        if a2 == 0.0 {
            let s: V2 = self.points.iter().map(|p| p.coords).sum();
            return P2::from(s / n as f64);
        }
        o + V2::new(cx, cy) / (3.0 * a2)
    }

    /// Winding number of the polygon about `q` (counterclockwise turns positive); 0 outside.
    pub fn winding_number(&self, q: &P2) -> i32 {
        let n = self.points.len();
        let mut w = 0;
        for i in 0..n {
            let (a, b) = self.edge(i);
            let side = (b.x - a.x) * (q.y - a.y) - (q.x - a.x) * (b.y - a.y);
            if a.y <= q.y {
                if b.y > q.y && side > 0.0 {
                    w += 1;
                }
            } else if b.y <= q.y && side < 0.0 {
                w -= 1;
            }
        }
        w
    }

    /// Whether `q` is inside (non-zero winding). Points exactly on the boundary may go either
    /// way; use [`Polygon::distance_to_boundary`] when that matters.
    pub fn contains(&self, q: &P2) -> bool {
        self.winding_number(q) != 0
    }

    /// The boundary point nearest `q`, with the index of its edge.
    pub fn closest_boundary_point(&self, q: &P2) -> Option<(P2, usize)> {
        (0..self.points.len())
            .map(|i| {
                let (a, b) = self.edge(i);
                let d = b - a;
                let l2 = d.norm_squared();
                let t = if l2 > 0.0 {
                    ((q - a).dot(&d) / l2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                (a + d * t, i)
            })
            .min_by(|x, y| {
                (x.0 - q)
                    .norm_squared()
                    .total_cmp(&(y.0 - q).norm_squared())
            })
    }

    pub fn distance_to_boundary(&self, q: &P2) -> f64 {
        self.closest_boundary_point(q)
            .map_or(f64::INFINITY, |(p, _)| (p - q).norm())
    }

    /// Convex hull (Andrew's monotone chain), counterclockwise, collinear points dropped.
    pub fn convex_hull(&self) -> Polygon {
        convex_hull(&self.points)
    }

    /// The polygon scaled by `s` about `c`.
    pub fn scaled_about(&self, c: &P2, s: f64) -> Polygon {
        Polygon::new(self.points.iter().map(|p| c + (p - c) * s).collect())
    }

    /// The polygon scaled by (sx, sy) about `c` along the axes.
    pub fn scaled_xy_about(&self, c: &P2, sx: f64, sy: f64) -> Polygon {
        Polygon::new(
            self.points
                .iter()
                .map(|p| P2::new(c.x + (p.x - c.x) * sx, c.y + (p.y - c.y) * sy))
                .collect(),
        )
    }

    pub fn translated(&self, d: &V2) -> Polygon {
        Polygon::new(self.points.iter().map(|p| p + d).collect())
    }

    /// Each edge moved outward by `d` (inward for negative d), vertices at the intersection
    /// of the moved edges (mitre joins, the mitre capped at `4 |d|` from the vertex for very
    /// sharp corners). Outward is to the right of a counterclockwise polygon whatever this
    /// one's orientation. A simple offset: self-intersections from large inward offsets are
    /// not removed.
    pub fn offset(&self, d: f64) -> Polygon {
        let n = self.points.len();
        if n < 3 {
            return self.clone();
        }
        let sign = if self.signed_area() >= 0.0 { 1.0 } else { -1.0 };
        // Outward unit normal of edge i.
        let normal = |i: usize| -> V2 {
            let (a, b) = self.edge(i);
            let t = (b - a).try_normalize(0.0).unwrap_or(V2::zeros());
            V2::new(t.y, -t.x) * sign
        };
        let out = (0..n)
            .map(|i| {
                let n0 = normal((i + n - 1) % n);
                let n1 = normal(i);
                let m = n0 + n1;
                let c = 1.0 + n0.dot(&n1);
                // The mitre vector m d / (1 + n0.n1) reaches both offset edges.
                let v = if c > 1.0 / 8.0 {
                    m * (d / c)
                } else {
                    m.try_normalize(0.0).unwrap_or(n1) * (4.0 * d.abs()) * d.signum()
                };
                self.points[i] + v
            })
            .collect();
        Polygon::new(out)
    }

    /// Parameters t where the line `o + t dir` crosses the boundary (unsorted). A vertex
    /// exactly on the line counts as on its left side (as if the line were moved right by an
    /// infinitesimal amount), so crossings always come in pairs: a line through a vertex
    /// where the boundary crosses it counts once, and one touching a vertex counts twice (at
    /// the same t) or not at all.
    pub fn line_crossings(&self, o: &P2, dir: &V2) -> Vec<f64> {
        let n = crate::quarter_turn(dir);
        let mut ts = Vec::new();
        for i in 0..self.points.len() {
            let (a, b) = self.edge(i);
            let (sa, sb) = ((a - o).dot(&n), (b - o).dot(&n));
            if (sa < 0.0) != (sb < 0.0) {
                let f = sa / (sa - sb);
                let (ta, tb) = ((a - o).dot(dir), (b - o).dot(dir));
                ts.push(ta + f * (tb - ta));
            }
        }
        ts
    }

    /// Douglas-Peucker simplification of the closed polygon to `tol`: the ring is split at
    /// vertex 0 and the vertex farthest from it, and each half simplified; every dropped
    /// vertex is within `tol` of the kept outline.
    pub fn simplify(&self, tol: f64) -> Polygon {
        let p = &self.points;
        if p.len() < 4 {
            return self.clone();
        }
        let far = (1..p.len())
            .max_by(|&a, &b| {
                (p[a] - p[0])
                    .norm_squared()
                    .total_cmp(&(p[b] - p[0]).norm_squared())
            })
            .unwrap_or(1);
        let mut keep = vec![false; p.len() + 1];
        keep[0] = true;
        keep[far] = true;
        keep[p.len()] = true;
        let ring = |k: usize| p[k % p.len()];
        let mut stack = vec![(0, far), (far, p.len())];
        while let Some((a, b)) = stack.pop() {
            let (mut worst, mut at) = (0.0, 0);
            for k in a + 1..b {
                let d = segment_distance(&ring(k), &ring(a), &ring(b));
                if d > worst {
                    (worst, at) = (d, k);
                }
            }
            if worst > tol {
                keep[at] = true;
                stack.push((a, at));
                stack.push((at, b));
            }
        }
        Polygon::new((0..p.len()).filter(|&k| keep[k]).map(|k| p[k]).collect())
    }

    /// Index of the vertex farthest in direction `dir` (first of equals); None when empty.
    pub fn extreme_vertex(&self, dir: &V2) -> Option<usize> {
        (0..self.points.len()).reduce(|best, k| {
            if self.points[k].coords.dot(dir) > self.points[best].coords.dot(dir) {
                k
            } else {
                best
            }
        })
    }

    /// Bounding rectangle as (min, max); None when empty.
    pub fn bounds(&self) -> Option<(P2, P2)> {
        let first = *self.points.first()?;
        Some(
            self.points
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
        )
    }
}

/// Distance from `q` to the segment `a`-`b`.
pub fn segment_distance(q: &P2, a: &P2, b: &P2) -> f64 {
    let d = b - a;
    let l2 = d.norm_squared();
    let t = if l2 > 0.0 {
        ((q - a).dot(&d) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (q - (a + d * t)).norm()
}

/// Convex hull of a point set (Andrew's monotone chain), counterclockwise starting at the
/// lowest-then-leftmost point, collinear points dropped.
pub fn convex_hull(points: &[P2]) -> Polygon {
    let mut p: Vec<P2> = points.to_vec();
    p.sort_unstable_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    p.dedup();
    if p.len() < 3 {
        return Polygon::new(p);
    }
    let cross = |o: &P2, a: &P2, b: &P2| (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
    let mut h: Vec<P2> = Vec::with_capacity(2 * p.len());
    for q in p.iter() {
        while h.len() >= 2 && cross(&h[h.len() - 2], &h[h.len() - 1], q) <= 0.0 {
            h.pop();
        }
        h.push(*q);
    }
    let lower = h.len() + 1;
    for q in p.iter().rev().skip(1) {
        while h.len() >= lower && cross(&h[h.len() - 2], &h[h.len() - 1], q) <= 0.0 {
            h.pop();
        }
        h.push(*q);
    }
    h.pop();
    Polygon::new(h)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A polygon from literal `[x, y]` pairs.
    fn poly(p: &[[f64; 2]]) -> Polygon {
        Polygon::new(p.iter().map(|&q| P2::from(q)).collect())
    }

    fn circle(n: usize, r: f64, c: P2) -> Polygon {
        Polygon::new(
            (0..n)
                .map(|k| {
                    let a = std::f64::consts::TAU * k as f64 / n as f64;
                    c + V2::new(a.cos(), a.sin()) * r
                })
                .collect(),
        )
    }

    #[test]
    fn area_centroid_containment() {
        let sq = poly(&[[1.0, 1.0], [3.0, 1.0], [3.0, 2.0], [1.0, 2.0]]);
        assert_eq!(sq.signed_area(), 2.0);
        assert_eq!(sq.orientation(), Orientation::CounterClockwise);
        assert_eq!(sq.centroid(), P2::new(2.0, 1.5));
        assert_eq!(sq.perimeter(), 6.0);
        assert!(sq.contains(&P2::new(2.0, 1.5)));
        assert!(!sq.contains(&P2::new(0.0, 1.5)));
        let mut cw = sq.clone();
        cw.reverse();
        assert_eq!(cw.signed_area(), -2.0);
        assert_eq!(cw.winding_number(&P2::new(2.0, 1.5)), -1);
        assert!(cw.contains(&P2::new(2.0, 1.5)));
        cw.make_ccw();
        assert!(cw.is_ccw());
        assert_eq!(sq.points[2], P2::new(3.0, 2.0));
        // Far from the origin the shoelace stays exact.
        let far = sq.translated(&V2::new(1e7, -1e7));
        assert_eq!(far.signed_area(), 2.0);
    }

    #[test]
    fn hull_offset_scale_crossings_simplify() {
        let c = P2::new(5.0, -3.0);
        let ring = circle(400, 10.0, c);
        let mut pts = ring.points.clone();
        pts.push(c);
        pts.push(P2::new(6.0, -2.0));
        let hull = convex_hull(&pts);
        assert_eq!(hull.len(), 400);
        assert!(hull.is_ccw());
        let off = ring.offset(2.0);
        // The offset of a regular polygon is regular with apothem + 2.
        let apothem = 10.0 * (std::f64::consts::PI / 400.0).cos();
        let want = (apothem + 2.0) / apothem * 10.0;
        for p in &off.points {
            assert!(((p - c).norm() - want).abs() < 1e-9);
        }
        let mut rev = ring.clone();
        rev.reverse();
        assert!((rev.offset(2.0).area() - off.area()).abs() < 1e-9);
        let sc = ring.scaled_about(&c, 1.5);
        assert!((sc.area() - 2.25 * ring.area()).abs() < 1e-9);
        assert!((sc.centroid() - c).norm() < 1e-12);
        let t = ring.line_crossings(&c, &V2::new(0.6, 0.8));
        assert_eq!(t.len(), 2);
        assert!(((t[0] - t[1]).abs() - 20.0).abs() < 1e-2);
        let s = ring.simplify(0.05);
        assert!(s.len() < 100 && s.len() > 20, "{}", s.len());
        for p in &ring.points {
            assert!(s.distance_to_boundary(p) <= 0.05 + 1e-12);
        }
        assert_eq!(ring.extreme_vertex(&V2::new(1.0, 0.0)), Some(0));
        // A line through a vertex that it only touches is not a crossing.
        let tri = poly(&[[0.0, 0.0], [2.0, 0.0], [1.0, 1.0]]);
        let touch = tri.line_crossings(&P2::new(0.0, 1.0), &V2::new(1.0, 0.0));
        assert_eq!(touch, vec![1.0, 1.0]);
        assert_eq!(
            tri.line_crossings(&P2::new(0.0, 0.0), &V2::new(1.0, 0.0))
                .len(),
            0
        );
        assert_eq!(
            tri.line_crossings(&P2::new(0.0, 0.5), &V2::new(1.0, 0.0))
                .len(),
            2
        );
    }
}
