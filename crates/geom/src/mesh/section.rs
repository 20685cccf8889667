//! Plane sections of a mesh into closed ordered polylines.
//!
//! Robustness: each vertex gets a side from the sign of its signed distance, and a vertex
//! exactly on the plane counts as on the positive side. That is the exact result for the
//! plane moved by an infinitesimal amount against its normal (a symbolic perturbation):
//! no vertex is ever on the plane, every crossed edge has one end on each side, each
//! triangle is crossed by zero or two of its edges, and on a closed 2-manifold mesh the
//! segments join into closed loops with no special cases. A crossing point is a function of
//! its edge alone, so the two triangles sharing an edge produce the identical point, and an
//! on-plane vertex is returned exactly. Loops of zero area (the plane touching the surface
//! from outside at a vertex, along an edge or along a path of edges) are dropped.

use super::TriMesh;
use crate::plane::Plane;
use crate::polyline::Polyline;
use crate::P3;
use std::collections::HashMap;

impl TriMesh {
    /// The section of the mesh by `plane`: one polyline per loop. For a closed, outward
    /// oriented mesh every loop is closed and turns counterclockwise about the plane normal
    /// around solid material (outer boundaries counterclockwise, holes clockwise, seen from
    /// the side the normal points to), so a loop's signed area in the plane's local frame is
    /// positive for an outer boundary. On an open mesh, chains that end at a hole come back
    /// as open polylines.
    pub fn section(&self, plane: &Plane) -> Vec<Polyline> {
        let s: Vec<f64> = self
            .vertices
            .iter()
            .map(|p| plane.signed_distance(p))
            .collect();
        self.section_with_distances(&s)
    }

    /// The section by the level set `s = 0` of per-vertex values `s` (signed distances to a
    /// plane, or any other function linear along edges).
    pub fn section_with_distances(&self, s: &[f64]) -> Vec<Polyline> {
        let pos = |i: u32| s[i as usize] >= 0.0;
        let key = |a: u32, b: u32| (a.min(b), a.max(b));
        // Each segment runs from the crossing on the edge the triangle leaves the positive
        // side by to the one it re-enters by (in the triangle's own corner order); with
        // outward triangles that puts the material on the left seen from the normal side.
        let mut segs: Vec<((u32, u32), (u32, u32))> = Vec::new();
        for t in &self.triangles {
            let p = [pos(t[0]), pos(t[1]), pos(t[2])];
            if p[0] == p[1] && p[1] == p[2] {
                continue;
            }
            let (mut exit, mut entry) = ((0, 0), (0, 0));
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                if p[k] && !p[(k + 1) % 3] {
                    exit = key(a, b);
                } else if !p[k] && p[(k + 1) % 3] {
                    entry = key(a, b);
                }
            }
            segs.push((exit, entry));
        }
        let start: HashMap<(u32, u32), usize> =
            segs.iter().enumerate().map(|(i, sg)| (sg.0, i)).collect();
        let point = |(a, b): (u32, u32)| -> P3 {
            let (sa, sb) = (s[a as usize], s[b as usize]);
            let (pa, pb) = (self.vertices[a as usize], self.vertices[b as usize]);
            if sa == 0.0 {
                pa
            } else if sb == 0.0 {
                pb
            } else {
                pa + (pb - pa) * (sa / (sa - sb))
            }
        };
        let mut has_prev = vec![false; segs.len()];
        for sg in &segs {
            if let Some(&j) = start.get(&sg.1) {
                has_prev[j] = true;
            }
        }
        let mut used = vec![false; segs.len()];
        let mut out = Vec::new();
        // Open chains first (from segments nobody leads into), then the closed loops.
        let order = (0..segs.len())
            .filter(|&i| !has_prev[i])
            .chain((0..segs.len()).filter(|&i| has_prev[i]));
        for i0 in order.collect::<Vec<_>>() {
            if used[i0] {
                continue;
            }
            let mut pts = vec![point(segs[i0].0)];
            let mut i = i0;
            let closed = loop {
                used[i] = true;
                let end = segs[i].1;
                match start.get(&end) {
                    Some(&j) if j == i0 => break true,
                    Some(&j) if !used[j] => {
                        pts.push(point(end));
                        i = j;
                    }
                    _ => {
                        pts.push(point(end));
                        break false;
                    }
                }
            };
            pts.dedup();
            if closed && pts.len() > 1 && pts.first() == pts.last() {
                pts.pop();
            }
            if closed && (pts.len() < 3 || encloses_nothing(&pts)) {
                continue;
            }
            out.push(Polyline {
                points: pts,
                closed,
            });
        }
        out
    }
}

/// Whether a closed loop has zero vector area: the plane touching the surface from outside
/// along a path of on-plane edges gives a loop that runs along the path and back (A B C B),
/// the limit of a sliver whose area vanishes with the perturbation. Exact for such loops (each
/// cross product cancels its reverse); the tolerance only absorbs the rounding of the sum.
fn encloses_nothing(pts: &[P3]) -> bool {
    let n = pts.len();
    let o = pts[0].coords;
    let mut area = crate::V3::zeros();
    let mut perimeter = 0.0;
    for i in 0..n {
        let (a, b) = (pts[i].coords - o, pts[(i + 1) % n].coords - o);
        area += a.cross(&b);
        perimeter += (b - a).norm();
    }
    area.norm() <= 1e-12 * perimeter * perimeter
}

#[cfg(test)]
mod tests {
    use super::*;
    fn cuboid(a: P3, b: P3) -> TriMesh {
        TriMesh::cuboid(a, b)
    }
    use crate::V3;

    #[test]
    fn cuboid_sections_including_through_vertices() {
        let m = cuboid(P3::origin(), P3::new(2.0, 3.0, 1.0));
        let mid = m.section(&Plane::axis_aligned(2, 0.5));
        assert_eq!(mid.len(), 1);
        assert!(mid[0].closed);
        let poly = mid[0].to_polygon(&Plane::axis_aligned(2, 0.5));
        assert!((poly.signed_area() - 6.0).abs() < 1e-12);
        // Each side is two triangles: 8 points, two on each side of the square.
        assert_eq!(mid[0].len(), 8);
        // Through the top face: the plane moved down infinitesimally still cuts the sides.
        let top = m.section(&Plane::axis_aligned(2, 1.0));
        assert_eq!(top.len(), 1);
        assert!(
            (top[0]
                .to_polygon(&Plane::axis_aligned(2, 1.0))
                .signed_area()
                - 6.0)
                .abs()
                < 1e-12
        );
        assert!(m.section(&Plane::axis_aligned(2, 0.0)).is_empty());
        // The flipped plane gives the same region, counterclockwise about the flipped normal.
        let f = Plane::axis_aligned(2, 0.5).flipped();
        let fl = m.section(&f);
        assert!((fl[0].to_polygon(&f).signed_area() - 6.0).abs() < 1e-12);
        // A diagonal plane through two opposite vertical edges (four vertices on the plane).
        let d = Plane::new(P3::origin(), V3::new(3.0, -2.0, 0.0)).unwrap();
        let dl = m.section(&d);
        assert_eq!(dl.len(), 1);
        let area = dl[0].to_polygon(&d).signed_area();
        assert!((area - 13f64.sqrt()).abs() < 1e-12, "{area}");
        // Touching the box at one corner from outside: nothing.
        let c = Plane::new(P3::new(2.0, 3.0, 1.0), V3::new(1.0, 1.0, 1.0)).unwrap();
        assert!(m.section(&c).is_empty(), "{:?}", m.section(&c));
    }

    #[test]
    fn open_mesh_gives_open_chain() {
        let mut m = cuboid(P3::origin(), P3::new(1.0, 1.0, 1.0));
        // Remove the x+ face (triangles 10 and 11).
        m.triangles.truncate(10);
        let l = m.section(&Plane::axis_aligned(2, 0.5));
        assert_eq!(l.len(), 1);
        assert!(!l[0].closed);
        assert_eq!(l[0].len(), 7);
    }
}
