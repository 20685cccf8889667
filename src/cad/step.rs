//! The solid as a STEP file (ISO 10303-21, AP214 AUTOMOTIVE_DESIGN, millimetres): a
//! FACETED_BREP, the form STEP gives a closed solid of planar faces. Each face is a
//! FACE_SURFACE on a PLANE bounded by a POLY_LOOP of shared CARTESIAN_POINTs: the top's
//! triangles, one quad per wall chord, and the bottom as one polygon per boundary loop
//! (or its triangles when the top has more than one loop). All faces sit in one CLOSED_SHELL.

use crate::surface::solid::OutlineSolid;
use std::fmt::Write as _;
use std::path::Path;

/// Writes `solid` to `path` as a faceted STEP solid, atomically; returns the face count.
pub fn write_faceted_step(path: &Path, solid: &OutlineSolid, name: &str) -> std::io::Result<usize> {
    let (text, faces) = faceted_step(solid, name);
    crate::io::write_atomic(path, text.as_bytes())?;
    Ok(faces)
}

/// The STEP text of `solid` and its number of faces.
pub fn faceted_step(solid: &OutlineSolid, name: &str) -> (String, usize) {
    let mut w = Data::default();
    let name = quoted(name);
    let app = w.add("APPLICATION_CONTEXT('automotive design')".into());
    w.add(format!(
        "APPLICATION_PROTOCOL_DEFINITION('international standard','automotive_design',2000,#{app})"
    ));
    let pc = w.add(format!("PRODUCT_CONTEXT('',#{app},'mechanical')"));
    let product = w.add(format!("PRODUCT({name},{name},'',(#{pc}))"));
    w.add(format!(
        "PRODUCT_RELATED_PRODUCT_CATEGORY('part',$,(#{product}))"
    ));
    let pdf = w.add(format!("PRODUCT_DEFINITION_FORMATION('','',#{product})"));
    let pdc = w.add(format!(
        "PRODUCT_DEFINITION_CONTEXT('part definition',#{app},'design')"
    ));
    let pd = w.add(format!("PRODUCT_DEFINITION('design','',#{pdf},#{pdc})"));
    let pds = w.add(format!("PRODUCT_DEFINITION_SHAPE('','',#{pd})"));
    let mm = w.add("(LENGTH_UNIT()NAMED_UNIT(*)SI_UNIT(.MILLI.,.METRE.))".into());
    let rad = w.add("(NAMED_UNIT(*)PLANE_ANGLE_UNIT()SI_UNIT($,.RADIAN.))".into());
    let sr = w.add("(NAMED_UNIT(*)SI_UNIT($,.STERADIAN.)SOLID_ANGLE_UNIT())".into());
    let unc = w.add(format!(
        "UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE(1.E-6),#{mm},'distance_accuracy_value','confusion accuracy')"
    ));
    let ctx = w.add(format!(
        "(GEOMETRIC_REPRESENTATION_CONTEXT(3)GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT((#{unc}))GLOBAL_UNIT_ASSIGNED_CONTEXT((#{mm},#{rad},#{sr}))REPRESENTATION_CONTEXT('',''))"
    ));
    let origin = w.add("CARTESIAN_POINT('',(0.,0.,0.))".into());
    let dz = w.add("DIRECTION('',(0.,0.,1.))".into());
    let dx = w.add("DIRECTION('',(1.,0.,0.))".into());
    let axis = w.add(format!("AXIS2_PLACEMENT_3D('',#{origin},#{dz},#{dx})"));

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
            point[k] = w.add(format!(
                "CARTESIAN_POINT('',({},{},{}))",
                real(p[0]),
                real(p[1]),
                real(p[2])
            ));
        }
    }
    let mut faces = Vec::new();
    for f in facets(solid) {
        let pts: Vec<[f64; 3]> = f.ids.iter().map(|&k| v[k as usize]).collect();
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
        let e = sub(pts[1], pts[0]);
        let d = dot(e, n);
        let xd = unit([e[0] - d * n[0], e[1] - d * n[1], e[2] - d * n[2]]);
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

    let mut out = String::with_capacity(w.items.iter().map(|s| s.len() + 12).sum::<usize>() + 512);
    out.push_str("ISO-10303-21;\nHEADER;\n");
    out.push_str("FILE_DESCRIPTION(('footscan foot model: faceted closed solid, millimetres, foot frame'),'2;1');\n");
    let _ = writeln!(
        out,
        "FILE_NAME({name},'',('footscan'),(''),'footscan {}','footscan','');",
        env!("CARGO_PKG_VERSION")
    );
    out.push_str("FILE_SCHEMA(('AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }'));\nENDSEC;\nDATA;\n");
    for (i, body) in w.items.iter().enumerate() {
        wrap_into(&mut out, &format!("#{}={body};", i + 1));
    }
    out.push_str("ENDSEC;\nEND-ISO-10303-21;\n");
    (out, count)
}

/// One planar face of the solid: its vertex loop (counterclockwise seen from outside) and
/// its outward unit normal.
pub(crate) struct Facet {
    pub ids: Vec<u32>,
    pub normal: [f64; 3],
}

/// The faces of `solid`: the top's triangles, one quad per wall chord, and the bottom as one
/// polygon (its triangles when the top has more than one boundary loop).
pub(crate) fn facets(solid: &OutlineSolid) -> Vec<Facet> {
    let v = &solid.vertices;
    let mut out = Vec::with_capacity(solid.top.len() + solid.boundary_len() + 1);
    let mut add = |ids: Vec<u32>| {
        let pts: Vec<[f64; 3]> = ids.iter().map(|&k| v[k as usize]).collect();
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
    if solid.loops.len() == 1 {
        add(solid.loops[0].iter().rev().map(|&k| k + 1).collect());
    } else {
        for &[a, b, c] in &solid.top {
            add(vec![a + 1, c + 1, b + 1]);
        }
    }
    out
}

#[derive(Default)]
struct Data {
    items: Vec<String>,
}

impl Data {
    fn add(&mut self, body: String) -> usize {
        self.items.push(body);
        self.items.len()
    }
}

/// Unit normal of a planar polygon by Newell's method (robust for any vertex count).
fn newell(p: &[[f64; 3]]) -> [f64; 3] {
    let mut n = [0.0; 3];
    for k in 0..p.len() {
        let (a, b) = (p[k], p[(k + 1) % p.len()]);
        n[0] += (a[1] - b[1]) * (a[2] + b[2]);
        n[1] += (a[2] - b[2]) * (a[0] + b[0]);
        n[2] += (a[0] - b[0]) * (a[1] + b[1]);
    }
    unit(n)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn unit(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    if l > 0.0 {
        a.map(|c| c / l)
    } else {
        [0.0, 0.0, 1.0]
    }
}

/// A STEP string literal of printable ASCII, apostrophes and backslashes doubled.
fn quoted(s: &str) -> String {
    let clean: String = s
        .chars()
        .map(|c| if (' '..='~').contains(&c) { c } else { '?' })
        .collect();
    format!("'{}'", clean.replace('\\', "\\\\").replace('\'', "''"))
}

/// A real that reads back to the same f64, always with a decimal point (Part 21).
pub(crate) fn real(x: f64) -> String {
    if x == 0.0 {
        return "0.".to_string();
    }
    let a = x.abs();
    let mut s = if (1e-4..1e15).contains(&a) {
        format!("{x}")
    } else {
        format!("{x:E}")
    };
    match s.find('E') {
        Some(e) if !s[..e].contains('.') => s.insert(e, '.'),
        None if !s.contains('.') => s.push('.'),
        _ => {}
    }
    s
}

/// One instance, broken after commas (outside strings) into lines of about 80 characters.
fn wrap_into(out: &mut String, entity: &str) {
    let mut col = 0;
    let mut in_string = false;
    for ch in entity.chars() {
        out.push(ch);
        col += 1;
        if ch == '\'' {
            in_string = !in_string;
        }
        if ch == ',' && !in_string && col >= 72 {
            out.push('\n');
            col = 0;
        }
    }
    out.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::solid::outline_solid;

    #[test]
    fn a_box_has_six_kinds_of_faces_and_every_point_once() {
        let poly = vec![[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]];
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
