//! The original last at a cut: a surface skinned through the uncut last's slices either side
//! of the cutting plane, the same section code as the joins, so a joined last's seam can be
//! measured against the last its kept part came from.
//!
//! Both joining methods make their seams interior to one C2 surface through the kept parts'
//! sections and the fill (or patch), so the seam figures between the pieces pass by
//! construction. What the fill does at the seam then shows as the kept part's end bending
//! away from its original last; measuring the joined surface at the seam against this
//! reference says how far (normal angle, curvature across the seam), on the same scale for
//! both methods.

use super::error::JoinError;
use super::seam::{self, SeamMetrics};
use super::sections::{self, Section};
use footscan_geom::mesh::TriMesh;
use footscan_geom::nurbs::skin::interpolate_grid;
use footscan_geom::nurbs::NurbsSurface;
use footscan_geom::plane::Plane;

/// Slices either side of the plane, their step (mm) and points per slice: the Gordon join's
/// part step, and a ring dense enough for the nearest-point search of the seam figures.
pub const HALF: usize = 3;
pub const STEP_MM: f64 = 2.5;
pub const POINTS: usize = 400;

/// The last `mesh` (as placed in the common frame) near `plane`: 2 [`HALF`] + 1 slices
/// [`STEP_MM`] apart centred on the plane, resampled as the joins resample theirs and
/// interpolated cubic in both directions; the plane's slice is at v = 1/2. `last` names the
/// last in errors.
pub fn near_plane(mesh: &TriMesh, plane: &Plane, last: &str) -> Result<NurbsSurface, JoinError> {
    let n = 2 * HALF + 1;
    let mut secs: Vec<Section> = Vec::with_capacity(n);
    for j in 0..n {
        let off = (j as f64 - HALF as f64) * STEP_MM;
        let pl = Plane {
            origin: plane.origin + plane.normal * off,
            ..*plane
        };
        secs.push(sections::cut(mesh, &pl, off, last)?);
    }
    let refs: Vec<&Section> = secs.iter().collect();
    let what = |s: usize| {
        format!(
            "of the {last} last at {:+.1} mm from its cutting plane (reference)",
            (s as f64 - HALF as f64) * STEP_MM
        )
    };
    let cr = sections::crossings(&refs, 45.0, 0.05, &what)?;
    let (u, _, pts) = sections::resample(&refs, &cr, POINTS);
    let v: Vec<f64> = (0..n).map(|j| j as f64 / (n - 1) as f64).collect();
    let mut grid = Vec::with_capacity(u.len() * n);
    for k in 0..u.len() {
        for s in &pts {
            grid.push(s[k]);
        }
    }
    Ok(interpolate_grid(&grid, &u, &v, 3, 3, true)?)
}

/// The seam figures of a joined surface's seam (`joined` at v = `v`) against the original
/// last there (`reference` from [`near_plane`]): how far the seam strays from the original's
/// section, the angle between their normals, the jump of the normal curvature across.
pub fn against(
    joined: &NurbsSurface,
    v: f64,
    reference: &NurbsSurface,
    samples: usize,
) -> SeamMetrics {
    seam::seam(joined, v, reference, 0.5, samples)
}

/// Both seams of a joined last against the original lasts: the back part's surface at its
/// end (v = 1) against the back last near the back plane, the toe part's at its start (v = 0)
/// against the toe last near the toe plane.
pub fn seams_against_originals(
    (back, toe): (&NurbsSurface, &NurbsSurface),
    (back_mesh, toe_mesh): (&TriMesh, &TriMesh),
    (back_plane, toe_plane): (&Plane, &Plane),
    samples: usize,
) -> Result<[SeamMetrics; 2], JoinError> {
    let rb = near_plane(back_mesh, back_plane, "back")?;
    let rt = near_plane(toe_mesh, toe_plane, "toe")?;
    Ok([
        against(back, 1.0, &rb, samples),
        against(toe, 0.0, &rt, samples),
    ])
}

/// How far the original last is itself from G1 along a cut: the angle between the normals of
/// every two facets that share an edge within `band_mm` of `plane`, degrees (max, mean). A
/// scanned last is a polyhedron; its facets meet at angles that no smooth surface through its
/// sections can follow, so this is the floor of the normal figure of [`against`].
pub fn facet_angles(mesh: &TriMesh, plane: &Plane, band_mm: f64) -> (f64, f64) {
    use std::collections::HashMap;
    let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    let (mut max, mut sum, mut n) = (0.0f64, 0.0, 0usize);
    for ((a, b), faces) in &edges {
        if faces.len() != 2 {
            continue;
        }
        let (pa, pb) = (mesh.vertices[*a as usize], mesh.vertices[*b as usize]);
        let (da, db) = (plane.signed_distance(&pa), plane.signed_distance(&pb));
        if da.min(db) > band_mm || da.max(db) < -band_mm {
            continue;
        }
        let c = mesh
            .face_normal(faces[0])
            .dot(&mesh.face_normal(faces[1]))
            .clamp(-1.0, 1.0);
        let ang = c.acos().to_degrees();
        max = max.max(ang);
        sum += ang;
        n += 1;
    }
    (max, sum / n.max(1) as f64)
}
