//! Seam quality of a joined last, the same figures for every joining method: along the whole
//! seam, the position gap, the angle between the normals of the two sides and the jump of
//! the normal curvature across the seam; and how far each kept part strays from the mesh
//! it was fitted to.
//!
//! The two sides of a seam are given as surfaces and the v of the seam's iso-curve on each,
//! so a method whose sides are parametrised differently (another point count, another
//! start) is measured the same way: each sample of side A is matched to the nearest point of
//! side B's seam curve.

use footscan_geom::mesh::{Bvh, TriMesh};
use footscan_geom::nurbs::NurbsSurface;
use footscan_geom::{P3, V3};
use serde::Serialize;

/// Below this curvature (1/mm, a radius of 1 m) a relative curvature jump is taken relative
/// to it instead, so flat stretches do not divide by zero.
pub const CURVATURE_FLOOR: f64 = 1e-3;

/// Figures of one seam over `samples` points along it.
#[derive(Debug, Clone, Copy, Serialize, Default)]
pub struct SeamMetrics {
    pub samples: usize,
    /// Position gap, mm: max and mean.
    pub gap_max_mm: f64,
    pub gap_mean_mm: f64,
    /// Angle between the two normals, degrees: max and mean.
    pub normal_max_deg: f64,
    pub normal_mean_deg: f64,
    /// |k_A - k_B| / max(|k_A|, |k_B|, floor) of the normal curvature across the seam: max
    /// and mean.
    pub curvature_rel_max: f64,
    pub curvature_rel_mean: f64,
    /// Largest absolute jump of that curvature, 1/mm.
    pub curvature_abs_max: f64,
}

/// Deviation of a fitted surface from a mesh, sampled on a grid of the surface, mm.
#[derive(Debug, Clone, Copy, Serialize, Default)]
pub struct Deviation {
    pub samples: usize,
    pub rms_mm: f64,
    pub max_mm: f64,
    /// Where the largest deviation is.
    pub max_at: P3,
}

fn unit(v: V3) -> V3 {
    let n = v.norm();
    if n > 0.0 {
        v / n
    } else {
        v
    }
}

/// Measure the seam between side A (`a` at v = `va`) and side B (`b` at v = `vb`).
pub fn seam(a: &NurbsSurface, va: f64, b: &NurbsSurface, vb: f64, samples: usize) -> SeamMetrics {
    let (ua0, ua1) = a.domain_u();
    let (ub0, ub1) = b.domain_u();
    // Coarse table of side B's seam curve for the nearest-point search.
    let nb = 400;
    let ub_at = |k: f64| ub0 + (ub1 - ub0) * k / nb as f64;
    let table: Vec<P3> = (0..=nb).map(|k| b.point(ub_at(k as f64), vb)).collect();
    let mut m = SeamMetrics {
        samples,
        ..Default::default()
    };
    for s in 0..samples {
        let ua = ua0 + (ua1 - ua0) * (s as f64 + 0.5) / samples as f64;
        let pa = a.point(ua, va);
        let k0 = (0..=nb)
            .min_by(|&i, &j| (table[i] - pa).norm().total_cmp(&(table[j] - pa).norm()))
            .unwrap();
        // Golden-section search on the bracketing cells.
        let (mut lo, mut hi) = (ub_at(k0 as f64 - 1.0), ub_at(k0 as f64 + 1.0));
        if !b.periodic_u {
            lo = lo.max(ub0);
            hi = hi.min(ub1);
        }
        let f = |u: f64| (b.point(u, vb) - pa).norm();
        let g = 0.5 * (5f64.sqrt() - 1.0);
        let (mut x1, mut x2) = (hi - g * (hi - lo), lo + g * (hi - lo));
        let (mut f1, mut f2) = (f(x1), f(x2));
        for _ in 0..60 {
            if f1 < f2 {
                hi = x2;
                x2 = x1;
                f2 = f1;
                x1 = hi - g * (hi - lo);
                f1 = f(x1);
            } else {
                lo = x1;
                x1 = x2;
                f1 = f2;
                x2 = lo + g * (hi - lo);
                f2 = f(x2);
            }
        }
        let ub = 0.5 * (lo + hi);
        let gap = f(ub);
        let ca = a.curvature(ua, va);
        let cb = b.curvature(ub, vb);
        let dot = ca.normal.dot(&cb.normal);
        let sign = if dot < 0.0 { -1.0 } else { 1.0 };
        let angle = dot.abs().min(1.0).acos().to_degrees();
        // Across the seam: in A's tangent plane, perpendicular to the seam tangent.
        let da = a.derivatives(ua, va, 1);
        let t_seam = unit(da[1][0]);
        let across = unit(ca.normal.cross(&t_seam));
        let ka = a.normal_curvature(ua, va, &across);
        let across_b = unit(across - cb.normal * across.dot(&cb.normal));
        let kb = sign * b.normal_curvature(ub, vb, &across_b);
        let jump = (ka - kb).abs();
        let rel = jump / ka.abs().max(kb.abs()).max(CURVATURE_FLOOR);
        m.gap_max_mm = m.gap_max_mm.max(gap);
        m.gap_mean_mm += gap / samples as f64;
        m.normal_max_deg = m.normal_max_deg.max(angle);
        m.normal_mean_deg += angle / samples as f64;
        m.curvature_rel_max = m.curvature_rel_max.max(rel);
        m.curvature_rel_mean += rel / samples as f64;
        m.curvature_abs_max = m.curvature_abs_max.max(jump);
    }
    m
}

/// Deviation of surface `s` from `mesh` on an `nu` x `nv` grid of its domain.
pub fn deviation(s: &NurbsSurface, mesh: &TriMesh, nu: usize, nv: usize) -> Deviation {
    deviation_bvh(s, &Bvh::new(mesh), nu, nv)
}

/// [`deviation`] with a tree built once.
pub fn deviation_bvh(s: &NurbsSurface, bvh: &Bvh, nu: usize, nv: usize) -> Deviation {
    let (u0, u1) = s.domain_u();
    let (v0, v1) = s.domain_v();
    let mut d = Deviation::default();
    let mut sum = 0.0;
    for i in 0..nu {
        let u = u0 + (u1 - u0) * i as f64 / nu as f64;
        for j in 0..nv {
            let v = v0 + (v1 - v0) * j as f64 / (nv - 1).max(1) as f64;
            let p = s.point(u, v);
            if let Some(c) = bvh.closest_point(&p) {
                sum += c.distance * c.distance;
                d.samples += 1;
                if c.distance > d.max_mm {
                    d.max_mm = c.distance;
                    d.max_at = p;
                }
            }
        }
    }
    d.rms_mm = (sum / d.samples.max(1) as f64).sqrt();
    d
}
