//! The daily check: a short pass over the staircase gauge measured with the current
//! calibration, each step's height error against the gauge's stated heights and the block's
//! width against its stated width (the y scale), pass or fail against a tolerance.
//!
//! Heights: every row whose point lies within [`ASSIGN_MM`] of a step's stated height counts
//! for that step; the step's error is the median of (measured − stated), which ignores the rows
//! on a riser. Width: on each frame whose line crosses a raised step from side to side, the
//! step's first and last rows; lines fitted to them over the pass give the block's yaw, and
//! their distance across plus one row spacing (each end row lies half a row inside its side on
//! average) is the width. The width is coarser than the heights: the detector also loses about
//! a row at each end of the line (its along-line smoothing), so the simulator's true
//! calibration measures the 60 mm block 0.27 mm narrow; it is judged against its own, wider
//! tolerance (`calibration.verify_width_tolerance_mm`).

use super::data::StairFrame;
use super::Calibration;
use footscan_geom::P3;
use footscan_targets::StaircaseGeometry;
use serde::{Deserialize, Serialize};

/// A row's point belongs to the step whose stated height is nearest, within this (mm).
pub const ASSIGN_MM: f64 = 1.5;
/// Steps closer to the glass than this are not used for the width (the glass around the
/// block would merge with them).
const RAISED_MM: f64 = 2.0;

/// One step of the gauge.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct StepError {
    pub stated_mm: f64,
    /// Median of measured − stated (mm); NaN when the step was not seen.
    pub error_mm: f64,
    /// Spread of the measured heights (RMS about their median, mm).
    pub rms_mm: f64,
    pub points: usize,
    pub passed: bool,
}

/// A daily check's result.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CheckReport {
    pub date: String,
    /// The checked calibration's method and date.
    pub calibration: String,
    pub tolerance_mm: f64,
    pub width_tolerance_mm: f64,
    pub steps: Vec<StepError>,
    pub width_stated_mm: f64,
    pub width_mm: f64,
    /// width_mm / width_stated_mm.
    pub y_scale: f64,
    pub width_passed: bool,
    pub passed: bool,
    /// What failed, in words (empty when it passed).
    pub failures: Vec<String>,
}

/// Measure the gauge seen in `frames` with `cal` and judge it against `tolerance_mm`.
pub fn check(
    frames: &[StairFrame],
    g: &StaircaseGeometry,
    cal: &Calibration,
    tolerance_mm: f64,
    width_tolerance_mm: f64,
) -> CheckReport {
    let tri = cal.triangulator();
    let n = g.heights_mm.len();
    let mut z: Vec<Vec<f64>> = vec![Vec::new(); n];
    // Per raised step, per frame: (x, y of one side, y of the other, unused).
    let mut sides: Vec<(f64, f64, f64, f64)> = Vec::new();
    for f in frames {
        // Per row: the point and the step it belongs to (None: glass or nothing near a step).
        let pts: Vec<Option<(P3, Option<usize>)>> = f
            .col
            .iter()
            .enumerate()
            .map(|(r, &c)| {
                let p = c
                    .is_finite()
                    .then(|| tri.point(f.x_mm, c, r as f64))
                    .flatten()?;
                let j = (0..n)
                    .filter(|&j| (p[2] - g.heights_mm[j]).abs() <= ASSIGN_MM)
                    .min_by(|&a, &b| {
                        (p[2] - g.heights_mm[a])
                            .abs()
                            .total_cmp(&(p[2] - g.heights_mm[b]).abs())
                    });
                Some((p, j))
            })
            .collect();
        for (p, j) in pts.iter().flatten() {
            if let Some(j) = j {
                z[*j].push(p[2]);
            }
        }
        // The block's sides on this frame: the first and last rows of a raised step that the
        // line crosses from one side to the other (no line beyond: the glass shows none).
        for j in (0..n).filter(|&j| g.heights_mm[j] > RAISED_MM) {
            let rows: Vec<usize> = (0..pts.len())
                .filter(|&r| matches!(pts[r], Some((_, Some(k))) if k == j))
                .collect();
            let (Some(&r0), Some(&r1)) = (rows.first(), rows.last()) else {
                continue;
            };
            if r1 < r0 + 10 || rows.len() < (r1 - r0) * 9 / 10 {
                continue;
            }
            let (p0, p1) = (pts[r0].unwrap().0, pts[r1].unwrap().0);
            let spacing = (p1[1] - p0[1]) / (r1 - r0) as f64;
            sides.push((p0[0], p0[1], p1[1], spacing));
        }
    }
    let mut failures = Vec::new();
    let steps: Vec<StepError> = (0..n)
        .map(|j| {
            let h = g.heights_mm[j];
            let mut v = z[j].clone();
            v.sort_by(f64::total_cmp);
            let (error_mm, rms_mm) = if v.len() >= 20 {
                let med = v[v.len() / 2];
                let rms = (v.iter().map(|a| (a - med).powi(2)).sum::<f64>() / v.len() as f64)
                    .sqrt();
                (med - h, rms)
            } else {
                (f64::NAN, f64::NAN)
            };
            let passed = error_mm.abs() <= tolerance_mm;
            if !passed {
                failures.push(if error_mm.is_nan() {
                    format!("the step at {h} mm was not seen")
                } else {
                    format!(
                        "the step at {h} mm measures {:.3} mm ({error_mm:+.3} mm, tolerance {tolerance_mm} mm)",
                        h + error_mm
                    )
                });
            }
            StepError {
                stated_mm: h,
                error_mm,
                rms_mm,
                points: v.len(),
                passed,
            }
        })
        .collect();
    let width_mm = block_width(&sides);
    let width_passed = (width_mm - g.width_mm).abs() <= width_tolerance_mm;
    if !width_passed {
        failures.push(format!(
            "the block measures {width_mm:.3} mm across, its stated width is {} mm ({:+.3} mm, tolerance {width_tolerance_mm} mm, y scale {:.5})",
            g.width_mm,
            width_mm - g.width_mm,
            width_mm / g.width_mm
        ));
    }
    CheckReport {
        date: footscan_util::now_rfc3339(),
        calibration: format!("{} of {}", cal.method, cal.date),
        tolerance_mm,
        width_tolerance_mm,
        steps,
        width_stated_mm: g.width_mm,
        width_mm,
        y_scale: width_mm / g.width_mm,
        width_passed,
        passed: failures.is_empty(),
        failures,
    }
}

/// One frame's view of the block's sides: (x, y of one side, y of the other, row spacing).
type Side = (f64, f64, f64, f64);

/// The block's width from its sides seen on each frame: (x, y first, y last, row spacing).
fn block_width(all: &[(f64, f64, f64, f64)]) -> f64 {
    // Frames where the line crosses a riser see a step over part of the width only.
    let widest = all.iter().map(|s| s.2 - s.1).fold(0.0, f64::max);
    let sides: Vec<_> = all
        .iter()
        .copied()
        .filter(|s| s.2 - s.1 >= 0.9 * widest)
        .collect();
    if sides.len() < 3 {
        return f64::NAN;
    }
    let line = |pick: &dyn Fn(&Side) -> f64| -> (f64, f64) {
        let n = sides.len() as f64;
        let mx = sides.iter().map(|s| s.0).sum::<f64>() / n;
        let my = sides.iter().map(pick).sum::<f64>() / n;
        let sxx = sides.iter().map(|s| (s.0 - mx).powi(2)).sum::<f64>();
        let sxy = sides
            .iter()
            .map(|s| (s.0 - mx) * (pick(s) - my))
            .sum::<f64>();
        let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        (my - b * mx, b)
    };
    let (a0, b0) = line(&|s| s.1);
    let (a1, b1) = line(&|s| s.2);
    let n = sides.len() as f64;
    let mx = sides.iter().map(|s| s.0).sum::<f64>() / n;
    let spacing = sides.iter().map(|s| s.3).sum::<f64>() / n;
    let across = (a1 + b1 * mx) - (a0 + b0 * mx) + spacing;
    across * (0.5 * (b0 + b1)).atan().cos()
}
