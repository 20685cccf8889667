//! Choosing a stock last for a scanned foot (docs/method.md 9.5): the foot's plantar figures
//! and tape girths become the last's targets by the comfort rules (`customize::targets`), and
//! every last of the shop's collection, measured as a last maker measures it (`measure_last`),
//! is ranked by how little it must change to meet them: the largest change of any station
//! (length, widths, girths) first, the bottom outline's largest move second.

use crate::customize::clinic::{Plantar, StockCut, TapeGirths};
use crate::customize::measure::Measures;
use crate::customize::rules::RuleSet;
use crate::customize::{targets, Inputs, RuleRow};
use crate::measure_last::LastMeasures;
use crate::size::SIZE_GROUP;
use footscan_geom::mesh::TriMesh;
use footscan_geom::{Side, P3};
use serde::Serialize;

/// The plan length exceeds the 1.5 mm outline's by more than this share only where the toe
/// stands clear of the glass after the lay-flat (see [`judge_last`]).
const TOE_CLEAR: f64 = 0.05;

/// One rule's station on one last: what the last has, what the rule asks, the change.
#[derive(Clone, Debug, Serialize)]
pub struct StationChange {
    pub rule: &'static str,
    pub quantity: &'static str,
    /// The last's measure this is compared with.
    pub last_measure: &'static str,
    pub last_mm: f64,
    pub target_mm: f64,
    pub change_mm: f64,
    /// False: the rule does not apply to this last (said in `cannot`).
    pub applicable: bool,
}

/// One last of the collection, judged.
#[derive(Clone, Debug, Serialize)]
pub struct Candidate {
    pub name: String,
    pub side: Option<Side>,
    /// The last is for the other side: it is mirrored before it is customized.
    pub mirrored: bool,
    pub stations: Vec<StationChange>,
    /// The largest change of any applicable station (mm, absolute) and its quantity.
    pub largest_change_mm: f64,
    pub largest_at: &'static str,
    /// The bottom outline's largest move: the toe end's (length change) or a side's at the
    /// joint, waist or heel seat (half the width change), mm.
    pub outline_change_mm: f64,
    /// Rules the last cannot meet (it is ranked after every last that can), and why.
    pub cannot: Vec<String>,
    /// What was done or assumed (mirrored, side unknown, rule not applicable).
    pub notes: Vec<String>,
    pub eligible: bool,
}

/// The foot's rule targets: `customize::targets` on the plantar scan's figures and the tape
/// girths (rows I-A .. IV, as the clinic path computes them).
pub fn foot_targets(foot: &Plantar, g: &TapeGirths, rules: &RuleSet, inp: &Inputs) -> Vec<RuleRow> {
    let o = P3::origin();
    let fm = Measures {
        length: foot.length,
        ball_width: foot.ball_width,
        waist_width: foot.waist_width,
        heel_width: foot.heel_width,
        ball_girth: g.ball,
        instep_girth: g.instep,
        long_heel_girth: g.long_heel,
        ankle_girth: g.ankle,
        o,
        a: o,
        p: o,
        b: o,
        c: o,
        d: o,
        e: o,
        heel_centre: o,
        instep_top: o,
        heel_m: o,
        heel_l: o,
        outline: Vec::new(),
        ball: Vec::new(),
        instep: Vec::new(),
        long_heel: Vec::new(),
        ankle: Vec::new(),
        profile: Vec::new(),
    };
    targets(rules, inp, &fm).0
}

/// What every last is judged against: the fitter's tape girths, the comfort rules and what
/// the last is for (the heel height, when given, for every last; else each last's own).
pub struct Wanted<'a> {
    pub girths: &'a TapeGirths,
    pub rules: &'a RuleSet,
    pub inp: &'a Inputs,
}

/// The heel allowance the rules give the shoe (rule I-A: how far the last's bottom starts
/// behind the foot's heel), which the footprint's placement leaves out of the fit.
pub fn heel_allowance(rules: &RuleSet, inp: &Inputs) -> f64 {
    rules.i_a.heel_allowance_mm.get(inp.shoe)
}

/// Judges one last (its measures and its mesh, cut as the clinic path cuts it) against the
/// foot's targets (`foot_targets`, with the rules' heel allowance) for the scanned foot.
pub fn judge_last(
    name: &str,
    lm: &LastMeasures,
    mesh: &TriMesh,
    rows: &[RuleRow],
    foot: &Plantar,
) -> (Candidate, Option<StockCut>) {
    let side = foot.side;
    let ankle_tape = rows
        .iter()
        .find(|r| r.quantity == "ankle girth")
        .map_or(f64::NAN, |r| r.foot_mm);
    // The cut `customize_stock` starts from, so a change here is the change it must make.
    let cut = crate::customize::clinic::cut_stock(
        mesh.clone(),
        name,
        lm.side,
        side,
        crate::customize::clinic::StockOptions::default(),
        ankle_tape,
    );
    let mut cannot = Vec::new();
    // The stations as the solve measures the last it moves (`shape::evaluate`: the last's
    // 1.5 mm bottom and whole girths, stations placed by the foot's length), so a change
    // here is the change the solve must make; the cut's own measures are the foot-style
    // ones the field starts from.
    let (cm, mirrored, mut notes, no_leg, cut) = match cut {
        Ok(c) => (
            crate::customize::measure::measure(&c.stock, Some(foot.length), c.medial).map(
                |mut m| {
                    // A toe the lay-flat leaves clear of the glass (its bottom curve carried
                    // on straight under a toe spring that steepens) ends the 1.5 mm outline
                    // short: LastScan_Warped's at 216.4 mm, 28 mm behind its plan end. The
                    // solve's build carries it down, so there the plan length (the size
                    // check's) is the last's bottom; elsewhere the plan length is longer by
                    // the heel's and toe's overhang (5 mm, 2 %, on a last made for the foot).
                    if c.measures.length > (1.0 + TOE_CLEAR) * m.length {
                        m.length = c.measures.length;
                    }
                    m
                },
            ),
            c.mirrored,
            c.notes.clone(),
            c.no_leg.clone(),
            Some(c),
        ),
        Err(e) => (Err(footscan_util::chain(&e)), false, Vec::new(), None, None),
    };
    let mut stations = Vec::new();
    for r in rows {
        // The rules' quantities as the clinic path cuts them on the stock last (the same
        // cut `customize_stock` starts from), so a change here is the change it must make.
        let (measure, value) = match (r.quantity, &cm) {
            ("bottom length", Ok(c)) => ("bottom length (1.5 mm outline)", c.length),
            ("ball width", Ok(c)) => ("ball width (B, C)", c.ball_width),
            ("waist width", Ok(c)) => ("waist width (D, E)", c.waist_width),
            ("heel width", Ok(c)) => ("heel width", c.heel_width),
            ("ball girth", Ok(c)) => ("ball girth", c.ball_girth),
            ("instep girth", Ok(c)) => ("instep girth", c.instep_girth),
            ("long-heel girth", Ok(c)) => ("long-heel girth", c.long_heel_girth),
            ("ankle girth", Ok(c)) => ("ankle girth", c.ankle_girth),
            (_, Err(_)) => ("", f64::NAN),
            _ => continue,
        };
        let mut applicable = value.is_finite();
        if r.quantity == "ankle girth" {
            if let Some(why) = &no_leg {
                applicable = false;
                notes.push(format!("rule {} (ankle girth) {why}", r.rule));
            }
        }
        if r.quantity == "long-heel girth" {
            let heel = Some(lm.heel_height);
            if let Some(why) = crate::customize::clinic::long_heel_not_applicable(heel, r.foot_mm) {
                applicable = false;
                notes.push(format!("rule {} (long-heel girth) {why}", r.rule));
            }
        }
        stations.push(StationChange {
            rule: r.rule,
            quantity: r.quantity,
            last_measure: measure,
            last_mm: value,
            target_mm: r.target_mm,
            change_mm: r.target_mm - value,
            applicable,
        });
    }
    let mut eligible = true;
    if let Err(why) = &cm {
        eligible = false;
        cannot.push(format!("the clinic path cannot cut this last: {why}"));
    }
    if let Some(len) = stations.iter().find(|s| s.quantity == "bottom length") {
        let rel = len.change_mm / len.target_mm;
        if rel.abs() > SIZE_GROUP {
            eligible = false;
            cannot.push(format!(
                "rule {} (bottom length): the last is {:.1} mm, the foot needs {:.1} mm: too {} \
                 by {:.1} %, more than a size group ({:.0} %)",
                len.rule,
                len.last_mm,
                len.target_mm,
                if rel > 0.0 { "short" } else { "long" },
                100.0 * rel.abs(),
                100.0 * SIZE_GROUP
            ));
        }
    }
    let (largest_change_mm, largest_at) = stations
        .iter()
        .filter(|s| s.applicable)
        .map(|s| (s.change_mm.abs(), s.quantity))
        .fold((0.0, ""), |a, b| if b.0 > a.0 { b } else { a });
    let ch = |q: &str| {
        stations
            .iter()
            .find(|s| s.quantity == q)
            .map_or(0.0, |s| s.change_mm)
    };
    let outline_change_mm = ch("bottom length")
        .abs()
        .max(0.5 * ch("ball width").abs())
        .max(0.5 * ch("waist width").abs())
        .max(0.5 * ch("heel width").abs());
    let c = Candidate {
        name: name.to_string(),
        side: lm.side,
        mirrored,
        stations,
        largest_change_mm,
        largest_at,
        outline_change_mm,
        cannot,
        notes,
        eligible,
    };
    (c, cut)
}

/// A build-up under this (mm) is within the placement's own noise and not a change.
const BUILD_UP_NOTE_MM: f64 = 0.2;

/// The footprint build-up the clinic path would lay on this last (`build_up_estimate`, mm)
/// as a station of its own: a last that fits the foot only when built up has changed that
/// much too (its sides, and the girths round them).
fn add_build_up(c: &mut Candidate, build_up: f64) {
    if build_up <= BUILD_UP_NOTE_MM {
        return;
    }
    c.stations.push(StationChange {
        rule: "fit",
        quantity: "footprint build-up",
        last_measure: "side room of the plan outline (estimated)",
        last_mm: -build_up,
        target_mm: 0.0,
        change_mm: build_up,
        applicable: true,
    });
    if build_up > c.largest_change_mm {
        c.largest_change_mm = build_up;
        c.largest_at = "footprint build-up";
    }
    c.outline_change_mm = c.outline_change_mm.max(build_up);
    c.notes.push(format!(
        "the footprint stands up to {build_up:.1} mm out of this last's sides where the foot \
         must fit: the clinic path builds it up there"
    ));
}

/// Ranks candidates: eligible ones first, by the largest station change, then by the bottom
/// outline's change, then by name.
pub fn rank(c: &mut [Candidate]) {
    c.sort_by(|a, b| {
        b.eligible
            .cmp(&a.eligible)
            .then(a.largest_change_mm.total_cmp(&b.largest_change_mm))
            .then(a.outline_change_mm.total_cmp(&b.outline_change_mm))
            .then(a.name.cmp(&b.name))
    });
}

/// The last mirrored across its long vertical plane (y -> -y in the file, triangles turned
/// to keep the outside out): a left last made a right one.
pub fn mirrored(mut m: TriMesh) -> TriMesh {
    // Mirror across the plane through the centroid normal to the mesh's second axis of its
    // plan: measured frames differ per file, so mirror in y of the file and let every later
    // stage find its own frame (a mirror is a mirror whichever vertical plane it is in).
    for p in &mut m.vertices {
        p.y = -p.y;
    }
    m.flip();
    m
}

/// Reads, size-checks, measures and judges every last file (in parallel over the cores), in
/// the order given; a file that cannot be read or measured is a candidate that cannot meet
/// any rule, saying why. Returns the candidates and the meshes (None where unreadable).
/// The rule targets differ from last to last only by the heel height (rule II-F's ball girth
/// follows it), which is the last's own unless `inp` gives one. `units` and `length_mm` read
/// the files that the collection's `lasts.toml` ([`crate::collection`]) does not list.
pub fn judge_files(
    files: &[std::path::PathBuf],
    units: footscan_geom::mesh::Units,
    length_mm: Option<f64>,
    foot: &Plantar,
    want: &Wanted,
) -> Vec<(Candidate, Option<TriMesh>)> {
    type Judged = (Candidate, Option<TriMesh>, Option<(StockCut, Vec<RuleRow>)>);
    let heel_allowance = heel_allowance(want.rules, want.inp);
    let one = |p: &std::path::PathBuf| -> Judged {
        let name = p.display().to_string();
        let default = crate::collection::ReadAs { units, length_mm };
        let got = crate::collection::Collection::for_file(p, default)
            .map_err(|e| e.to_string())
            .and_then(|r| {
                TriMesh::load_solid(p, r.units, r.length_mm).map_err(|e| {
                    // A collection may mix units: name the per-file way as well.
                    let file = p.file_name().unwrap_or_default().to_string_lossy();
                    footscan_util::chain(&e.retold(
                        &format!(
                            "pass --units m, or for this file alone `[\"{file}\"] units = \"m\"` \
                             in the {} beside it",
                            crate::collection::COLLECTION_FILE
                        ),
                        &format!(
                            "give the length of its longest side with --length MM, or for this \
                             file alone `[\"{file}\"] length_mm = ...` in the {} beside it",
                            crate::collection::COLLECTION_FILE
                        ),
                    ))
                })
            })
            .and_then(|(m, _)| {
                crate::size::check_last_size(p, &m).map_err(|e| footscan_util::chain(&e))?;
                let lm = crate::measure_last::measure_last(m.clone(), &name)
                    .map_err(|e| footscan_util::chain(&e))?;
                Ok((m, lm))
            });
        match got {
            Ok((m, lm)) => {
                let (inp, heel_note) =
                    crate::customize::clinic::stock_inputs(want.inp, Some(lm.heel_height));
                let rows = foot_targets(foot, want.girths, want.rules, &inp);
                let (mut c, cut) = judge_last(&name, &lm, &m, &rows, foot);
                c.notes.extend(heel_note);
                (c, Some(m), cut.map(|cut| (cut, rows)))
            }
            Err(why) => (
                Candidate {
                    name: name.clone(),
                    side: None,
                    mirrored: false,
                    stations: Vec::new(),
                    largest_change_mm: f64::INFINITY,
                    largest_at: "",
                    outline_change_mm: f64::INFINITY,
                    cannot: vec![format!("not measured: {why}")],
                    notes: Vec::new(),
                    eligible: false,
                },
                None,
                None,
            ),
        }
    };
    let cores = crate::par::cores(8);
    let mut judged: Vec<Judged> = crate::par::map(files.len(), cores, |k| one(&files[k]));
    // The build-up costs a build of the last (a tenth of a second on a 64k-triangle last), so
    // it is estimated in the order of the stations' changes, a core's worth at a time, until
    // the next last's stations alone change it more than the best last changes in all: a
    // build-up only adds to a change, so no last after it can come first.
    let mut order: Vec<usize> = (0..judged.len())
        .filter(|&k| judged[k].0.eligible && judged[k].2.is_some())
        .collect();
    order.sort_by(|&a, &b| {
        judged[a]
            .0
            .largest_change_mm
            .total_cmp(&judged[b].0.largest_change_mm)
    });
    let mut best = f64::INFINITY;
    let mut next = 0;
    while next < order.len() && judged[order[next]].0.largest_change_mm < best {
        let batch: Vec<usize> = order[next..]
            .iter()
            .copied()
            .take(cores)
            .take_while(|&k| judged[k].0.largest_change_mm < best)
            .collect();
        let est = crate::par::map(batch.len(), cores, |j| {
            let (cut, rows) = judged[batch[j]].2.as_ref().expect("cut filtered");
            crate::customize::clinic::build_up_estimate(cut, foot, rows, heel_allowance)
        });
        for (&k, b) in batch.iter().zip(est) {
            add_build_up(&mut judged[k].0, b);
            best = best.min(judged[k].0.largest_change_mm);
        }
        next += batch.len();
    }
    for &k in &order[next..] {
        judged[k].0.notes.push(
            "the footprint's build-up was not estimated: the stations alone change this last \
             more than the best last changes in all"
                .into(),
        );
    }
    judged.into_iter().map(|(c, m, _)| (c, m)).collect()
}
