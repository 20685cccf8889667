//! Indexed triangle meshes: file formats, validation, units, plane sections and distance
//! queries.
//!
//! A [`TriMesh`] holds its vertices once and triangles as index triples, counterclockwise
//! seen from outside for a closed, outward-oriented mesh. STL stores each triangle's corners
//! separately; loading welds corners at exactly equal positions (see [`TriMesh::weld`] for
//! a tolerance).

mod bvh;
pub mod cloud;
mod error;
mod gltf;
mod intake;
mod intersect;
mod io;
mod section;
mod shapes;
mod units;
mod validate;

pub use bvh::{Bvh, ClosestPoint, Feature, RayHit, SignedDistance};
pub use error::{Defect, MeshError};
pub use gltf::{
    foot_in_last_glb, glb, glb_scene, gltf_position, write_foot_in_last_glb, write_glb,
    write_glb_scene, GlbError, GlbLine, GlbMark, GlbPart, GlbScene, PROUD_FULL_MM,
};
pub use intake::{
    axis_name, intake, orient_consistently, Axes, AxesError, Intake, IntakeOptions, CUT_MIN_SPAN,
    CUT_PLANARITY, FOOT_ELONGATION, FOOT_LENGTH_MM,
};
pub use io::{Format, StlKind};
pub use units::{LoadReport, Units, UnitsDecision, UnknownUnits, MIN_PLAUSIBLE_MM};
pub use validate::MeshReport;

use crate::bbox::Aabb;
use crate::{P3, V3};

/// An indexed triangle mesh in millimetres.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TriMesh {
    pub vertices: Vec<P3>,
    pub triangles: Vec<[u32; 3]>,
}

/// What [`TriMesh::weld`] changed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WeldReport {
    /// Vertices removed (merged into another).
    pub merged_vertices: usize,
    /// Triangles dropped because two of their corners merged.
    pub dropped_triangles: usize,
}

impl TriMesh {
    pub fn new(vertices: Vec<P3>, triangles: Vec<[u32; 3]>) -> TriMesh {
        TriMesh {
            vertices,
            triangles,
        }
    }

    /// A mesh from triangle soup (three corners per triangle), corners at bit-identical
    /// positions merged (+0 and -0 are the same position).
    pub fn from_soup(corners: &[[P3; 3]]) -> TriMesh {
        Self::from_triangles(corners.len(), corners.iter().copied())
    }

    /// [`TriMesh::from_soup`] from `n` triangles given one at a time, so a reader need not
    /// hold them all as a soup beside the mesh it builds.
    pub fn from_triangles(n: usize, corners: impl Iterator<Item = [P3; 3]>) -> TriMesh {
        let mut map: std::collections::HashMap<[u64; 3], u32> =
            std::collections::HashMap::with_capacity(n * 2);
        let mut vertices = Vec::with_capacity(n / 2 + 3);
        let triangles = corners
            .map(|tri| {
                tri.map(|p| {
                    let key = [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits());
                    *map.entry(key).or_insert_with(|| {
                        vertices.push(p);
                        (vertices.len() - 1) as u32
                    })
                })
            })
            .collect();
        TriMesh {
            vertices,
            triangles,
        }
    }

    /// Corner positions of triangle `t`.
    pub fn corners(&self, t: usize) -> [P3; 3] {
        self.triangles[t].map(|i| self.vertices[i as usize])
    }

    /// Unnormalised normal `(b - a) x (c - a)` of triangle `t` (twice its area in length).
    pub fn face_normal_raw(&self, t: usize) -> V3 {
        let [a, b, c] = self.corners(t);
        (b - a).cross(&(c - a))
    }

    /// Unit normal of triangle `t` (zero for a degenerate triangle).
    pub fn face_normal(&self, t: usize) -> V3 {
        self.face_normal_raw(t)
            .try_normalize(0.0)
            .unwrap_or_else(V3::zeros)
    }

    pub fn bbox(&self) -> Aabb {
        Aabb::from_points(&self.vertices)
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| self.face_normal_raw(t).norm() / 2.0)
            .sum()
    }

    /// Enclosed volume by the divergence theorem (signed: positive for a closed mesh with
    /// outward normals). Corners are taken relative to the bounding-box centre, which keeps
    /// the sum accurate for meshes far from the origin.
    pub fn volume(&self) -> f64 {
        let c = self.bbox().center();
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, d] = t.map(|i| self.vertices[i as usize] - c);
                a.dot(&b.cross(&d))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Vertex normals: the angle-weighted mean of the incident face normals (unit; zero for
    /// an unused vertex). Angle weights make the normal independent of how a flat region is
    /// triangulated.
    pub fn vertex_normals(&self) -> Vec<V3> {
        let mut n = vec![V3::zeros(); self.vertices.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            let fnorm = self.face_normal(t);
            let angles = corner_angles(&self.corners(t));
            for k in 0..3 {
                n[tri[k] as usize] += fnorm * angles[k];
            }
        }
        n.iter()
            .map(|v| v.try_normalize(0.0).unwrap_or_else(V3::zeros))
            .collect()
    }

    /// Applies a rigid motion.
    pub fn transform(&mut self, iso: &nalgebra::Isometry3<f64>) {
        for p in &mut self.vertices {
            *p = iso * *p;
        }
    }

    /// Applies an affine map; a map that mirrors (negative determinant) also reverses every
    /// triangle so the mesh stays outward-oriented.
    pub fn transform_affine(&mut self, m: &nalgebra::Affine3<f64>) {
        for p in &mut self.vertices {
            *p = m * *p;
        }
        if m.matrix().fixed_view::<3, 3>(0, 0).determinant() < 0.0 {
            self.flip();
        }
    }

    /// Scales uniformly about the origin.
    pub fn scale(&mut self, s: f64) {
        for p in &mut self.vertices {
            p.coords *= s;
        }
        if s < 0.0 {
            self.flip();
        }
    }

    /// Scales by (sx, sy, sz) about `centre` (reversing the triangles for an odd number of
    /// negative factors).
    pub fn scale_about(&mut self, centre: &P3, s: &V3) {
        for p in &mut self.vertices {
            *p = centre + (*p - centre).component_mul(s);
        }
        if s.x * s.y * s.z < 0.0 {
            self.flip();
        }
    }

    pub fn translate(&mut self, d: &V3) {
        for p in &mut self.vertices {
            *p += d;
        }
    }

    /// Reverses the orientation of every triangle.
    pub fn flip(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Merges vertices closer than `tol` (each to the first kept vertex within `tol` of it,
    /// on a hash grid of cell `tol`), then drops triangles that lost a corner and vertices
    /// that no triangle uses. `tol = 0` merges exactly equal positions only.
    pub fn weld(&mut self, tol: f64) -> WeldReport {
        use std::collections::HashMap;
        let n0 = self.vertices.len();
        let mut remap = vec![0u32; n0];
        let mut kept: Vec<P3> = Vec::with_capacity(n0);
        if tol > 0.0 {
            let cell = |p: &P3| [p.x, p.y, p.z].map(|c| (c / tol).floor() as i64);
            let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
            for (i, p) in self.vertices.iter().enumerate() {
                let c = cell(p);
                let mut found = None;
                'search: for dx in -1..=1 {
                    for dy in -1..=1 {
                        for dz in -1..=1 {
                            if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                                for &k in list {
                                    if (kept[k as usize] - p).norm() <= tol {
                                        found = Some(k);
                                        break 'search;
                                    }
                                }
                            }
                        }
                    }
                }
                remap[i] = found.unwrap_or_else(|| {
                    kept.push(*p);
                    let k = (kept.len() - 1) as u32;
                    grid.entry(c).or_default().push(k);
                    k
                });
            }
        } else {
            let mut map: HashMap<[u64; 3], u32> = HashMap::new();
            for (i, p) in self.vertices.iter().enumerate() {
                let key = [p.x, p.y, p.z].map(|c| (c + 0.0).to_bits());
                remap[i] = *map.entry(key).or_insert_with(|| {
                    kept.push(*p);
                    (kept.len() - 1) as u32
                });
            }
        }
        let t0 = self.triangles.len();
        let mut tris: Vec<[u32; 3]> = self
            .triangles
            .iter()
            .map(|t| t.map(|i| remap[i as usize]))
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
        let dropped = t0 - tris.len();
        // Drop vertices no triangle uses any more, keeping the order of the rest.
        let mut used = vec![u32::MAX; kept.len()];
        let mut verts = Vec::with_capacity(kept.len());
        for t in &mut tris {
            for i in t.iter_mut() {
                if used[*i as usize] == u32::MAX {
                    used[*i as usize] = verts.len() as u32;
                    verts.push(kept[*i as usize]);
                }
                *i = used[*i as usize];
            }
        }
        self.vertices = verts;
        self.triangles = tris;
        WeldReport {
            merged_vertices: n0 - self.vertices.len(),
            dropped_triangles: dropped,
        }
    }

    /// Connected components (triangles sharing a vertex are connected): a component index
    /// per triangle, and the number of components.
    pub fn components(&self) -> (Vec<u32>, usize) {
        let mut parent: Vec<u32> = (0..self.vertices.len() as u32).collect();
        fn find(p: &mut [u32], mut i: u32) -> u32 {
            while p[i as usize] != i {
                p[i as usize] = p[p[i as usize] as usize];
                i = p[i as usize];
            }
            i
        }
        for t in &self.triangles {
            let a = find(&mut parent, t[0]);
            for &v in &t[1..] {
                let b = find(&mut parent, v);
                if a != b {
                    parent[b as usize] = a;
                }
            }
        }
        let mut label = vec![u32::MAX; self.vertices.len()];
        let mut count = 0u32;
        let comp = self
            .triangles
            .iter()
            .map(|t| {
                let r = find(&mut parent, t[0]) as usize;
                if label[r] == u32::MAX {
                    label[r] = count;
                    count += 1;
                }
                label[r]
            })
            .collect();
        (comp, count as usize)
    }
}

/// Interior angles at the three corners of a triangle (radians; 0 at a repeated corner).
pub(crate) fn corner_angles(c: &[P3; 3]) -> [f64; 3] {
    let ang = |p: &P3, q: &P3, r: &P3| {
        let (u, v) = (q - p, r - p);
        let s = u.cross(&v).norm();
        s.atan2(u.dot(&v))
    };
    [
        ang(&c[0], &c[1], &c[2]),
        ang(&c[1], &c[2], &c[0]),
        ang(&c[2], &c[0], &c[1]),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    fn cuboid(a: P3, b: P3) -> TriMesh {
        TriMesh::cuboid(a, b)
    }

    #[test]
    fn cuboid_properties() {
        let mut m = cuboid(P3::new(1.0, 2.0, 3.0), P3::new(3.0, 5.0, 7.0));
        assert_eq!(m.volume(), 24.0);
        assert_eq!(m.area(), 2.0 * (6.0 + 12.0 + 8.0));
        let n = m.vertex_normals();
        assert!((n[0] + V3::new(1.0, 1.0, 1.0).normalize()).norm() < 1e-12);
        m.scale_about(&P3::origin(), &V3::new(-1.0, 1.0, 1.0));
        assert_eq!(m.volume(), 24.0);
        m.transform(&nalgebra::Isometry3::new(
            V3::new(1.0, 0.0, 0.0),
            V3::new(0.0, 0.0, 1.0),
        ));
        assert!((m.volume() - 24.0).abs() < 1e-12);
        assert_eq!(m.components().1, 1);
    }

    #[test]
    fn weld_merges_within_tolerance() {
        let m = cuboid(P3::origin(), P3::new(1.0, 1.0, 1.0));
        let soup: Vec<[P3; 3]> = (0..m.triangles.len()).map(|t| m.corners(t)).collect();
        let welded = TriMesh::from_soup(&soup);
        assert_eq!(welded.vertices.len(), 8);
        // Jitter every corner by < 1e-6 and weld at 1e-5.
        let mut jit = welded.clone();
        jit.vertices.clear();
        jit.triangles.clear();
        for (k, tri) in soup.iter().enumerate() {
            for (c, p) in tri.iter().enumerate() {
                let e = 1e-7 * ((k * 3 + c) % 7) as f64;
                jit.vertices.push(p + V3::new(e, -e, e));
            }
            let b = (k * 3) as u32;
            jit.triangles.push([b, b + 1, b + 2]);
        }
        let r = jit.weld(1e-5);
        assert_eq!(jit.vertices.len(), 8);
        assert_eq!(r.merged_vertices, 36 - 8);
        assert_eq!(r.dropped_triangles, 0);
        assert!((jit.volume() - 1.0).abs() < 1e-5);
    }
}
