//! The parameter study of the joining method: auxiliary sections, points per section and the
//! rotation angle of the plane bundle against build time and seam quality, on the real last
//! pairs. The criterion bench and `footscan bench join` print the same table.

use super::{join, output, JoinError, JoinParams};
use footscan_geom::mesh::{MeshError, TriMesh, Units};
use std::path::Path;
use std::time::Instant;

/// A pair of lasts to join: the back part comes from `back`, the toe part from `toe`.
pub struct Pair {
    pub name: String,
    pub back: TriMesh,
    pub toe: TriMesh,
}

/// The two real pairs from a data directory holding `lasts/`: the LastScan Default (back)
/// with Warped (toe), and Last_Heeled_RoundTip (back) with Last_Flat_RoundTip (toe), both
/// RoundTip lasts scaled to 260 mm.
pub fn real_pairs(data: &Path) -> Result<Vec<Pair>, MeshError> {
    let dir = data.join("lasts");
    let load =
        |f: &str, len: Option<f64>| TriMesh::load_solid(dir.join(f), Units::Auto, len).map(|r| r.0);
    Ok(vec![
        Pair {
            name: "LastScan Default+Warped".into(),
            back: load("LastScan_Default.stl", None)?,
            toe: load("LastScan_Warped.stl", None)?,
        },
        Pair {
            name: "RoundTip Heeled+Flat".into(),
            back: load("Last_Heeled_RoundTip.stl", Some(260.0))?,
            toe: load("Last_Flat_RoundTip.stl", Some(260.0))?,
        },
    ])
}

/// One setting of the study.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Case {
    /// Auxiliary sections on each side.
    pub aux: usize,
    pub points: usize,
    pub angle_deg: f64,
}

/// The settings of the paper's study, each varied from its setting (2 auxiliary sections,
/// 500 points, 45 deg): auxiliary sections 1-4, points 100-1000, angle 10-90 deg.
pub fn paper_cases() -> Vec<Case> {
    let base = Case {
        aux: 2,
        points: 500,
        angle_deg: 45.0,
    };
    let mut v: Vec<Case> = (1..=4).map(|aux| Case { aux, ..base }).collect();
    for points in [100, 200, 300, 500, 700, 1000] {
        v.push(Case { points, ..base });
    }
    for angle_deg in [10.0, 20.0, 30.0, 45.0, 60.0, 90.0] {
        v.push(Case { angle_deg, ..base });
    }
    v
}

/// Figures of one case on one pair.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Row {
    pub pair: String,
    pub aux: usize,
    pub points: usize,
    pub angle_deg: f64,
    pub sections: usize,
    pub guides: usize,
    /// Fastest of the repeats, ms (the join alone, without measuring or writing).
    pub time_ms: f64,
    /// Its steps, ms: cutting and resampling the sections; section and guide curves; the
    /// Gordon surface.
    pub sections_ms: f64,
    pub curves_ms: f64,
    pub gordon_ms: f64,
    /// Worst of the two seams.
    pub gap_mm: f64,
    pub normal_deg: f64,
    pub curvature_rel: f64,
    /// Worst of the two kept parts against their meshes.
    pub fit_rms_mm: f64,
    pub fit_max_mm: f64,
}

/// Run every case on every pair, timing the best of `repeats` joins.
pub fn run(pairs: &[Pair], cases: &[Case], repeats: usize) -> Result<Vec<Row>, JoinError> {
    let mut rows = Vec::new();
    for pair in pairs {
        for c in cases {
            let p = JoinParams {
                aux_back: c.aux,
                aux_toe: c.aux,
                points: c.points,
                angle_deg: c.angle_deg,
                // The study is of the Gordon network's settings; the fit of the kept parts
                // is timed and measured by the methods table.
                fit_parts: false,
                ..JoinParams::default()
            };
            let mut best = f64::INFINITY;
            let mut fastest = None;
            for _ in 0..repeats.max(1) {
                let t = Instant::now();
                let j = join(&pair.back, &pair.toe, &p)?;
                let ms = t.elapsed().as_secs_f64() * 1e3;
                if ms < best {
                    best = ms;
                    fastest = Some(j);
                }
            }
            let j = fastest.unwrap();
            let q = output::quality(&j, 200)?;
            let (s, d) = (
                [q.back_seam, q.toe_seam],
                [q.back_deviation, q.toe_deviation],
            );
            rows.push(Row {
                pair: pair.name.clone(),
                aux: c.aux,
                points: c.points,
                angle_deg: c.angle_deg,
                sections: j.network.sections.len(),
                guides: j.network.guides.len(),
                time_ms: best,
                sections_ms: j.timings.sections,
                curves_ms: j.timings.curves,
                gordon_ms: j.timings.gordon,
                gap_mm: s[0].gap_max_mm.max(s[1].gap_max_mm),
                normal_deg: s[0].normal_max_deg.max(s[1].normal_max_deg),
                curvature_rel: s[0].curvature_rel_max.max(s[1].curvature_rel_max),
                fit_rms_mm: d[0].rms_mm.max(d[1].rms_mm),
                fit_max_mm: d[0].max_mm.max(d[1].max_mm),
            });
        }
    }
    Ok(rows)
}

/// The rows as a plain-text table.
pub fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "{:<24} {:>3} {:>6} {:>5} {:>4} {:>6} {:>8} {:>17} {:>8} {:>10} {:>8} {:>8} {:>8}\n",
        "pair",
        "aux",
        "points",
        "angle",
        "secs",
        "guides",
        "time ms",
        "sec/curv/Gor ms",
        "gap mm",
        "normal deg",
        "curv rel",
        "fit rms",
        "fit max"
    );
    for r in rows {
        s.push_str(&format!(
            "{:<24} {:>3} {:>6} {:>5.0} {:>4} {:>6} {:>8.1} {:>17} {:>8.1e} {:>10.1e} {:>8.1e} {:>8.3} {:>8.3}\n",
            r.pair,
            r.aux,
            r.points,
            r.angle_deg,
            r.sections,
            r.guides,
            r.time_ms,
            format!("{:.1}/{:.1}/{:.1}", r.sections_ms, r.curves_ms, r.gordon_ms),
            r.gap_mm,
            r.normal_deg,
            r.curvature_rel,
            r.fit_rms_mm,
            r.fit_max_mm
        ));
    }
    s
}
