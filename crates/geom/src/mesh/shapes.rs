//! Simple closed meshes: boxes and spheres, for tests, benchmarks and scenes.

use super::TriMesh;
use crate::{P3, V3};
use std::collections::HashMap;

impl TriMesh {
    /// An axis-aligned box, outward-oriented, 8 vertices and 12 triangles.
    pub fn cuboid(min: P3, max: P3) -> TriMesh {
        let v: Vec<P3> = (0..8)
            .map(|k| {
                P3::new(
                    if k & 1 == 0 { min.x } else { max.x },
                    if k & 2 == 0 { min.y } else { max.y },
                    if k & 4 == 0 { min.z } else { max.z },
                )
            })
            .collect();
        let quads = [
            [0, 2, 3, 1], // z-
            [4, 5, 7, 6], // z+
            [0, 1, 5, 4], // y-
            [2, 6, 7, 3], // y+
            [0, 4, 6, 2], // x-
            [1, 3, 7, 5], // x+
        ];
        let mut t = Vec::new();
        for q in quads {
            t.push([q[0], q[1], q[2]]);
            t.push([q[0], q[2], q[3]]);
        }
        TriMesh::new(v, t)
    }

    /// A sphere: an icosahedron subdivided `levels` times (20 * 4^levels triangles), its
    /// vertices on the sphere, outward-oriented.
    pub fn icosphere(centre: P3, radius: f64, levels: u32) -> TriMesh {
        let g = (1.0 + 5f64.sqrt()) / 2.0;
        let mut dirs: Vec<V3> = [
            (-1.0, g, 0.0),
            (1.0, g, 0.0),
            (-1.0, -g, 0.0),
            (1.0, -g, 0.0),
            (0.0, -1.0, g),
            (0.0, 1.0, g),
            (0.0, -1.0, -g),
            (0.0, 1.0, -g),
            (g, 0.0, -1.0),
            (g, 0.0, 1.0),
            (-g, 0.0, -1.0),
            (-g, 0.0, 1.0),
        ]
        .iter()
        .map(|&(x, y, z)| V3::new(x, y, z).normalize())
        .collect();
        let mut tris: Vec<[u32; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
            let mut next = Vec::with_capacity(tris.len() * 4);
            for t in &tris {
                let mut m = [0u32; 3];
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    m[k] = *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                        dirs.push((dirs[a as usize] + dirs[b as usize]).normalize());
                        (dirs.len() - 1) as u32
                    });
                }
                next.push([t[0], m[0], m[2]]);
                next.push([t[1], m[1], m[0]]);
                next.push([t[2], m[2], m[1]]);
                next.push(m);
            }
            tris = next;
        }
        TriMesh::new(dirs.iter().map(|d| centre + d * radius).collect(), tris)
    }
}
