//! Axis-aligned bounding boxes.

use crate::{P3, V3};

/// An axis-aligned box `[min, max]`. The empty box has `min = +inf`, `max = -inf`, so
/// extending it by any point gives that point's box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: P3,
    pub max: P3,
}

impl Default for Aabb {
    fn default() -> Self {
        Aabb::empty()
    }
}

impl Aabb {
    pub fn empty() -> Aabb {
        Aabb {
            min: P3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
            max: P3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
        }
    }

    pub fn new(min: P3, max: P3) -> Aabb {
        Aabb { min, max }
    }

    /// The smallest box holding every point (empty for no points).
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a P3>) -> Aabb {
        let mut b = Aabb::empty();
        for p in points {
            b.extend(p);
        }
        b
    }

    pub fn is_empty(&self) -> bool {
        (0..3).any(|k| self.min[k] > self.max[k])
    }

    pub fn extend(&mut self, p: &P3) {
        self.min = self.min.inf(p);
        self.max = self.max.sup(p);
    }

    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            min: self.min.inf(&o.min),
            max: self.max.sup(&o.max),
        }
    }

    /// Size along x, y, z (zero for the empty box).
    pub fn extent(&self) -> V3 {
        if self.is_empty() {
            V3::zeros()
        } else {
            self.max - self.min
        }
    }

    /// The longest side.
    pub fn longest_extent(&self) -> f64 {
        self.extent().max()
    }

    /// Index (0, 1, 2) of the longest side.
    pub fn longest_axis(&self) -> usize {
        self.extent().imax()
    }

    pub fn center(&self) -> P3 {
        nalgebra::center(&self.min, &self.max)
    }

    pub fn diagonal(&self) -> f64 {
        self.extent().norm()
    }

    /// Surface area (the cost measure of a bounding-volume tree).
    pub fn surface_area(&self) -> f64 {
        let e = self.extent();
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    /// The box grown by `d` on every side.
    pub fn inflated(&self, d: f64) -> Aabb {
        let v = V3::repeat(d);
        Aabb {
            min: self.min - v,
            max: self.max + v,
        }
    }

    pub fn contains(&self, p: &P3) -> bool {
        (0..3).all(|k| p[k] >= self.min[k] && p[k] <= self.max[k])
    }

    pub fn intersects(&self, o: &Aabb) -> bool {
        (0..3).all(|k| self.min[k] <= o.max[k] && o.min[k] <= self.max[k])
    }

    /// Squared distance from `p` to the box (0 inside).
    pub fn distance_squared(&self, p: &P3) -> f64 {
        (0..3)
            .map(|k| {
                let d = (self.min[k] - p[k]).max(p[k] - self.max[k]).max(0.0);
                d * d
            })
            .sum()
    }

    /// The entry and exit parameters of the ray `o + t d` (t in [t_min, t_max]) through the
    /// box (slab method); None when it misses. `inv_d` is `1 / d` per component.
    pub fn ray_interval(&self, o: &P3, inv_d: &V3, t_min: f64, t_max: f64) -> Option<(f64, f64)> {
        let (mut t0, mut t1) = (t_min, t_max);
        for k in 0..3 {
            if inv_d[k].is_infinite() {
                // Parallel to the slab: inside it (faces included) for every t, or never.
                // The product form would give 0 x inf = NaN for an origin on a face, and
                // the NaN ordered the bounds as (inf, NaN): a ray lying on a face missed.
                if o[k] < self.min[k] || o[k] > self.max[k] {
                    return None;
                }
                continue;
            }
            let a = (self.min[k] - o[k]) * inv_d[k];
            let b = (self.max[k] - o[k]) * inv_d[k];
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            t0 = t0.max(lo);
            t1 = t1.min(hi);
            if t0 > t1 {
                return None;
            }
        }
        Some((t0, t1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_queries() {
        let b = Aabb::from_points(&[P3::new(0.0, 0.0, 0.0), P3::new(2.0, 1.0, 4.0)]);
        assert_eq!(b.extent(), V3::new(2.0, 1.0, 4.0));
        assert_eq!(b.longest_axis(), 2);
        assert!(b.contains(&P3::new(1.0, 1.0, 1.0)));
        assert_eq!(b.distance_squared(&P3::new(3.0, 2.0, 2.0)), 2.0);
        assert!(Aabb::empty().is_empty());
        assert_eq!(Aabb::empty().extent(), V3::zeros());
        let d = V3::new(1.0, 0.0, 0.0);
        let inv = d.map(|c| 1.0 / c);
        let r = b.ray_interval(&P3::new(-1.0, 0.5, 1.0), &inv, 0.0, f64::INFINITY);
        assert_eq!(r, Some((1.0, 3.0)));
        assert!(b
            .ray_interval(&P3::new(-1.0, 1.5, 1.0), &inv, 0.0, f64::INFINITY)
            .is_none());
        // A ray parallel to two slabs lying on a face of each (x = 0, y = 1), both signs of
        // zero: it runs along the box's edge and enters at z = 0.
        for d in [V3::new(0.0, 0.0, 1.0), V3::new(-0.0, -0.0, 1.0)] {
            let inv = d.map(|c| 1.0 / c);
            let r = b.ray_interval(&P3::new(0.0, 1.0, -1.0), &inv, 0.0, f64::INFINITY);
            assert_eq!(r, Some((1.0, 5.0)), "{d:?}");
            assert!(b
                .ray_interval(&P3::new(-1e-12, 1.0, -1.0), &inv, 0.0, f64::INFINITY)
                .is_none());
        }
        assert!(b.intersects(&Aabb::new(P3::new(2.0, 1.0, 4.0), P3::new(3.0, 3.0, 5.0))));
        assert_eq!(b.surface_area(), 2.0 * (2.0 + 4.0 + 8.0));
    }
}
