//! The clinic's way to a customized last: our scanner sees only the sole, so the foot comes
//! as the plantar measurements of a scan (length, ball, waist and heel widths, side) plus the
//! girths a fitter measures with a tape, and a stock last from the shop's collection is the
//! starting frame. The stock last is cut like a foot (its characteristic curves), the rules
//! are applied to the foot's values, and the stock last is deformed by the same solved field
//! as on the whole-foot path until its cut values are the targets (docs/method.md 10.7).

use super::bottom::{shear, BottomCurve, FLAT_TOL_MM};
use super::measure::{measure, Side};
use super::rules::RuleSet;
use super::{clearance, foot_in_frame, footprint_clearance, frame_curves, judge, shape, targets};
use super::{CustomizeError, Customized, Inputs};
use footscan_geom::mesh::TriMesh;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The four girths a fitter measures with a tape (mm); the daemon's last request carries
/// them as JSON.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TapeGirths {
    pub ball: f64,
    pub instep: f64,
    pub long_heel: f64,
    pub ankle: f64,
}

/// Tape girths a person can have (mm).
const GIRTH_RANGE: (f64, f64) = (120.0, 600.0);

impl TapeGirths {
    /// Parse a girths file: `ball = 245.0`, `instep = 240.0`, `long_heel = 330.0`,
    /// `ankle = 230.0` (mm, TOML). Every missing girth is named; an unknown key or a value
    /// outside 120-600 mm is an error.
    pub fn parse(text: &str, name: &str) -> Result<TapeGirths, CustomizeError> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct G {
            ball: Option<f64>,
            instep: Option<f64>,
            long_heel: Option<f64>,
            ankle: Option<f64>,
        }
        let bad = |why: String| CustomizeError::Rules(format!("{name}: {why}"));
        let g: G = toml::from_str(text).map_err(|e| bad(e.to_string()))?;
        let all = [
            ("ball", g.ball),
            ("instep", g.instep),
            ("long_heel", g.long_heel),
            ("ankle", g.ankle),
        ];
        let missing: Vec<&str> = all.iter().filter(|x| x.1.is_none()).map(|x| x.0).collect();
        if !missing.is_empty() {
            return Err(bad(format!(
                "missing girths: {} (mm, measured with a tape: ball, instep, long_heel, ankle)",
                missing.join(", ")
            )));
        }
        let v = |x: Option<f64>| x.unwrap_or_default();
        TapeGirths::checked(v(g.ball), v(g.instep), v(g.long_heel), v(g.ankle)).map_err(bad)
    }

    /// The four girths, each refused (named) outside 120-600 mm.
    pub fn checked(ball: f64, instep: f64, long_heel: f64, ankle: f64) -> Result<Self, String> {
        for (k, v) in [
            ("ball", ball),
            ("instep", instep),
            ("long_heel", long_heel),
            ("ankle", ankle),
        ] {
            if !(GIRTH_RANGE.0..=GIRTH_RANGE.1).contains(&v) {
                return Err(format!(
                    "{k} = {v} mm: a girth is {:.0}-{:.0} mm",
                    GIRTH_RANGE.0, GIRTH_RANGE.1
                ));
            }
        }
        Ok(TapeGirths {
            ball,
            instep,
            long_heel,
            ankle,
        })
    }

    pub fn load(path: &Path) -> Result<TapeGirths, CustomizeError> {
        let text = std::fs::read_to_string(path).map_err(|e| {
            CustomizeError::Rules(format!("{}: cannot read the girths: {e}", path.display()))
        })?;
        TapeGirths::parse(&text, &path.display().to_string())
    }
}

/// The plantar scan's figures the rules need (docs/method.md section 8).
#[derive(Clone, Debug)]
pub struct Plantar {
    pub side: Side,
    pub length: f64,
    pub ball_width: f64,
    pub waist_width: f64,
    pub heel_width: f64,
    /// The footprint (the body's and the toes' outlines) in the foot's frame: x along the
    /// axis from the heel point, y positive on the medial side (mm). The clearance is
    /// measured on it; empty: the stock last's own clearance inside the new one instead.
    pub footprint: Vec<Vec<[f64; 2]>>,
}

impl TapeGirths {
    /// The girths against the scan's plan widths: a tape round the ball goes under the sole
    /// and back over the top, so it is longer than twice the ball width; the long-heel girth
    /// goes round the back of the heel and over the instep, so it is longer than the instep
    /// girth. The error says which girth and by how much (the caller names the file).
    pub fn check_against(&self, foot: &Plantar) -> Result<(), String> {
        let least = 2.0 * foot.ball_width;
        if self.ball < least {
            return Err(format!(
                "ball = {:.1} mm is less than twice the scanned ball width ({:.1} mm), {:.1} mm \
                 short of the least a tape round the ball can read: measure the ball girth \
                 again (round the first and fifth joints)",
                self.ball,
                foot.ball_width,
                least - self.ball
            ));
        }
        if self.long_heel <= self.instep {
            return Err(format!(
                "long_heel = {:.1} mm is not longer than instep = {:.1} mm: the long-heel \
                 girth goes round the back of the heel and over the instep (are the two \
                 swapped?)",
                self.long_heel, self.instep
            ));
        }
        Ok(())
    }
}

/// The clinic path's choices beyond the rules.
#[derive(Clone, Copy, Debug, Default)]
pub struct StockOptions {
    /// Refuse a stock last of the other side than the scanned foot instead of mirroring it.
    pub strict_sides: bool,
}

/// A last has a leg where its top, laid flat, rises above this fraction of its bottom
/// length: a boot last. The low-cut lasts of DATA/lasts rise 0.30-0.42 L (docs/method.md
/// 10.7); below it, the section at the ankle girth's station is the last's whole back part,
/// cut off by its top, and the ankle girth rule (IV) has no counterpart on it.
pub const LEG_RISE: f64 = 0.5;

/// The stock last (a closed world mesh, z up) deformed so its measured values meet the rules
/// applied to the scanned and taped foot; a last of the other side is mirrored (see
/// [`customize_stock_with`]).
pub fn customize_stock(
    stock: TriMesh,
    name: &str,
    foot: &Plantar,
    girths: &TapeGirths,
    rules: &RuleSet,
    inp: &Inputs,
) -> Result<Customized, CustomizeError> {
    customize_stock_with(
        stock,
        name,
        foot,
        girths,
        rules,
        inp,
        StockOptions::default(),
    )
}

/// [`customize_stock`] with options. The stock last's side is read as a last maker reads
/// it ([`crate::measure_last`]); one of the other side than the foot is mirrored (a note
/// says so), or refused with `strict_sides`. Rules with no counterpart on the last (the
/// ankle girth on a low-cut last) are reported as not applicable and not solved for.
pub fn customize_stock_with(
    stock: TriMesh,
    name: &str,
    foot: &Plantar,
    girths: &TapeGirths,
    rules: &RuleSet,
    inp: &Inputs,
    opts: StockOptions,
) -> Result<Customized, CustomizeError> {
    girths
        .check_against(foot)
        .map_err(|why| CustomizeError::Rules(format!("the girths: {why}")))?;
    let mut notes = Vec::new();
    let mut stock = stock;
    let foot_side = match foot.side {
        Side::Left => crate::measure_last::LastSide::Left,
        Side::Right => crate::measure_last::LastSide::Right,
    };
    let word = |s: crate::measure_last::LastSide| match s {
        crate::measure_last::LastSide::Left => "left",
        crate::measure_last::LastSide::Right => "right",
    };
    match crate::measure_last::measure_last(stock.clone(), name).map(|m| m.side) {
        Ok(Some(s)) if s != foot_side => {
            if opts.strict_sides {
                return Err(CustomizeError::Rules(format!(
                    "{name}: a {} last for a {} foot (strict sides): give a {} last, or \
                     leave out the strict-sides option to have this one mirrored",
                    word(s),
                    word(foot_side),
                    word(foot_side)
                )));
            }
            for v in &mut stock.vertices {
                v.y = -v.y;
            }
            for t in &mut stock.triangles {
                t.swap(1, 2);
            }
            notes.push(format!(
                "the stock last is a {} last and the scan a {} foot: the last was mirrored \
                 to the foot's side",
                word(s),
                word(foot_side)
            ));
        }
        Ok(Some(_)) => {}
        Ok(None) | Err(_) => notes.push(format!(
            "the stock last's side could not be read: taken to be the foot's ({})",
            word(foot_side)
        )),
    }
    let (mut stock, mut frame) = foot_in_frame(stock, name)?;
    // A shop's last has toe spring and a raised heel: laid flat by its bottom curve, its
    // 1.5 mm outline is its whole bottom again, as on the lasts the whole-foot path makes.
    let bottom = BottomCurve::of(&stock).filter(|b| b.rise() > FLAT_TOL_MM);
    if let Some(b) = &bottom {
        shear(&mut stock, |x| -b.at(x));
    }
    // The side a foot's frame finds from where the toes reach furthest says little on a
    // last (its toe is one smooth tip; two real lasts read "left" both as given and
    // mirrored): the stock last is taken to be for the scanned foot's side.
    frame.side = foot.side;
    let medial = frame.medial_sign();
    let sm = measure(&stock, None, medial).map_err(|why| CustomizeError::NotAFoot {
        name: name.into(),
        why,
    })?;
    // The foot's values: the scan's plan figures and the tape's girths; the stock last's
    // own cuts stay as the curves Algorithm II moves.
    let mut fm = sm.clone();
    fm.length = foot.length;
    fm.ball_width = foot.ball_width;
    fm.waist_width = foot.waist_width;
    fm.heel_width = foot.heel_width;
    fm.ball_girth = girths.ball;
    fm.instep_girth = girths.instep;
    fm.long_heel_girth = girths.long_heel;
    fm.ankle_girth = girths.ankle;
    let (mut rows, heel_allow) = targets(rules, inp, &fm);
    // A stock last far from the foot's size is the wrong last, not a deformation.
    let (have, need) = (sm.length, rows[0].target_mm);
    if (have - need).abs() > crate::size::SIZE_GROUP * need {
        return Err(CustomizeError::Rules(format!(
            "{name}: its bottom is {have:.1} mm long and the foot needs {need:.1} mm (rule \
             I-A): {:.1} mm {}, more than a size group ({:.0} %): choose a {} last",
            (have - need).abs(),
            if have < need { "short" } else { "long" },
            crate::size::SIZE_GROUP * 100.0,
            if have < need { "longer" } else { "shorter" }
        )));
    }
    // The ankle girth needs a leg: on a low-cut last the section at its station is the
    // whole back part under the last's top.
    let bb = stock.bbox();
    let rise = bb.max.z - bb.min.z;
    if rise < LEG_RISE * sm.length {
        let r = &mut rows[7];
        r.applies = false;
        r.not_applicable = Some(format!(
            "not applicable for this last: a low-cut last has no leg (its top rises {rise:.0} \
             mm above its bottom, {:.0} % of its length; a boot last's leg rises above {:.0} \
             %), so its section at the ankle girth's station is its whole back part ({:.1} mm \
             round against the foot's {:.1} mm)",
            100.0 * rise / sm.length,
            100.0 * LEG_RISE,
            sm.ankle_girth,
            girths.ankle
        ));
    }
    let target: [f64; 8] = std::array::from_fn(|i| {
        if rows[i].applies {
            rows[i].target_mm
        } else {
            f64::NAN
        }
    });
    let heel_point = sm.sole_from();
    let sec = shape::Sections::of_foot(&stock, sm.length, heel_point, &|_| 0.0);
    let mut nd = shape::Nodes::of(&sm);
    // Stations of the rules at the foot's length. The stock last has its heel allowance
    // already (its heel point is the last's); its chamfer is laid again through its own heel
    // point, a no-op where the heel already rises clear of it. Without it, the sections'
    // flat band turned a simulated stock's 45 degree chamfer into a terrace at the outline's
    // 1.5 mm, the heel point jumped 4.5 mm between Newton steps and the solve failed (240 and
    // 238 mm stocks for a 250 mm scan: bottom length and long-heel girth off by 2-2.5 mm).
    nd.length = foot.length;
    nd.holds_foot = false;
    nd.heel_allowance = heel_point.max(0.0);
    let (last, lm, field, evals) =
        shape::solve(&sec, &nd, &sm, &target, medial).map_err(|e| actionable(e, &rows, name))?;
    let on_last = shape::values(&lm);
    let curve_target: [f64; 8] = std::array::from_fn(|i| {
        if target[i].is_nan() {
            on_last[i]
        } else {
            target[i]
        }
    });
    let (fits, curves) = frame_curves(&sm, &sec.sole_outline(), &lm, &curve_target)?;
    judge(&mut rows, &lm);
    // The foot we have is its footprint: it must lie inside the last's bottom where the rules
    // say the foot must fit (the frame's medial side is +y or -y by the side).
    let fp: Vec<Vec<[f64; 2]>> = foot
        .footprint
        .iter()
        .map(|l| l.iter().map(|p| [p[0], p[1] * medial]).collect())
        .collect();
    let cl = if fp.is_empty() {
        let mut cl = clearance(&stock, &last, &nd, rows[2].change_mm);
        cl.of = "stock last";
        cl
    } else {
        // The foot's heel stands behind the last's bottom by the heel allowance (rule I-A):
        // that part of the footprint is outside by rule.
        let mut at_foot = nd;
        at_foot.heel_allowance = heel_allow;
        footprint_clearance(&fp, &lm.outline, &at_foot, rows[2].change_mm)
    };
    let (mut last, mut stock, mut curves) = (last, stock, curves);
    let mut bottom_curve = None;
    if let Some(b) = &bottom {
        // Raised back: the last's x mapped onto the stock's by their extents (the toe
        // stretch and the length change move the bottom's features with them).
        let (s, l) = (stock.bbox(), last.bbox());
        let k = (s.max.x - s.min.x) / (l.max.x - l.min.x);
        let on_stock = |x: f64| s.min.x + (x - l.min.x) * k;
        shear(&mut last, |x| b.at(on_stock(x)));
        // The curve as last.stl was raised by it (x on the output last), so the output laid
        // flat by report.json's curve is the last the rules were measured on.
        bottom_curve = Some(
            b.samples()
                .into_iter()
                .map(|[x, z]| [l.min.x + (x - s.min.x) / k, z])
                .collect::<Vec<_>>(),
        );
        shear(&mut stock, |x| b.at(x));
        for (_, c) in &mut curves.last {
            for p in &mut c.points {
                p.z += b.at(on_stock(p.x));
            }
        }
        for (_, c) in &mut curves.foot {
            for p in &mut c.points {
                p.z += b.at(p.x);
            }
        }
    }
    Ok(Customized {
        frame_in_world: frame,
        foot: stock,
        foot_measures: fm,
        last,
        last_measures: lm,
        rules: rows,
        fits,
        curves,
        field,
        evaluations: evals,
        clearance: cl,
        bottom_curve,
        footprint: fp,
        notes,
    })
}

/// A failed solve said the way a last maker can act on: each missed rule, by how much the
/// last stays off its target, and what would make it possible (another last, or the rule's
/// change in the rule file).
fn actionable(e: CustomizeError, rows: &[super::RuleRow], name: &str) -> CustomizeError {
    let CustomizeError::Unmet { misses, .. } = &e else {
        return e;
    };
    let parts: Vec<String> = misses
        .iter()
        .map(|&(i, d)| {
            let r = &rows[i];
            let (more, fewer) = match (i, d > 0.0) {
                (0, true) => ("longer", "shorter"),
                (0, false) => ("shorter", "longer"),
                (1..=3, true) => ("wider", "narrower"),
                (1..=3, false) => ("narrower", "wider"),
                (_, true) => ("larger", "smaller"),
                (_, false) => ("smaller", "larger"),
            };
            let what = match i {
                0 => "bottom",
                3 => "heel seat",
                2 => "waist",
                1 => "joint",
                6 => "heel part (heel seat round to the instep)",
                _ => r.quantity,
            };
            let key = if i == 0 {
                "toe_allowance_mm".to_string()
            } else {
                "change_mm".to_string()
            };
            format!(
                "rule {} ({}): this last's {what} stays {:.1} mm {more} than the target of \
                 {:.1} mm (foot {:.1} {:+.1}) allows: choose a last with a {fewer} {what}, \
                 or allow {} {:+.1} mm over the foot in the rule file ({} [\"{}\"] \
                 {key} by {:.1} mm)",
                r.rule,
                r.quantity,
                d.abs(),
                r.target_mm,
                r.foot_mm,
                r.change_mm,
                r.quantity,
                r.change_mm + d + d.signum() * 0.5,
                if d > 0.0 { "raise" } else { "lower" },
                r.rule,
                d.abs() + 0.5
            )
        })
        .collect();
    CustomizeError::Rules(format!(
        "{name}: the rules cannot all be met on this last: {}",
        parts.join("; ")
    ))
}
