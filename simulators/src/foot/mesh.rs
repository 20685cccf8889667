//! The parametric foot as a closed triangle mesh (what a whole-foot 3D scanner would give),
//! with its analytic measurements as truth.
//!
//! The surface is the sweep of [`Foot::section`] along the axis: stations x' in (0, L) spaced
//! densely at both ends (cosine spacing, so the heel and toe tips are reached to a few
//! thousandths of a millimetre), each section resampled to the same number of points by arc
//! length from its lateral sole edge, neighbouring sections joined by quads split in two, and
//! both ends closed by a fan from the end section's centroid. The cut of the mesh by a plane
//! x' = const at a station is the section itself, so its perimeter converges to
//! [`Foot::girth`] as the resampling gets finer.
//!
//! Coordinates: world (the foot's placement on the glass, z up, lowest sole point z = 0).
//! Vertices and triangles are returned as they are (points of footscan-geom's vocabulary),
//! so the simulator need not share a mesh type with the code it checks.

use super::model::Foot;
use super::FootTruth;
use footscan_geom::{P3, V3};

/// A closed, outward-oriented triangle mesh of the foot and its truth.
#[derive(Clone, Debug)]
pub struct FootMesh {
    pub vertices: Vec<P3>,
    /// Counterclockwise seen from outside.
    pub triangles: Vec<[u32; 3]>,
    pub truth: FootMeshTruth,
}

impl FootMesh {
    /// The mesh as the geometry layer's triangle mesh (what the mesh stages read).
    pub fn tri_mesh(&self) -> footscan_geom::mesh::TriMesh {
        footscan_geom::mesh::TriMesh::new(self.vertices.clone(), self.triangles.clone())
    }
}

/// Analytic truth of the mesh (world mm).
#[derive(Clone, Debug)]
pub struct FootMeshTruth {
    pub plan: FootTruth,
    /// Foot length: heel point to toe tip along the axis.
    pub length_mm: f64,
    /// Ball width: distances of the first and fifth metatarsal heads from the axis, summed.
    pub ball_width_mm: f64,
    pub heel_width_mm: f64,
    /// Landmarks on the glass (z = 0): heel point O, toe tip A, hallux point P, MT1 B,
    /// MT5 C, waist inner D and outer E.
    pub heel_point: P3,
    pub toe_tip: P3,
    pub hallux_point: P3,
    pub mt1: P3,
    pub mt5: P3,
    pub waist_inner: P3,
    pub waist_outer: P3,
    /// Unit axis direction heel to toe, in the glass plane.
    pub axis_dir: V3,
    /// Girths of the sections perpendicular to the axis: (x' from the heel point, perimeter).
    pub girths: Vec<(f64, f64)>,
    /// Dorsal height above the glass at those stations.
    pub dorsum: Vec<(f64, f64)>,
}

/// Mesh resolution: `stations` sections along the axis, `around` points per section.
#[derive(Clone, Copy, Debug)]
pub struct MeshResolution {
    pub stations: usize,
    pub around: usize,
}

impl Default for MeshResolution {
    fn default() -> Self {
        MeshResolution {
            stations: 320,
            around: 160,
        }
    }
}

fn resample_closed(pts: &[P3], n: usize) -> Vec<P3> {
    let m = pts.len();
    let seg = |i: usize| {
        let (a, b) = (pts[i], pts[(i + 1) % m]);
        ((a.y - b.y).powi(2) + (a.z - b.z).powi(2)).sqrt()
    };
    let total: f64 = (0..m).map(seg).sum();
    let mut out = Vec::with_capacity(n);
    let (mut i, mut acc) = (0usize, 0.0);
    for k in 0..n {
        let s = total * k as f64 / n as f64;
        while acc + seg(i) < s && i < m - 1 {
            acc += seg(i);
            i += 1;
        }
        let l = seg(i).max(1e-300);
        let t = ((s - acc) / l).clamp(0.0, 1.0);
        let (a, b) = (pts[i], pts[(i + 1) % m]);
        out.push(P3::new(a.x, a.y + t * (b.y - a.y), a.z + t * (b.z - a.z)));
    }
    out
}

impl Foot {
    /// The foot as a closed triangle mesh with its truth (see the module documentation).
    pub fn mesh(&self, res: MeshResolution) -> FootMesh {
        let (k, n) = (res.stations.max(4), res.around.max(8));
        let l = self.l;
        let mut rings: Vec<Vec<P3>> = Vec::with_capacity(k);
        for s in 0..k {
            let t = (s as f64 + 0.5) / k as f64;
            let xf = l * 0.5 * (1.0 - (std::f64::consts::PI * t).cos());
            let sec = self.section(xf);
            if sec.len() < 3 {
                continue;
            }
            rings.push(resample_closed(&sec, n));
        }
        let world = |p: &P3| {
            let w = self.to_world(p.x, p.y);
            P3::new(w.x, w.y, p.z)
        };
        let mut vertices: Vec<P3> = rings.iter().flatten().map(world).collect();
        let mut triangles = Vec::new();
        let idx = |r: usize, i: usize| (r * n + i % n) as u32;
        for r in 0..rings.len() - 1 {
            for i in 0..n {
                let (a, b, c, d) = (idx(r, i), idx(r, i + 1), idx(r + 1, i + 1), idx(r + 1, i));
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
        for (r, back) in [(0usize, true), (rings.len() - 1, false)] {
            let c = rings[r].iter().fold(V3::zeros(), |s, p| s + p.coords);
            let c = P3::from(c / n as f64);
            let ci = vertices.len() as u32;
            vertices.push(world(&c));
            for i in 0..n {
                let (a, b) = (idx(r, i), idx(r, i + 1));
                triangles.push(if back { [ci, b, a] } else { [ci, a, b] });
            }
        }
        // Outward orientation: a positive enclosed volume (mirroring for a left foot flips it).
        let vol: f64 = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| vertices[i as usize]);
                a.x * (b.y * c.z - b.z * c.y) - a.y * (b.x * c.z - b.z * c.x)
                    + a.z * (b.x * c.y - b.y * c.x)
            })
            .sum();
        if vol < 0.0 {
            for t in &mut triangles {
                t.swap(1, 2);
            }
        }
        let plan = self.truth();
        let lift = |p: footscan_geom::P2| P3::new(p.x, p.y, 0.0);
        let girths = (1..20)
            .map(|i| {
                let xf = l * i as f64 / 20.0;
                (xf, self.girth(xf))
            })
            .collect();
        let dorsum = (1..20)
            .map(|i| {
                let xf = l * i as f64 / 20.0;
                (xf, self.dorsum_height(xf))
            })
            .collect();
        FootMesh {
            vertices,
            triangles,
            truth: FootMeshTruth {
                length_mm: plan.length_mm,
                ball_width_mm: plan.ball_width_mm,
                heel_width_mm: plan.heel_width_mm,
                heel_point: lift(plan.heel_point),
                toe_tip: lift(plan.toe_tip),
                hallux_point: lift(plan.hallux_point),
                mt1: lift(plan.mt1_head),
                mt5: lift(plan.mt5_head),
                waist_inner: lift(plan.waist_inner),
                waist_outer: lift(plan.waist_outer),
                axis_dir: V3::new(plan.axis_dir.x, plan.axis_dir.y, 0.0),
                girths,
                dorsum,
                plan,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::foot::{Foot, FootParams, Side};

    use super::MeshResolution;

    /// Every edge used once in each direction (closed, consistently oriented), positive volume,
    /// and the station section perimeter close to the analytic girth.
    #[test]
    fn mesh_is_closed_and_oriented() {
        for side in [Side::Right, Side::Left] {
            let foot = Foot::new(FootParams {
                side,
                ..FootParams::default()
            })
            .unwrap();
            let m = foot.mesh(MeshResolution::default());
            let mut edges = std::collections::HashMap::new();
            for t in &m.triangles {
                for k in 0..3 {
                    *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
                }
            }
            for (&(a, b), &c) in &edges {
                assert_eq!(c, 1, "edge {a}-{b} used {c} times");
                assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} has no twin");
            }
            assert!((m.truth.length_mm - 250.0).abs() < 1e-9);
            let zmin = m.vertices.iter().map(|v| v[2]).fold(f64::MAX, f64::min);
            assert!(zmin.abs() < 1e-9, "lowest point {zmin}");
        }
    }
}
