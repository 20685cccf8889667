//! The solid as a STEP file (ISO 10303-21, AP214 AUTOMOTIVE_DESIGN, millimetres): a
//! FACETED_BREP, the form STEP gives a closed solid of planar faces. Each face is a
//! FACE_SURFACE on a PLANE bounded by a POLY_LOOP of shared CARTESIAN_POINTs: the top's
//! triangles, one quad per wall chord, and the bottom as one polygon per boundary loop
//! (or its triangles when the top has more than one loop). All faces sit in one CLOSED_SHELL.

use crate::surface::solid::OutlineSolid;
use footscan_geom::export::step::Document;
use footscan_geom::export::{real, Header};
use footscan_geom::{P3, V3};
use std::path::Path;

/// Writes `solid` to `path` as a faceted STEP solid, atomically; returns the face count.
pub fn write_faceted_step(path: &Path, solid: &OutlineSolid, name: &str) -> std::io::Result<usize> {
    let (text, faces) = faceted_step(solid, name);
    crate::io::write_atomic(path, text.as_bytes())?;
    Ok(faces)
}

/// The STEP text of `solid` and its number of faces.
pub fn faceted_step(solid: &OutlineSolid, name: &str) -> (String, usize) {
    let mut w = Document::new(
        &Header::new(name),
        "footscan foot model: faceted closed solid, millimetres, foot frame",
    );
    let (name, ctx, pds, axis) = (w.name.clone(), w.ctx, w.pds, w.axis);

    // Points: every vertex a face uses, once.
    let v = &solid.vertices;
    let mut point = vec![0usize; v.len()];
    let mut used = vec![false; v.len()];
    for t in &solid.top {
        for &k in t {
            used[k as usize] = true;
            used[k as usize + 1] = true;
        }
    }
    for (k, p) in v.iter().enumerate() {
        if used[k] {
            point[k] = w.point(*p);
        }
    }
    let mut faces = Vec::new();
    for f in facets(solid) {
        let (p0, p1) = (v[f.ids[0] as usize], v[f.ids[1] as usize]);
        let n = f.normal;
        let loop_ = w.add(format!(
            "POLY_LOOP('',({}))",
            f.ids
                .iter()
                .map(|&k| format!("#{}", point[k as usize]))
                .collect::<Vec<_>>()
                .join(",")
        ));
        let bound = w.add(format!("FACE_OUTER_BOUND('',#{loop_},.T.)"));
        // The plane through the first point, its normal the loop's (Newell), x along the
        // first edge made perpendicular to it.
        let e = p1 - p0;
        let xd = unit(e - n * e.dot(&n));
        let nd = w.add(format!(
            "DIRECTION('',({},{},{}))",
            real(n[0]),
            real(n[1]),
            real(n[2])
        ));
        let xr = w.add(format!(
            "DIRECTION('',({},{},{}))",
            real(xd[0]),
            real(xd[1]),
            real(xd[2])
        ));
        let ax = w.add(format!(
            "AXIS2_PLACEMENT_3D('',#{},#{nd},#{xr})",
            point[f.ids[0] as usize]
        ));
        let plane = w.add(format!("PLANE('',#{ax})"));
        faces.push(w.add(format!("FACE_SURFACE('',(#{bound}),#{plane},.T.)")));
    }
    let count = faces.len();
    let shell = w.add(format!(
        "CLOSED_SHELL('',({}))",
        faces
            .iter()
            .map(|f| format!("#{f}"))
            .collect::<Vec<_>>()
            .join(",")
    ));
    let brep = w.add(format!("FACETED_BREP({name},#{shell})"));
    let rep = w.add(format!(
        "FACETED_BREP_SHAPE_REPRESENTATION({name},(#{brep},#{axis}),#{ctx})"
    ));
    w.add(format!("SHAPE_DEFINITION_REPRESENTATION(#{pds},#{rep})"));

    let out = w.finish();
    (out, count)
}

/// One planar face of the solid: its vertex loop (counterclockwise seen from outside) and
/// its outward unit normal.
pub(crate) struct Facet {
    pub ids: Vec<u32>,
    pub normal: V3,
}

/// The faces of `solid`: the top's triangles, one quad per wall chord, and the bottom as one
/// polygon (its triangles when the top has more than one boundary loop or the bottom is not
/// flat).
pub(crate) fn facets(solid: &OutlineSolid) -> Vec<Facet> {
    let v = &solid.vertices;
    let mut out = Vec::with_capacity(solid.top.len() + solid.boundary_len() + 1);
    let mut add = |ids: Vec<u32>| {
        let pts: Vec<P3> = ids.iter().map(|&k| v[k as usize]).collect();
        let normal = newell(&pts);
        out.push(Facet { ids, normal });
    };
    for t in &solid.top {
        add(t.to_vec());
    }
    for lp in &solid.loops {
        for k in 0..lp.len() {
            let (a, b) = (lp[k], lp[(k + 1) % lp.len()]);
            add(vec![a, a + 1, b + 1, b]);
        }
    }
    // One polygon only when it is planar: a bottom bent along a curve (an insole on a
    // shoe's heel and toe spring) is written as the top's triangulation too.
    let bz = solid
        .loops
        .first()
        .and_then(|l| l.first())
        .map(|&k| v[k as usize + 1][2]);
    let flat = solid
        .loops
        .iter()
        .flatten()
        .all(|&k| Some(v[k as usize + 1][2]) == bz)
        && solid
            .top
            .iter()
            .flatten()
            .all(|&k| Some(v[k as usize + 1][2]) == bz);
    if solid.loops.len() == 1 && flat {
        add(solid.loops[0].iter().rev().map(|&k| k + 1).collect());
    } else {
        for &[a, b, c] in &solid.top {
            add(vec![a + 1, c + 1, b + 1]);
        }
    }
    out
}

/// Unit normal of a planar polygon by Newell's method (robust for any vertex count).
fn newell(p: &[P3]) -> V3 {
    let mut n = V3::zeros();
    for k in 0..p.len() {
        let (a, b) = (p[k], p[(k + 1) % p.len()]);
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    unit(n)
}

fn unit(a: V3) -> V3 {
    let l = a.norm();
    if l > 0.0 {
        a / l
    } else {
        V3::z()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::solid::outline_solid;

    #[test]
    fn a_box_has_six_kinds_of_faces_and_every_point_once() {
        let poly = [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]].map(footscan_geom::P2::from);
        let s = outline_solid(&poly, 0.5, Some(-1.0), |_, _| Some(1.0)).unwrap();
        let (text, faces) = faceted_step(&s, "box");
        // 2 x 4 cells (16 triangles) at the top plus walls and the bottom.
        assert_eq!(faces, s.top.len() + s.boundary_len() + 1);
        assert!(text.contains("FACETED_BREP('box',"));
        assert_eq!(text.matches("CLOSED_SHELL").count(), 1);
        assert!(real(1e-7).contains(".E"), "{}", real(1e-7));
        assert_eq!(real(3.0), "3.");
    }
}
