//! A closed triangle mesh of the modelled sole: the height map's valid region triangulated
//! (two triangles per cell whose four corners have a height), walls down every boundary edge
//! and a bottom at `base_z`, so the solid is watertight (every edge in exactly two triangles,
//! once in each direction) with outward normals (counter-clockwise seen from outside).

use crate::geom::HeightMap;
use footscan_geom::mesh::TriMesh;
use footscan_geom::P3;

/// Close the height map's valid region into a solid with its bottom at `base_z` (below every
/// height). Cells touching only diagonally would make a vertex where four walls meet; one of
/// each such pair is dropped, so the mesh stays a manifold.
pub fn closed_from_heightmap(map: &HeightMap, base_z: f64) -> TriMesh {
    let (nx, ny) = (map.nx, map.ny);
    if nx < 2 || ny < 2 {
        return TriMesh::default();
    }
    let (qx, qy) = (nx - 1, ny - 1);
    let mut quad = vec![false; qx * qy];
    for j in 0..qy {
        for i in 0..qx {
            quad[j * qx + i] = [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)]
                .iter()
                .all(|&(a, b)| map.get(a, b).is_finite());
        }
    }
    let q = |quad: &Vec<bool>, i: isize, j: isize| -> bool {
        i >= 0
            && j >= 0
            && (i as usize) < qx
            && (j as usize) < qy
            && quad[j as usize * qx + i as usize]
    };
    // Drop diagonal-only contacts at a vertex until none is left.
    loop {
        let mut changed = false;
        for j in 1..qy as isize {
            for i in 1..qx as isize {
                // Quads around vertex (i, j): SW (i-1, j-1), SE (i, j-1), NW (i-1, j), NE (i, j).
                let (sw, se, nw, ne) = (
                    q(&quad, i - 1, j - 1),
                    q(&quad, i, j - 1),
                    q(&quad, i - 1, j),
                    q(&quad, i, j),
                );
                if sw && ne && !se && !nw {
                    quad[j as usize * qx + i as usize] = false;
                    changed = true;
                } else if se && nw && !sw && !ne {
                    quad[j as usize * qx + i as usize - 1] = false;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    // Vertices: a top and a bottom copy of every grid node a quad uses.
    let mut top = vec![u32::MAX; nx * ny];
    let mut mesh = TriMesh::default();
    for j in 0..qy {
        for i in 0..qx {
            if !quad[j * qx + i] {
                continue;
            }
            for (a, b) in [(i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)] {
                let k = b * nx + a;
                if top[k] == u32::MAX {
                    top[k] = mesh.vertices.len() as u32;
                    mesh.vertices
                        .push(P3::new(map.x(a), map.y(b), map.get(a, b)));
                    mesh.vertices.push(P3::new(map.x(a), map.y(b), base_z));
                }
            }
        }
    }
    let t = |a: usize, b: usize| top[b * nx + a];
    for j in 0..qy {
        for i in 0..qx {
            if !quad[j * qx + i] {
                continue;
            }
            let (v00, v10, v11, v01) = (t(i, j), t(i + 1, j), t(i + 1, j + 1), t(i, j + 1));
            mesh.triangles.push([v00, v10, v11]);
            mesh.triangles.push([v00, v11, v01]);
            mesh.triangles.push([v00 + 1, v11 + 1, v10 + 1]);
            mesh.triangles.push([v00 + 1, v01 + 1, v11 + 1]);
            // Counter-clockwise edges (a -> b, region on the left) and the quad across.
            let (ii, jj) = (i as isize, j as isize);
            for (a, b, oi, oj) in [
                (v00, v10, ii, jj - 1),
                (v10, v11, ii + 1, jj),
                (v11, v01, ii, jj + 1),
                (v01, v00, ii - 1, jj),
            ] {
                if !q(&quad, oi, oj) {
                    mesh.triangles.push([a, a + 1, b + 1]);
                    mesh.triangles.push([a, b + 1, b]);
                }
            }
        }
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_mesh_of_an_irregular_region_is_watertight_with_the_right_volume() {
        // A ring (hole in the middle), a diagonal-only contact and a separate island.
        let mut m = HeightMap::new(0.0, 0.0, 1.0, 12, 10);
        for j in 1..8 {
            for i in 1..8 {
                if !(j == 4 && i == 4) {
                    m.set(i, j, 2.0);
                }
            }
        }
        // Quad (7, 7) touches the ring's corner quad (6, 6) only at vertex (7, 7).
        for (i, j) in [(8, 7), (7, 8), (8, 8)] {
            m.set(i, j, 2.0);
        }
        // A separate island: quad (10, 1).
        for (i, j) in [(10, 1), (11, 1), (10, 2), (11, 2)] {
            m.set(i, j, 2.0);
        }
        let mesh = closed_from_heightmap(&m, 0.0);
        mesh.check_closed().unwrap();
        // Ring: 6 x 6 quads minus the 4 around the hole = 32, plus quad (7, 7), plus the
        // island, less one of the diagonal pair: 33 unit quads of height 2.
        let v = mesh.volume();
        assert!((v - 2.0 * 33.0).abs() < 1e-9, "{v}");
        assert!(mesh.face_normal(0).z > 0.99);
        // Reversing one triangle breaks the orientation check.
        let mut bad = mesh.clone();
        bad.triangles[0].swap(1, 2);
        assert!(bad.check_closed().is_err());
        bad.triangles.pop();
        assert!(bad.check_closed().is_err());
    }
}
