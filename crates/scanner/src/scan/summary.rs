//! The scan summary written as scan.json, with the error against ground truth where a
//! simulator supplied it.

use super::quality::{Quality, ScanStatus};
use crate::scandata::ScanGrid;
use footscan_geom::P3;
use serde::Serialize;

/// Ground truth per frame (camera sequence number), from a simulator.
pub trait TruthSource: Send + Sync {
    /// The true surface point of every row (`None` where the row truly has no line), or
    /// `None` if no truth was recorded for that frame.
    fn frame(&self, seq: u64) -> Option<Vec<Option<P3>>>;
}

#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct TruthStats {
    /// 3D distance between each scanned point and the true surface point of the same
    /// frame and row.
    pub rms_mm: f64,
    pub max_mm: f64,
    pub p99_mm: f64,
    /// Height (z) error alone.
    pub height_rms_mm: f64,
    /// Points compared.
    pub compared: usize,
    /// Rows with a true line where no point was produced.
    pub missed_rows: usize,
    /// Points where the truth has no line (spurious detections).
    pub spurious_points: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct StageReport {
    pub name: String,
    #[serde(rename = "in")]
    pub input: u64,
    #[serde(rename = "out")]
    pub output: u64,
    pub dropped: u64,
    pub mean_latency_ms: f64,
    pub max_latency_ms: f64,
    pub blocked_ms: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct ScanSummary {
    /// "complete", "complete with warnings", "side mismatch", "rescan", "failed" or
    /// "cancelled" (the quality gate's verdict, docs/method.md section 3.3).
    pub status: ScanStatus,
    /// Why, in an operator's words (the gate's issues, worst first, or the error).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    pub frames: u64,
    pub dropped_frames: u64,
    /// Frames taken while the head had not advanced (start of the move), not used.
    pub stationary_frames: u64,
    pub points: usize,
    pub seconds: f64,
    /// Slider range actually covered (mm).
    pub x_range_mm: [f64; 2],
    pub stages: Vec<StageReport>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub truth: Option<TruthStats>,
    /// Laser-off frames (`scan.background = "ends"`) and the rows in which the detector still
    /// found a line (false detections: should be 0).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub laser_off: Option<LaserOffStats>,
    /// What the quality gate looked at (scans that produced a grid).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quality: Option<Quality>,
    /// What each per-scan and sink plugin stage did: its values, its report, or why it was
    /// skipped (docs/plugins.md).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub plugins: Vec<PluginRecord>,
    /// The CAD files (`model.bezier`), which follow the results: "building" in the scan.json
    /// written with the verdict, then what became of them.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model: Option<super::model_job::ModelProgress>,
    /// When the results and the CAD files were ready, after the last frame.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub timeline: Option<Timeline>,
}

/// When the scan's outputs were ready (seconds).
#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq)]
pub struct Timeline {
    /// From the start of the scan to its last frame.
    pub last_frame_s: f64,
    /// From the last frame to the results: measurements.json, plantar.png, heightmap.png
    /// and the verdict in scan.json.
    pub results_after_last_frame_s: f64,
    /// From the last frame to the CAD files (None while they are being written).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub model_after_last_frame_s: Option<f64>,
}

/// One per-scan or sink plugin stage's outcome, kept in scan.json.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct PluginRecord {
    /// `wasm` or `exec`.
    pub stage: String,
    /// The module's file or the command.
    pub plugin: String,
    /// `scan` or `sink`.
    pub place: String,
    /// "ok", or "skipped" (an optional stage that failed: `required = false`).
    pub status: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// A per-scan stage's values.
    #[serde(skip_serializing_if = "std::collections::BTreeMap::is_empty")]
    pub values: std::collections::BTreeMap<String, f64>,
    /// A sink's report, a file in the scan directory.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub report: Option<String>,
}

#[derive(Clone, Copy, Debug, Default, Serialize, PartialEq, Eq)]
pub struct LaserOffStats {
    pub frames: u64,
    pub rows_found: u64,
}

/// Point count and truth comparison of a finished grid; run totals are filled in by the caller.
pub fn summarize(grid: &ScanGrid, truth: Option<&dyn TruthSource>) -> ScanSummary {
    let xs = grid.frames.iter().map(|f| f.x_mm);
    let x_range_mm = [
        xs.clone().fold(f64::INFINITY, f64::min),
        xs.fold(f64::NEG_INFINITY, f64::max),
    ];
    ScanSummary {
        status: ScanStatus::Complete,
        reason: None,
        frames: grid.frames.len() as u64,
        dropped_frames: 0,
        stationary_frames: 0,
        points: grid.valid_count(),
        seconds: 0.0,
        x_range_mm,
        stages: Vec::new(),
        truth: truth.map(|t| compare(grid, t)),
        laser_off: None,
        quality: None,
        plugins: Vec::new(),
        model: None,
        timeline: None,
    }
}

fn compare(grid: &ScanGrid, truth: &dyn TruthSource) -> TruthStats {
    let mut errs = Vec::new();
    let (mut sum2, mut hsum2) = (0.0, 0.0);
    let mut s = TruthStats::default();
    for (i, meta) in grid.frames.iter().enumerate() {
        let Some(rows) = truth.frame(meta.seq) else {
            continue;
        };
        for (row, t) in rows.iter().enumerate().take(grid.rows) {
            let p = grid.point(i, row);
            match (t, p[0].is_finite()) {
                (None, true) => s.spurious_points += 1,
                (None, false) => {}
                (Some(_), false) => s.missed_rows += 1,
                (Some(t), true) => {
                    let d2: f64 = (0..3).map(|k| (p[k] - t[k]).powi(2)).sum();
                    sum2 += d2;
                    hsum2 += (p[2] - t[2]).powi(2);
                    errs.push(d2.sqrt());
                }
            }
        }
    }
    s.compared = errs.len();
    if !errs.is_empty() {
        let n = errs.len() as f64;
        s.rms_mm = (sum2 / n).sqrt();
        s.height_rms_mm = (hsum2 / n).sqrt();
        errs.sort_by(f64::total_cmp);
        s.max_mm = *errs.last().unwrap();
        s.p99_mm = errs[((errs.len() - 1) as f64 * 0.99) as usize];
    }
    s
}

impl ScanSummary {
    fn empty(status: ScanStatus) -> Self {
        ScanSummary {
            status,
            reason: None,
            frames: 0,
            dropped_frames: 0,
            stationary_frames: 0,
            points: 0,
            seconds: 0.0,
            x_range_mm: [f64::NAN; 2],
            stages: Vec::new(),
            truth: None,
            laser_off: None,
            quality: None,
            plugins: Vec::new(),
            model: None,
            timeline: None,
        }
    }

    /// The verdict in one line: "complete with warnings: 35 frames dropped, ...".
    pub fn verdict(&self) -> String {
        super::quality::verdict(self.status, self.reason.as_deref())
    }

    /// A scan that ended without a grid (cancelled before any frame, or no summary stage).
    pub fn without_grid(cancelled: bool) -> Self {
        Self::empty(if cancelled {
            ScanStatus::Cancelled
        } else {
            ScanStatus::Complete
        })
    }

    pub fn failed(reason: &str) -> Self {
        ScanSummary {
            reason: Some(reason.to_string()),
            ..Self::empty(ScanStatus::Failed)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::LinePeak;
    use crate::scandata::{FrameMeta, FramePoints};
    use footscan_hal::Timestamp;

    struct Flat;
    impl TruthSource for Flat {
        fn frame(&self, seq: u64) -> Option<Vec<Option<P3>>> {
            (seq < 2).then(|| {
                (0..3)
                    .map(|row| (row < 2).then_some(P3::new(seq as f64, row as f64, 0.0)))
                    .collect()
            })
        }
    }

    #[test]
    fn compares_rows_with_truth() {
        let mut g = ScanGrid::new(3);
        for seq in 0..3u64 {
            let pts = vec![
                P3::new(seq as f64, 0.0, 0.3),
                P3::from([f64::NAN; 3]),
                P3::new(seq as f64, 2.0, 0.0),
            ];
            g.push(FramePoints {
                meta: FrameMeta {
                    index: seq,
                    seq,
                    timestamp: Timestamp::default(),
                    x_mm: seq as f64,
                },
                lines: vec![LinePeak::NONE; 3],
                points: pts,
            });
        }
        let s = summarize(&g, Some(&Flat));
        let t = s.truth.unwrap();
        assert_eq!(t.compared, 2);
        assert_eq!(t.missed_rows, 2);
        assert_eq!(t.spurious_points, 2);
        assert!((t.rms_mm - 0.3).abs() < 1e-12 && (t.max_mm - 0.3).abs() < 1e-12);
        assert_eq!(s.points, 6);
        assert_eq!(s.x_range_mm, [0.0, 2.0]);
    }
}
