//! Surfaces through slices, and the closed mesh of a filled last.
//!
//! By default ([`skin_split`]) one skin runs through every slice from heel to toe (periodic
//! cubic around at the shared point parameters, cubic across) and is split at the two
//! boundary slices, as the Gordon join splits its one surface: the seams are interior, so
//! curvature carries across them; what the fill's slices do at a seam then shows as the
//! kept part's end bending away from its original last, which is measured against that
//! last ([`crate::join::reference`]). Or ([`skin_slices`]) each piece is skinned through its
//! own slices only, with the end derivatives taken from the piece's own two end slices; the
//! seam figures then say what the fill's slices carry across the seam, not what a skin
//! through both sides would smooth over.

use super::Slice;
use crate::join::gordon::split_v;
use crate::join::tessellation::Tessellation;
use footscan_geom::mesh::TriMesh;
use footscan_geom::nurbs::fit::interpolate_with;
use footscan_geom::nurbs::skin::interpolate_grid;
use footscan_geom::nurbs::{NurbsError, NurbsSurface};
use footscan_geom::{P3, V3};

/// One skin through all `slices` (z increasing) at the point parameters `u`, v in
/// proportion to z, split at the slices at `z_back` and `z_toe` into the back part, the fill
/// and the toe part, each on [0, 1] x [0, 1].
pub fn skin_split(
    slices: &[Slice],
    u: &[f64],
    z_back: f64,
    z_toe: f64,
) -> Result<(NurbsSurface, NurbsSurface, NurbsSurface), NurbsError> {
    let nl = slices.len();
    let nk = u.len();
    let (z0, z1) = (slices[0].z, slices[nl - 1].z);
    let v: Vec<f64> = slices.iter().map(|s| (s.z - z0) / (z1 - z0)).collect();
    let at = |z: f64| {
        v.iter()
            .zip(slices)
            .find(|(_, s)| (s.z - z).abs() < 1e-9)
            .map(|(v, _)| *v)
            .ok_or_else(|| NurbsError::Invalid {
                what: "slice skin split",
                reason: format!("no slice at z = {z} mm"),
            })
    };
    let (vb, vt) = (at(z_back)?, at(z_toe)?);
    let mut grid = Vec::with_capacity(nk * nl);
    for k in 0..nk {
        for s in slices {
            grid.push(s.points[k]);
        }
    }
    let all = interpolate_grid(&grid, u, &v, 3, 3, true)?;
    let (back, rest) = split_v(&all, vb)?;
    let (fill, toe) = split_v(&rest, vt)?;
    let unit = |s: NurbsSurface| s.reparametrized((0.0, 1.0), (0.0, 1.0));
    Ok((unit(back), unit(fill), unit(toe)))
}

/// Skin the slices `slices[l]` (at positions `z[l]` along the slice normal, increasing)
/// through their points at parameters `u` (periodic, period 1). v runs over [0, 1] in
/// proportion to z.
pub fn skin_slices(slices: &[Vec<P3>], u: &[f64], z: &[f64]) -> Result<NurbsSurface, NurbsError> {
    let nl = slices.len();
    let nk = u.len();
    if nl < 3 {
        return Err(NurbsError::Invalid {
            what: "slice skinning",
            reason: format!("{nl} slices; need at least 3"),
        });
    }
    let span = z[nl - 1] - z[0];
    let v: Vec<f64> = z.iter().map(|zz| (zz - z[0]) / span).collect();
    // Derivative rows d/dv at both ends: the chord to the neighbour slice, the same
    // one-sided first difference the discrete tangent condition of the extension matches
    // (forward difference of the fill = backward difference of the part, up to a slide
    // along the slice), so the seam's normal jump is zero exactly when that condition holds.
    let chord = |a: usize, b: usize| -> Vec<V3> {
        (0..nk)
            .map(|k| (slices[b][k] - slices[a][k]) / (v[b] - v[a]))
            .collect()
    };
    let d0 = chord(0, 1);
    let d1 = chord(nl - 2, nl - 1);
    // Around the slices first: rows [d0, slices.., d1], linear (identity) across, so the
    // result's control net holds each row's periodic interpolant.
    let rows = nl + 2;
    let mut grid = Vec::with_capacity(nk * rows);
    for k in 0..nk {
        grid.push(P3::from(d0[k]));
        for s in slices {
            grid.push(s[k]);
        }
        grid.push(P3::from(d1[k]));
    }
    let ident: Vec<f64> = (0..rows).map(|l| l as f64).collect();
    let around = interpolate_grid(&grid, u, &ident, 3, 1, true)?;
    // Then across: one interpolation with end derivatives per control column.
    let mut points = Vec::with_capacity(around.nu * (nl + 2));
    let mut knots_v = Vec::new();
    let mut nv = 0;
    let mut degree_v = 3;
    for i in 0..around.nu {
        let col = &around.points[i * rows..(i + 1) * rows];
        let c = interpolate_with(
            &col[1..rows - 1],
            &v,
            3,
            Some((col[0].coords, col[rows - 1].coords)),
        )?;
        if i == 0 {
            knots_v = c.knots.clone();
            nv = c.points.len();
            degree_v = c.degree;
        }
        points.extend(c.points);
    }
    let s = NurbsSurface {
        degree_u: around.degree_u,
        degree_v,
        knots_u: around.knots_u.clone(),
        knots_v,
        nu: around.nu,
        nv,
        points,
        weights: None,
        periodic_u: true,
        periodic_v: false,
    };
    s.validate()?;
    Ok(s)
}

/// Tessellate the pieces into one closed mesh: `nu` points around, rows about every
/// `step_mm` along each piece, seam rows shared, ends closed by fans to `ends`. Parts are
/// numbered by their index in `pieces` (0 back, 1 fill, 2 toe) for the pictures.
pub fn tessellate(
    pieces: &[&NurbsSurface],
    ends: (P3, P3),
    nu: usize,
    step_mm: f64,
) -> Tessellation {
    let mut t = Tessellation {
        vertices: Vec::new(),
        normals: Vec::new(),
        part: Vec::new(),
        triangles: Vec::new(),
    };
    let mut rows = 0usize;
    for (k, s) in pieces.iter().enumerate() {
        let len = (0..8)
            .map(|i| {
                let u = i as f64 / 8.0;
                (1..=24)
                    .map(|q| {
                        (s.point(u, q as f64 / 24.0) - s.point(u, (q - 1) as f64 / 24.0)).norm()
                    })
                    .sum::<f64>()
            })
            .fold(0.0, f64::max);
        let nv = ((len / step_mm).ceil() as usize).max(2);
        let first = usize::from(k != 0);
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
    let first = t.vertices.len() as u32;
    let axis = (ends.1 - ends.0).normalize();
    t.vertices.push(ends.0);
    t.normals.push(-axis);
    t.part.push(0);
    t.vertices.push(ends.1);
    t.normals.push(axis);
    t.part.push((pieces.len() - 1) as u8);
    for i in 0..nu {
        t.triangles.push([first, idx(0, i + 1), idx(0, i)]);
        t.triangles
            .push([first + 1, idx(rows - 1, i), idx(rows - 1, i + 1)]);
    }
    let m = TriMesh::new(t.vertices.clone(), t.triangles.clone());
    if m.volume() < 0.0 {
        for tr in t.triangles.iter_mut() {
            tr.swap(1, 2);
        }
    }
    t
}
