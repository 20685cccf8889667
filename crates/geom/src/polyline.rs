//! Open and closed polylines in 3D.

use crate::plane::Plane;
use crate::polygon::Polygon;
use crate::P3;

/// A polyline through `points`. A closed polyline joins the last point back to the first
/// (the first point is not repeated at the end).
#[derive(Debug, Clone, PartialEq)]
pub struct Polyline {
    pub points: Vec<P3>,
    pub closed: bool,
}

/// The point of a polyline nearest a query.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestOnPolyline {
    pub point: P3,
    pub distance: f64,
    /// Segment index: from `points[segment]` to the next point (cyclically when closed).
    pub segment: usize,
    /// Position along that segment, 0..=1.
    pub t: f64,
    /// Arc length from the first point to `point`.
    pub arc_length: f64,
}

impl Polyline {
    pub fn open(points: Vec<P3>) -> Polyline {
        Polyline {
            points,
            closed: false,
        }
    }

    pub fn closed(points: Vec<P3>) -> Polyline {
        Polyline {
            points,
            closed: true,
        }
    }

    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Number of segments (n - 1 open, n closed with at least two points).
    pub fn segment_count(&self) -> usize {
        match (self.points.len(), self.closed) {
            (0 | 1, _) => 0,
            (n, false) => n - 1,
            (n, true) => n,
        }
    }

    /// Segment `i` as its two end points.
    pub fn segment(&self, i: usize) -> (P3, P3) {
        (self.points[i], self.points[(i + 1) % self.points.len()])
    }

    /// Total length (including the closing segment of a closed polyline).
    pub fn length(&self) -> f64 {
        (0..self.segment_count())
            .map(|i| {
                let (a, b) = self.segment(i);
                (b - a).norm()
            })
            .sum()
    }

    /// Cumulative arc length at each point, plus the total at the end for a closed polyline
    /// (so the result has `segment_count() + 1` entries).
    pub fn cumulative_lengths(&self) -> Vec<f64> {
        let mut s = Vec::with_capacity(self.segment_count() + 1);
        let mut acc = 0.0;
        s.push(0.0);
        for i in 0..self.segment_count() {
            let (a, b) = self.segment(i);
            acc += (b - a).norm();
            s.push(acc);
        }
        s
    }

    /// The point at arc length `s` from the first point (clamped for open polylines, wrapped
    /// for closed ones).
    pub fn point_at(&self, s: f64) -> P3 {
        let cum = self.cumulative_lengths();
        self.point_at_with(&cum, s)
    }

    /// [`Polyline::point_at`] with the [`Polyline::cumulative_lengths`] computed once by the
    /// caller (many points along one polyline).
    pub fn point_at_with(&self, cum: &[f64], s: f64) -> P3 {
        let total = *cum.last().unwrap_or(&0.0);
        if self.points.len() < 2 || total == 0.0 {
            return self.points[0];
        }
        let s = if self.closed {
            s.rem_euclid(total)
        } else {
            s.clamp(0.0, total)
        };
        // First segment whose end is at or beyond s.
        let i = cum[1..].partition_point(|&c| c < s).min(cum.len() - 2);
        let (a, b) = self.segment(i);
        let l = cum[i + 1] - cum[i];
        let t = if l > 0.0 { (s - cum[i]) / l } else { 0.0 };
        a + (b - a) * t
    }

    /// `n` points equally spaced in arc length. Open: from the first point to the last,
    /// both included. Closed: starting at the first point, spacing length / n (the result is
    /// again a closed polyline of n points).
    pub fn resample(&self, n: usize) -> Polyline {
        assert!(!self.points.is_empty(), "resample of an empty polyline");
        let cum = self.cumulative_lengths();
        let total = *cum.last().unwrap();
        let pts = (0..n)
            .map(|k| {
                let s = if self.closed {
                    total * k as f64 / n as f64
                } else if n > 1 {
                    total * k as f64 / (n - 1) as f64
                } else {
                    0.0
                };
                self.point_at_with(&cum, s)
            })
            .collect();
        Polyline {
            points: pts,
            closed: self.closed,
        }
    }

    /// The nearest point to `q` on the polyline; None when it has no points.
    pub fn closest_point(&self, q: &P3) -> Option<ClosestOnPolyline> {
        if self.points.is_empty() {
            return None;
        }
        if self.points.len() == 1 {
            return Some(ClosestOnPolyline {
                point: self.points[0],
                distance: (q - self.points[0]).norm(),
                segment: 0,
                t: 0.0,
                arc_length: 0.0,
            });
        }
        let mut best: Option<ClosestOnPolyline> = None;
        let mut s0 = 0.0;
        for i in 0..self.segment_count() {
            let (a, b) = self.segment(i);
            let d = b - a;
            let l2 = d.norm_squared();
            let t = if l2 > 0.0 {
                ((q - a).dot(&d) / l2).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let p = a + d * t;
            let dist = (q - p).norm();
            if best.is_none_or(|b| dist < b.distance) {
                best = Some(ClosestOnPolyline {
                    point: p,
                    distance: dist,
                    segment: i,
                    t,
                    arc_length: s0 + t * l2.sqrt(),
                });
            }
            s0 += l2.sqrt();
        }
        best
    }

    /// Length-weighted centroid of the polyline's segments (its centre of mass as a wire);
    /// the first point for a polyline of zero length.
    pub fn centroid(&self) -> P3 {
        let mut acc = crate::V3::zeros();
        let mut total = 0.0;
        for i in 0..self.segment_count() {
            let (a, b) = self.segment(i);
            let l = (b - a).norm();
            acc += (a.coords + b.coords) * (0.5 * l);
            total += l;
        }
        if total > 0.0 {
            P3::from(acc / total)
        } else {
            self.points[0]
        }
    }

    /// Mean of the points.
    pub fn vertex_mean(&self) -> P3 {
        let s: crate::V3 = self.points.iter().map(|p| p.coords).sum();
        P3::from(s / self.points.len() as f64)
    }

    /// The polyline reversed in place (a closed one keeps its first point first).
    pub fn reverse(&mut self) {
        self.points.reverse();
        if self.closed && !self.points.is_empty() {
            self.points.rotate_right(1);
        }
    }

    /// The points in the local frame of `plane`, as a 2D polygon (projection onto the plane).
    pub fn to_polygon(&self, plane: &Plane) -> Polygon {
        Polygon::new(self.points.iter().map(|p| plane.to_local(p)).collect())
    }

    /// Largest distance of a point from `plane`.
    pub fn max_plane_distance(&self, plane: &Plane) -> f64 {
        self.points
            .iter()
            .map(|p| plane.signed_distance(p).abs())
            .fold(0.0, f64::max)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Polyline {
        Polyline::closed(vec![
            P3::new(0.0, 0.0, 0.0),
            P3::new(2.0, 0.0, 0.0),
            P3::new(2.0, 2.0, 0.0),
            P3::new(0.0, 2.0, 0.0),
        ])
    }

    #[test]
    fn lengths_resampling_closest() {
        let sq = square();
        assert_eq!(sq.length(), 8.0);
        let mut open = sq.clone();
        open.closed = false;
        assert_eq!(open.length(), 6.0);
        let r = sq.resample(8);
        assert_eq!(r.len(), 8);
        assert!((r.points[1] - P3::new(1.0, 0.0, 0.0)).norm() < 1e-15);
        assert!((r.points[7] - P3::new(0.0, 1.0, 0.0)).norm() < 1e-15);
        let ro = open.resample(7);
        assert_eq!(ro.points[0], open.points[0]);
        assert!((ro.points[6] - open.points[3]).norm() < 1e-15);
        let c = sq.closest_point(&P3::new(-1.0, 1.5, 3.0)).unwrap();
        assert_eq!(c.segment, 3);
        assert!((c.point - P3::new(0.0, 1.5, 0.0)).norm() < 1e-15);
        assert!((c.arc_length - 6.5).abs() < 1e-12);
        assert!((c.distance - 10f64.sqrt()).abs() < 1e-12);
        assert!((sq.centroid() - P3::new(1.0, 1.0, 0.0)).norm() < 1e-15);
        assert_eq!(sq.point_at(-1.0), P3::new(0.0, 1.0, 0.0));
        let mut rev = sq.clone();
        rev.reverse();
        assert_eq!(rev.points[0], sq.points[0]);
        assert_eq!(rev.points[1], sq.points[3]);
        let poly = sq.to_polygon(&Plane::axis_aligned(2, 0.0));
        assert_eq!(poly.signed_area(), 4.0);
    }
}
