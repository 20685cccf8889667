//! Validation of a closed, 2-manifold, consistently outward-oriented solid.

use super::{Defect, MeshError, TriMesh};
use crate::bbox::Aabb;
use std::collections::HashMap;
use std::path::Path;

/// Facts about a valid mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct MeshReport {
    pub vertices: usize,
    pub triangles: usize,
    /// Connected components (a last is one).
    pub components: usize,
    /// Enclosed volume (positive).
    pub volume: f64,
    pub area: f64,
    pub bbox: Aabb,
}

/// A triangle is degenerate when its smallest height is below this fraction of its longest
/// edge (or it repeats a corner).
const DEGENERATE_RATIO: f64 = 1e-10;

impl TriMesh {
    /// Checks that the mesh is a valid solid: indices in range, no degenerate triangle, every
    /// edge in exactly two triangles (closed and 2-manifold), the two running along it in
    /// opposite directions (consistent orientation), and positive volume (outward normals).
    /// The first defect found, in triangle order, is returned.
    pub fn check(&self) -> Result<MeshReport, Defect> {
        if self.triangles.is_empty() {
            return Err(Defect::Empty);
        }
        let nv = self.vertices.len();
        self.check_indices()?;
        for (t, tri) in self.triangles.iter().enumerate() {
            let c = self.corners(t);
            let longest = (0..3)
                .map(|k| (c[(k + 1) % 3] - c[k]).norm_squared())
                .fold(0.0, f64::max);
            let twice_area = self.face_normal_raw(t).norm();
            if tri[0] == tri[1]
                || tri[1] == tri[2]
                || tri[0] == tri[2]
                || twice_area <= DEGENERATE_RATIO * longest
            {
                return Err(Defect::Degenerate {
                    triangle: t,
                    corners: *tri,
                    positions: c,
                });
            }
        }
        self.check_edges()?;
        let volume = self.volume();
        if volume.is_nan() || volume <= 0.0 {
            return Err(Defect::InsideOut { volume });
        }
        Ok(MeshReport {
            vertices: nv,
            triangles: self.triangles.len(),
            components: self.components().1,
            volume,
            area: self.area(),
            bbox: self.bbox(),
        })
    }

    /// The topology half of [`TriMesh::check`]: indices in range and every edge in exactly
    /// two triangles running along it in opposite directions (closed, 2-manifold along
    /// edges, consistently oriented). Thin or flat triangles pass: a solid closed over a
    /// height map has walls of zero height where the surface meets its base.
    pub fn check_closed(&self) -> Result<(), Defect> {
        self.check_indices()?;
        self.check_edges()
    }

    fn check_indices(&self) -> Result<(), Defect> {
        let nv = self.vertices.len();
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&i) = tri.iter().find(|&&i| i as usize >= nv) {
                return Err(Defect::IndexOutOfRange {
                    triangle: t,
                    index: i,
                    vertices: nv,
                });
            }
        }
        Ok(())
    }

    fn check_edges(&self) -> Result<(), Defect> {
        // Per undirected edge: uses in the direction low -> high and high -> low.
        let mut edges: HashMap<(u32, u32), (u32, u32)> =
            HashMap::with_capacity(self.triangles.len() * 2);
        for tri in &self.triangles {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let e = edges.entry((a.min(b), a.max(b))).or_default();
                if a < b {
                    e.0 += 1;
                } else {
                    e.1 += 1;
                }
            }
        }
        for tri in &self.triangles {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let (fwd, back) = edges[&(a.min(b), a.max(b))];
                let (pa, pb) = (self.vertices[a as usize], self.vertices[b as usize]);
                match fwd + back {
                    1 => return Err(Defect::OpenEdge { a, b, pa, pb }),
                    2 => {
                        if fwd != 1 {
                            return Err(Defect::Misoriented { a, b, pa, pb });
                        }
                    }
                    n => {
                        return Err(Defect::NonManifoldEdge {
                            a,
                            b,
                            pa,
                            pb,
                            triangles: n as usize,
                        })
                    }
                }
            }
        }
        Ok(())
    }

    /// [`TriMesh::check`], the error naming `path`.
    pub fn validate(&self, path: impl AsRef<Path>) -> Result<MeshReport, MeshError> {
        self.check().map_err(|defect| MeshError::Invalid {
            path: path.as_ref().to_path_buf(),
            defect,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    fn cuboid(a: P3, b: P3) -> TriMesh {
        TriMesh::cuboid(a, b)
    }
    use crate::P3;

    /// A solid closed over a height map has zero-height walls where the surface meets its
    /// base: closed and oriented (what `check_closed` asks), though `check` calls it
    /// degenerate.
    #[test]
    fn closed_check_is_topology_only() {
        let mut flat = cuboid(P3::origin(), P3::new(1.0, 2.0, 3.0));
        for p in &mut flat.vertices {
            if p.x > 0.5 {
                p.z = 0.0;
            }
        }
        assert!(matches!(flat.check(), Err(Defect::Degenerate { .. })));
        flat.check_closed().unwrap();
        let mut flipped = flat.clone();
        flipped.triangles[0].swap(1, 2);
        assert!(matches!(
            flipped.check_closed(),
            Err(Defect::Misoriented { .. })
        ));
        flipped.triangles.pop();
        assert!(flipped.check_closed().is_err());
    }

    #[test]
    fn defects_are_found_and_named() {
        let good = cuboid(P3::origin(), P3::new(1.0, 2.0, 3.0));
        let r = good.check().unwrap();
        assert_eq!((r.components, r.volume), (1, 6.0));

        let mut open = good.clone();
        open.triangles.pop();
        let e = open.validate("open.stl").unwrap_err().to_string();
        assert!(
            e.starts_with("open.stl: the mesh is not closed: edge"),
            "{e}"
        );

        let mut flipped = good.clone();
        flipped.triangles[3].swap(0, 1);
        assert!(matches!(flipped.check(), Err(Defect::Misoriented { .. })));

        let mut inside_out = good.clone();
        inside_out.flip();
        assert!(matches!(inside_out.check(), Err(Defect::InsideOut { .. })));

        let mut nm = good.clone();
        let t = nm.triangles[0];
        nm.triangles.push(t);
        nm.triangles.push([t[0], t[2], t[1]]);
        assert!(matches!(
            nm.check(),
            Err(Defect::NonManifoldEdge { triangles: 4, .. })
        ));

        let mut deg = good.clone();
        deg.vertices.push(P3::new(0.5, 0.0, 0.0));
        deg.triangles.push([0, 1, 8]);
        assert!(matches!(
            deg.check(),
            Err(Defect::Degenerate { triangle: 12, .. })
        ));

        let mut two = good.clone();
        let mut other = cuboid(P3::new(5.0, 0.0, 0.0), P3::new(6.0, 1.0, 1.0));
        for t in &mut other.triangles {
            *t = t.map(|i| i + 8);
        }
        two.vertices.extend(other.vertices);
        two.triangles.extend(other.triangles);
        assert_eq!(two.check().unwrap().components, 2);
        assert_eq!(TriMesh::default().check(), Err(Defect::Empty));
    }
}
