//! The quality gate of docs/method.md section 3.3: every scan gets a verdict from what the
//! pipeline knows (dropped frames and the gaps they leave, rows lost, a foot cut by the scan
//! range or the camera's view, no sole on the glass, the side), so a bad scan is caught
//! before the patient leaves instead of being archived as "complete".
//!
//! Small gaps are bridged in the grid (the slider positions of the neighbouring frames are
//! known, the sole is smooth over a few millimetres), so the model stays one piece; a gap too
//! wide to bridge, a cut foot or a scan that lost much of the sole is a rescan.

use crate::detect::{LinePeak, Reject};
use crate::scandata::{FrameMeta, ScanGrid};
use footscan_geom::P3;
use serde::{Deserialize, Serialize};
use std::fmt;

/// A scan's state: running, or how it ended, in scan.json and the daemon's archive (one enum
/// from the pipeline to the HTTP edge). The strings are today's and earlier records': old
/// scan.json files and archive records keep loading.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub enum ScanStatus {
    /// Still acquiring (the daemon's archive; a finished scan.json never says it).
    #[serde(rename = "running")]
    Running,
    #[serde(rename = "complete")]
    Complete,
    /// Usable, but the operator should read the reason (bridged gaps, a few rows lost).
    #[serde(rename = "complete with warnings")]
    CompleteWithWarnings,
    /// The scan looks like the other foot than the operator chose: confirm or rescan.
    #[serde(rename = "side mismatch")]
    SideMismatch,
    /// The pipeline ran but the scan cannot be used: scan again (the files are kept).
    #[serde(rename = "rescan")]
    Rescan,
    /// The pipeline stopped (a device, a stage): no usable files.
    #[serde(rename = "failed")]
    Failed,
    #[serde(rename = "cancelled")]
    Cancelled,
}

impl ScanStatus {
    pub const ALL: [ScanStatus; 7] = [
        ScanStatus::Running,
        ScanStatus::Complete,
        ScanStatus::CompleteWithWarnings,
        ScanStatus::SideMismatch,
        ScanStatus::Rescan,
        ScanStatus::Failed,
        ScanStatus::Cancelled,
    ];

    /// The string of scan.json and the archive index.
    pub fn as_str(self) -> &'static str {
        match self {
            ScanStatus::Running => "running",
            ScanStatus::Complete => "complete",
            ScanStatus::CompleteWithWarnings => "complete with warnings",
            ScanStatus::SideMismatch => "side mismatch",
            ScanStatus::Rescan => "rescan",
            ScanStatus::Failed => "failed",
            ScanStatus::Cancelled => "cancelled",
        }
    }

    pub fn parse(s: &str) -> Option<ScanStatus> {
        Self::ALL.into_iter().find(|x| x.as_str() == s)
    }

    /// What an operator reads first: "failed: rescan" rather than "rescan".
    pub fn label(self) -> &'static str {
        match self {
            ScanStatus::Rescan => "failed: rescan",
            ScanStatus::SideMismatch => "needs confirmation",
            s => s.as_str(),
        }
    }

    /// The scan's files can be used as they are (possibly with warnings to read).
    pub fn is_usable(self) -> bool {
        matches!(
            self,
            ScanStatus::Complete | ScanStatus::CompleteWithWarnings
        )
    }
}

impl fmt::Display for ScanStatus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl PartialEq<str> for ScanStatus {
    fn eq(&self, other: &str) -> bool {
        self.as_str() == other
    }
}

impl PartialEq<&str> for ScanStatus {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}

/// `[quality]` of the scanner config: the gate's thresholds.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct QualitySection {
    /// Gaps between neighbouring frames up to this (mm) are bridged by interpolation; a wider
    /// gap over the foot is a rescan.
    pub bridge_mm: f64,
    /// The scan must hold the whole foot: a measured foot touching either end of the scan
    /// range is a rescan. false for partial scans (a heel, a quick test): noted only.
    pub whole_foot: bool,
    /// The object on the glass must lie whole inside the scan range even when no foot is
    /// measured (a last bottom: cut at the toe, its length and side cannot be told), so one
    /// running past either end of the range is a rescan. false (plates, calibration
    /// targets, which may fill the range): noted only.
    pub whole_object: bool,
    /// Share of the sole's rows lost (a line the detector rejected, or no point) above which
    /// the scan warns, and above which it is a rescan.
    pub lost_warn: f64,
    pub lost_rescan: f64,
}

impl Default for QualitySection {
    fn default() -> Self {
        QualitySection {
            bridge_mm: 3.0,
            whole_foot: true,
            whole_object: false,
            lost_warn: 0.01,
            lost_rescan: 0.10,
        }
    }
}

/// A `[quality]` value out of its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum QualityError {
    #[error("quality.bridge_mm = {0}: valid range is [0, 20]")]
    BridgeMm(f64),
    #[error("quality.lost_warn and quality.lost_rescan are shares in [0, 1]")]
    LostShares,
}

impl QualityError {
    /// The key the error is about, to locate it in the config file.
    pub fn key(&self) -> &'static str {
        match self {
            QualityError::BridgeMm(_) => "bridge_mm",
            QualityError::LostShares => "lost_warn",
        }
    }
}

impl QualitySection {
    pub fn validate(&self) -> Result<(), QualityError> {
        if !(self.bridge_mm >= 0.0 && self.bridge_mm <= 20.0) {
            return Err(QualityError::BridgeMm(self.bridge_mm));
        }
        if !(0.0..=1.0).contains(&self.lost_warn) || !(0.0..=1.0).contains(&self.lost_rescan) {
            return Err(QualityError::LostShares);
        }
        Ok(())
    }
}

/// How much an issue weighs in the verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Level {
    /// Said, but the scan stays "complete".
    Note,
    Warning,
    /// The operator must confirm (the side).
    Confirm,
    Rescan,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Issue {
    pub level: Level,
    pub text: String,
}

/// Rows inside the sole without a point, by the detector's reason.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RejectCounts {
    pub below_threshold: u64,
    pub saturated: u64,
    pub ambiguous: u64,
    pub border: u64,
    /// A lone row's line dropped as a speck ([`Reject::Isolated`]).
    #[serde(default)]
    pub isolated: u64,
    /// A line was found but gave no 3D point (outside the calibrated volume).
    pub not_triangulated: u64,
}

/// The operator's side and the scan's.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SideCheck {
    pub chosen: Option<String>,
    pub detected: String,
}

/// Everything the gate looked at, in scan.json under `quality`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Quality {
    pub dropped_frames: u64,
    /// The scan's nominal slider step (mm).
    pub step_mm: f64,
    /// Frames holding the foot (at least [`FOOT_ROWS`] points).
    pub foot_frames: u64,
    /// Largest slider distance between neighbouring frames over the foot (mm), before
    /// bridging.
    pub largest_gap_mm: f64,
    /// Frames interpolated into the grid.
    pub bridged_frames: u64,
    /// Slider ranges over the foot left unscanned (too wide to bridge).
    pub unbridged_gaps_mm: Vec<[f64; 2]>,
    /// Rows inside the sole lost: a line rejected as saturated, ambiguous or at the image
    /// border, or found but not triangulated. Rows below the threshold are not counted (the
    /// sole between the toes and the ball has no surface to return a line).
    pub rows_lost: u64,
    pub rows_lost_share: f64,
    pub rejects: RejectCounts,
    /// Where the foot runs out of the scan: "start of the scan range", "end of the scan
    /// range", "edge of the camera's view".
    pub cut: Vec<String>,
    /// 0.5th percentile of the foot's heights (mm): near 0 when the sole stands on the glass.
    pub lowest_mm: Option<f64>,
    /// Set when a foot was measured.
    pub side: Option<SideCheck>,
    /// The measured foot's doubtful figures (measurements.json's warnings): each makes the
    /// scan "complete with warnings".
    #[serde(default)]
    pub measure_warnings: Vec<String>,
    pub issues: Vec<Issue>,
}

/// The camera sequence number of a frame interpolated into a gap: no camera took it, and no
/// ground truth belongs to it.
pub const BRIDGED_SEQ: u64 = u64::MAX;

/// Points a frame needs to count as holding the foot.
pub const FOOT_ROWS: usize = 10;
/// Rows at the top and bottom of the image: points there mean the foot runs past the view.
const EDGE_ROWS: usize = 3;

fn valid_rows(g: &ScanGrid, i: usize) -> usize {
    (0..g.rows)
        .filter(|&j| g.point(i, j)[0].is_finite())
        .count()
}

/// Interpolate the frames missing between neighbours closer than `bridge_mm`, when either
/// holds the foot; returns the facts about gaps for [`Quality`]. A row gets an interpolated
/// point where both neighbours have one in that row, else none; frames are renumbered and
/// the interpolated ones carry [`BRIDGED_SEQ`].
pub fn bridge_gaps(grid: &mut ScanGrid, step_mm: f64, bridge_mm: f64) -> Quality {
    let mut q = Quality {
        step_mm,
        ..Quality::default()
    };
    let n = grid.frames.len();
    let rows = grid.rows;
    if n == 0 || rows == 0 {
        return q;
    }
    let foot: Vec<bool> = (0..n).map(|i| valid_rows(grid, i) >= FOOT_ROWS).collect();
    q.foot_frames = foot.iter().filter(|&&f| f).count() as u64;
    // Frames missing before frame i that are bridged: decided first, so a scan with nothing
    // to bridge keeps its grid instead of copying it (30 MB, and the results of a scan wait
    // on this: issue 34 item 2).
    let mut bridge = vec![0usize; n];
    for i in 1..n {
        let (a, b) = (grid.frames[i - 1], grid.frames[i]);
        let d = b.x_mm - a.x_mm;
        let over_foot = foot[i - 1] || foot[i];
        if over_foot {
            q.largest_gap_mm = q.largest_gap_mm.max(d);
        }
        let missing = (d / step_mm).round() as i64 - 1;
        if over_foot && missing > 0 {
            if d <= bridge_mm + 1e-9 {
                bridge[i] = missing as usize;
                q.bridged_frames += missing as u64;
            } else {
                q.unbridged_gaps_mm.push([a.x_mm, b.x_mm]);
            }
        }
    }
    if q.bridged_frames == 0 {
        for (k, f) in grid.frames.iter_mut().enumerate() {
            f.index = k as u64;
        }
        return q;
    }
    let mut frames = Vec::with_capacity(n);
    let mut lines = Vec::with_capacity(grid.lines.len());
    let mut points = Vec::with_capacity(grid.points.len());
    for (i, &missing) in bridge.iter().enumerate() {
        if missing > 0 {
            let (a, b) = (grid.frames[i - 1], grid.frames[i]);
            let d = b.x_mm - a.x_mm;
            for k in 1..=missing {
                let t = k as f64 / (missing + 1) as f64;
                frames.push(FrameMeta {
                    index: 0,
                    seq: BRIDGED_SEQ,
                    timestamp: footscan_hal::Timestamp {
                        nanos: a.timestamp.nanos
                            + ((b.timestamp.nanos.saturating_sub(a.timestamp.nanos)) as f64 * t)
                                as u64,
                    },
                    x_mm: a.x_mm + d * t,
                });
                for j in 0..rows {
                    let (pa, pb) = (grid.point(i - 1, j), grid.point(i, j));
                    let (la, lb) = (grid.lines[(i - 1) * rows + j], grid.lines[i * rows + j]);
                    if pa[0].is_finite() && pb[0].is_finite() {
                        points.push(pa + (pb - pa) * t);
                        lines.push(LinePeak {
                            col: la.col + (lb.col - la.col) * t,
                            intensity: la.intensity.min(lb.intensity),
                            width: la.width.max(lb.width),
                            quality: la.quality.min(lb.quality),
                            reject: None,
                        });
                    } else {
                        points.push(P3::from([f64::NAN; 3]));
                        lines.push(LinePeak::NONE);
                    }
                }
            }
        }
        frames.push(grid.frames[i]);
        lines.extend_from_slice(&grid.lines[i * rows..(i + 1) * rows]);
        points.extend_from_slice(&grid.points[i * rows..(i + 1) * rows]);
    }
    for (k, f) in frames.iter_mut().enumerate() {
        f.index = k as u64;
    }
    grid.frames = frames;
    grid.lines = lines;
    grid.points = points;
    q
}

/// Rows lost, reject reasons, the foot at the ends of the range or the edge of the view, and
/// the lowest sole height, from the (bridged) grid into `q`.
pub fn inspect(grid: &ScanGrid, q: &mut Quality) {
    let (n, rows) = (grid.frames.len(), grid.rows);
    let foot: Vec<usize> = (0..n)
        .filter(|&i| valid_rows(grid, i) >= FOOT_ROWS)
        .collect();
    if foot.is_empty() {
        return;
    }
    let mut valid = 0u64;
    let mut zs = Vec::new();
    let mut edge_frames = 0;
    for &i in &foot {
        let idx: Vec<usize> = (0..rows)
            .filter(|&j| grid.point(i, j)[0].is_finite())
            .collect();
        let (j0, j1) = (idx[0], *idx.last().unwrap());
        if j0 < EDGE_ROWS || j1 + EDGE_ROWS >= rows {
            edge_frames += 1;
        }
        for j in j0..=j1 {
            let p = grid.point(i, j);
            if p[0].is_finite() {
                valid += 1;
                zs.push(p[2]);
                continue;
            }
            let l = grid.lines[i * rows + j];
            let r = &mut q.rejects;
            match l.reject {
                None => r.not_triangulated += 1,
                Some(Reject::BelowThreshold) => r.below_threshold += 1,
                Some(Reject::Saturated) => r.saturated += 1,
                Some(Reject::Ambiguous) => r.ambiguous += 1,
                Some(Reject::Border) => r.border += 1,
                Some(Reject::Isolated) => r.isolated += 1,
            }
        }
    }
    let r = q.rejects;
    q.rows_lost = r.saturated + r.ambiguous + r.border + r.not_triangulated;
    q.rows_lost_share = q.rows_lost as f64 / (valid + q.rows_lost).max(1) as f64;
    // The first and last frames of the scan are at the ends of its range.
    if foot[0] == 0 {
        q.cut.push("start of the scan range".into());
    }
    if *foot.last().unwrap() == n - 1 {
        q.cut.push("end of the scan range".into());
    }
    if edge_frames >= 3 {
        q.cut.push("edge of the camera's view".into());
    }
    // The 0.5 % quantile: selected, not sorted (253 000 heights, 15 ms).
    let k = (zs.len() - 1) / 200;
    q.lowest_mm = Some(*zs.select_nth_unstable_by(k, f64::total_cmp).1);
}

/// The verdict: issues from `q` (with the operator's side `chosen` and whether a foot was
/// measured), the status they add up to, and the reason in an operator's words.
pub fn judge(
    q: &mut Quality,
    cfg: &QualitySection,
    frames: u64,
    measured_foot: bool,
) -> (ScanStatus, Option<String>) {
    let mut issues = Vec::new();
    let push = |issues: &mut Vec<Issue>, level, text: String| issues.push(Issue { level, text });
    if let Some(s) = &q.side {
        if let Some(c) = &s.chosen {
            if *c != s.detected {
                push(
                    &mut issues,
                    Level::Confirm,
                    format!("side mismatch: chose {c}, scan looks {}", s.detected),
                );
            }
        }
    }
    if let Some(g) = q
        .unbridged_gaps_mm
        .iter()
        .max_by(|a, b| (a[1] - a[0]).total_cmp(&(b[1] - b[0])))
    {
        let more = match q.unbridged_gaps_mm.len() {
            1 => String::new(),
            n => format!(" and {} narrower gaps", n - 1),
        };
        push(
            &mut issues,
            Level::Rescan,
            format!(
                "{:.1} mm of the foot not scanned (frames lost between {:.1} and {:.1} mm){more}",
                g[1] - g[0],
                g[0],
                g[1]
            ),
        );
    }
    for c in &q.cut {
        let foot_cut = c.contains("range");
        // Only a measured foot must be whole: a plate, a last bottom or a calibration target
        // may fill the range and the view.
        let whole = if measured_foot {
            cfg.whole_foot
        } else {
            cfg.whole_object
        };
        let level = if whole { Level::Rescan } else { Level::Note };
        let what = if measured_foot { "foot" } else { "object" };
        let advice = if foot_cut {
            format!("place the {what} inside the scanned length")
        } else {
            format!("place the {what} in the middle of the glass")
        };
        push(
            &mut issues,
            level,
            format!("the {what} runs past the {c}: {advice}"),
        );
    }
    if q.rows_lost > 0 && q.rows_lost_share > cfg.lost_warn {
        let r = &q.rejects;
        let mut why = [
            (r.saturated, "the line too bright (lower exposure or gain)"),
            (
                r.ambiguous,
                "two lines in a row (a reflection or stray light)",
            ),
            (r.border, "the line at the image border"),
            (r.not_triangulated, "outside the calibrated volume"),
        ];
        why.sort_by_key(|w| std::cmp::Reverse(w.0));
        let level = if q.rows_lost_share > cfg.lost_rescan {
            Level::Rescan
        } else {
            Level::Warning
        };
        push(
            &mut issues,
            level,
            format!(
                "{:.1} % of the sole lost, mostly {}",
                100.0 * q.rows_lost_share,
                why[0].1
            ),
        );
    }
    if measured_foot {
        if let Some(z) = q.lowest_mm.filter(|z| *z > 1.5) {
            push(
                &mut issues,
                Level::Warning,
                format!(
                    "no sole on the glass (lowest point {z:.1} mm above it): is the foot standing on the glass?"
                ),
            );
        }
    }
    if q.dropped_frames > 0 || q.bridged_frames > 0 {
        let mut text = format!(
            "{} frames dropped, largest gap {:.1} mm",
            q.dropped_frames, q.largest_gap_mm
        );
        if q.bridged_frames > 0 {
            text += &format!(", bridged ({} frames interpolated)", q.bridged_frames);
        }
        // A few single lost frames (a loaded machine) bridge without harm; many, or wider
        // gaps, are worth the operator's look at the model.
        let many = q.bridged_frames as f64 > 0.01 * frames.max(1) as f64;
        let wide = q.bridged_frames > 0 && q.largest_gap_mm > 2.01 * q.step_mm;
        let level = if q.unbridged_gaps_mm.is_empty() && (many || wide) {
            Level::Warning
        } else {
            Level::Note
        };
        push(&mut issues, level, text);
    }
    if !q.measure_warnings.is_empty() {
        // A partial scan by design measures part of a foot: its figures' doubts are noted,
        // not warned (the foot cut by the range is already noted above).
        let level = if cfg.whole_foot {
            Level::Warning
        } else {
            Level::Note
        };
        push(
            &mut issues,
            level,
            format!("measurements to check: {}", q.measure_warnings.join("; ")),
        );
    }
    issues.sort_by_key(|i| std::cmp::Reverse(i.level));
    let worst = issues.first().map(|i| i.level);
    let status = match worst {
        Some(Level::Rescan) => ScanStatus::Rescan,
        Some(Level::Confirm) => ScanStatus::SideMismatch,
        Some(Level::Warning) => ScanStatus::CompleteWithWarnings,
        _ => ScanStatus::Complete,
    };
    // Notes stay in `issues`: a complete scan has no reason to read.
    let said: Vec<&str> = issues
        .iter()
        .filter(|i| i.level > Level::Note)
        .map(|i| i.text.as_str())
        .collect();
    let reason = (!said.is_empty()).then(|| said.join("; "));
    q.issues = issues;
    (status, reason)
}

/// The verdict as one line: "complete with warnings: 35 frames dropped, ...".
pub fn verdict(status: ScanStatus, reason: Option<&str>) -> String {
    match reason {
        Some(r) if !r.is_empty() => format!("{}: {r}", status.label()),
        _ => status.label().to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scandata::FramePoints;

    /// Frames at `xs` with a flat sole in rows 5-24 of 30 (z = x / 100).
    fn grid(xs: &[f64]) -> ScanGrid {
        let mut g = ScanGrid::new(30);
        for (k, &x) in xs.iter().enumerate() {
            g.push(FramePoints {
                meta: FrameMeta {
                    index: k as u64,
                    seq: k as u64,
                    timestamp: footscan_hal::Timestamp::default(),
                    x_mm: x,
                },
                lines: (0..30)
                    .map(|j| LinePeak {
                        reject: (!(5..25).contains(&j)).then_some(Reject::BelowThreshold),
                        col: 1.0,
                        ..LinePeak::NONE
                    })
                    .collect(),
                points: (0..30)
                    .map(|j| match j {
                        5..25 => P3::new(x, j as f64, x / 100.0),
                        _ => P3::from([f64::NAN; 3]),
                    })
                    .collect(),
            });
        }
        g
    }

    #[test]
    fn small_gaps_are_bridged_wide_ones_not() {
        // 0, 0.5, [1.0, 1.5 lost], 2.0, 2.5, [3 .. 22.5 lost], 23.0
        let mut g = grid(&[0.0, 0.5, 2.0, 2.5, 23.0]);
        let q = bridge_gaps(&mut g, 0.5, 3.0);
        assert_eq!(q.bridged_frames, 2);
        assert_eq!(q.largest_gap_mm, 20.5);
        assert_eq!(q.unbridged_gaps_mm, vec![[2.5, 23.0]]);
        let xs: Vec<f64> = g.frames.iter().map(|f| f.x_mm).collect();
        assert_eq!(xs, [0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 23.0]);
        assert_eq!(g.frames[2].seq, BRIDGED_SEQ);
        assert_eq!(g.frames[6].index, 6);
        assert!((g.point(3, 7)[2] - 0.015).abs() < 1e-12);
        assert_eq!(g.valid_count(), 7 * 20);
    }

    #[test]
    fn doubtful_measurements_make_a_scan_complete_with_warnings() {
        let cfg = QualitySection::default();
        let g = grid(&[0.0, 0.5, 1.0, 1.5, 2.0]);
        let mut q = Quality::default();
        inspect(&g, &mut q);
        q.cut.clear();
        let (s, _) = judge(&mut q.clone(), &cfg, 5, true);
        assert_eq!(s, ScanStatus::Complete);
        q.measure_warnings = vec!["the first metatarsal head is at 41 % of the length".into()];
        let (s, r) = judge(&mut q.clone(), &cfg, 5, true);
        assert_eq!(s, ScanStatus::CompleteWithWarnings);
        assert_eq!(
            r.as_deref(),
            Some("measurements to check: the first metatarsal head is at 41 % of the length")
        );
        // A partial scan by design: noted only.
        let partial = QualitySection {
            whole_foot: false,
            ..cfg
        };
        let (s, r) = judge(&mut q, &partial, 5, true);
        assert_eq!(s, ScanStatus::Complete, "{r:?}");
    }

    #[test]
    fn the_verdict_names_the_worst_issue_first() {
        let cfg = QualitySection::default();
        let mut g = grid(&[0.0, 0.5, 2.0, 2.5, 3.0]);
        let mut q = bridge_gaps(&mut g, 0.5, 3.0);
        inspect(&g, &mut q);
        q.dropped_frames = 3;
        // The foot fills the scan: cut at both ends, a rescan when a foot was measured.
        let (s, r) = judge(&mut q.clone(), &cfg, 5, true);
        assert_eq!(s, ScanStatus::Rescan);
        assert!(r.unwrap().starts_with("the foot runs past the start"));
        // No foot measured (a last bottom): a rescan only when the object must be whole.
        let (s, _) = judge(&mut q.clone(), &cfg, 5, false);
        assert_ne!(s, ScanStatus::Rescan);
        let whole = QualitySection {
            whole_object: true,
            ..cfg.clone()
        };
        let (s, r) = judge(&mut q.clone(), &whole, 5, false);
        assert_eq!(s, ScanStatus::Rescan);
        assert!(r.unwrap().starts_with("the object runs past the start"));
        // A partial scan: noted; the bridged gap (3 of 8 frames, 1.5 mm) is the warning.
        let partial = QualitySection {
            whole_foot: false,
            ..cfg.clone()
        };
        let (s, r) = judge(&mut q.clone(), &partial, 5, true);
        assert_eq!(s, ScanStatus::CompleteWithWarnings);
        assert!(r
            .unwrap()
            .starts_with("3 frames dropped, largest gap 1.5 mm, bridged"),);
        q.side = Some(SideCheck {
            chosen: Some("left".into()),
            detected: "right".into(),
        });
        let (s, r) = judge(&mut q, &partial, 5, true);
        assert_eq!(s, ScanStatus::SideMismatch);
        assert!(r
            .unwrap()
            .starts_with("side mismatch: chose left, scan looks right"));
        assert_eq!(verdict(ScanStatus::Rescan, Some("x")), "failed: rescan: x");
        for st in ScanStatus::ALL {
            let json = serde_json::to_string(&st).unwrap();
            assert_eq!(json, format!("\"{}\"", st.as_str()));
            assert_eq!(serde_json::from_str::<ScanStatus>(&json).unwrap(), st);
        }
    }
}
