//! IGES 5.3 writer: curves as entity 126, surfaces as entity 128, in millimetres.
//!
//! The file has the five fixed-format sections of 80-column records (Start, Global,
//! Directory Entry, Parameter Data, Terminate), each record numbered in columns 74-80 with
//! its section letter in column 73. Parameter data are free format (',' between parameters,
//! ';' at the end of an entity) in columns 1-64 with the back pointer to the entity's
//! directory entry in 66-72; a number is never split across records. Strings are Hollerith
//! (`5HHELLO`). Entities appear in the order given, curves first, then surfaces; entity
//! labels are CURVE and SURFACE with the 1-based index as subscript.
//!
//! Knot vectors, weights and control points are written exactly as stored (an unclamped
//! periodic B-spline keeps its knots; its periodic flag is set), so readers evaluate the
//! same point at the same parameter. Flags written:
//! - 126: PROP1 planar (control points in one plane; its normal is then written too),
//!   PROP2 closed (start point = end point), PROP3 polynomial (no weights, or all equal),
//!   PROP4 periodic.
//! - 128: PROP1/PROP2 closed in u/v (the boundary iso-curves at both ends of the domain are
//!   the same curve), PROP3 polynomial, PROP4/PROP5 periodic in u/v.

use super::{
    ascii, check_curve, check_surface, curve_ends, iso_curve, plane_normal, real, same_curve,
    same_point_tol, utc, ExportError, Header,
};
use crate::nurbs::{NurbsCurve, NurbsSurface};
use std::path::Path;

/// Writes `curves` and `surfaces` to one IGES file at `path`, atomically.
pub fn write(
    path: &Path,
    curves: &[NurbsCurve],
    surfaces: &[NurbsSurface],
    header: &Header,
) -> Result<(), ExportError> {
    let text = to_string(curves, surfaces, header)?;
    super::write_atomic(path, text.as_bytes())
}

/// Writes a curve network (a last's frame of sections and guides) as IGES curves only.
pub fn write_frame(path: &Path, curves: &[NurbsCurve], header: &Header) -> Result<(), ExportError> {
    write(path, curves, &[], header)
}

/// The IGES text of `curves` and `surfaces` (see the module notes for the layout).
pub fn to_string(
    curves: &[NurbsCurve],
    surfaces: &[NurbsSurface],
    header: &Header,
) -> Result<String, ExportError> {
    if curves.is_empty() && surfaces.is_empty() {
        return Err(ExportError::Empty);
    }
    for (k, c) in curves.iter().enumerate() {
        check_curve(k, c)?;
    }
    for (k, s) in surfaces.iter().enumerate() {
        check_surface(k, s)?;
    }

    // Parameter data of every entity, then records.
    let mut entities: Vec<(u32, Vec<String>, &str, usize)> = Vec::new();
    for (k, c) in curves.iter().enumerate() {
        entities.push((126, curve_params(c), "CURVE", k + 1));
    }
    for (k, s) in surfaces.iter().enumerate() {
        entities.push((128, surface_params(s), "SURFACE", k + 1));
    }

    let mut out = String::new();
    let start = [
        format!(
            "{} written by footscan-geom (IGES 5.3, millimetres).",
            ascii(&header.name)
        ),
        format!(
            "{} B-spline curves (entity 126), {} B-spline surfaces (entity 128).",
            curves.len(),
            surfaces.len()
        ),
    ];
    for (i, line) in start.iter().enumerate() {
        let line: String = line.chars().take(72).collect();
        out.push_str(&format!("{line:<72}S{:>7}\n", i + 1));
    }
    let global = global_section(curves, surfaces, header);
    for (i, line) in global.iter().enumerate() {
        out.push_str(&format!("{line:<72}G{:>7}\n", i + 1));
    }

    // Lay out the parameter data to know each entity's first record and record count.
    let mut pd_lines: Vec<(String, usize)> = Vec::new(); // (text, DE sequence number)
    let mut de = String::new();
    for (e, (ty, params, label, subscript)) in entities.iter().enumerate() {
        let de_seq = 2 * e + 1;
        let first = pd_lines.len() + 1;
        for line in pack(params, 64) {
            pd_lines.push((line, de_seq));
        }
        let count = pd_lines.len() + 1 - first;
        // Field order: type, PD pointer, structure, line font, level, view, transform,
        // label display, status (visible, independent, geometry, top-down).
        de.push_str(&format!(
            "{ty:>8}{first:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}{:>8}D{de_seq:>7}\n",
            0, 1, 0, 0, 0, 0, "00000000"
        ));
        // Type, line weight, colour, PD record count, form, two reserved, label, subscript.
        de.push_str(&format!(
            "{ty:>8}{:>8}{:>8}{count:>8}{:>8}{:>8}{:>8}{label:>8}{subscript:>8}D{:>7}\n",
            0,
            0,
            0,
            "",
            "",
            de_seq + 1
        ));
    }
    out.push_str(&de);
    for (i, (text, de_seq)) in pd_lines.iter().enumerate() {
        out.push_str(&format!("{text:<64} {de_seq:>7}P{:>7}\n", i + 1));
    }
    out.push_str(&format!(
        "S{:>7}G{:>7}D{:>7}P{:>7}{:40}T{:>7}\n",
        start.len(),
        global.len(),
        2 * entities.len(),
        pd_lines.len(),
        "",
        1
    ));
    Ok(out)
}

/// A Hollerith string, cut to `max` characters so it fits one record.
fn hollerith(s: &str, max: usize) -> String {
    let s: String = ascii(s).chars().take(max).collect();
    if s.is_empty() {
        String::new()
    } else {
        format!("{}H{}", s.len(), s)
    }
}

fn global_section(
    curves: &[NurbsCurve],
    surfaces: &[NurbsSurface],
    header: &Header,
) -> Vec<String> {
    let (y, mo, d, h, mi, s) = utc(header.time);
    let date = format!("{y:04}{mo:02}{d:02}.{h:02}{mi:02}{s:02}");
    let max_coord = curves
        .iter()
        .flat_map(|c| c.points.iter())
        .chain(surfaces.iter().flat_map(|s| s.points.iter()))
        .flat_map(|q| q.iter())
        .fold(0.0f64, |m, c| m.max(c.abs()));
    let file_name = format!("{}.igs", header.name);
    let params = vec![
        "1H,".to_string(),                         // 1 parameter delimiter
        "1H;".to_string(),                         // 2 record delimiter
        hollerith(&header.name, 60),               // 3 product id (sender)
        hollerith(&file_name, 60),                 // 4 file name
        hollerith("footscan-geom", 60),            // 5 native system
        hollerith(env!("CARGO_PKG_VERSION"), 60),  // 6 preprocessor version
        "32".to_string(),                          // 7 integer bits
        "38".to_string(),                          // 8 single precision max power of ten
        "6".to_string(),                           // 9 single precision digits
        "308".to_string(),                         // 10 double precision max power
        "15".to_string(),                          // 11 double precision digits
        hollerith(&header.name, 60),               // 12 product id (receiver)
        real(1.0),                                 // 13 model space scale
        "2".to_string(),                           // 14 units flag: millimetres
        "2HMM".to_string(),                        // 15 units name
        "1".to_string(),                           // 16 line weight gradations
        real(1.0),                                 // 17 maximum line width, mm
        format!("15H{date}"),                      // 18 date and time of the file
        real(header.resolution_mm),                // 19 minimum resolution, mm
        real(max_coord.max(header.resolution_mm)), // 20 approximate maximum coordinate
        hollerith(&header.author, 60),             // 21 author
        hollerith(&header.organization, 60),       // 22 organisation
        "11".to_string(),                          // 23 version: IGES 5.3
        "0".to_string(),                           // 24 drafting standard: none
        format!("15H{date}"),                      // 25 date the model was made
    ];
    pack(&params, 72)
}

/// Joins parameters with ',' and a final ';' into records of at most `width` characters,
/// breaking only between parameters.
fn pack(params: &[String], width: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut line = String::new();
    for (i, p) in params.iter().enumerate() {
        let token = format!("{p}{}", if i + 1 == params.len() { ';' } else { ',' });
        if !line.is_empty() && line.len() + token.len() > width {
            lines.push(std::mem::take(&mut line));
        }
        line.push_str(&token);
    }
    lines.push(line);
    lines
}

fn polynomial(weights: Option<&[f64]>) -> bool {
    weights.is_none_or(|w| w.iter().all(|x| *x == w[0]))
}

fn curve_params(c: &NurbsCurve) -> Vec<String> {
    let n = c.points.len();
    let tol = same_point_tol(&c.points);
    let normal = plane_normal(&c.points, tol);
    let (a, b) = curve_ends(c);
    let closed = (a - b).norm() <= tol;
    let mut p = vec![
        "126".to_string(),
        (n - 1).to_string(),
        c.degree.to_string(),
        u8::from(normal.is_some()).to_string(),
        u8::from(closed).to_string(),
        u8::from(polynomial(c.weights.as_deref())).to_string(),
        u8::from(c.periodic).to_string(),
    ];
    p.extend(c.knots.iter().map(|k| real(*k)));
    p.extend((0..n).map(|i| real(c.weights.as_ref().map_or(1.0, |w| w[i]))));
    for q in &c.points {
        p.extend([real(q.x), real(q.y), real(q.z)]);
    }
    p.push(real(c.knots[c.degree]));
    p.push(real(c.knots[n]));
    let nn = normal.unwrap_or_default();
    p.extend([real(nn.x), real(nn.y), real(nn.z)]);
    p
}

fn surface_params(s: &NurbsSurface) -> Vec<String> {
    let tol = same_point_tol(&s.points);
    let (u0, u1) = (s.knots_u[s.degree_u], s.knots_u[s.nu]);
    let (v0, v1) = (s.knots_v[s.degree_v], s.knots_v[s.nv]);
    let closed_u = same_curve(&iso_curve(s, false, u0), &iso_curve(s, false, u1), tol);
    let closed_v = same_curve(&iso_curve(s, true, v0), &iso_curve(s, true, v1), tol);
    let mut p = vec![
        "128".to_string(),
        (s.nu - 1).to_string(),
        (s.nv - 1).to_string(),
        s.degree_u.to_string(),
        s.degree_v.to_string(),
        u8::from(closed_u).to_string(),
        u8::from(closed_v).to_string(),
        u8::from(polynomial(s.weights.as_deref())).to_string(),
        u8::from(s.periodic_u).to_string(),
        u8::from(s.periodic_v).to_string(),
    ];
    p.extend(s.knots_u.iter().map(|k| real(*k)));
    p.extend(s.knots_v.iter().map(|k| real(*k)));
    // IGES runs the first (u) index fastest; ours is stored v-fastest.
    for j in 0..s.nv {
        for i in 0..s.nu {
            p.push(real(s.weights.as_ref().map_or(1.0, |w| w[i * s.nv + j])));
        }
    }
    for j in 0..s.nv {
        for i in 0..s.nu {
            let q = s.points[i * s.nv + j];
            p.extend([real(q.x), real(q.y), real(q.z)]);
        }
    }
    p.extend([real(u0), real(u1), real(v0), real(v1)]);
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::P3;

    fn line() -> NurbsCurve {
        NurbsCurve {
            degree: 1,
            knots: vec![0.0, 0.0, 1.0, 1.0],
            points: vec![P3::new(0.0, 0.0, 0.0), P3::new(10.0, 0.0, 0.0)],
            weights: None,
            periodic: false,
        }
    }

    #[test]
    fn records_are_80_columns_and_numbered() {
        let h = Header::new("a part, with a comma");
        let text = to_string(&[line(), line()], &[], &h).unwrap();
        let mut counts = std::collections::HashMap::new();
        for l in text.lines() {
            assert_eq!(l.len(), 80, "{l:?}");
            let sec = l.as_bytes()[72] as char;
            let n = counts.entry(sec).or_insert(0usize);
            *n += 1;
            assert_eq!(l[73..].trim().parse::<usize>().unwrap(), *n, "{l:?}");
        }
        assert_eq!(counts[&'D'], 4);
        assert_eq!(counts[&'T'], 1);
        assert!(text.contains("2HMM"));
        assert!(text.contains("20Ha part, with a comma"));
    }

    /// The PROP1..PROP4 flags of the first 126 entity in `text`.
    fn curve_flags(text: &str) -> String {
        let pd = text.lines().find(|l| l.as_bytes()[72] == b'P').unwrap();
        pd.split(',').skip(3).take(4).collect::<Vec<_>>().join(",")
    }

    #[test]
    fn curve_flags_planar_closed_polynomial_periodic() {
        let h = Header::new("flags");
        let s = 0.5f64.sqrt();
        let sq = [
            (1., 0.),
            (1., 1.),
            (0., 1.),
            (-1., 1.),
            (-1., 0.),
            (-1., -1.),
            (0., -1.),
            (1., -1.),
            (1., 0.),
        ];
        let circle = NurbsCurve::new(
            2,
            vec![0., 0., 0., 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1., 1., 1.],
            sq.iter().map(|(x, y)| P3::new(*x, *y, 3.0)).collect(),
            Some(vec![1., s, 1., s, 1., s, 1., s, 1.]),
        )
        .unwrap();
        // Planar, closed, rational, not periodic.
        assert_eq!(
            curve_flags(&to_string(&[circle], &[], &h).unwrap()),
            "1,1,0,0"
        );
        // A periodic cubic through a non-planar loop: closed, polynomial, periodic.
        let loop_pts = [(0., 0., 0.), (1., 0., 1.), (1., 1., 0.), (0., 1., 1.)];
        let mut pts: Vec<P3> = loop_pts
            .iter()
            .map(|(x, y, z)| P3::new(*x, *y, *z))
            .collect();
        pts.extend_from_within(..3);
        let knots = (0..11).map(f64::from).collect();
        let periodic = NurbsCurve::new_periodic(3, knots, pts, None).unwrap();
        assert_eq!(
            curve_flags(&to_string(&[periodic], &[], &h).unwrap()),
            "0,1,1,1"
        );
        // An open straight line: collinear points give no unique plane.
        assert_eq!(
            curve_flags(&to_string(&[line()], &[], &h).unwrap()),
            "0,0,1,0"
        );
    }

    #[test]
    fn bad_knots_are_named() {
        let mut c = line();
        c.knots = vec![0.0, 1.0, 0.5, 1.0];
        let e = to_string(&[line(), c], &[], &Header::new("x")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("curve 1: knots must be non-decreasing"),
            "{e}"
        );
        assert!(matches!(
            to_string(&[], &[], &Header::new("x")),
            Err(ExportError::Empty)
        ));
    }
}
