//! Measurements against a simulator's ground truth (`truth.json`, a serialised
//! `footscan_sim::foot::FootTruth`): the error table of tests and `footscan measure`.

use super::{Measurements, Side};
use footscan_geom::{P2, V2};
use serde::{Deserialize, Serialize};

/// What an error row measures, and so its unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ErrorKind {
    /// A length or width; error = measured - truth (mm).
    Length,
    /// A point; error = distance between measured and true point (mm).
    Landmark,
    /// An angle; error = measured - truth (degrees).
    Angle,
    /// A ratio; error = measured - truth.
    Index,
}

#[derive(Clone, Debug, Serialize)]
pub struct ErrorRow {
    pub name: &'static str,
    pub kind: ErrorKind,
    /// Scalars have one value, points two ([x, y]).
    pub truth: Vec<f64>,
    pub measured: Vec<f64>,
    pub error: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct TruthComparison {
    pub side_correct: bool,
    pub rows: Vec<ErrorRow>,
}

/// The fields of `FootTruth` compared here (others are ignored).
#[derive(Deserialize)]
struct TruthRef {
    side: Side,
    heel_point: P2,
    toe_tip: P2,
    heel_centre: P2,
    mt2_head: P2,
    axis_dir: V2,
    length_mm: f64,
    mt1_head: P2,
    mt5_head: P2,
    ball_width_mm: f64,
    waist_inner: P2,
    waist_outer: P2,
    midfoot_width_mm: f64,
    midfoot_inner: P2,
    midfoot_outer: P2,
    heel_width_mm: f64,
    hallux_point: P2,
    arch_height_mm: f64,
    arch_index: f64,
    contact_area_mm2: f64,
}

/// Compare `m` with the truth serialised as JSON (the `truth.json` of a simulated scan).
pub fn compare_with_truth(
    m: &Measurements,
    truth_json: &str,
) -> Result<TruthComparison, serde_json::Error> {
    let t: TruthRef = serde_json::from_str(truth_json)?;
    let mut rows = Vec::new();
    let mut point = |name, truth: P2, got: P2| {
        let d = got - truth;
        rows.push(ErrorRow {
            name,
            kind: ErrorKind::Landmark,
            truth: vec![truth.x, truth.y],
            measured: vec![got.x, got.y],
            error: d.x.hypot(d.y),
        })
    };
    point("heel_point", t.heel_point, m.heel_point);
    point("toe_tip", t.toe_tip, m.toe_tip);
    point("heel_centre", t.heel_centre, m.heel_centre);
    point("mt2_head", t.mt2_head, m.mt2_head);
    point("mt1_head", t.mt1_head, m.mt1_head);
    point("mt5_head", t.mt5_head, m.mt5_head);
    point("waist_inner", t.waist_inner, m.waist_inner);
    point("waist_outer", t.waist_outer, m.waist_outer);
    point("midfoot_inner", t.midfoot_inner, m.midfoot_inner);
    point("midfoot_outer", t.midfoot_outer, m.midfoot_outer);
    point("hallux_point", t.hallux_point, m.hallux_point);
    let angle = |d: V2| d.y.atan2(d.x).to_degrees();
    rows.push(ErrorRow {
        name: "axis_angle_deg",
        kind: ErrorKind::Angle,
        truth: vec![angle(t.axis_dir)],
        measured: vec![m.axis_angle_deg],
        error: m.axis_angle_deg - angle(t.axis_dir),
    });
    let mut scalar = |name, kind, truth: f64, got: f64| {
        rows.push(ErrorRow {
            name,
            kind,
            truth: vec![truth],
            measured: vec![got],
            error: got - truth,
        })
    };
    use ErrorKind::{Index, Length};
    scalar("foot_length_mm", Length, t.length_mm, m.foot_length_mm);
    scalar("ball_width_mm", Length, t.ball_width_mm, m.ball_width_mm);
    scalar(
        "midfoot_width_mm",
        Length,
        t.midfoot_width_mm,
        m.midfoot_width_mm,
    );
    scalar("heel_width_mm", Length, t.heel_width_mm, m.heel_width_mm);
    scalar("arch_height_mm", Length, t.arch_height_mm, m.arch_height_mm);
    scalar("arch_index", Index, t.arch_index, m.arch_index);
    // Reported, not a figure of docs/method.md section 8: relative error of the contact area.
    scalar(
        "contact_area_rel",
        Index,
        1.0,
        m.contact_area_mm2 / t.contact_area_mm2,
    );
    Ok(TruthComparison {
        side_correct: t.side == m.side,
        rows,
    })
}

impl TruthComparison {
    /// Largest |error| among the rows of `kind`.
    pub fn worst(&self, kind: ErrorKind) -> f64 {
        self.rows
            .iter()
            .filter(|r| r.kind == kind)
            .map(|r| r.error.abs())
            .fold(0.0, f64::max)
    }

    pub fn row(&self, name: &str) -> Option<&ErrorRow> {
        self.rows.iter().find(|r| r.name == name)
    }

    /// A plain-text table: measurement, truth, measured, error.
    pub fn table(&self) -> String {
        let fmt = |v: &[f64], digits: usize| -> String {
            match v {
                [a] => format!("{a:.digits$}"),
                [a, b] => format!("({a:.2}, {b:.2})"),
                _ => String::new(),
            }
        };
        let mut s = format!(
            "{:18} {:>20} {:>20} {:>10}\n",
            "measurement", "truth", "measured", "error"
        );
        for r in &self.rows {
            let d = if r.kind == ErrorKind::Index { 4 } else { 2 };
            let unit = match r.kind {
                ErrorKind::Length | ErrorKind::Landmark => " mm",
                ErrorKind::Angle => " deg",
                ErrorKind::Index => "",
            };
            let e = match r.kind {
                ErrorKind::Index => format!("{:+.4}", r.error),
                ErrorKind::Landmark => format!("{:.3}{unit}", r.error),
                _ => format!("{:+.3}{unit}", r.error),
            };
            s.push_str(&format!(
                "{:18} {:>20} {:>20} {:>10}\n",
                r.name,
                fmt(&r.truth, d),
                fmt(&r.measured, d),
                e
            ));
        }
        s.push_str(&format!(
            "side {}\n",
            if self.side_correct {
                "correct"
            } else {
                "WRONG"
            }
        ));
        s
    }
}
