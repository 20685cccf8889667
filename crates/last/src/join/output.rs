//! What a join hands over: the surfaces as IGES and STEP, a closed STL of the whole last,
//! the curve network and the seam figures as JSON, and the pictures.

use super::gordon::Network;
use super::seam::{self, Deviation, SeamMetrics};
pub use super::tessellation::Tessellation;
use super::{reference, zebra, JoinError, Joined, Timings};
use footscan_geom::export::{iges, step, Header};
use footscan_geom::mesh::{Format, TriMesh};
use footscan_geom::nurbs::{NurbsCurve, NurbsSurface};
use footscan_geom::P3;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Seam and fit figures of a joined last.
#[derive(Debug, Clone, Serialize)]
pub struct Quality {
    /// Back part / join patch and join patch / toe part.
    pub back_seam: SeamMetrics,
    pub toe_seam: SeamMetrics,
    /// Kept parts against the meshes they came from.
    pub back_deviation: Deviation,
    pub toe_deviation: Deviation,
    /// The joined surface at each seam against the original last there
    /// ([`super::reference`]): the same figures, the kept part's end against the last it came
    /// from.
    pub back_original: SeamMetrics,
    pub toe_original: SeamMetrics,
    /// Largest |S_guides - T| over the surface, mm: what the guides add to the section skin.
    pub guides_contribution_mm: f64,
    /// Largest distance between sections and guides at their common parameters, mm.
    pub network_mismatch_mm: f64,
    /// The original lasts' own facet angles within 2.5 mm of each plane, deg (max, mean):
    /// what a seam against them cannot go below ([`reference::facet_angles`]).
    pub back_facets_deg: (f64, f64),
    pub toe_facets_deg: (f64, f64),
    /// How the kept parts were fitted to their meshes (back, toe), when they were.
    pub fits: Option<[super::keep::PartFit; 2]>,
}

/// Measure a joined last (seams with `samples` points each); fails only where the original
/// lasts cannot be cut for the reference near the planes.
pub fn quality(j: &Joined, samples: usize) -> Result<Quality, JoinError> {
    let [back_original, toe_original] = reference::seams_against_originals(
        (&j.back, &j.toe),
        (&j.back_mesh, &j.toe_mesh),
        (&j.back_plane, &j.toe_plane),
        samples,
    )?;
    let back_seam = seam::seam(&j.back, 1.0, &j.patch, 0.0, samples);
    let toe_seam = seam::seam(&j.patch, 1.0, &j.toe, 0.0, samples);
    let back_deviation = seam::deviation(&j.back, &j.back_mesh, 240, 120);
    let toe_deviation = seam::deviation(&j.toe, &j.toe_mesh, 240, 80);
    let g = &j.gordon;
    let guides_contribution_mm = g
        .s_guides
        .points
        .iter()
        .zip(&g.tensor.points)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max);
    Ok(Quality {
        back_seam,
        toe_seam,
        back_deviation,
        toe_deviation,
        back_original,
        toe_original,
        guides_contribution_mm,
        network_mismatch_mm: g.network_mismatch,
        back_facets_deg: reference::facet_angles(&j.back_mesh, &j.back_plane, 2.5),
        toe_facets_deg: reference::facet_angles(&j.toe_mesh, &j.toe_plane, 2.5),
        fits: j.fits,
    })
}

/// Tessellate the three surfaces into one closed mesh: `nu` points around, rows about every
/// `step_mm` along, the seam rows shared, and each end closed by a fan to its end point.
pub fn tessellate(j: &Joined, nu: usize, step_mm: f64) -> Tessellation {
    let mut t = Tessellation {
        vertices: Vec::new(),
        normals: Vec::new(),
        part: Vec::new(),
        triangles: Vec::new(),
    };
    let surfs: [&NurbsSurface; 3] = [&j.back, &j.patch, &j.toe];
    let mut rows = 0usize;
    for (k, s) in surfs.iter().enumerate() {
        // Length along v from the mean distance between the end sections' points.
        let len = (0..16)
            .map(|i| {
                let u = i as f64 / 16.0;
                let mut l = 0.0;
                let mut prev = s.point(u, 0.0);
                for q in 1..=32 {
                    let p = s.point(u, q as f64 / 32.0);
                    l += (p - prev).norm();
                    prev = p;
                }
                l
            })
            .sum::<f64>()
            / 16.0;
        let nv = ((len / step_mm).ceil() as usize).max(2);
        let first = if k == 0 { 0 } else { 1 };
        for jv in first..=nv {
            let v = jv as f64 / nv as f64;
            for i in 0..nu {
                let u = i as f64 / nu as f64;
                t.vertices.push(s.point(u, v));
                t.normals.push(s.normal(u, v));
                t.part.push(k as u8);
            }
            rows += 1;
        }
    }
    let idx = |r: usize, i: usize| (r * nu + i % nu) as u32;
    for r in 0..rows - 1 {
        for i in 0..nu {
            t.triangles
                .push([idx(r, i), idx(r, i + 1), idx(r + 1, i + 1)]);
            t.triangles
                .push([idx(r, i), idx(r + 1, i + 1), idx(r + 1, i)]);
        }
    }
    // End caps.
    let heel = t.vertices.len() as u32;
    t.vertices.push(j.heel_end);
    t.normals.push(-j.back_plane.normal);
    t.part.push(0);
    let tip = t.vertices.len() as u32;
    t.vertices.push(j.toe_end);
    t.normals.push(j.toe_plane.normal);
    t.part.push(2);
    for i in 0..nu {
        t.triangles.push([heel, idx(0, i + 1), idx(0, i)]);
        t.triangles
            .push([tip, idx(rows - 1, i), idx(rows - 1, i + 1)]);
    }
    // Make the orientation outward (positive volume).
    let m = TriMesh::new(t.vertices.clone(), t.triangles.clone());
    if m.volume() < 0.0 {
        for tr in t.triangles.iter_mut() {
            tr.swap(1, 2);
        }
    }
    t
}

/// The closed STL of a join whose kept parts were fitted: the original meshes themselves on
/// the kept sides of the planes (trimmed there), the patch between them with `nu` points
/// around and rows about every `step_mm`, each seam closed by a strip between the trimmed
/// mesh's boundary and the patch's end row (they are at most [`super::keep::TOL_MM`] apart,
/// the fitted parts' distance from their meshes). Without fitted parts, or when a plane does
/// not leave one loop, [`tessellate`].
pub fn tessellate_kept(j: &Joined, nu: usize, step_mm: f64) -> Tessellation {
    if j.fits.is_none() {
        return tessellate(j, nu, step_mm);
    }
    let (bm, bl) = super::keep::trim(&j.back_mesh, &j.back_plane, -1.0);
    let (tm, tl) = super::keep::trim(&j.toe_mesh, &j.toe_plane, 1.0);
    if bl.len() < 3 || tl.len() < 3 {
        return tessellate(j, nu, step_mm);
    }
    let mut t = Tessellation {
        vertices: Vec::new(),
        normals: Vec::new(),
        part: Vec::new(),
        triangles: Vec::new(),
    };
    let add_mesh = |t: &mut Tessellation, m: &TriMesh, part: u8| -> u32 {
        let base = t.vertices.len() as u32;
        t.vertices.extend_from_slice(&m.vertices);
        t.normals.extend(m.vertex_normals());
        t.part.extend(std::iter::repeat_n(part, m.vertices.len()));
        t.triangles.extend(
            m.triangles
                .iter()
                .map(|tr| [tr[0] + base, tr[1] + base, tr[2] + base]),
        );
        base
    };
    let bb = add_mesh(&mut t, &bm, 0);
    // The patch's rows, v = 0 (the back seam) to 1.
    let s = &j.patch;
    let len = (0..16)
        .map(|i| (s.point(i as f64 / 16.0, 0.0) - s.point(i as f64 / 16.0, 1.0)).norm())
        .sum::<f64>()
        / 16.0;
    let nv = ((len / step_mm).ceil() as usize).max(2);
    let pb = t.vertices.len() as u32;
    for jv in 0..=nv {
        let v = jv as f64 / nv as f64;
        for i in 0..nu {
            let u = i as f64 / nu as f64;
            t.vertices.push(s.point(u, v));
            t.normals.push(s.normal(u, v));
            t.part.push(1);
        }
    }
    let idx = |r: usize, i: usize| pb + (r * nu + i % nu) as u32;
    for r in 0..nv {
        for i in 0..nu {
            t.triangles
                .push([idx(r, i), idx(r, i + 1), idx(r + 1, i + 1)]);
            t.triangles
                .push([idx(r, i), idx(r + 1, i + 1), idx(r + 1, i)]);
        }
    }
    let tb = add_mesh(&mut t, &tm, 2);
    let axis = j.back_plane.normal;
    let row = |r: usize| (0..nu).map(|i| idx(r, i)).collect::<Vec<u32>>();
    for (lp, base, r) in [(&bl, bb, 0), (&tl, tb, nv)] {
        let mut a: Vec<u32> = lp.iter().map(|&i| i + base).collect();
        let b = row(r);
        if super::keep::turn(&t.vertices, &a, &axis) != super::keep::turn(&t.vertices, &b, &axis) {
            a.reverse();
        }
        let z = super::keep::zip(&t.vertices, &a, &b);
        t.triangles.extend(z);
    }
    let mut m = TriMesh::new(t.vertices.clone(), t.triangles.clone());
    if footscan_geom::mesh::orient_consistently(&mut m).is_ok() {
        if m.volume() < 0.0 {
            m.flip();
        }
        t.triangles = m.triangles;
    }
    t
}

#[derive(Serialize)]
struct CurveJson {
    degree: usize,
    knots: Vec<f64>,
    poles: Vec<P3>,
    periodic: bool,
}

fn curve_json(c: &NurbsCurve) -> CurveJson {
    CurveJson {
        degree: c.degree,
        knots: c.knots.clone(),
        poles: c.points.clone(),
        periodic: c.periodic,
    }
}

#[derive(Serialize)]
struct SurfaceJson {
    degree_u: usize,
    degree_v: usize,
    knots_u: Vec<f64>,
    knots_v: Vec<f64>,
    nu: usize,
    nv: usize,
    poles: Vec<P3>,
    periodic_u: bool,
}

fn surface_json(s: &NurbsSurface) -> SurfaceJson {
    SurfaceJson {
        degree_u: s.degree_u,
        degree_v: s.degree_v,
        knots_u: s.knots_u.clone(),
        knots_v: s.knots_v.clone(),
        nu: s.nu,
        nv: s.nv,
        poles: s.points.clone(),
        periodic_u: s.periodic_u,
    }
}

/// The curve network and our Gordon surface, for an independent rebuild (scripts/
/// occt_gordon_compare.py).
pub fn network_json(j: &Joined) -> String {
    network_json_of(&j.network, &j.gordon.surface, j.timings.gordon)
}

/// A curve network, the Gordon surface we built on it and our build time (ms) as JSON.
pub fn network_json_of(n: &Network, surface: &NurbsSurface, build_ms: f64) -> String {
    #[derive(Serialize)]
    struct Net {
        sections: Vec<CurveJson>,
        guides: Vec<CurveJson>,
        u_cross: Vec<f64>,
        v_cross: Vec<f64>,
        gordon: SurfaceJson,
        build_ms: f64,
    }
    serde_json::to_string(&Net {
        sections: n.sections.iter().map(curve_json).collect(),
        guides: n.guides.iter().map(curve_json).collect(),
        u_cross: n.u_cross.clone(),
        v_cross: n.v_cross.clone(),
        gordon: surface_json(surface),
        build_ms,
    })
    .expect("network serialises")
}

/// Everything [`write`] produced.
#[derive(Debug, Clone)]
pub struct Written {
    pub files: Vec<PathBuf>,
    pub quality: Quality,
}

#[derive(Serialize)]
struct Report<'a> {
    method: &'static str,
    quality: &'a Quality,
    timings: &'a Timings,
    sections: usize,
    guides: usize,
    points_per_section: usize,
    back_plane: [f64; 6],
    toe_plane: [f64; 6],
    stl: &'a str,
}

/// Write joined.igs, joined.step, joined.stl, seams.json, network.json, zebra.png and
/// views.png into `dir` (created if missing).
pub fn write(j: &Joined, dir: &Path, name: &str) -> std::io::Result<Written> {
    std::fs::create_dir_all(dir)?;
    let io =
        |e: footscan_geom::export::ExportError| std::io::Error::other(footscan_util::chain(&e));
    let surfs = [j.back.clone(), j.patch.clone(), j.toe.clone()];
    let header = Header::new(name);
    let mut files = Vec::new();
    let p = dir.join("joined.igs");
    iges::write(&p, &[], &surfs, &header).map_err(io)?;
    files.push(p);
    let p = dir.join("joined.step");
    step::write(&p, &[], &surfs, &header).map_err(io)?;
    files.push(p);
    let t = tessellate_kept(j, 240, 1.0);
    let mesh = TriMesh::new(t.vertices.clone(), t.triangles.clone());
    let stl_check = match mesh.check() {
        Ok(r) => format!("closed, volume {:.0} mm3", r.volume),
        Err(d) => format!("not closed: {d}"),
    };
    let p = dir.join("joined.stl");
    mesh.write(&p, Format::StlBinary)
        .map_err(|e| std::io::Error::other(footscan_util::chain(&e)))?;
    files.push(p);
    let quality = quality(j, 400).map_err(|e| std::io::Error::other(footscan_util::chain(&e)))?;
    let plane6 = |p: &footscan_geom::plane::Plane| {
        [
            p.origin.x, p.origin.y, p.origin.z, p.normal.x, p.normal.y, p.normal.z,
        ]
    };
    let report = Report {
        method: "gordon",
        quality: &quality,
        timings: &j.timings,
        sections: j.network.sections.len(),
        guides: j.network.guides.len(),
        points_per_section: j.network.sections[0].points.len() - j.network.sections[0].degree,
        back_plane: plane6(&j.back_plane),
        toe_plane: plane6(&j.toe_plane),
        stl: &stl_check,
    };
    let p = dir.join("seams.json");
    crate::draw::write_atomic(
        &p,
        serde_json::to_string_pretty(&report).unwrap().as_bytes(),
    )?;
    files.push(p);
    let p = dir.join("network.json");
    crate::draw::write_atomic(&p, network_json(j).as_bytes())?;
    files.push(p);
    let seam_pts: Vec<Vec<P3>> = [(&j.back, 1.0), (&j.toe, 0.0)]
        .iter()
        .map(|(s, v)| (0..=200).map(|i| s.point(i as f64 / 200.0, *v)).collect())
        .collect();
    let x0 = j.back_plane.origin.x - 35.0;
    let x1 = j.toe_plane.origin.x + 35.0;
    let q = &quality;
    let caption = format!(
        "{name}: seams back/toe gap {:.1e}/{:.1e} mm, normal {:.1e}/{:.1e} deg, curvature {:.1e}/{:.1e}",
        q.back_seam.gap_max_mm,
        q.toe_seam.gap_max_mm,
        q.back_seam.normal_max_deg,
        q.toe_seam.normal_max_deg,
        q.back_seam.curvature_rel_max,
        q.toe_seam.curvature_rel_max
    );
    let p = dir.join("zebra.png");
    zebra::zebra_png(&p, &t, (x0, x1), &seam_pts, &caption)?;
    files.push(p);
    let p = dir.join("views.png");
    zebra::views_png(&p, &t, &seam_pts, &caption)?;
    files.push(p);
    Ok(Written { files, quality })
}
