//! The clinic's way to a customized last: our scanner sees only the sole, so the foot comes
//! as the plantar measurements of a scan (length, ball, waist and heel widths, side) plus the
//! girths a fitter measures with a tape, and a stock last from the shop's collection is the
//! starting frame. The stock last is cut like a foot (its characteristic curves), the rules
//! are applied to the foot's values, and the stock last is deformed by the same solved field
//! as on the whole-foot path until its cut values are the targets (docs/method.md 10.7).

use super::bottom::{shear, BottomCurve, FLAT_TOL_MM};
use super::measure::{measure, PlanProfile, Side, PLAN_STEP};
use super::rules::RuleSet;
use super::{clearance, foot_in_frame, footprint_clearance, frame_curves, judge, shape, targets};
use super::{CustomizeError, Customized, Inputs};
use footscan_geom::mesh::TriMesh;
use footscan_geom::{P2, P3};
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
    pub footprint: Vec<Vec<P2>>,
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

/// A last whose own heel is higher than this (mm) is a high-heeled last, and a long-heel
/// girth taped on the foot standing flat has no counterpart on it (rule II-H is reported
/// as not applicable, with the reason). The trade takes the heel girth for high-heeled work
/// with the foot posed as in the shoe, its heel raised to the shoe's height, because the
/// girth round the heel and over the instep changes with that pose (F. Y. Golding, The
/// Manufacture of Boots and Shoes, "The operation of measuring"); a heel of 1 to 1.5 in is
/// called low and one of 2 in and more high (P. B. Roth, 1929). 2 in (50.8 mm): of the
/// shared lasts Last_Heeled_RoundTip's heel is 114.8 mm (at 260 mm), the others' 2.5 mm
/// (LastScan) and 28.2 mm (Last_Flat_RoundTip at a 252.8 mm stick, docs/method.md 9.3);
/// 10.7, fifth round.
pub const HIGH_HEEL_MM: f64 = 50.8;

/// Why the flat foot's long-heel girth (rule II-H) does not apply to a last with its own
/// heel of `heel` mm (None: not measured, the rule applies), if so. `tape`: the foot's
/// long-heel girth as taped (mm), for the reason.
pub fn long_heel_not_applicable(heel: Option<f64>, tape: f64) -> Option<String> {
    let h = heel.filter(|h| h.is_finite() && *h > HIGH_HEEL_MM)?;
    Some(format!(
        "not applicable for this last: a high-heeled last (its heel {h:.1} mm, over \
         {HIGH_HEEL_MM:.1} mm) holds the foot with its heel raised, and the long-heel girth \
         taped on the foot standing flat ({tape:.1} mm) is not that foot's: the trade takes \
         the heel girth for high-heeled work with the heel raised to the shoe's height"
    ))
}

/// A stock last as the clinic path cuts it, and as `last choose` judges it (one cut, so the
/// ranking's changes are the ones the customization makes).
pub struct StockCut {
    /// For the foot's side, in a foot's frame, laid flat by its bottom curve.
    pub stock: TriMesh,
    pub frame: super::measure::FootFrame,
    /// The bottom curve it was laid flat by (None: flat already).
    pub(crate) bottom: Option<BottomCurve>,
    pub medial: f64,
    /// Its values by the rules' definitions, at its own length.
    pub measures: super::measure::Measures,
    /// Why the ankle girth rule has no counterpart on it (a low-cut last), if so.
    pub no_leg: Option<String>,
    /// The last was of the other side and is mirrored.
    pub mirrored: bool,
    /// What was done or assumed (mirrored, side unknown).
    pub notes: Vec<String>,
}

/// A stock last's heel height differing from the one asked by more than this (mm) is said in
/// the notes: the last keeps its own.
const HEEL_NOTE_MM: f64 = 5.0;
/// One size's joint girth step in the Paris system: a stock last whose build-up for the
/// footprint grows a girth by more is a size too narrow for the foot, and is told so.
pub const GIRTH_SIZE_STEP_MM: f64 = 5.0;

/// The inputs the rules use for a stock last whose own heel height is `own` (measured as a
/// last maker does, None when it could not be): the heel asked, else the last's own, for
/// the clinic path keeps the stock last's bottom curve and so its heel. With a note when the
/// heel is taken from the last, assumed, or asked different from the last's.
pub fn stock_inputs(inp: &Inputs, own: Option<f64>) -> (Inputs, Option<String>) {
    let own = own.filter(|h| h.is_finite());
    let (heel, note) = match (inp.heel_mm, own) {
        (Some(h), Some(o)) if (h - o).abs() > HEEL_NOTE_MM => (
            h,
            Some(format!(
                "heel height {h:.0} mm as asked for the rules (ball girth, rule II-F); the \
                 stock last keeps its own heel of {o:.1} mm (its bottom curve is not changed)"
            )),
        ),
        (Some(h), _) => (h, None),
        (None, Some(o)) => {
            let h = o.clamp(super::HEEL_RANGE_MM.0, super::HEEL_RANGE_MM.1);
            (
                h,
                Some(format!(
                    "heel height {h:.1} mm: the stock last's own, which it keeps (rule II-F's \
                     ball girth allowance follows it; give a heel height to use another)"
                )),
            )
        }
        (None, None) => (
            super::DEFAULT_HEEL_MM,
            Some(format!(
                "heel height {:.0} mm assumed: the stock last's heel could not be measured",
                super::DEFAULT_HEEL_MM
            )),
        ),
    };
    (
        Inputs {
            heel_mm: Some(heel),
            ..*inp
        },
        note,
    )
}

/// Cuts `stock` (read as a `last_side` last, None when its shape does not tell) for a
/// `foot_side` foot whose tape ankle girth is `ankle_tape` (for the reason a rule does not
/// apply). A last of the other side is mirrored, or refused with `opts.strict_sides`.
pub fn cut_stock(
    mut stock: TriMesh,
    name: &str,
    last_side: Option<Side>,
    foot_side: Side,
    opts: StockOptions,
    ankle_tape: f64,
) -> Result<StockCut, CustomizeError> {
    let mut notes = Vec::new();
    let want = foot_side;
    let word = Side::as_str;
    let mirrored = matches!(last_side, Some(s) if s != want);
    match last_side {
        Some(s) if s != want => {
            if opts.strict_sides {
                return Err(CustomizeError::Rules(format!(
                    "{name}: a {} last for a {} foot (strict sides): give a {} last, or \
                     leave out the strict-sides option to have this one mirrored",
                    word(s),
                    word(want),
                    word(want)
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
                word(want)
            ));
        }
        Some(_) => {}
        None => notes.push(format!(
            "the stock last's side could not be read: taken to be the foot's ({})",
            word(want)
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
    frame.side = foot_side;
    let medial = frame.medial_sign();
    let sm = measure(&stock, None, medial).map_err(|why| CustomizeError::NotAFoot {
        name: name.into(),
        why,
    })?;
    // The ankle girth needs a leg: on a low-cut last the section at its station is the
    // whole back part under the last's top.
    let bb = stock.bbox();
    let rise = bb.max.z - bb.min.z;
    let no_leg = (rise < LEG_RISE * sm.length).then(|| {
        format!(
            "not applicable for this last: a low-cut last has no leg (its top rises {rise:.0} \
             mm above its bottom, {:.0} % of its length; a boot last's leg rises above {:.0} \
             %), so its section at the ankle girth's station is its whole back part ({:.1} mm \
             round against the foot's {:.1} mm)",
            100.0 * rise / sm.length,
            100.0 * LEG_RISE,
            sm.ankle_girth,
            ankle_tape
        )
    });
    Ok(StockCut {
        stock,
        frame,
        bottom,
        medial,
        measures: sm,
        no_leg,
        mirrored,
        notes,
    })
}

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
    let lm = crate::measure_last::measure_last(stock.clone(), name);
    let side = lm.as_ref().map(|m| m.side);
    let (applied, heel_note) = stock_inputs(inp, lm.as_ref().ok().map(|m| m.heel_height));
    let inp = &applied;
    let StockCut {
        stock,
        frame,
        bottom,
        medial,
        measures: sm,
        no_leg,
        mut notes,
        ..
    } = cut_stock(
        stock,
        name,
        side.ok().flatten(),
        foot.side,
        opts,
        girths.ankle,
    )?;
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
    notes.extend(heel_note);
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
    // Rules with no counterpart on this last: the ankle (IV, row 7) on a low-cut last, the
    // flat long heel (II-H, row 6) on a high-heeled one, whose own heel decides (the last
    // keeps its bottom curve, whatever heel is asked).
    let own_heel = lm.as_ref().ok().map(|m| m.heel_height);
    let not_applicable = [
        (7, no_leg),
        (6, long_heel_not_applicable(own_heel, girths.long_heel)),
    ];
    for (k, why) in not_applicable {
        if let Some(why) = why {
            rows[k].applies = false;
            rows[k].not_applicable = Some(why);
        }
    }
    let target: [f64; 8] = std::array::from_fn(|i| {
        if rows[i].applies {
            rows[i].target_mm
        } else {
            f64::NAN
        }
    });
    let (sec, nd) = stock_sections(&stock, &sm, foot.length);
    let (mut last, mut lm, field, evals) =
        shape::solve(&sec, &nd, &sm, &target, medial).map_err(|e| actionable(e, &rows, name))?;
    judge(&mut rows, &lm);
    // The foot we have is its footprint: it must lie inside the last's bottom where the rules
    // say the foot must fit (the frame's medial side is +y or -y by the side).
    let mut fp = footprint_in_frame(foot, medial);
    let mut built = Vec::new();
    let mut placement = None;
    let cl = if fp.is_empty() {
        let mut cl = clearance(&stock, &last, &nd, rows[2].change_mm);
        cl.of = "stock last";
        cl
    } else {
        // The foot's heel stands behind the last's bottom by the heel allowance (rule I-A):
        // that part of the footprint is outside by rule.
        let mut at_foot = nd;
        at_foot.heel_allowance = heel_allow;
        // A footprint is the foot's plan outline (the sole seen from below, its sides where
        // they bulge furthest), so it is held against the last's plan outline, not against
        // the last's 1.5 mm bottom: a shop last's sides round in above the featherline, and
        // there the footprint stood 4-15 mm out of lasts whose plan widths met every rule.
        let mut plan = PlanProfile::new(&last, PLAN_STEP, f64::INFINITY);
        let pivot = 0.5 * foot.length;
        let pl = place_footprint(&fp, &plan, &at_foot, pivot);
        for p in fp.iter_mut().flatten() {
            *p = pl.apply(*p, pivot);
        }
        placement = Some(pl);
        if pl != Placement::default() {
            notes.push(format!(
                "the footprint was set in the last as a fitter sets a foot: turned {:+.1} \
                 degrees, moved {:+.1} mm across and {:+.1} mm along the last",
                pl.turn_deg * medial,
                pl.across_mm * medial,
                pl.along_mm
            ));
        }
        let ups = build_up(&mut last, &plan, &fp, &at_foot, medial);
        if !ups.is_empty() {
            let before: Vec<f64> = rows.iter().map(|r| r.last_mm).collect();
            let met: Vec<bool> = rows.iter().map(|r| r.met).collect();
            lm = measure(&last, Some(nd.length), medial).map_err(|why| {
                CustomizeError::NotAFoot {
                    name: name.into(),
                    why: format!("after the build-up for the footprint: {why}"),
                }
            })?;
            judge(&mut rows, &lm);
            for ((r, b), m) in rows.iter_mut().zip(before).zip(met) {
                // Growths under 0.05 mm are the cut's own noise, below any bound.
                if r.applies && (r.last_mm - b).abs() >= 0.05 {
                    r.built_up_mm = r.last_mm - b;
                    r.met = m;
                }
            }
            let grown: Vec<String> = rows
                .iter()
                .filter(|r| r.quantity.ends_with("girth") && r.built_up_mm > GIRTH_SIZE_STEP_MM)
                .map(|r| format!("{} {} by {:.1} mm", r.rule, r.quantity, r.built_up_mm))
                .collect();
            if !grown.is_empty() {
                notes.push(format!(
                    "warning: this last is too narrow for the footprint: its build-up grows {} \
                     past the rule, more than a size's girth step ({GIRTH_SIZE_STEP_MM} mm, \
                     Paris): a wider last fits this foot better (`footscan last choose` ranks \
                     the shelf by the change each needs)",
                    grown.join(", ")
                ));
            }
            for u in &ups {
                notes.push(format!(
                    "the last was built up on its {} side for the footprint: {:.2} mm at {:.0} \
                     mm along the foot, from {:.0} to {:.0} mm (a stock last's sides round in \
                     where the scanned sole spreads; the rule table shows what it grew)",
                    u.side, u.max_mm, u.at_x_mm, u.from_x_mm, u.to_x_mm
                ));
            }
            plan = PlanProfile::new(&last, PLAN_STEP, f64::INFINITY);
        }
        built = ups;
        footprint_clearance(&fp, &[plan.outline()], &at_foot, rows[2].change_mm)
    };
    let on_last = shape::values(&lm);
    let curve_target: [f64; 8] = std::array::from_fn(|i| {
        if target[i].is_nan() || rows[i].built_up_mm != 0.0 {
            on_last[i]
        } else {
            target[i]
        }
    });
    let (fits, curves) = frame_curves(&sm, &sec.sole_outline(), &lm, &curve_target)?;
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
                .map(|p| P2::new(l.min.x + (p.x - s.min.x) / k, p.y))
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
        heel_mm: inp.heel(),
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
        placement,
        build_up: built,
    })
}

/// A failed solve said the way a last maker can act on: each missed rule, by how much the
/// last stays off its target, and what would make it possible (another last, or the rule's
/// change in the rule file).
/// The stock last's sections and the rules' stations at the foot's length. The stock last
/// has its heel allowance already (its heel point is the last's); its chamfer is laid again
/// through its own heel point, a no-op where the heel already rises clear of it. Without it,
/// the sections' flat band turned a simulated stock's 45 degree chamfer into a terrace at the
/// outline's 1.5 mm, the heel point jumped 4.5 mm between Newton steps and the solve failed
/// (240 and 238 mm stocks for a 250 mm scan: bottom length and long-heel girth off by 2-2.5 mm).
fn stock_sections(
    stock: &TriMesh,
    sm: &super::measure::Measures,
    foot_length: f64,
) -> (shape::Sections, shape::Nodes) {
    let heel_point = sm.sole_from();
    let sec = shape::Sections::of_foot(stock, sm.length, heel_point, &|_| 0.0);
    let mut nd = shape::Nodes::of(sm);
    nd.length = foot_length;
    nd.holds_foot = false;
    nd.heel_allowance = heel_point.max(0.0);
    (sec, nd)
}

/// The footprint's loops in the foot frame with the medial side +y.
fn footprint_in_frame(foot: &Plantar, medial: f64) -> Vec<Vec<P2>> {
    foot.footprint
        .iter()
        .map(|l| l.iter().map(|p| P2::new(p.x, p.y * medial)).collect())
        .collect()
}

/// How far the footprint stands out of the last the solve starts from (the stock with the
/// rules' length and widths set, `shape::neutral`), placed as the clinic path places it,
/// where the foot must fit (heel seat, midfoot, toe box): the build-up the clinic path would
/// lay on, estimated in one evaluation instead of a solve (mm, the larger side's; 0 inside).
/// `last choose` ranks by it, so a last that fits only when built up is not ranked first.
pub fn build_up_estimate(
    cut: &StockCut,
    foot: &Plantar,
    rows: &[super::RuleRow],
    heel_allowance: f64,
) -> f64 {
    if foot.footprint.is_empty() || rows.len() < 4 {
        return 0.0;
    }
    let (sec, nd) = stock_sections(&cut.stock, &cut.measures, foot.length);
    let target: [f64; 4] = std::array::from_fn(|i| rows[i].target_mm);
    let p0 = shape::neutral(&cut.measures, &target, &nd);
    let last = shape::build(&sec, &nd, &p0);
    let plan = PlanProfile::new(&last, PLAN_STEP, f64::INFINITY);
    let mut at_foot = nd;
    at_foot.heel_allowance = heel_allowance;
    let fp = footprint_in_frame(foot, cut.medial);
    let pivot = 0.5 * foot.length;
    let pl = place_footprint(&fp, &plan, &at_foot, pivot);
    fp.iter()
        .flatten()
        .filter(|p| matches!(super::region_of_plan(&at_foot, p.x), 1 | 2 | 4))
        .map(|&p| BUILD_UP_ROOM_MM - plan.side_room(pl.apply(p, pivot)))
        .filter(|n| n.is_finite())
        .fold(0.0, f64::max)
}

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

/// Where the footprint stands in the last: turned about the foot's mid-length on the axis and
/// moved, as a fitter sets a foot in a shoe (positive `across_mm` towards the medial side).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Placement {
    pub turn_deg: f64,
    pub along_mm: f64,
    pub across_mm: f64,
}

/// How far a placement may move the footprint from the last's frame: the foot's axis and the
/// last's are each found from their own outlines, and a foot stands in a shoe a few degrees
/// and millimetres either way of the last's centre line; beyond these the last is not the
/// foot's. Along the axis only a little: the heel allowance (rule I-A) sets the heel's place.
const TURN_MAX_DEG: f64 = 6.0;
const ACROSS_MAX_MM: f64 = 8.0;
const ALONG_MAX_MM: f64 = 2.0;

impl Placement {
    fn apply(&self, p: P2, pivot: f64) -> P2 {
        let (s, c) = self.turn_deg.to_radians().sin_cos();
        let (x, y) = (p.x - pivot, p.y);
        P2::new(
            pivot + c * x - s * y + self.along_mm,
            s * x + c * y + self.across_mm,
        )
    }
}

/// The placement of the footprint (foot frame, medial +y) in the last's plan outline that
/// leaves the most room where the foot must fit (heel seat, midfoot, toe box) and at the
/// ball: the least side room over those points, each point's room taken across the axis
/// against the last's plan extremes at its station (ahead of or behind the last: the distance
/// beyond its end). A grid over turn, across and along, then a pattern search from its best.
fn place_footprint(fp: &[Vec<P2>], plan: &PlanProfile, nd: &shape::Nodes, pivot: f64) -> Placement {
    let judged: Vec<P2> = fp
        .iter()
        .flatten()
        .copied()
        .filter(|p| {
            let r = super::region_of_plan(nd, p.x);
            r != 0
        })
        .collect();
    // Every third point: the outline is traced at a tenth of a millimetre.
    let pts: Vec<P2> = judged.iter().step_by(3).copied().collect();
    if pts.is_empty() {
        return Placement::default();
    }
    let room = |pl: &Placement| -> f64 {
        pts.iter()
            .map(|&p| plan.side_room(pl.apply(p, pivot)))
            .fold(f64::INFINITY, f64::min)
    };
    let mut best = (Placement::default(), room(&Placement::default()));
    let steps = |max: f64, h: f64| {
        let n = (max / h).round() as i32;
        (-n..=n).map(move |i| i as f64 * h)
    };
    for turn_deg in steps(TURN_MAX_DEG, 1.0) {
        for across_mm in steps(ACROSS_MAX_MM, 1.0) {
            for along_mm in steps(ALONG_MAX_MM, 1.0) {
                let pl = Placement {
                    turn_deg,
                    along_mm,
                    across_mm,
                };
                let r = room(&pl);
                if r > best.1 {
                    best = (pl, r);
                }
            }
        }
    }
    let mut h = 0.5;
    while h > 0.01 {
        let mut moved = false;
        for (dt, dx, dy) in [
            (h, 0.0, 0.0),
            (-h, 0.0, 0.0),
            (0.0, h, 0.0),
            (0.0, -h, 0.0),
            (0.0, 0.0, h),
            (0.0, 0.0, -h),
        ] {
            let b = best.0;
            let pl = Placement {
                turn_deg: (b.turn_deg + dt).clamp(-TURN_MAX_DEG, TURN_MAX_DEG),
                along_mm: (b.along_mm + dx).clamp(-ALONG_MAX_MM, ALONG_MAX_MM),
                across_mm: (b.across_mm + dy).clamp(-ACROSS_MAX_MM, ACROSS_MAX_MM),
            };
            let r = room(&pl);
            if r > best.1 + 1e-9 {
                best = (pl, r);
                moved = true;
            }
        }
        if !moved {
            h *= 0.5;
        }
    }
    best.0
}

/// Room the build-up leaves between the footprint and the last's plan outline (mm).
const BUILD_UP_ROOM_MM: f64 = 0.1;
/// The build-up spreads over this distance either side of where it is needed (mm): a last
/// maker's build-up (leather or cork laid on the stock last and sanded in) runs out smoothly.
const BUILD_UP_SPREAD_MM: f64 = 8.0;
/// Above the side's widest point the build-up runs out over this height (mm).
const BUILD_UP_FADE_MM: f64 = 15.0;

/// One side's build-up of the last, as report.json and the CLI give it.
#[derive(Clone, Debug, Serialize)]
pub struct BuildUp {
    /// "medial" or "lateral".
    pub side: &'static str,
    /// Where it is largest (foot frame, mm along the axis) and by how much (mm).
    pub at_x_mm: f64,
    pub max_mm: f64,
    /// Where it starts and ends along the axis (mm).
    pub from_x_mm: f64,
    pub to_x_mm: f64,
}

/// Build the last's sides out where the placed footprint stands outside its plan outline in
/// the regions the foot must fit (heel seat, midfoot, toe box), as a last maker builds up a
/// stock last for a patient: each side's half-width at a station grows by the most any
/// footprint point there lacks (plus [`BUILD_UP_ROOM_MM`]), spread and smoothed over
/// [`BUILD_UP_SPREAD_MM`] so that it never falls below what a point needs; a vertex moves out
/// by that growth times its share of the half-width, so the centre line, the bottom's middle
/// and the top stay where the rules put them. `medial` is the frame's medial sign (+y or -y).
fn build_up(
    last: &mut TriMesh,
    plan: &PlanProfile,
    fp: &[Vec<P2>],
    nd: &shape::Nodes,
    medial: f64,
) -> Vec<BuildUp> {
    let n = plan.hi.len();
    let mut need = [vec![0.0f64; n], vec![0.0f64; n]];
    for &p in fp.iter().flatten() {
        let r = super::region_of_plan(nd, p.x);
        if r == 0 || r == 3 {
            continue;
        }
        let room = plan.side_room(p);
        if room >= BUILD_UP_ROOM_MM || !room.is_finite() {
            continue;
        }
        let k = ((p.x - plan.x0) / plan.step).round();
        if k < 0.0 || k as usize >= n {
            continue;
        }
        let k = k as usize;
        let (Some(hi), Some(lo)) = (plan.hi[k], plan.lo[k]) else {
            continue;
        };
        let side = usize::from(hi.y - p.y < p.y - lo.y);
        need[side][k] = need[side][k].max(BUILD_UP_ROOM_MM - room);
    }
    let r = (BUILD_UP_SPREAD_MM / plan.step).round() as usize;
    let grow: Vec<Vec<f64>> = need
        .iter()
        .map(|v| {
            let window = |k: usize| k.saturating_sub(r)..=(k + r).min(n - 1);
            let m: Vec<f64> = (0..n)
                .map(|k| v[window(k)].iter().copied().fold(0.0, f64::max))
                .collect();
            (0..n)
                .map(|k| {
                    let w = window(k);
                    let len = w.clone().count() as f64;
                    m[w].iter().sum::<f64>() / len
                })
                .collect()
        })
        .collect();
    let at = |v: &[f64], x: f64| {
        let t = ((x - plan.x0) / plan.step).clamp(0.0, (n - 1) as f64);
        let k = (t.floor() as usize).min(n - 1);
        let k1 = (k + 1).min(n - 1);
        v[k] + (t - k as f64) * (v[k1] - v[k])
    };
    let ys = |side: &[Option<P3>]| -> Vec<f64> {
        side.iter().map(|q| q.map_or(f64::NAN, |q| q.y)).collect()
    };
    let zs = |side: &[Option<P3>]| -> Vec<f64> {
        side.iter().map(|q| q.map_or(f64::NAN, |q| q.z)).collect()
    };
    let (his, los) = (ys(&plan.hi), ys(&plan.lo));
    let (hiz, loz) = (zs(&plan.hi), zs(&plan.lo));
    if grow.iter().all(|g| g.iter().all(|&w| w == 0.0)) {
        return Vec::new();
    }
    // Up to the height of the side's widest point the side moves out whole; above it the
    // build-up runs out over BUILD_UP_FADE_MM, so the top and the girths round it grow by
    // little more than the bottom's widening.
    let fade = |z: f64, ze: f64| {
        if ze.is_finite() {
            (1.0 - (z - ze) / BUILD_UP_FADE_MM).clamp(0.0, 1.0)
        } else {
            1.0
        }
    };
    for v in &mut last.vertices {
        let (hi, lo) = (at(&his, v.x), at(&los, v.x));
        if !(hi.is_finite() && lo.is_finite()) || hi <= lo {
            continue;
        }
        let c = 0.5 * (hi + lo);
        let half = 0.5 * (hi - lo);
        if v.y >= c {
            let f = fade(v.z, at(&hiz, v.x));
            v.y += at(&grow[1], v.x) * f * ((v.y - c) / half).clamp(0.0, 1.0);
        } else {
            let f = fade(v.z, at(&loz, v.x));
            v.y -= at(&grow[0], v.x) * f * ((c - v.y) / half).clamp(0.0, 1.0);
        }
    }
    let mut out = Vec::new();
    for (i, g) in grow.iter().enumerate() {
        let Some((k, &max)) = g.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)) else {
            continue;
        };
        if max <= 0.0 {
            continue;
        }
        let first = g.iter().position(|&w| w > 0.0).unwrap_or(k);
        let last_k = g.iter().rposition(|&w| w > 0.0).unwrap_or(k);
        let x = |k: usize| plan.x0 + k as f64 * plan.step;
        // Side 1 is +y: medial when the frame's medial sign is +1.
        let is_medial = (i == 1) == (medial > 0.0);
        out.push(BuildUp {
            side: if is_medial { "medial" } else { "lateral" },
            at_x_mm: x(k),
            max_mm: max,
            from_x_mm: x(first),
            to_x_mm: x(last_k),
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn heel_is_asked_or_the_stock_lasts_own() {
        let asked = |h| Inputs {
            heel_mm: h,
            ..Inputs::default()
        };
        // Not asked: the last's own, clamped to a heel's range, said in a note.
        let (i, n) = stock_inputs(&asked(None), Some(115.66));
        assert_eq!(i.heel_mm, Some(115.66));
        assert!(n.unwrap().contains("115.7 mm: the stock last's own"));
        let (i, _) = stock_inputs(&asked(None), Some(130.0));
        assert_eq!(i.heel_mm, Some(super::super::HEEL_RANGE_MM.1));
        // Not measurable: the default, said.
        let (i, n) = stock_inputs(&asked(None), None);
        assert_eq!(i.heel(), super::super::DEFAULT_HEEL_MM);
        assert!(n.unwrap().contains("could not be measured"));
        // Asked: used; a note only where the last's own differs.
        let (i, n) = stock_inputs(&asked(Some(25.0)), Some(27.0));
        assert_eq!((i.heel_mm, n), (Some(25.0), None));
        let (i, n) = stock_inputs(&asked(Some(25.0)), Some(115.0));
        assert_eq!(i.heel_mm, Some(25.0));
        assert!(n.unwrap().contains("keeps its own heel of 115.0 mm"));
    }
}
