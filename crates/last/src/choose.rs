//! Choosing a stock last for a scanned foot (docs/method.md 9.5): the foot's plantar figures
//! and tape girths become the last's targets by the comfort rules (`customize::targets`), and
//! every last of the shop's collection, measured as a last maker measures it (`measure_last`),
//! is ranked by how little it must change to meet them: the largest change of any station
//! (length, widths, girths) first, the bottom outline's largest move second.

use crate::customize::clinic::{Plantar, TapeGirths};
use crate::customize::measure::{Measures, Side};
use crate::customize::rules::RuleSet;
use crate::customize::{targets, Inputs, RuleRow};
use crate::measure_last::{LastMeasures, LastSide};
use crate::size::SIZE_GROUP;
use footscan_geom::mesh::TriMesh;
use footscan_geom::P3;
use serde::Serialize;

/// The foot's ankle girth is taken up to this fraction of its length above the glass, at
/// this fraction of its length from the heel (docs/method.md 10.1).
const ANKLE_AT: f64 = 0.30;
const ANKLE_TOP: f64 = 0.35;

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
    pub side: Option<LastSide>,
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

/// The last's ankle girth as the foot's is taken: the section by the plane x = 0.30 of the
/// stick length from the heel point (measuring frame), below `top` above the ground, the
/// perimeter of its convex hull; with the section's highest point (None: no section).
pub fn ankle_girth(mesh: &TriMesh, lm: &LastMeasures, top: f64) -> Option<(f64, f64)> {
    let f = lm.frame;
    let map = |q: &P3| {
        P3::new(
            f[0][0] * q.x + f[0][1] * q.y + f[0][2] * q.z + f[0][3],
            f[1][0] * q.x + f[1][1] * q.y + f[1][2] * q.z + f[1][3],
            f[2][0] * q.x + f[2][1] * q.y + f[2][2] * q.z + f[2][3],
        )
    };
    let v: Vec<P3> = mesh.vertices.iter().map(map).collect();
    let x = ANKLE_AT * lm.stick_length;
    let mut pts: Vec<[f64; 2]> = Vec::new();
    let mut high = f64::NEG_INFINITY;
    for t in &mesh.triangles {
        let c = [v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]];
        let mut cut: Vec<P3> = Vec::new();
        for k in 0..3 {
            let (a, b) = (c[k], c[(k + 1) % 3]);
            if (a.x - x) * (b.x - x) < 0.0 || (a.x == x && b.x != x) {
                let s = (x - a.x) / (b.x - a.x);
                cut.push(a + (b - a) * s);
            }
        }
        if cut.len() < 2 {
            continue;
        }
        let (mut p, mut q) = (cut[0], cut[1]);
        high = high.max(p.z).max(q.z);
        if p.z > q.z {
            std::mem::swap(&mut p, &mut q);
        }
        if p.z > top {
            continue;
        }
        if q.z > top {
            let s = (top - p.z) / (q.z - p.z);
            q = p + (q - p) * s;
        }
        pts.push([p.y, p.z]);
        pts.push([q.y, q.z]);
    }
    if pts.len() < 3 {
        return None;
    }
    Some((hull_perimeter(pts), high))
}

fn hull_perimeter(mut p: Vec<[f64; 2]>) -> f64 {
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let mut h: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = h.len();
        let it: Box<dyn Iterator<Item = &[f64; 2]>> = if pass == 0 {
            Box::new(p.iter())
        } else {
            Box::new(p.iter().rev())
        };
        for &q in it {
            while h.len() >= start + 2 && cross(h[h.len() - 2], h[h.len() - 1], q) <= 0.0 {
                h.pop();
            }
            h.push(q);
        }
        h.pop();
    }
    (0..h.len())
        .map(|k| {
            let (a, b) = (h[k], h[(k + 1) % h.len()]);
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt()
        })
        .sum()
}

/// Judges one last (its measures and, for the ankle rule, its mesh) against the foot's
/// targets (`foot_targets`) for a foot of `side` and `foot_length`.
pub fn judge_last(
    name: &str,
    lm: &LastMeasures,
    mesh: &TriMesh,
    rows: &[RuleRow],
    side: Side,
    foot_length: f64,
) -> Candidate {
    let cm = clinic_measures(mesh, name, side, foot_length);
    let mut cannot = Vec::new();
    let mut notes = Vec::new();
    let want = match side {
        Side::Left => LastSide::Left,
        Side::Right => LastSide::Right,
    };
    let mirrored = match lm.side {
        Some(s) if s != want => {
            notes.push(format!(
                "a {} last for a {} foot: mirrored",
                format!("{s:?}").to_lowercase(),
                format!("{want:?}").to_lowercase()
            ));
            true
        }
        Some(_) => false,
        None => {
            notes.push("side not told by the last's shape: taken as the foot's".into());
            false
        }
    };
    let top = ANKLE_TOP * foot_length;
    let ankle = ankle_girth(mesh, lm, top);
    let mut stations = Vec::new();
    for r in rows {
        // The rules' quantities as the clinic path cuts them on the stock last (the same
        // cut `customize_stock` starts from), so a change here is the change it must make.
        let (measure, value) = match (r.quantity, &cm) {
            ("bottom length", Ok(c)) => ("1.5 mm outline length", c.length),
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
            match ankle {
                Some((_, high)) if high >= top - 1.0 => {}
                Some((_, high)) => {
                    applicable = false;
                    cannot.push(format!(
                        "rule {} (ankle girth) not applicable on a low-cut last: its section at \
                         0.30 L reaches {:.1} mm, the foot's ankle girth is taken up to {:.1} mm",
                        r.rule, high, top
                    ));
                }
                None => {
                    applicable = false;
                    cannot.push(format!(
                        "rule {} (ankle girth): no section at 0.30 L",
                        r.rule
                    ));
                }
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
    Candidate {
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
    }
}

/// The stock last cut as the clinic path cuts a last: in a foot's frame, laid flat by its
/// bottom curve when it has toe spring or a raised heel, for the foot's side, its stations
/// placed by the foot's length (as the customized last is judged).
fn clinic_measures(
    mesh: &TriMesh,
    name: &str,
    side: Side,
    foot_length: f64,
) -> Result<Measures, String> {
    use crate::customize::bottom::{shear, BottomCurve, FLAT_TOL_MM};
    let (mut stock, mut frame) = crate::customize::foot_in_frame(mesh.clone(), name)
        .map_err(|e| footscan_util::chain(&e))?;
    if let Some(b) = BottomCurve::of(&stock).filter(|b| b.rise() > FLAT_TOL_MM) {
        shear(&mut stock, |x| -b.at(x));
    }
    frame.side = side;
    crate::customize::measure::measure(&stock, Some(foot_length), frame.medial_sign())
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
pub fn judge_files(
    files: &[std::path::PathBuf],
    units: footscan_geom::mesh::Units,
    length_mm: Option<f64>,
    rows: &[RuleRow],
    side: Side,
    foot_length: f64,
) -> Vec<(Candidate, Option<TriMesh>)> {
    let one = |p: &std::path::PathBuf| -> (Candidate, Option<TriMesh>) {
        let name = p.display().to_string();
        let got = TriMesh::load_solid(p, units, length_mm)
            .map_err(|e| footscan_util::chain(&e))
            .and_then(|(m, _)| {
                crate::size::check_last_size(p, &m).map_err(|e| footscan_util::chain(&e))?;
                let lm = crate::measure_last::measure_last(m.clone(), &name)
                    .map_err(|e| footscan_util::chain(&e))?;
                Ok((m, lm))
            });
        match got {
            Ok((m, lm)) => (judge_last(&name, &lm, &m, rows, side, foot_length), Some(m)),
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
            ),
        }
    };
    crate::par::map(files.len(), crate::par::cores(8), |k| one(&files[k]))
}
