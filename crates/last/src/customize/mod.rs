//! A customized last from a whole-foot mesh: characteristic points and curves cut from the
//! foot, fitted as NURBS (Algorithm I), deformed by comfort rules with the least change of
//! control points in type order I, II, III, IV (Algorithm II), and a closed last whose
//! measured sizes meet every rule (see [`shape`] for how the surface is made and why).
//! Method: docs/method.md section 10; paper: "Adaptive deformation of characteristic NURBS
//! curves for customized shoe-last" (Ren, Wang, Liu, Luo, 2013).

pub(crate) mod bottom;
use bottom::{raise, shear, BottomCurve, FLAT_TOL_MM};
pub mod clinic;
pub mod curves;
mod error;
pub mod landmarks;
pub mod measure;
pub mod rules;
pub mod shape;

pub use error::CustomizeError;

use curves::{fit_loop, least_change, Constraint, FitRecord};
use footscan_geom::mesh::{Bvh, Format, Intake, IntakeOptions, TriMesh};
use footscan_geom::nurbs::NurbsCurve;
use footscan_geom::{P2, P3};
use measure::{find_frame, measure, FootFrame, Loop3, Measures, OUTLINE_Z};
use rules::{RuleSet, Shoe, Wearer};
use serde::Serialize;
use std::path::Path;

/// What the last is for.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct Inputs {
    pub shoe: Shoe,
    pub wearer: Wearer,
    /// Heel height of the shoe (mm), which rule II-F's ball girth allowance follows. None:
    /// on the clinic path the stock last's own (the last keeps its bottom curve, so its
    /// heel is the shoe's), elsewhere [`DEFAULT_HEEL_MM`].
    pub heel_mm: Option<f64>,
}

/// The heel height assumed where neither the request nor a stock last gives one (mm).
pub const DEFAULT_HEEL_MM: f64 = 25.0;

impl Inputs {
    /// The heel height the rules use.
    pub fn heel(&self) -> f64 {
        self.heel_mm.unwrap_or(DEFAULT_HEEL_MM)
    }
}

impl Default for Inputs {
    /// A men's dress last, the heel as [`Inputs::heel_mm`] says: what the CLI and footscand
    /// assume when a request does not say.
    fn default() -> Self {
        Inputs {
            shoe: Shoe::Dress,
            wearer: Wearer::Man,
            heel_mm: None,
        }
    }
}

/// Heel heights a last is made for (mm): flat to a high dress heel.
pub const HEEL_RANGE_MM: (f64, f64) = (0.0, 120.0);

/// Foot length range accepted as a foot (mm).
pub const FOOT_LENGTH_RANGE: (f64, f64) = footscan_geom::mesh::FOOT_LENGTH_MM;

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
    /// Met, or nothing to meet: a rule with no counterpart on the last (see `applies`).
    pub met: bool,
    pub source: String,
    /// The rule has a counterpart on this last (the clinic path's ankle girth on a low-cut
    /// last has none); else `not_applicable` says why and the rule was not solved for.
    pub applies: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_applicable: Option<String>,
    /// How much the clinic path's build-up for the footprint grew this measure after the
    /// solve met it (mm; 0 where nothing was built up): judged on the solve, shown as grown.
    #[serde(skip_serializing_if = "is_zero")]
    pub built_up_mm: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
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
    /// Largest distance of the eq. 9 deformed foot curve from the output last's own cut (mm).
    pub max_dev_from_last_mm: f64,
    /// Wall time of this curve's Algorithm I fit and Algorithm II deformation (ms; the
    /// deviation check after them not counted).
    pub fit_deform_ms: f64,
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
    /// The bottom curve (x, height above the glass, every millimetre) by which the last was
    /// raised after it was made flat; the rules' values are those of the last laid flat by
    /// it. Clinic path: a stock last with toe spring or a raised heel. Whole-foot path: a
    /// foot whose midfoot does not reach the glass, the last's bottom following its arch.
    pub bottom_curve: Option<Vec<P2>>,
    /// Clinic path: the scan's footprint in the last's frame (drawn in the top view).
    pub footprint: Vec<Vec<P2>>,
    /// What was done to the input that the user should know (the clinic path: a stock last
    /// of the other side mirrored).
    pub notes: Vec<String>,
    /// Clinic path: where the footprint was set in the last, and what of the last was built
    /// up so the footprint fits (empty: nothing).
    pub placement: Option<clinic::Placement>,
    pub build_up: Vec<clinic::BuildUp>,
    /// The heel height the rules used (mm): the one asked, else the stock last's own on the
    /// clinic path (see [`Inputs::heel_mm`]).
    pub heel_mm: f64,
}

/// How far the foot stands inside the last, region by region (negative: the foot presses
/// out through the last). The rules decide where it must fit: the toe box (I-A's toe
/// allowance, III's forefoot "as the foot"), the midfoot (II-G, II-H, IV increase the
/// girths; I-C's narrower waist lets the sides press by half its reduction) and the heel
/// seat (I-D, II-H) must hold the foot; at the ball (II-F's reduced girth) and behind the
/// heel allowance (I-A) the last is smaller than the foot on purpose and the figure is a
/// report, not a requirement.
#[derive(Clone, Debug, Serialize)]
pub struct Clearance {
    /// What stands inside the last: "foot" (the foot mesh), or "stock last" on the clinic
    /// path (no whole foot: how the stock last sits in the customized one).
    pub of: &'static str,
    pub regions: Vec<RegionClearance>,
    /// Smallest clearance less the allowed press over the regions where the foot must fit
    /// (>= -[`FIT_TOL_MM`]: the foot fits where the rules say it must).
    pub must_fit_margin_mm: f64,
    /// Smallest clearance anywhere below the top, and where (foot frame, mm).
    pub overall_mm: f64,
    pub worst_at_mm: P3,
    /// Where the foot does not fit where the rules say it must: which region, where, and
    /// what of the last's construction presses it there (None where it fits).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub missed_because: Option<String>,
}

/// One region's clearance.
#[derive(Clone, Debug, Serialize)]
pub struct RegionClearance {
    pub region: &'static str,
    /// The rules that shape the last here.
    pub rules: &'static str,
    /// How far the foot may press out here (mm) where the rules say it must fit; None where
    /// they make the last smaller than the foot on purpose.
    pub allowed_press_mm: Option<f64>,
    pub min_mm: f64,
    pub at_mm: P3,
    pub vertices: usize,
}

impl RegionClearance {
    /// Whether the foot fits here as the rules say (always true where they compress it).
    pub fn met(&self) -> bool {
        self.allowed_press_mm
            .is_none_or(|a| self.vertices == 0 || self.min_mm >= -a - FIT_TOL_MM)
    }
}

/// Slack of the must-fit check (mm): the last's sections are polygons of 128 points through
/// hulls of the foot's cuts 150 stations apart, so a surface that follows the foot lies
/// within about this of it.
pub const FIT_TOL_MM: f64 = 0.3;

impl Clearance {
    pub fn region(&self, name: &str) -> Option<&RegionClearance> {
        self.regions.iter().find(|r| r.region == name)
    }
    /// One line for the CLI, the bench and the picture.
    pub fn summary(&self) -> String {
        let parts: Vec<String> = self
            .regions
            .iter()
            .filter(|r| r.vertices > 0)
            .map(|r| {
                format!(
                    "{} {:+.2}{}",
                    r.region,
                    r.min_mm,
                    match r.allowed_press_mm {
                        None => " (pressed by rule)",
                        Some(_) if !r.met() => " (MISSED)",
                        Some(_) => "",
                    }
                )
            })
            .collect();
        parts.join(", ")
    }
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
        + r.ii_f.per_10mm_heel_mm * (inp.heel() - r.ii_f.heel_reference_mm).max(0.0) / 10.0;
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
        applies: true,
        not_applicable: None,
        built_up_mm: 0.0,
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

/// Load a foot mesh (STL, OBJ, PLY) as it comes (units, axes and orientation found from the
/// mesh: [`footscan_geom::mesh::intake`]), and bring it into its own frame.
pub fn load_foot(path: &Path) -> Result<(TriMesh, FootFrame), CustomizeError> {
    load_foot_with(path, &IntakeOptions::default()).map(|(m, f, _)| (m, f))
}

/// [`load_foot`] with the units, length and axes given where known. Returns the foot in its
/// frame, the frame in the file's own coordinates (millimetres: file units times the unit
/// scale), and what the intake did (notes for the CLI).
pub fn load_foot_with(
    path: &Path,
    opts: &IntakeOptions,
) -> Result<(TriMesh, FootFrame, Intake), CustomizeError> {
    let intake = TriMesh::read_foot(path, opts).map_err(|e| {
        e.retold(
            "pass --units m (or --units auto)",
            "give its unit with --units mm|cm|m or its heel-to-toe length with --length MM",
        )
    })?;
    let name = path.display().to_string();
    let (m, mut frame) = foot_in_frame(intake.mesh.clone(), &name)?;
    // The frame in the file's coordinates (the intake only turned and moved the mesh).
    frame.origin = intake.to_file_mm(&frame.origin);
    frame.ex = intake.dir_to_file(&frame.ex);
    frame.ey = intake.dir_to_file(&frame.ey);
    Ok((m, frame, intake))
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
    // A foot whose midfoot does not reach the glass (scanned without weight on it) is laid
    // flat by the curve under its arch, the last made on the flat foot and raised back: its
    // bottom then follows the arch (a shank), where a flat bottom filled the gap, the
    // girths outgrew the rules by 3-20 mm and the solver gave them back over the instep,
    // pressing the dorsum 3-7 mm (docs/method.md 10.5). The rules' values are those of the
    // last laid flat, as on the clinic path; the foot's are the foot's own.
    let bottom = BottomCurve::under_arch(&foot).filter(|b| b.rise() > FLAT_TOL_MM);
    let lift = |x: f64| bottom.as_ref().map_or(0.0, |b| b.at(x));
    let sec = shape::Sections::of_foot(&foot, fm.length, fm.sole_from(), &lift);
    // The surface: the field solved so the cut last meets every rule.
    let mut nd = shape::Nodes::of(&fm);
    nd.heel_allowance = heel_allow;
    // The long-heel plane of the foot laid flat (its instep top lowered with its section).
    nd.instep_top.1 -= lift(nd.instep_top.0);
    let (mut last, lm, field, evals) = shape::solve(&sec, &nd, &fm, &target, medial)?;
    judge(&mut rows, &lm);
    // Raised back (the arch lies behind the toe stretch, so the last's x there is the
    // foot's), and the last's curves with it: Algorithm II moves the foot's own curves onto
    // the last as it is.
    let mut outline = sec.sole_outline();
    let mut on_last = lm.clone();
    if bottom.is_some() {
        shear(&mut last, lift);
        raise(&mut outline, lift);
        for l in on_last.outline.iter_mut().chain([
            &mut on_last.ball,
            &mut on_last.instep,
            &mut on_last.long_heel,
            &mut on_last.ankle,
            &mut on_last.profile,
        ]) {
            raise(l, lift);
        }
    }
    // Algorithm I on the foot's characteristic curves, Algorithm II onto the last's.
    let (fits, curves) = frame_curves(&fm, &outline, &on_last, &target)?;
    let mut clearance = clearance(&foot, &last, &nd, rows[2].change_mm);
    clearance.missed_because = why_missed(&clearance, &field, &nd, medial);
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
        bottom_curve: bottom.map(|b| b.samples()),
        footprint: Vec::new(),
        notes: Vec::new(),
        placement: None,
        build_up: Vec::new(),
        heel_mm: inp.heel(),
    })
}

impl Customized {
    /// Where the last is not what the rules ask, one line each: a rule whose value on the
    /// last is outside its bound, a region where the foot must fit and presses out beyond
    /// what the rules allow (plus [`FIT_TOL_MM`]). Empty: the last is as the rules say.
    pub fn misfits(&self) -> Vec<String> {
        let mut out: Vec<String> = self
            .rules
            .iter()
            .filter(|r| !r.met)
            .map(|r| {
                format!(
                    "rule {} ({}) not met: {:.2} mm on the last for a target of {:.2} mm (bound {:.2})",
                    r.rule, r.quantity, r.last_mm, r.target_mm, r.bound_mm
                )
            })
            .collect();
        for r in self.clearance.regions.iter().filter(|r| !r.met()) {
            out.push(format!(
                "the {} presses out through the {} by {:.2} mm at ({:.1}, {:.1}, {:.1}) (foot frame), where {} say it must fit{}",
                self.clearance.of,
                r.region,
                -r.min_mm,
                r.at_mm.x,
                r.at_mm.y,
                r.at_mm.z,
                r.rules,
                match r.allowed_press_mm {
                    Some(a) if a > 0.0 => format!(" (pressing by {a:.2} mm allowed, {FIT_TOL_MM} mm slack)"),
                    _ => format!(" ({FIT_TOL_MM} mm slack)"),
                }
            ));
        }
        out
    }
}

/// Why the foot stands out of its last where the rules say it must fit: the worst missed
/// region, its point (fraction of the length, height, side) and the field values that take
/// the last inward there (a width scale below one pulls the walls about the axis; a negative
/// offset or widening gives girth back over the top). None where every region is met.
fn why_missed(
    c: &Clearance,
    field: &shape::Params,
    nd: &shape::Nodes,
    medial: f64,
) -> Option<String> {
    let r = c
        .regions
        .iter()
        .filter(|r| !r.met())
        .min_by(|a, b| a.min_mm.total_cmp(&b.min_mm))?;
    let (x, y, z) = (r.at_mm.x, r.at_mm.y, r.at_mm.z);
    let side = if y * medial > 0.0 {
        "medial"
    } else {
        "lateral"
    };
    let [_, syh, syw, syb, _, dh, da, di, kup] = *field;
    let mut inward = Vec::new();
    let scale = match r.region {
        "heel seat" => Some(("heel", syh)),
        "midfoot" => Some(("waist", syw)),
        "toe box" => Some(("ball", syb)),
        _ => None,
    };
    if let Some((n, s)) = scale.filter(|s| s.1 < 1.0) {
        inward.push(format!(
            "the {n} width scale {s:.4} (the last's plan width, taken from hulls that \
             hold the foot between stations, came out wider than the foot's and the \
             rule's width is given back from both walls)"
        ));
    }
    for (n, v) in [("heel", dh), ("ankle", da), ("instep", di)] {
        if v < 0.0 {
            inward.push(format!(
                "the {n} offset {v:+.2} mm (girth given back over the top)"
            ));
        }
    }
    if kup < 0.0 {
        inward.push(format!(
            "the upper midfoot's widening {:+.1} % (girth given back from the walls)",
            100.0 * kup
        ));
    }
    let cause = if inward.is_empty() {
        "no field value takes the last inward there: the foot stands out between the last's \
         sections (128-point polygons through hulls at 250 stations) or its own surface is \
         rougher than the tolerance"
            .to_string()
    } else {
        inward.join("; ")
    };
    Some(format!(
        "{} {:+.2} mm (allowed {:.2}) at {:.2} L, {:.0} mm up, {side}: {cause}",
        r.region,
        r.min_mm,
        -(r.allowed_press_mm.unwrap_or(0.0) + FIT_TOL_MM),
        x / nd.length,
        z
    ))
}

/// Each rule's value cut from the output last, its error and whether it is within bound.
pub(crate) fn judge(rows: &mut [RuleRow], lm: &Measures) {
    let v = shape::values(lm);
    for (r, v) in rows.iter_mut().zip(v) {
        r.last_mm = v;
        if r.applies {
            r.error_mm = v - r.target_mm;
            r.met = r.error_mm.abs() <= r.bound_mm;
        } else {
            r.error_mm = f64::NAN;
            r.met = true;
        }
    }
}

/// The regions of a clearance, in the order [`region_of`] numbers them.
fn clearance_regions(waist_change_mm: f64) -> [RegionClearance; 5] {
    [
        ("heel allowance", "I-A heel allowance", None),
        ("heel seat", "I-D, II-H", Some(0.0)),
        (
            "midfoot",
            "I-C, II-G, II-H, IV",
            Some(0.5 * (-waist_change_mm).max(0.0)),
        ),
        ("ball", "II-F (reduced girth)", None),
        ("toe box", "I-A toe allowance, III", Some(0.0)),
    ]
    .map(|(region, rules, allowed_press_mm)| RegionClearance {
        region,
        rules,
        allowed_press_mm,
        min_mm: f64::INFINITY,
        at_mm: P3::new(f64::NAN, f64::NAN, f64::NAN),
        vertices: 0,
    })
}

/// The region of a footprint point (on the glass: the outline's height).
pub(crate) fn region_of_plan(nd: &shape::Nodes, x: f64) -> usize {
    region_of(nd, x, OUTLINE_Z)
}

/// The region of a point of the foot frame (x along the axis, z up).
fn region_of(nd: &shape::Nodes, x: f64, z: f64) -> usize {
    // Under the heel allowance's 45 degree chamfer (with a millimetre's margin).
    if nd.heel_allowance > 0.0 && z < OUTLINE_Z + nd.heel_allowance - x + 1.0 {
        0
    } else if x < nd.heel_window {
        1
    } else if x < nd.forefoot {
        2
    } else if x < nd.toe_box {
        3
    } else {
        4
    }
}

/// The clearance from the regions' smallest figures.
fn clearance_of(of: &'static str, regions: [RegionClearance; 5]) -> Clearance {
    let must_fit_margin_mm = regions
        .iter()
        .filter(|r| r.vertices > 0)
        .filter_map(|r| r.allowed_press_mm.map(|a| r.min_mm + a))
        .fold(f64::INFINITY, f64::min);
    // The overall worst is the worst region's (every counted point is in one region).
    let (overall_mm, worst_at_mm) = regions
        .iter()
        .filter(|r| r.vertices > 0)
        .min_by(|a, b| a.min_mm.total_cmp(&b.min_mm))
        .map_or(
            (f64::INFINITY, P3::new(f64::NAN, f64::NAN, f64::NAN)),
            |r| (r.min_mm, r.at_mm),
        );
    Clearance {
        of,
        regions: regions.into(),
        must_fit_margin_mm,
        overall_mm,
        worst_at_mm,
        missed_because: None,
    }
}

fn note(r: &mut RegionClearance, c: f64, at: P3) {
    r.vertices += 1;
    if c < r.min_mm {
        r.min_mm = c;
        r.at_mm = at;
    }
}

pub(crate) fn clearance(
    foot: &TriMesh,
    last: &TriMesh,
    nd: &shape::Nodes,
    waist_change_mm: f64,
) -> Clearance {
    let bvh = Bvh::new(last);
    let mut regions = clearance_regions(waist_change_mm);
    let top = shape::TOP_Z * nd.length;
    for p in &foot.vertices {
        if p.z > top - 1.0 {
            continue;
        }
        let Some(sd) = bvh.signed_distance(p) else {
            continue;
        };
        note(&mut regions[region_of(nd, p.x, p.z)], -sd.distance, *p);
    }
    clearance_of("foot", regions)
}

/// The clinic path's clearance: no whole foot, so the scanned footprint (its body and toe
/// outlines, placed in the last's frame) against the last's plan outline, point by point
/// (inside: the distance to the outline; outside: its negative).
pub(crate) fn footprint_clearance(
    footprint: &[Vec<P2>],
    last_outline: &[Loop3],
    nd: &shape::Nodes,
    waist_change_mm: f64,
) -> Clearance {
    let mut regions = clearance_regions(waist_change_mm);
    let loops: Vec<footscan_geom::polygon::Polygon> = last_outline
        .iter()
        .map(|l| {
            footscan_geom::polygon::Polygon::new(l.iter().map(|p| P2::new(p.x, p.y)).collect())
        })
        .collect();
    for p in footprint.iter().flatten() {
        let inside = loops.iter().any(|l| l.contains(p));
        let d = loops
            .iter()
            .map(|l| l.distance_to_boundary(p))
            .fold(f64::INFINITY, f64::min);
        if !d.is_finite() {
            continue;
        }
        let c = if inside { d } else { -d };
        note(
            &mut regions[region_of(nd, p.x, OUTLINE_Z)],
            c,
            P3::new(p.x, p.y, OUTLINE_Z),
        );
    }
    clearance_of("footprint", regions)
}

/// One characteristic curve: name, type (I-IV), foot cut, last cut, girth target.
type CurveSpec<'a> = (&'static str, u8, &'a [P3], &'a [P3], Option<f64>);

/// Algorithm I on the six foot curves, then Algorithm II in type order (I: the bottom
/// outline; II: the ball, instep and long-heel girths; III: the side profile; IV: the ankle
/// girth). Each curve's nodes (its characteristic points and evenly spaced points between
/// them, by arc length from the point nearest the last's) move to the matching points of the
/// output last's own cut by the same plane, with the least change of control points (eq. 9).
/// The targets come from the last, which was solved so that the cut mesh meets every rule,
/// so the frame written is the frame of that last (within `max_dev_from_last_mm`), not a
/// second answer to the rules that could disagree with it.
pub(crate) fn frame_curves(
    f: &Measures,
    outline: &[P3],
    lm: &Measures,
    target: &[f64; 8],
) -> Result<(Vec<FitRecord>, Frame), CustomizeError> {
    let tol = 0.05;
    let mut fits = Vec::new();
    let mut fit = |name: &'static str, pts: &[P3]| -> Result<NurbsCurve, CustomizeError> {
        let (c, r) = fit_loop(name, pts, 1.0, tol)?;
        fits.push(r);
        Ok(c)
    };
    let last_outline = lm
        .outline
        .iter()
        .max_by(|a, b| {
            let la = footscan_geom::polyline::Polyline::closed((*a).clone()).length();
            let lb = footscan_geom::polyline::Polyline::closed((*b).clone()).length();
            la.total_cmp(&lb)
        })
        .cloned()
        .unwrap_or_default();
    let specs: [CurveSpec; 6] = [
        ("bottom_outline", 1, outline, &last_outline, None),
        ("ball_girth", 2, &f.ball, &lm.ball, Some(target[4])),
        ("instep_girth", 2, &f.instep, &lm.instep, Some(target[5])),
        (
            "long_heel_girth",
            2,
            &f.long_heel,
            &lm.long_heel,
            Some(target[6]),
        ),
        ("side_profile", 3, &f.profile, &lm.profile, None),
        ("ankle_girth", 4, &f.ankle, &lm.ankle, Some(target[7])),
    ];
    let mut foot = Vec::new();
    let mut last = Vec::new();
    let mut deform = Vec::new();
    for (name, kind, fpts, lpts, tgt) in specs {
        let t0 = std::time::Instant::now();
        let c = fit(name, fpts)?;
        let fit_ms = t0.elapsed().as_secs_f64() * 1e3;
        let (_, mut rec) = conform(name, kind, &c, lpts, tgt)?;
        // Algorithm I's fit plus Algorithm II's solve (not the report's check after it).
        rec.fit_deform_ms += fit_ms;
        // The frame written: the last's own cut fitted by Algorithm I (within the fit's
        // tolerance of the mesh). Eq. 9 interpolates the foot curve's nodes onto the same cut
        // (the record above) but keeps the foot curve's knots, which leaves it up to a few
        // millimetres off where the last has an edge the foot has not (the flat bottom).
        // Points 0.5 mm apart: at the flat bottom's right-angled corners a fit through points
        // 1 mm apart cut the corner by 0.13 mm and a girth curve came out 0.5 mm short.
        let (l, _) = fit_loop(name, lpts, 0.5, tol)?;
        foot.push((name, c));
        last.push((name, l));
        deform.push(rec);
    }
    Ok((fits, Frame { foot, last, deform }))
}

/// Algorithm II for one closed curve onto a closed target polyline (see [`frame_curves`]).
fn conform(
    name: &'static str,
    kind: u8,
    c: &NurbsCurve,
    target: &[P3],
    target_len: Option<f64>,
) -> Result<(NurbsCurve, DeformRecord), CustomizeError> {
    let t0 = std::time::Instant::now();
    if target.len() < 3 {
        return Err(CustomizeError::Curve {
            curve: name.into(),
            why: "the last has no section for this curve".into(),
        });
    }
    let (a, b) = c.domain();
    let nfree = if c.periodic {
        c.points.len() - c.degree
    } else {
        c.points.len()
    };
    // A node at the Greville abscissa of every control point: R is the square collocation
    // matrix, nonsingular wherever the fit put its knots (Schoenberg-Whitney), so eq. 9 has
    // one solution and the curve passes through the last at every node. Fewer nodes leave
    // control points the minimum-norm change barely moves between moved ones: a comb.
    let p = c.degree;
    let node_u: Vec<f64> = (0..nfree)
        .map(|i| {
            let g = c.knots[i + 1..=i + p].iter().sum::<f64>() / p as f64;
            a + (g - a).rem_euclid(b - a)
        })
        .collect();
    let k = node_u.len();
    if k < 4 {
        return Err(CustomizeError::Curve {
            curve: name.into(),
            why: format!("{nfree} control points: too few to deform"),
        });
    }
    // Arc length of the foot curve at each node (fraction of the whole): chords through
    // eight samples between consecutive nodes.
    let sub = 8;
    let mut cum = vec![0.0; k + 1];
    let mut prev = c.point(node_u[0]);
    for i in 0..k {
        let (u0, mut u1) = (node_u[i], node_u[(i + 1) % k]);
        if u1 < u0 {
            u1 += b - a;
        }
        let mut acc = 0.0;
        for j in 1..=sub {
            let q = c.point(u0 + (u1 - u0) * j as f64 / sub as f64);
            acc += (q - prev).norm();
            prev = q;
        }
        cum[i + 1] = cum[i] + acc;
    }
    let total = cum[k];
    let node_s: Vec<f64> = cum[..k].iter().map(|&x| x / total).collect();
    // The target by arc length from the point nearest the curve's start, in the curve's
    // direction.
    let pl = footscan_geom::polyline::Polyline::closed(target.to_vec());
    let tcum = pl.cumulative_lengths();
    let tlen = *tcum.last().unwrap();
    let p0 = c.point(node_u[0]);
    let s0 = pl.closest_point(&p0).map_or(0.0, |q| q.arc_length);
    let ahead = c.point(node_u[1]);
    let fwd = (pl.point_at_with(&tcum, s0 + node_s[1] * tlen) - ahead).norm()
        <= (pl.point_at_with(&tcum, s0 - node_s[1] * tlen) - ahead).norm();
    let sign = if fwd { 1.0 } else { -1.0 };
    let cons: Vec<Constraint> = node_u
        .iter()
        .zip(&node_s)
        .map(|(&u, &sf)| {
            let q = pl.point_at_with(&tcum, s0 + sign * sf * tlen);
            Constraint {
                name,
                u,
                order: 0,
                delta: q - c.point(u),
            }
        })
        .collect();
    let d = least_change(name, c, &cons)?;
    // The deformation proper ends here; what follows checks and reports it.
    let deform_ms = t0.elapsed().as_secs_f64() * 1e3;
    // Agreement with the last: every sample of the curve against the target loop as cut.
    let dev = (0..400)
        .map(|i| {
            let p = d.point(a + (b - a) * i as f64 / 400.0);
            (0..target.len())
                .map(|j| seg_dist(&p, &target[j], &target[(j + 1) % target.len()]))
                .fold(f64::MAX, f64::min)
        })
        .fold(0.0, f64::max);
    let max_move = c
        .points
        .iter()
        .zip(&d.points)
        .map(|(p, q)| (p - q).norm())
        .fold(0.0, f64::max);
    let rec = DeformRecord {
        curve: name,
        curve_type: kind,
        constraints: cons.len(),
        max_control_move_mm: max_move,
        length_mm: d.length(),
        target_mm: target_len,
        max_dev_from_last_mm: dev,
        fit_deform_ms: deform_ms,
    };
    Ok((d, rec))
}

fn seg_dist(p: &P3, a: &P3, b: &P3) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-300)).clamp(0.0, 1.0);
    (p - (a + ab * t)).norm()
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
    #[serde(skip_serializing_if = "Option::is_none")]
    bottom_curve: Option<&'a [P2]>,
    foot_points: FootPoints,
    /// Whether the last misses a rule or the must-fit check ([`Customized::misfits`]); a
    /// misfit is written only when asked (`--keep-misfit`), with MISFIT.txt beside it.
    misfit: bool,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    misfits: Vec<String>,
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    notes: &'a [String],
    #[serde(skip_serializing_if = "Option::is_none")]
    placement: Option<clinic::Placement>,
    #[serde(skip_serializing_if = "<[_]>::is_empty")]
    build_up: &'a [clinic::BuildUp],
}

/// The file written beside a last that misses its rules (`--keep-misfit`).
pub const MISFIT_FILE: &str = "MISFIT.txt";

/// The foot's characteristic points in its frame (mm; docs/method.md 10.1 defines them), so a
/// last maker or a test can compare them with landmarks of their own.
#[derive(Serialize)]
struct FootPoints {
    heel_point_o: P3,
    toe_tip_a: P3,
    hallux_p: P3,
    mt1_b: P3,
    mt5_c: P3,
    waist_inner_d: P3,
    waist_outer_e: P3,
    heel_centre: P3,
    instep_top: P3,
}

impl FootPoints {
    fn of(m: &Measures) -> FootPoints {
        FootPoints {
            heel_point_o: m.o,
            toe_tip_a: m.a,
            hallux_p: m.p,
            mt1_b: m.b,
            mt5_c: m.c,
            waist_inner_d: m.d,
            waist_outer_e: m.e,
            heel_centre: m.heel_centre,
            instep_top: m.instep_top,
        }
    }
}

/// Write last.stl, last.igs, last.step, frame.igs, report.json and customize.png into `dir`.
/// Every rule must be met and the last closed first; nothing is written otherwise. The
/// report says whether the foot fits where the rules say it must (`misfit`, `misfits`).
pub fn write_outputs(c: &Customized, inp: &Inputs, dir: &Path) -> Result<(), CustomizeError> {
    write_files(c, inp, dir, false)
}

/// [`write_outputs`] of a last that misses its rules, marked so: report.json has
/// `"misfit": true` and the reasons, and MISFIT.txt says what is wrong in words.
pub fn write_misfit(c: &Customized, inp: &Inputs, dir: &Path) -> Result<(), CustomizeError> {
    write_files(c, inp, dir, true)
}

fn write_files(
    c: &Customized,
    inp: &Inputs,
    dir: &Path,
    marked: bool,
) -> Result<(), CustomizeError> {
    let out = |p: &Path, why: String| CustomizeError::Output {
        path: p.display().to_string(),
        why,
    };
    let misfits = c.misfits();
    if !marked {
        if let Some(r) = c.rules.iter().find(|r| !r.met) {
            return Err(CustomizeError::Infeasible {
                why: format!(
                    "rule {} ({}) not met on the last: {:.2} mm for a target of {:.2} mm",
                    r.rule, r.quantity, r.last_mm, r.target_mm
                ),
            });
        }
    }
    c.last
        .check()
        .map_err(|d| out(dir, format!("the last is not closed: {d}")))?;
    std::fs::create_dir_all(dir).map_err(|e| out(dir, e.to_string()))?;
    let p = dir.join("last.stl");
    c.last
        .write(&p, Format::StlBinary)
        .map_err(|e| out(&p, e.to_string()))?;
    // glTF for the web and Blender: the last, and the foot inside it (issue 35).
    let p = dir.join("last.glb");
    footscan_geom::mesh::write_glb(
        &p,
        &[footscan_geom::mesh::GlbPart {
            name: "last",
            mesh: &c.last,
            colour: [0.7, 0.7, 0.75, 1.0],
            vertex_colours: None,
        }],
    )
    .map_err(|e| out(&p, e.to_string()))?;
    let p = dir.join("foot_in_last.glb");
    // On the clinic path (a stock last placed on the footprint) there is no whole foot:
    // the stock last stands inside, named so.
    let inner = if c.placement.is_some() {
        "stock last"
    } else {
        "foot"
    };
    footscan_geom::mesh::write_foot_in_last_glb(&p, &c.foot, inner, &c.last)
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
    // The heel the rules used, which the clinic path took from the stock last when not asked.
    let applied = Inputs {
        heel_mm: Some(c.heel_mm),
        ..*inp
    };
    let rep = Report {
        inputs: &applied,
        frame: &c.frame_in_world,
        rules: &c.rules,
        fits: &c.fits,
        deform: &c.curves.deform,
        clearance: &c.clearance,
        field: c.field,
        mesh_evaluations: c.evaluations,
        last_triangles: c.last.triangles.len(),
        bottom_curve: c.bottom_curve.as_deref(),
        foot_points: FootPoints::of(&c.foot_measures),
        misfit: !misfits.is_empty(),
        misfits: misfits.clone(),
        notes: &c.notes,
        placement: c.placement,
        build_up: &c.build_up,
    };
    let p = dir.join("report.json");
    let j = serde_json::to_string_pretty(&rep).map_err(|e| out(&p, e.to_string()))?;
    crate::draw::write_atomic(&p, j.as_bytes()).map_err(|e| out(&p, e.to_string()))?;
    let p = dir.join("customize.png");
    picture::draw(c, &p).map_err(|e| out(&p, e.to_string()))?;
    if marked && !misfits.is_empty() {
        let p = dir.join(MISFIT_FILE);
        let text = format!(
            "MISFIT: this last does not do what its rules ask. Check it before a shoe is made on it.\n\n{}\n\nreport.json has the rules' table and the clearance by region (\"misfit\": true).\n",
            misfits
                .iter()
                .map(|m| format!("- {m}"))
                .collect::<Vec<_>>()
                .join("\n")
        );
        crate::draw::write_atomic(&p, text.as_bytes()).map_err(|e| out(&p, e.to_string()))?;
    }
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
    write_atomic(c, inp, out, false)
}

/// [`write_misfit`] all or nothing, as [`write_outputs_atomic`]; MISFIT.txt listed last.
pub fn write_misfit_atomic(
    c: &Customized,
    inp: &Inputs,
    out: &Path,
) -> Result<Vec<std::path::PathBuf>, CustomizeError> {
    write_atomic(c, inp, out, true)
}

fn write_atomic(
    c: &Customized,
    inp: &Inputs,
    out: &Path,
    marked: bool,
) -> Result<Vec<std::path::PathBuf>, CustomizeError> {
    let err = |p: &Path, why: String| CustomizeError::Output {
        path: p.display().to_string(),
        why,
    };
    crate::outdir::write_dir_atomic(out, |tmp| {
        write_files(c, inp, tmp, marked).map_err(|e| match e {
            CustomizeError::Output { path, why } => (path.into(), why),
            e => (tmp.to_path_buf(), e.to_string()),
        })
    })
    .map_err(|(p, why)| err(&p, why))?;
    let mut files: Vec<std::path::PathBuf> = OUTPUT_FILES.iter().map(|n| out.join(n)).collect();
    if out.join(MISFIT_FILE).is_file() {
        files.push(out.join(MISFIT_FILE));
    }
    Ok(files)
}

pub mod picture;
pub mod surface;
