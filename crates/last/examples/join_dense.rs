//! Where the fitted kept parts stray from their meshes between the fit's check points
//! (`cargo run --release -p footscan-last --example join_dense [-- N]`): per part of both
//! real pairs, on a 1200 x 600 grid uniform in the parameters, the N (default 20) worst
//! points at least 3 mm apart, each with its side of the mesh (out: the surface bulges
//! past it; in: it cuts inside), its parameters, the sharpest bend between the
//! facets around its nearest mesh point (dihedral angle of the nearest facet and its
//! neighbours two edges out), the fitted surface's knot spans there (mm around and along)
//! and the distances on a 2 x 4 grid of that span (the fit's check grid is 2 x 4 per span of
//! the section surface); then the other direction, the mesh vertices to the surface (their
//! feet found on a 1200 x 600 tessellation and by Gauss-Newton, vertices whose foot lies on
//! an end row left out: they are past the part). The lasts are read from FOOTSCAN_DATA.

use footscan_geom::mesh::{Bvh, TriMesh};
use footscan_geom::P3;
use footscan_last::join::{self, keep, study, JoinParams};
use std::collections::HashMap;
use std::path::PathBuf;

fn distinct(k: &[f64], lo: f64, hi: f64) -> Vec<f64> {
    let mut v: Vec<f64> = k.iter().copied().filter(|&x| x >= lo && x <= hi).collect();
    v.dedup();
    v
}

fn span(k: &[f64], t: f64) -> (f64, f64) {
    let i = k.partition_point(|&x| x <= t).clamp(1, k.len() - 1);
    (k[i - 1], k[i])
}

/// Largest angle, deg, between the normal of facet `t` or of a facet within two edges of it
/// and the normals of their edge neighbours.
fn bend(m: &TriMesh, adj: &[Vec<usize>], t: usize) -> f64 {
    let mut ring = vec![t];
    for _ in 0..2 {
        let mut next = ring.clone();
        for &a in &ring {
            next.extend(&adj[a]);
        }
        next.sort();
        next.dedup();
        ring = next;
    }
    let mut worst: f64 = 0.0;
    for &a in &ring {
        for &b in &adj[a] {
            let c = m.face_normal(a).dot(&m.face_normal(b)).clamp(-1.0, 1.0);
            worst = worst.max(c.acos().to_degrees());
        }
    }
    worst
}

fn main() {
    let data = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let top: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20);
    let pairs = study::real_pairs(&data).expect("real last pairs (set FOOTSCAN_DATA)");
    for pair in &pairs {
        let p = JoinParams {
            fit_parts: true,
            ..JoinParams::default()
        };
        let j = join::join(&pair.back, &pair.toe, &p).unwrap();
        let f = j.fits.unwrap();
        for (part, f, s, m) in [
            ("back", &f[0], &j.back, &j.back_mesh),
            ("toe", &f[1], &j.toe, &j.toe_mesh),
        ] {
            let bvh = Bvh::new(m);
            let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
            for (t, tri) in m.triangles.iter().enumerate() {
                for k in 0..3 {
                    let (a, b) = (tri[k], tri[(k + 1) % 3]);
                    edges.entry((a.min(b), a.max(b))).or_default().push(t);
                }
            }
            let mut adj = vec![Vec::new(); m.triangles.len()];
            for ts in edges.values() {
                for &a in ts {
                    for &b in ts {
                        if a != b {
                            adj[a].push(b);
                        }
                    }
                }
            }
            let (u0, u1) = s.domain_u();
            let (v0, v1) = s.domain_v();
            let ku = distinct(&s.knots_u, u0, u1);
            let kv = distinct(&s.knots_v, v0, v1);
            let (nu, nv) = (1200, 600);
            let mut grid = Vec::with_capacity(nu * nv);
            for i in 0..nu {
                let u = u0 + (u1 - u0) * i as f64 / nu as f64;
                for k in 0..nv {
                    let v = v0 + (v1 - v0) * k as f64 / (nv - 1) as f64;
                    let q = s.point(u, v);
                    let c = bvh.closest_point(&q).unwrap();
                    grid.push((c.distance, u, v, q, c.triangle));
                }
            }
            let over = grid.iter().filter(|g| g.0 > 0.1).count();
            let mut order: Vec<usize> = (0..grid.len()).collect();
            order.sort_by(|&a, &b| grid[b].0.total_cmp(&grid[a].0));
            println!(
                "{} {part}: {} x {} spans, check grid max {:.3} mm; 1200 x 600: max {:.3} mm, \
                 {} points over 0.1 mm ({:.2}%)",
                pair.name,
                ku.len() - 1,
                kv.len() - 1,
                f.max_mm,
                grid[order[0]].0,
                over,
                100.0 * over as f64 / grid.len() as f64
            );
            println!(
                "    mm  side     x      y      z       u       v   bend deg  span u x v mm   \
                 span 2x4 max mm"
            );
            let mut shown: Vec<P3> = Vec::new();
            for &k in &order {
                if shown.len() >= top {
                    break;
                }
                let (d, u, v, q, t) = grid[k];
                if shown.iter().any(|x| (x - q).norm() < 3.0) {
                    continue;
                }
                shown.push(q);
                let side = if bvh.signed_distance(&q).unwrap().distance > 0.0 {
                    "out"
                } else {
                    "in "
                };
                let (a, b) = span(&ku, u);
                let (c, e) = span(&kv, v);
                let su = (s.point(b, v) - s.point(a, v)).norm();
                let sv = (s.point(u, e) - s.point(u, c)).norm();
                let mut sm: f64 = 0.0;
                for fu in [0.0, 0.5] {
                    for fv in [0.0, 0.25, 0.5, 0.75] {
                        let x = s.point(a + fu * (b - a), c + fv * (e - c));
                        sm = sm.max(bvh.closest_point(&x).unwrap().distance);
                    }
                }
                println!(
                    "  {d:.3} {side} {:6.1} {:6.1} {:6.1}  {u:.4} {v:.4}  {:6.1}    {su:5.2} x \
                     {sv:5.2}   {sm:.3}",
                    q.x,
                    q.y,
                    q.z,
                    bend(m, &adj, t)
                );
            }
            // Mesh vertices to the surface.
            let mut verts = Vec::with_capacity(nu * nv);
            let (tu, tv) = (1200usize, 600usize);
            for i in 0..tu {
                for k in 0..=tv {
                    verts.push(s.point(
                        u0 + (u1 - u0) * i as f64 / tu as f64,
                        v0 + (v1 - v0) * k as f64 / tv as f64,
                    ));
                }
            }
            let id = |i: usize, k: usize| ((i % tu) * (tv + 1) + k) as u32;
            let mut tris = Vec::new();
            for i in 0..tu {
                for k in 0..tv {
                    tris.push([id(i, k), id(i + 1, k), id(i + 1, k + 1)]);
                    tris.push([id(i, k), id(i + 1, k + 1), id(i, k + 1)]);
                }
            }
            let tess = Bvh::new(&TriMesh::new(verts, tris));
            let (mut worst, mut at, mut n, mut n_over) = (0.0f64, P3::origin(), 0usize, 0usize);
            for x in &m.vertices {
                let c = tess.closest_point(x).unwrap();
                let (i, k) = (c.triangle / 2 / tv, c.triangle / 2 % tv);
                if k == 0 || k + 1 >= tv {
                    continue;
                }
                let mut u = u0 + (u1 - u0) * (i as f64 + 0.5) / tu as f64;
                let mut v = v0 + (v1 - v0) * (k as f64 + 0.5) / tv as f64;
                keep::project(s, x, &mut u, &mut v, 8);
                let d = (s.point(u, v) - x).norm().min(c.distance);
                n += 1;
                if d > 0.1 {
                    n_over += 1;
                }
                if d > worst {
                    worst = d;
                    at = *x;
                }
            }
            println!(
                "  mesh vertices to the surface: {n} vertices, max {worst:.3} mm at ({:.1}, \
                 {:.1}, {:.1}), {n_over} over 0.1 mm",
                at.x, at.y, at.z
            );
        }
    }
}
