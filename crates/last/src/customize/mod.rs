//! A customized last from a whole-foot mesh: characteristic points and curves cut from the
//! foot, fitted as NURBS (Algorithm I), deformed by comfort rules with the least change of
//! control points in type order I, II, III, IV (Algorithm II), and a closed last whose
//! measured sizes meet every rule (see [`shape`] for how the surface is made and why).
//! Method: docs/method.md section 10; paper: "Adaptive deformation of characteristic NURBS
//! curves for customized shoe-last" (Ren, Wang, Liu, Luo, 2013).

pub mod curves;
mod error;
pub mod measure;
pub mod rules;
pub mod shape;

pub use error::CustomizeError;

use curves::{fit_loop, least_change, param_of, secant, Constraint, FitRecord};
use footscan_geom::mesh::{Bvh, Format, TriMesh, Units};
use footscan_geom::nurbs::NurbsCurve;
use footscan_geom::{P3, V3};
use measure::{find_frame, measure, FootFrame, Measures};
use rules::{RuleSet, Shoe, Wearer};
use serde::Serialize;
use std::path::Path;

/// What the last is for.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Inputs {
    pub shoe: Shoe,
    pub wearer: Wearer,
    pub heel_mm: f64,
}

/// Foot length range accepted as a foot (mm).
pub const FOOT_LENGTH_RANGE: (f64, f64) = (100.0, 360.0);

/// One rule's row in the report.
#[derive(Clone, Debug, Serialize)]
pub struct RuleRow {
    pub rule: &'static str,
    pub curve_type: u8,
    pub quantity: &'static str,
    pub foot_mm: f64,
    pub change_mm: f64,
    pub target_mm: f64,
    /// Measured by cutting the output mesh.
    pub last_mm: f64,
    pub error_mm: f64,
    pub bound_mm: f64,
    pub met: bool,
    pub source: String,
}

/// The characteristic curves of the last's frame after Algorithm II.
#[derive(Clone, Debug)]
pub struct Frame {
    pub foot: Vec<(&'static str, NurbsCurve)>,
    pub last: Vec<(&'static str, NurbsCurve)>,
    /// For each deformed curve: largest control-point move and the size it reached.
    pub deform: Vec<DeformRecord>,
}

#[derive(Clone, Debug, Serialize)]
pub struct DeformRecord {
    pub curve: &'static str,
    pub curve_type: u8,
    pub constraints: usize,
    pub max_control_move_mm: f64,
    /// Length of the deformed curve and its target (girths), mm.
    pub length_mm: f64,
    pub target_mm: Option<f64>,
}

/// Everything a customization produced.
pub struct Customized {
    pub frame_in_world: FootFrame,
    pub foot: TriMesh,
    pub foot_measures: Measures,
    pub last: TriMesh,
    pub last_measures: Measures,
    pub rules: Vec<RuleRow>,
    pub fits: Vec<FitRecord>,
    pub curves: Frame,
    pub field: shape::Params,
    pub evaluations: usize,
    /// Smallest clearance of foot vertices inside the last (negative: the foot presses
    /// out through the last), overall and by region.
    pub clearance: Clearance,
}

#[derive(Clone, Debug, Serialize)]
pub struct Clearance {
    pub toe_box_mm: f64,
    pub ball_mm: f64,
    pub heel_seat_mm: f64,
    pub overall_mm: f64,
    /// The foot vertex where the overall minimum is (foot frame, mm): says which rule or
    /// which feature of the foot mesh it comes from (docs/method.md section 10).
    pub worst_at_mm: [f64; 3],
}

/// The rule targets for a foot: (rule, quantity, foot value, change, bound, source).
pub fn targets(
    r: &RuleSet,
    inp: &Inputs,
    f: &Measures,
) -> (Vec<RuleRow>, f64 /* heel allowance */) {
    let shoe_w = r.i_e.change_mm.get(inp.shoe);
    let toe = r.i_a.toe_allowance_mm.get(inp.shoe) + r.i_a.toe_allowance_extra_mm.get(inp.wearer);
    let heel = r.i_a.heel_allowance_mm.get(inp.shoe);
    let ball = r.ii_f.change_mm.get(inp.wearer)
        + r.ii_f.shoe_change_mm.get(inp.shoe)
        + r.ii_f.per_10mm_heel_mm * (inp.heel_mm - r.ii_f.heel_reference_mm).max(0.0) / 10.0;
    let row = |rule, t, q, foot: f64, ch: f64, b, s: &str| RuleRow {
        rule,
        curve_type: t,
        quantity: q,
        foot_mm: foot,
        change_mm: ch,
        target_mm: foot + ch,
        last_mm: f64::NAN,
        error_mm: f64::NAN,
        bound_mm: b,
        met: false,
        source: s.to_string(),
    };
    let rows = vec![
        row(
            "I-A",
            1,
            "bottom length",
            f.length,
            toe - heel,
            0.2,
            &r.i_a.source,
        ),
        row(
            "I-B",
            1,
            "ball width",
            f.ball_width,
            r.i_b.change_mm + shoe_w,
            0.2,
            &r.i_b.source,
        ),
        row(
            "I-C",
            1,
            "waist width",
            f.waist_width,
            r.i_c.change_mm + shoe_w,
            0.2,
            &r.i_c.source,
        ),
        row(
            "I-D",
            1,
            "heel width",
            f.heel_width,
            r.i_d.change_mm + shoe_w,
            0.2,
            &r.i_d.source,
        ),
        row(
            "II-F",
            2,
            "ball girth",
            f.ball_girth,
            ball,
            0.5,
            &r.ii_f.source,
        ),
        row(
            "II-G",
            2,
            "instep girth",
            f.instep_girth,
            r.ii_g.change_mm,
            0.5,
            &r.ii_g.source,
        ),
        row(
            "II-H",
            2,
            "long-heel girth",
            f.long_heel_girth,
            r.ii_h.change_mm,
            0.5,
            &r.ii_h.source,
        ),
        row(
            "IV",
            4,
            "ankle girth",
            f.ankle_girth,
            r.iv.change_mm,
            0.5,
            &r.iv.source,
        ),
    ];
    (rows, heel)
}

/// Load a foot mesh (STL, OBJ, PLY; metres detected from the size), check it is closed and
/// foot-sized, and bring it into its own frame.
pub fn load_foot(path: &Path) -> Result<(TriMesh, FootFrame), CustomizeError> {
    let (m, _rep) = TriMesh::load_solid(path, Units::Auto, None)?;
    let name = path.display().to_string();
    foot_in_frame(m, &name)
}

/// A closed world mesh (mm, z up) into its foot frame, with the extent check.
pub fn foot_in_frame(m: TriMesh, name: &str) -> Result<(TriMesh, FootFrame), CustomizeError> {
    if let Err(d) = m.check() {
        return Err(CustomizeError::NotAFoot {
            name: name.into(),
            why: format!("the mesh is not a closed solid: {d}"),
        });
    }
    let frame = find_frame(&m, name)?;
    let mut f = m;
    f.transform(&frame.world_to_frame());
    let bb = f.bbox();
    let l = bb.max.x - bb.min.x;
    if !(FOOT_LENGTH_RANGE.0..=FOOT_LENGTH_RANGE.1).contains(&l) {
        return Err(CustomizeError::NotAFoot {
            name: name.into(),
            why: format!(
                "heel-to-toe extent {l:.1} mm; a foot is {:.0} to {:.0} mm",
                FOOT_LENGTH_RANGE.0, FOOT_LENGTH_RANGE.1
            ),
        });
    }
    Ok((f, frame))
}

/// The whole customization of a foot already in its frame.
pub fn customize(
    foot: TriMesh,
    frame: FootFrame,
    rules: &RuleSet,
    inp: &Inputs,
) -> Result<Customized, CustomizeError> {
    let medial = frame.medial_sign();
    let fm = measure(&foot, None, medial).map_err(|why| CustomizeError::NotAFoot {
        name: "foot".into(),
        why,
    })?;
    if !(FOOT_LENGTH_RANGE.0..=FOOT_LENGTH_RANGE.1).contains(&fm.length) {
        return Err(CustomizeError::NotAFoot {
            name: "foot".into(),
            why: format!("sole outline length {:.1} mm out of range", fm.length),
        });
    }
    let (mut rows, heel_allow) = targets(rules, inp, &fm);
    let target: [f64; 8] = std::array::from_fn(|i| rows[i].target_mm);
    // Algorithm I and II on the characteristic curves.
    let (fits, curves) = frame_curves(&fm, &target, heel_allow)?;
    // The surface.
    let sec = shape::Sections::of_foot(&foot, fm.length);
    let mut nd = shape::Nodes::of(&fm);
    nd.heel_allowance = heel_allow;
    let (last, lm, field, evals) = shape::solve(&sec, &nd, &fm, &target, medial)?;
    let v = shape::values(&lm);
    for (i, r) in rows.iter_mut().enumerate() {
        r.last_mm = v[i];
        r.error_mm = v[i] - r.target_mm;
        r.met = r.error_mm.abs() <= r.bound_mm;
    }
    let clearance = clearance(&foot, &last, &fm);
    Ok(Customized {
        frame_in_world: frame,
        foot,
        foot_measures: fm,
        last,
        last_measures: lm,
        rules: rows,
        fits,
        curves,
        field,
        evaluations: evals,
        clearance,
    })
}

fn clearance(foot: &TriMesh, last: &TriMesh, fm: &Measures) -> Clearance {
    let bvh = Bvh::new(last);
    let (mut toe, mut ball, mut heel, mut all) = (f64::MAX, f64::MAX, f64::MAX, f64::MAX);
    let mut at = [f64::NAN; 3];
    let xb = fm.b.x.max(fm.c.x);
    let top = shape::TOP_Z * fm.length;
    for p in &foot.vertices {
        if p.z > top - 1.0 {
            continue;
        }
        let Some(sd) = bvh.signed_distance(p) else {
            continue;
        };
        let c = -sd.distance;
        if c < all {
            all = c;
            at = [p.x, p.y, p.z];
        }
        if p.x > xb + 0.04 * fm.length {
            toe = toe.min(c);
        } else if p.x > fm.b.x.min(fm.c.x) - 0.05 * fm.length {
            ball = ball.min(c);
        } else if p.x < 0.25 * fm.length && p.z < 0.1 * fm.length {
            heel = heel.min(c);
        }
    }
    Clearance {
        toe_box_mm: toe,
        ball_mm: ball,
        heel_seat_mm: heel,
        overall_mm: all,
        worst_at_mm: at,
    }
}

/// Algorithm I on the six foot curves, then Algorithm II in type order.
fn frame_curves(
    f: &Measures,
    target: &[f64; 8],
    heel_allow: f64,
) -> Result<(Vec<FitRecord>, Frame), CustomizeError> {
    let outline = f
        .outline
        .iter()
        .max_by(|a, b| {
            let la = footscan_geom::polyline::Polyline::closed((*a).clone()).length();
            let lb = footscan_geom::polyline::Polyline::closed((*b).clone()).length();
            la.total_cmp(&lb)
        })
        .cloned()
        .unwrap_or_default();
    let tol = 0.05;
    let mut fits = Vec::new();
    let mut fit = |name: &'static str, pts: &[P3]| -> Result<NurbsCurve, CustomizeError> {
        let (c, r) = fit_loop(name, pts, 1.0, tol)?;
        fits.push(r);
        Ok(c)
    };
    let c_out = fit("bottom_outline", &outline)?;
    let c_ball = fit("ball_girth", &f.ball)?;
    let c_inst = fit("instep_girth", &f.instep)?;
    let c_lh = fit("long_heel_girth", &f.long_heel)?;
    let c_prof = fit("side_profile", &f.profile)?;
    let c_ank = fit("ankle_girth", &f.ankle)?;
    let mut deform = Vec::new();
    let maxmove = |a: &NurbsCurve, b: &NurbsCurve| {
        a.points
            .iter()
            .zip(&b.points)
            .map(|(p, q)| (p - q).norm())
            .fold(0.0, f64::max)
    };
    // Type I: O back by the heel allowance, A forward so the length is met, widths split
    // between the medial and lateral points in proportion to their distances from the axis.
    let ext = target[0] - f.length + heel_allow;
    let split = |pm: &P3, pl: &P3, dw: f64| {
        let (am, al) = (pm.y.abs(), pl.y.abs());
        let s = (am + al).max(1e-9);
        (
            V3::new(0.0, pm.y.signum() * dw * am / s, 0.0),
            V3::new(0.0, pl.y.signum() * dw * al / s, 0.0),
        )
    };
    let (db, dc) = split(&f.b, &f.c, target[1] - f.ball_width);
    let (dd, de) = split(&f.d, &f.e, target[2] - f.waist_width);
    let (dhm, dhl) = split(&f.heel_m, &f.heel_l, target[3] - f.heel_width);
    let pts_i = [
        ("O", f.o, V3::new(heel_allow, 0.0, 0.0)),
        ("A", f.a, V3::new(ext, 0.0, 0.0)),
        ("B", f.b, db),
        ("C", f.c, dc),
        ("D", f.d, dd),
        ("E", f.e, de),
        ("heel medial", f.heel_m, dhm),
        ("heel lateral", f.heel_l, dhl),
    ];
    let cons: Vec<Constraint> = pts_i
        .iter()
        .map(|(n, p, d)| Constraint {
            name: n,
            u: param_of(&c_out, &P3::new(p.x, p.y, c_out.point(0.0).z)),
            order: 0,
            delta: *d,
        })
        .collect();
    let l_out = least_change("bottom_outline", &c_out, &cons)?;
    deform.push(DeformRecord {
        curve: "bottom_outline",
        curve_type: 1,
        constraints: cons.len(),
        max_control_move_mm: maxmove(&c_out, &l_out),
        length_mm: l_out.length(),
        target_mm: None,
    });
    // Type II: the bottom nodes follow type I; the top moves up or down until the girth
    // (the curve's length) is met.
    let moved = |p: &P3| -> V3 {
        let u = param_of(&c_out, &P3::new(p.x, p.y, c_out.point(0.0).z));
        l_out.point(u) - c_out.point(u)
    };
    let mut girth = |name: &'static str,
                     c: &NurbsCurve,
                     nodes: &[(&'static str, P3)],
                     tgt: f64,
                     kind: u8|
     -> Result<(NurbsCurve, V3), CustomizeError> {
        let top = (0..400)
            .map(|k| c.point(k as f64 / 400.0))
            .max_by(|a, b| a.z.total_cmp(&b.z))
            .unwrap();
        let ut = param_of(c, &top);
        let mut base: Vec<Constraint> = nodes
            .iter()
            .map(|(n, p)| Constraint {
                name: n,
                u: param_of(c, p),
                order: 0,
                delta: moved(p),
            })
            .collect();
        base.push(Constraint {
            name: "top",
            u: ut,
            order: 0,
            delta: V3::zeros(),
        });
        let k = base.len() - 1;
        let run = |dz: f64, base: &mut Vec<Constraint>| {
            base[k].delta = V3::new(0.0, 0.0, dz);
            least_change(name, c, base)
        };
        let dz = secant(|dz| Ok(run(dz, &mut base.clone())?.length() - tgt), 1.0)?;
        let out = run(dz, &mut base)?;
        deform.push(DeformRecord {
            curve: name,
            curve_type: kind,
            constraints: base.len(),
            max_control_move_mm: maxmove(c, &out),
            length_mm: out.length(),
            target_mm: Some(tgt),
        });
        Ok((out, V3::new(0.0, 0.0, dz)))
    };
    let low = |c: &NurbsCurve, side: f64| {
        (0..400)
            .map(|k| c.point(k as f64 / 400.0))
            .filter(|p| p.z < 0.3 * (f.instep_top.z))
            .max_by(|a, b| (side * a.y).total_cmp(&(side * b.y)))
            .unwrap_or(c.point(0.0))
    };
    let (l_ball, t_ball) = girth(
        "ball_girth",
        &c_ball,
        &[("B", f.b), ("C", f.c)],
        target[4],
        2,
    )?;
    let (l_inst, t_inst) = girth(
        "instep_girth",
        &c_inst,
        &[
            ("instep medial", low(&c_inst, 1.0)),
            ("instep lateral", low(&c_inst, -1.0)),
        ],
        target[5],
        2,
    )?;
    let heel_back = (0..400)
        .map(|k| c_lh.point(k as f64 / 400.0))
        .min_by(|a, b| a.x.total_cmp(&b.x))
        .unwrap();
    let (l_lh, t_lh) = girth(
        "long_heel_girth",
        &c_lh,
        &[("heel back", heel_back)],
        target[6],
        2,
    )?;
    // Type III: the profile through the moved heel and toe points and the girth tops.
    let prof_pts = |x: f64| {
        (0..800)
            .map(|k| c_prof.point(k as f64 / 800.0))
            .filter(|p| p.z > 0.5 * f.instep_top.z.min(30.0))
            .min_by(|a, b| (a.x - x).abs().total_cmp(&(b.x - x).abs()))
            .unwrap_or(c_prof.point(0.0))
    };
    let back = (0..800)
        .map(|k| c_prof.point(k as f64 / 800.0))
        .min_by(|a, b| a.x.total_cmp(&b.x))
        .unwrap();
    let front = (0..800)
        .map(|k| c_prof.point(k as f64 / 800.0))
        .max_by(|a, b| a.x.total_cmp(&b.x))
        .unwrap();
    let pcons = vec![
        Constraint {
            name: "heel back",
            u: param_of(&c_prof, &back),
            order: 0,
            delta: V3::zeros(),
        },
        Constraint {
            name: "toe tip",
            u: param_of(&c_prof, &front),
            order: 0,
            delta: V3::new(ext, 0.0, 0.0),
        },
        Constraint {
            name: "ball top",
            u: param_of(&c_prof, &prof_pts(0.5 * (f.b.x + f.c.x))),
            order: 0,
            delta: t_ball,
        },
        Constraint {
            name: "instep top",
            u: param_of(&c_prof, &prof_pts(f.instep_top.x)),
            order: 0,
            delta: t_inst,
        },
        Constraint {
            name: "long-heel top",
            u: param_of(&c_prof, &prof_pts(f.instep_top.x + 0.02 * f.length)),
            order: 0,
            delta: t_lh,
        },
    ];
    let l_prof = least_change("side_profile", &c_prof, &pcons)?;
    deform.push(DeformRecord {
        curve: "side_profile",
        curve_type: 3,
        constraints: pcons.len(),
        max_control_move_mm: maxmove(&c_prof, &l_prof),
        length_mm: l_prof.length(),
        target_mm: None,
    });
    // Type IV: scaled about its centre at four extreme points until its length is met.
    let ctr = {
        let pts: Vec<P3> = (0..200).map(|k| c_ank.point(k as f64 / 200.0)).collect();
        pts.iter().fold(V3::zeros(), |s, p| s + p.coords) / pts.len() as f64
    };
    let ext4: Vec<(&'static str, P3)> = ["front", "back", "left", "right"]
        .iter()
        .zip([V3::x(), -V3::x(), V3::y(), -V3::y()])
        .map(|(n, d)| {
            let p = (0..400)
                .map(|k| c_ank.point(k as f64 / 400.0))
                .max_by(|a, b| a.coords.dot(&d).total_cmp(&b.coords.dot(&d)))
                .unwrap();
            (*n, p)
        })
        .collect();
    let ank = |s: f64| {
        let cons: Vec<Constraint> = ext4
            .iter()
            .map(|(n, p)| Constraint {
                name: n,
                u: param_of(&c_ank, p),
                order: 0,
                delta: (p.coords - ctr) * s,
            })
            .collect();
        least_change("ankle_girth", &c_ank, &cons)
    };
    let s = secant(|s| Ok(ank(s)?.length() - target[7]), 0.01)?;
    let l_ank = ank(s)?;
    deform.push(DeformRecord {
        curve: "ankle_girth",
        curve_type: 4,
        constraints: 4,
        max_control_move_mm: maxmove(&c_ank, &l_ank),
        length_mm: l_ank.length(),
        target_mm: Some(target[7]),
    });
    Ok((
        fits,
        Frame {
            foot: vec![
                ("bottom_outline", c_out),
                ("ball_girth", c_ball),
                ("instep_girth", c_inst),
                ("long_heel_girth", c_lh),
                ("side_profile", c_prof),
                ("ankle_girth", c_ank),
            ],
            last: vec![
                ("bottom_outline", l_out),
                ("ball_girth", l_ball),
                ("instep_girth", l_inst),
                ("long_heel_girth", l_lh),
                ("side_profile", l_prof),
                ("ankle_girth", l_ank),
            ],
            deform,
        },
    ))
}

#[derive(Serialize)]
struct Report<'a> {
    inputs: &'a Inputs,
    frame: &'a FootFrame,
    rules: &'a [RuleRow],
    fits: &'a [FitRecord],
    deform: &'a [DeformRecord],
    clearance: &'a Clearance,
    field: shape::Params,
    mesh_evaluations: usize,
    last_triangles: usize,
}

/// Write last.stl, last.igs, last.step, frame.igs, report.json and customize.png into `dir`.
/// Every rule must be met and the last closed first; nothing is written otherwise.
pub fn write_outputs(c: &Customized, inp: &Inputs, dir: &Path) -> Result<(), CustomizeError> {
    let out = |p: &Path, why: String| CustomizeError::Output {
        path: p.display().to_string(),
        why,
    };
    if let Some(r) = c.rules.iter().find(|r| !r.met) {
        return Err(CustomizeError::Infeasible {
            why: format!(
                "rule {} ({}) not met on the last: {:.2} mm for a target of {:.2} mm",
                r.rule, r.quantity, r.last_mm, r.target_mm
            ),
        });
    }
    c.last
        .check()
        .map_err(|d| out(dir, format!("the last is not closed: {d}")))?;
    std::fs::create_dir_all(dir).map_err(|e| out(dir, e.to_string()))?;
    let p = dir.join("last.stl");
    c.last
        .write(&p, Format::StlBinary)
        .map_err(|e| out(&p, e.to_string()))?;
    let surf = surface::last_surface(c)?;
    let hdr = footscan_geom::export::Header::new("footscan customized last");
    let p = dir.join("last.igs");
    footscan_geom::export::iges::write(&p, &[], std::slice::from_ref(&surf), &hdr)
        .map_err(|e| out(&p, e.to_string()))?;
    let p = dir.join("last.step");
    footscan_geom::export::step::write(&p, &[], std::slice::from_ref(&surf), &hdr)
        .map_err(|e| out(&p, e.to_string()))?;
    let frame: Vec<NurbsCurve> = c.curves.last.iter().map(|(_, k)| k.clone()).collect();
    let p = dir.join("frame.igs");
    footscan_geom::export::iges::write_frame(&p, &frame, &hdr)
        .map_err(|e| out(&p, e.to_string()))?;
    let rep = Report {
        inputs: inp,
        frame: &c.frame_in_world,
        rules: &c.rules,
        fits: &c.fits,
        deform: &c.curves.deform,
        clearance: &c.clearance,
        field: c.field,
        mesh_evaluations: c.evaluations,
        last_triangles: c.last.triangles.len(),
    };
    let p = dir.join("report.json");
    let j = serde_json::to_string_pretty(&rep).map_err(|e| out(&p, e.to_string()))?;
    crate::draw::write_atomic(&p, j.as_bytes()).map_err(|e| out(&p, e.to_string()))?;
    let p = dir.join("customize.png");
    picture::draw(c, &p).map_err(|e| out(&p, e.to_string()))?;
    Ok(())
}

/// The files [`write_outputs`] writes, in order.
pub const OUTPUT_FILES: [&str; 6] = [
    "last.stl",
    "last.igs",
    "last.step",
    "frame.igs",
    "report.json",
    "customize.png",
];

/// [`write_outputs`] all or nothing: into a temporary directory beside `out`, which replaces
/// `out` only once every file is written (a reader never sees half a last, and a failed run
/// leaves an earlier result as it was). Returns the files written.
pub fn write_outputs_atomic(
    c: &Customized,
    inp: &Inputs,
    out: &Path,
) -> Result<Vec<std::path::PathBuf>, CustomizeError> {
    let err = |p: &Path, why: String| CustomizeError::Output {
        path: p.display().to_string(),
        why,
    };
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    let name = out
        .file_name()
        .ok_or_else(|| err(out, "not a directory path".into()))?
        .to_string_lossy()
        .to_string();
    let pid = std::process::id();
    let tmp = parent.join(format!(".{name}.tmp{pid}"));
    let _ = std::fs::remove_dir_all(&tmp);
    let result = write_outputs(c, inp, &tmp).and_then(|()| {
        let old = parent.join(format!(".{name}.old{pid}"));
        let had = out.exists();
        if had {
            std::fs::rename(out, &old).map_err(|e| err(out, e.to_string()))?;
        }
        if let Err(e) = std::fs::rename(&tmp, out) {
            if had {
                let _ = std::fs::rename(&old, out);
            }
            return Err(err(out, e.to_string()));
        }
        if had {
            let _ = std::fs::remove_dir_all(&old);
        }
        Ok(())
    });
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result?;
    Ok(OUTPUT_FILES.iter().map(|n| out.join(n)).collect())
}

pub mod picture;
pub mod surface;
