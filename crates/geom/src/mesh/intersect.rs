//! Self-intersection: pairs of triangles that pass through each other. A mesh can be closed
//! and 2-manifold and still cross itself (a fold pushed through the opposite wall, a thin
//! part whose two sides swapped); a slicer or a CAM package then fails or cuts nonsense, so
//! the solids we hand out are checked for it.

use super::TriMesh;
use crate::bbox::Aabb;
use crate::P3;
use std::collections::HashMap;

impl TriMesh {
    /// Pairs of triangles (i < j) that share no corner and cross: an edge of one passes
    /// through the other's interior. Candidates come from a uniform grid over the
    /// triangles' boxes (a cell about the mean box size), so the cost grows with the
    /// triangles, not their square.
    pub fn self_intersections(&self) -> Vec<(usize, usize)> {
        let nt = self.triangles.len();
        if nt < 2 {
            return Vec::new();
        }
        let boxes: Vec<Aabb> = (0..nt)
            .map(|t| Aabb::from_points(self.corners(t).iter()))
            .collect();
        let bb = self.bbox();
        let mean = boxes.iter().map(|b| b.longest_extent()).sum::<f64>() / nt as f64;
        let cell = mean.max(bb.longest_extent() / 1024.0).max(1e-9);
        let ext = bb.extent();
        let n = [ext.x, ext.y, ext.z].map(|e| (e / cell).floor() as u64 + 1);
        let at = |p: &P3| -> [u64; 3] {
            let c = [p.x - bb.min.x, p.y - bb.min.y, p.z - bb.min.z];
            [0, 1, 2].map(|k| ((c[k] / cell).max(0.0) as u64).min(n[k] - 1))
        };
        let mut grid: HashMap<u64, Vec<u32>> = HashMap::new();
        for (t, b) in boxes.iter().enumerate() {
            let (lo, hi) = (at(&b.min), at(&b.max));
            for i in lo[0]..=hi[0] {
                for j in lo[1]..=hi[1] {
                    for k in lo[2]..=hi[2] {
                        grid.entry((i * n[1] + j) * n[2] + k)
                            .or_default()
                            .push(t as u32);
                    }
                }
            }
        }
        let mut pairs = Vec::new();
        for tris in grid.values() {
            for (x, &s) in tris.iter().enumerate() {
                for &t in &tris[x + 1..] {
                    let (s, t) = (s.min(t) as usize, s.max(t) as usize);
                    if !boxes[s].intersects(&boxes[t]) {
                        continue;
                    }
                    let (a, b) = (self.triangles[s], self.triangles[t]);
                    if a.iter().any(|v| b.contains(v)) {
                        continue;
                    }
                    if triangles_cross(&self.corners(s), &self.corners(t)) {
                        pairs.push((s, t));
                    }
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        pairs
    }
}

/// Two triangles with no shared corner cross when an edge of one passes through the other:
/// the segment where their planes meet inside both ends on an edge of one of them.
fn triangles_cross(a: &[P3; 3], b: &[P3; 3]) -> bool {
    (0..3).any(|i| segment_through(&a[i], &a[(i + 1) % 3], b))
        || (0..3).any(|i| segment_through(&b[i], &b[(i + 1) % 3], a))
}

/// The open segment p-q passes through the closed triangle (Moller-Trumbore); a segment in
/// the triangle's plane does not count.
fn segment_through(p: &P3, q: &P3, tri: &[P3; 3]) -> bool {
    let (e1, e2, d) = (tri[1] - tri[0], tri[2] - tri[0], q - p);
    let h = d.cross(&e2);
    let det = e1.dot(&h);
    let scale = e1.norm() * e2.norm() * d.norm();
    if det.abs() <= 1e-12 * scale {
        return false;
    }
    let f = 1.0 / det;
    let s = p - tri[0];
    let u = f * s.dot(&h);
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let r = s.cross(&e1);
    let v = f * d.dot(&r);
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = f * e2.dot(&r);
    t > 1e-12 && t < 1.0 - 1e-12
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::V3;

    #[test]
    fn a_sphere_does_not_cross_itself_and_two_overlapping_do() {
        let one = TriMesh::icosphere(P3::origin(), 10.0, 3);
        assert!(one.self_intersections().is_empty());
        let mut two = one.clone();
        let mut other = one.clone();
        other.translate(&V3::new(12.0, 0.0, 0.0));
        let off = two.vertices.len() as u32;
        two.vertices.extend(other.vertices);
        two.triangles
            .extend(other.triangles.iter().map(|t| t.map(|i| i + off)));
        let pairs = two.self_intersections();
        assert!(!pairs.is_empty());
        // Every pair found has one triangle of each sphere, near the circle where they meet
        // (x = 6, radius 8).
        for (s, t) in pairs {
            assert!(
                s < one.triangles.len() && t >= one.triangles.len(),
                "{s} {t}"
            );
            let c = two.corners(s)[0];
            assert!((c.x - 6.0).abs() < 2.0, "{c:?}");
        }
        // Apart, nothing crosses.
        let mut apart = one.clone();
        let mut far = one.clone();
        far.translate(&V3::new(20.5, 0.0, 0.0));
        let off = apart.vertices.len() as u32;
        apart.vertices.extend(far.vertices);
        apart
            .triangles
            .extend(far.triangles.iter().map(|t| t.map(|i| i + off)));
        assert!(apart.self_intersections().is_empty());
    }
}
