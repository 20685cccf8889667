//! STEP writer: ISO 10303-21 exchange files under the AP214 schema (AUTOMOTIVE_DESIGN),
//! lengths in millimetres.
//!
//! Layout of the DATA section:
//! - the product boilerplate a CAD tool needs to open the file as a part (application
//!   context and protocol, product, formation, definition, definition shape) and a geometric
//!   context with units mm / radian / steradian and the header's resolution as its
//!   uncertainty;
//! - a SHAPE_REPRESENTATION (the part's frame) related by SHAPE_REPRESENTATION_RELATIONSHIP to
//!   - for surfaces: a MANIFOLD_SURFACE_SHAPE_REPRESENTATION holding a SHELL_BASED_SURFACE_MODEL
//!     with one OPEN_SHELL per surface, each holding one ADVANCED_FACE on the surface, bounded
//!     by an edge loop along its four boundary iso-curves (written exactly as B-spline edge
//!     curves). A boundary that collapses to a point is left out; a surface closed in u or v
//!     has one seam edge used twice, in opposite senses;
//!   - for curves: a GEOMETRICALLY_BOUNDED_WIREFRAME_SHAPE_REPRESENTATION holding one
//!     GEOMETRIC_CURVE_SET.
//!
//! Curves and surfaces are B_SPLINE_CURVE_WITH_KNOTS and B_SPLINE_SURFACE_WITH_KNOTS (knots
//! written once each with their multiplicities) when all weights are equal, otherwise the
//! complex instances with RATIONAL_B_SPLINE_CURVE / RATIONAL_B_SPLINE_SURFACE. Control points
//! are written as stored, so readers evaluate the same point at the same parameter. STEP has
//! no periodic flag: a periodic B-spline is written in its unclamped form with its closed
//! flag set.

use super::{
    ascii, check_curve, check_surface, curve_ends, degenerate, iso_curve, real, same_curve,
    same_point_tol, utc, ExportError, Header,
};
use crate::nurbs::{NurbsCurve, NurbsSurface};
use crate::P3;
use std::fmt::Write as _;
use std::path::Path;

/// Writes `curves` and `surfaces` to one STEP AP214 file at `path`, atomically.
pub fn write(
    path: &Path,
    curves: &[NurbsCurve],
    surfaces: &[NurbsSurface],
    header: &Header,
) -> Result<(), ExportError> {
    let text = to_string(curves, surfaces, header)?;
    super::write_atomic(path, text.as_bytes())
}

/// The STEP text of `curves` and `surfaces` (see the module notes for the layout).
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
    let mut doc = Document::new(header, "B-spline curves and surfaces, millimetres");
    let (name, ctx, pds, axis) = (doc.name.clone(), doc.ctx, doc.pds, doc.axis);
    let w = &mut doc.data;
    let shape_rep = w.add(format!("SHAPE_REPRESENTATION({name},(#{axis}),#{ctx})"));
    w.add(format!(
        "SHAPE_DEFINITION_REPRESENTATION(#{pds},#{shape_rep})"
    ));

    if !surfaces.is_empty() {
        let shells: Vec<usize> = surfaces
            .iter()
            .map(|s| {
                let face = w.face(s);
                w.add(format!("OPEN_SHELL('',(#{face}))"))
            })
            .collect();
        let model = w.add(format!("SHELL_BASED_SURFACE_MODEL('',({}))", refs(&shells)));
        let rep = w.add(format!(
            "MANIFOLD_SURFACE_SHAPE_REPRESENTATION({name},(#{axis},#{model}),#{ctx})"
        ));
        w.add(format!(
            "SHAPE_REPRESENTATION_RELATIONSHIP('','',#{shape_rep},#{rep})"
        ));
    }
    if !curves.is_empty() {
        let ids: Vec<usize> = curves.iter().map(|c| w.curve(c)).collect();
        let set = w.add(format!("GEOMETRIC_CURVE_SET('',({}))", refs(&ids)));
        let rep = w.add(format!(
            "GEOMETRICALLY_BOUNDED_WIREFRAME_SHAPE_REPRESENTATION({name},(#{set},#{axis}),#{ctx})"
        ));
        w.add(format!(
            "SHAPE_REPRESENTATION_RELATIONSHIP('','',#{shape_rep},#{rep})"
        ));
    }

    let out = doc.finish();
    Ok(out)
}

/// A STEP document being written: the product boilerplate a CAD tool needs to open the file
/// as a part (application context and protocol, product, formation, definition, definition
/// shape, units mm / radian / steradian with the header's resolution as uncertainty, the
/// part's axis placement) is in place; the caller adds its representation entities and
/// `finish` wraps everything with the header section. Every STEP file of the project is
/// written through it (this module's B-spline export, the foot model's faceted solid).
pub struct Document {
    data: Data,
    header: Header,
    description: String,
    /// The part's name as a STEP string literal.
    pub name: String,
    /// The geometric representation context, the product definition shape and the part's
    /// axis placement, for the caller's shape representation.
    pub ctx: usize,
    pub pds: usize,
    pub axis: usize,
}

impl Document {
    pub fn new(header: &Header, description: &str) -> Document {
        let name = quoted(&header.name);
        let mut w = Data::default();
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
            "UNCERTAINTY_MEASURE_WITH_UNIT(LENGTH_MEASURE({}),#{mm},'distance_accuracy_value','confusion accuracy')",
            real(header.resolution_mm)
        ));
        let ctx = w.add(format!(
            "(GEOMETRIC_REPRESENTATION_CONTEXT(3)GLOBAL_UNCERTAINTY_ASSIGNED_CONTEXT((#{unc}))GLOBAL_UNIT_ASSIGNED_CONTEXT((#{mm},#{rad},#{sr}))REPRESENTATION_CONTEXT('',''))"
        ));
        let origin = w.point(P3::origin());
        let z = w.add("DIRECTION('',(0.,0.,1.))".into());
        let x = w.add("DIRECTION('',(1.,0.,0.))".into());
        let axis = w.add(format!("AXIS2_PLACEMENT_3D('',#{origin},#{z},#{x})"));
        Document {
            data: w,
            header: header.clone(),
            description: description.to_string(),
            name,
            ctx,
            pds,
            axis,
        }
    }

    /// Adds one entity instance (without `#n=` and `;`) and returns its number.
    pub fn add(&mut self, body: String) -> usize {
        self.data.add(body)
    }

    pub fn point(&mut self, q: P3) -> usize {
        self.data.point(q)
    }

    /// The whole exchange file.
    pub fn finish(self) -> String {
        let header = &self.header;
        let (y, mo, d, h, mi, s) = utc(header.time);
        let items = &self.data.items;
        let mut out =
            String::with_capacity(items.iter().map(|s| s.len() + 12).sum::<usize>() + 512);
        out.push_str("ISO-10303-21;\nHEADER;\n");
        let _ = writeln!(
            out,
            "FILE_DESCRIPTION(({}),'2;1');",
            quoted(&self.description)
        );
        let _ = writeln!(
            out,
            "FILE_NAME({},'{y:04}-{mo:02}-{d:02}T{h:02}:{mi:02}:{s:02}',({}),({}),'footscan-geom {}','footscan','');",
            quoted(&format!("{}.step", header.name)),
            quoted(&header.author),
            quoted(&header.organization),
            env!("CARGO_PKG_VERSION")
        );
        out.push_str(
            "FILE_SCHEMA(('AUTOMOTIVE_DESIGN { 1 0 10303 214 1 1 1 1 }'));\nENDSEC;\nDATA;\n",
        );
        for (i, body) in items.iter().enumerate() {
            wrap_into(&mut out, &format!("#{}={body};", i + 1));
        }
        out.push_str("ENDSEC;\nEND-ISO-10303-21;\n");
        out
    }
}

/// A STEP string literal: printable ASCII, apostrophes and backslashes doubled.
pub fn quoted(s: &str) -> String {
    format!("'{}'", ascii(s).replace('\\', "\\\\").replace('\'', "''"))
}

fn refs(ids: &[usize]) -> String {
    ids.iter()
        .map(|i| format!("#{i}"))
        .collect::<Vec<_>>()
        .join(",")
}

fn reals(xs: impl IntoIterator<Item = f64>) -> String {
    xs.into_iter().map(real).collect::<Vec<_>>().join(",")
}

fn flag(b: bool) -> &'static str {
    if b {
        ".T."
    } else {
        ".F."
    }
}

/// Distinct knot values and their multiplicities.
fn knots_mults(knots: &[f64]) -> (Vec<f64>, Vec<usize>) {
    let (mut k, mut m) = (Vec::new(), Vec::<usize>::new());
    for &x in knots {
        if k.last() == Some(&x) {
            *m.last_mut().unwrap() += 1;
        } else {
            k.push(x);
            m.push(1);
        }
    }
    (k, m)
}

fn uniform_weights(weights: Option<&[f64]>) -> bool {
    weights.is_none_or(|w| w.iter().all(|x| *x == w[0]))
}

/// Appends one instance, broken after commas (outside strings) into lines of about 80
/// characters; Part 21 allows a line break between any two tokens.
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

#[derive(Default)]
struct Data {
    items: Vec<String>,
}

impl Data {
    fn add(&mut self, body: String) -> usize {
        self.items.push(body);
        self.items.len()
    }

    fn point(&mut self, q: P3) -> usize {
        self.add(format!("CARTESIAN_POINT('',({}))", reals([q.x, q.y, q.z])))
    }

    fn curve(&mut self, c: &NurbsCurve) -> usize {
        let pts: Vec<usize> = c.points.iter().map(|q| self.point(*q)).collect();
        let (k, m) = knots_mults(&c.knots);
        let (a, b) = curve_ends(c);
        let closed = flag((a - b).norm() <= same_point_tol(&c.points));
        let mults = m
            .iter()
            .map(|x| x.to_string())
            .collect::<Vec<_>>()
            .join(",");
        let (p, pts, knots) = (c.degree, refs(&pts), reals(k));
        match c.weights.as_deref() {
            w if uniform_weights(w) => self.add(format!(
                "B_SPLINE_CURVE_WITH_KNOTS('',{p},({pts}),.UNSPECIFIED.,{closed},.F.,({mults}),({knots}),.UNSPECIFIED.)"
            )),
            w => self.add(format!(
                "(BOUNDED_CURVE()B_SPLINE_CURVE({p},({pts}),.UNSPECIFIED.,{closed},.F.)B_SPLINE_CURVE_WITH_KNOTS(({mults}),({knots}),.UNSPECIFIED.)CURVE()GEOMETRIC_REPRESENTATION_ITEM()RATIONAL_B_SPLINE_CURVE(({}))REPRESENTATION_ITEM(''))",
                reals(w.unwrap_or(&[]).iter().copied())
            )),
        }
    }

    fn surface(&mut self, s: &NurbsSurface, closed_u: bool, closed_v: bool) -> usize {
        let rows: Vec<String> = (0..s.nu)
            .map(|i| {
                let ids: Vec<usize> = (0..s.nv)
                    .map(|j| self.point(s.points[i * s.nv + j]))
                    .collect();
                format!("({})", refs(&ids))
            })
            .collect();
        let net = rows.join(",");
        let (ku, mu) = knots_mults(&s.knots_u);
        let (kv, mv) = knots_mults(&s.knots_v);
        let ints = |m: &[usize]| {
            m.iter()
                .map(|x| x.to_string())
                .collect::<Vec<_>>()
                .join(",")
        };
        let (du, dv, cu, cv) = (s.degree_u, s.degree_v, flag(closed_u), flag(closed_v));
        let knots = format!(
            "({}),({}),({}),({})",
            ints(&mu),
            ints(&mv),
            reals(ku),
            reals(kv)
        );
        match s.weights.as_deref() {
            w if uniform_weights(w) => self.add(format!(
                "B_SPLINE_SURFACE_WITH_KNOTS('',{du},{dv},({net}),.UNSPECIFIED.,{cu},{cv},.F.,{knots},.UNSPECIFIED.)"
            )),
            w => {
                let w = w.unwrap_or(&[]);
                let wrows: Vec<String> = (0..s.nu)
                    .map(|i| format!("({})", reals(w[i * s.nv..(i + 1) * s.nv].iter().copied())))
                    .collect();
                self.add(format!(
                    "(BOUNDED_SURFACE()B_SPLINE_SURFACE({du},{dv},({net}),.UNSPECIFIED.,{cu},{cv},.F.)B_SPLINE_SURFACE_WITH_KNOTS({knots},.UNSPECIFIED.)GEOMETRIC_REPRESENTATION_ITEM()RATIONAL_B_SPLINE_SURFACE(({}))REPRESENTATION_ITEM('')SURFACE())",
                    wrows.join(",")
                ))
            }
        }
    }

    /// An advanced face on `s` bounded by its four boundary iso-curves, walked counter-
    /// clockwise in (u, v) so the face normal is the surface's du x dv.
    fn face(&mut self, s: &NurbsSurface) -> usize {
        let tol = same_point_tol(&s.points);
        let (u0, u1) = (s.knots_u[s.degree_u], s.knots_u[s.nu]);
        let (v0, v1) = (s.knots_v[s.degree_v], s.knots_v[s.nv]);
        // Sides: v = v0 (a curve in u), u = u1, v = v1, u = u0 (curves in v).
        let sides = [
            iso_curve(s, true, v0),
            iso_curve(s, false, u1),
            iso_curve(s, true, v1),
            iso_curve(s, false, u0),
        ];
        let closed_u = same_curve(&sides[1], &sides[3], tol);
        let closed_v = same_curve(&sides[0], &sides[2], tol);
        let surf = self.surface(s, closed_u, closed_v);

        let (c00, c10) = curve_ends(&sides[0]);
        let (c01, c11) = curve_ends(&sides[2]);
        let mut vertices: Vec<(P3, usize)> = Vec::new();
        let mut vertex = |w: &mut Data, q: P3| -> usize {
            if let Some((_, id)) = vertices.iter().find(|(p, _)| (p - q).norm() <= tol) {
                return *id;
            }
            let cp = w.point(q);
            let id = w.add(format!("VERTEX_POINT('',#{cp})"));
            vertices.push((q, id));
            id
        };
        // (side, start corner, end corner of the side's curve, sense in the loop)
        let walk = [
            (0, c00, c10, true),
            (1, c10, c11, true),
            (2, c01, c11, false),
            (3, c00, c01, false),
        ];
        let mut edges: [Option<usize>; 4] = [None; 4];
        let mut oriented = Vec::new();
        for (side, a, b, sense) in walk {
            if degenerate(&sides[side], tol) {
                continue;
            }
            let shared = match side {
                2 if closed_v => edges[0],
                3 if closed_u => edges[1],
                _ => None,
            };
            let edge = match shared {
                Some(e) => e,
                None => {
                    let (va, vb) = (vertex(self, a), vertex(self, b));
                    let curve = self.curve(&sides[side]);
                    self.add(format!("EDGE_CURVE('',#{va},#{vb},#{curve},.T.)"))
                }
            };
            edges[side] = Some(edge);
            oriented.push(self.add(format!("ORIENTED_EDGE('',*,*,#{edge},{})", flag(sense))));
        }
        let lp = self.add(format!("EDGE_LOOP('',({}))", refs(&oriented)));
        let bound = self.add(format!("FACE_OUTER_BOUND('',#{lp},.T.)"));
        self.add(format!("ADVANCED_FACE('',(#{bound}),#{surf},.T.)"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn knots_with_multiplicities() {
        let (k, m) = knots_mults(&[0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0]);
        assert_eq!(k, vec![0.0, 0.5, 1.0]);
        assert_eq!(m, vec![3, 1, 3]);
    }

    #[test]
    fn strings_are_escaped() {
        assert_eq!(quoted("it's a\\b é"), "'it''s a\\\\b ?'");
    }

    #[test]
    fn wraps_outside_strings_only() {
        let mut out = String::new();
        let long = format!("X('{}',{})", "a,".repeat(60), "1.,".repeat(40));
        wrap_into(&mut out, &long);
        assert_eq!(out.replace('\n', ""), long);
        let first = out.lines().next().unwrap();
        assert!(first.len() > 120, "a break fell inside the string");
    }
}
