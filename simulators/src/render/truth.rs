//! The exact per-row ground truth of a frame (the module doc of the renderer, "Ground truth"):
//! the laser plane's curve on the scene sampled along y, its jumps and ends found by
//! bisection and each row's crossing by Brent's method.

use super::root::brent;
use crate::optics::{Optics, Projector};
use crate::surface::Surface;
use serde::{Deserialize, Serialize};

const SAMPLE_STEP_MM: f64 = 0.1;

/// Ground truth of one row.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum RowTruth {
    NoLine,
    /// Exact column of the line at the row centre and the world point imaged there.
    Line {
        col: f64,
        point: [f64; 3],
    },
}

/// Ground truth of one frame.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct FrameTruth {
    /// Physical slider position the frame was rendered at.
    pub slider_x: f64,
    /// One entry per image row.
    pub rows: Vec<RowTruth>,
}

impl FrameTruth {
    /// Rows that have a line.
    pub fn line_count(&self) -> usize {
        self.rows
            .iter()
            .filter(|r| matches!(r, RowTruth::Line { .. }))
            .count()
    }
}

#[derive(Clone, Copy, Debug)]
struct Sample {
    y: f64,
    p: [f64; 3],
    col: f64,
    row: f64,
}

struct TruthCtx<'a> {
    proj: &'a Projector,
    surface: &'a dyn Surface,
    x: f64,
}

impl TruthCtx<'_> {
    #[inline]
    fn eval(&self, y: f64) -> Option<Sample> {
        let x0 = self.proj.laser_x(self.x, y, 0.0);
        let z = self.surface.plane_height(x0, self.proj.tan_b, y)?;
        let p = [x0 + self.proj.tan_b * z, y, z];
        let [col, row] = self.proj.project(self.x, p)?;
        Some(Sample { y, p, col, row })
    }
}

pub(super) fn compute_truth(
    proj: &Projector,
    optics: &Optics,
    surface: Option<&dyn Surface>,
    x: f64,
    truth: &mut FrameTruth,
) {
    let h = optics.height as usize;
    truth.slider_x = x;
    truth.rows.clear();
    truth.rows.resize(h, RowTruth::NoLine);
    let Some(surface) = surface else { return };
    let ctx = TruthCtx { proj, surface, x };
    // y range the rows can see (generous: distortion and tilts are small).
    let zmax = surface.max_height().max(0.0);
    let half_rows = optics.cy.max(optics.height as f64 - optics.cy) + 32.0;
    let reach = 1.3 * half_rows * (optics.d_mm + zmax) / optics.f_px + 5.0;
    let (b0, b1) = surface.y_bounds();
    let y0 = (-reach).max(b0 - SAMPLE_STEP_MM);
    let y1 = reach.min(b1 + SAMPLE_STEP_MM);
    if y1 <= y0 {
        return;
    }
    let n = ((y1 - y0) / SAMPLE_STEP_MM).ceil() as usize;
    let cam = proj.camera_centre(x);
    let mut prev: Option<Sample> = None;
    let mut prev_y = y0;
    for i in 0..=n {
        let y = y0 + (y1 - y0) * i as f64 / n as f64;
        let cur = ctx.eval(y);
        match (prev, cur) {
            (Some(a), Some(b)) if (b.p[2] - a.p[2]).abs() > JUMP_MM => {
                // Possibly a jump of the height field (a step): image each side separately.
                let (ea, eb) = jump(&ctx, a, b);
                if let Some(ea) = ea {
                    segment(&ctx, a, ea, cam, optics, truth);
                }
                if let Some(eb) = eb {
                    segment(&ctx, eb, b, cam, optics, truth);
                }
            }
            (Some(a), Some(b)) => segment(&ctx, a, b, cam, optics, truth),
            (Some(a), None) => {
                if let Some(e) = edge(&ctx, a.y, y) {
                    segment(&ctx, a, e, cam, optics, truth);
                }
            }
            (None, Some(b)) if i > 0 => {
                if let Some(e) = edge(&ctx, b.y, prev_y) {
                    segment(&ctx, e, b, cam, optics, truth);
                }
            }
            _ => {}
        }
        prev = cur;
        prev_y = y;
    }
}

/// Height change between two samples beyond which [`jump`] looks for a discontinuity.
const JUMP_MM: f64 = 0.5;

/// Where the height field jumps between samples `a` and `b` (a step of a staircase): the last
/// sample on `a`'s side and the first on `b`'s, by bisection to 1e-11 mm (a sample belongs to
/// the side whose height it is nearer). On a continuous steep stretch this splits it at a
/// point, which loses nothing. A gap with no surface in between ends at the gap's edges.
fn jump(ctx: &TruthCtx, a: Sample, b: Sample) -> (Option<Sample>, Option<Sample>) {
    let (mut lo, mut hi) = (a, b);
    while (hi.y - lo.y).abs() > 1e-11 {
        let mid = 0.5 * (lo.y + hi.y);
        match ctx.eval(mid) {
            Some(m) if (m.p[2] - a.p[2]).abs() <= (m.p[2] - b.p[2]).abs() => lo = m,
            Some(m) => hi = m,
            None => return (edge(ctx, lo.y, mid), edge(ctx, hi.y, mid)),
        }
    }
    (Some(lo), Some(hi))
}

/// The last valid sample between `valid_y` (valid) and `invalid_y` (invalid), by bisection.
fn edge(ctx: &TruthCtx, valid_y: f64, invalid_y: f64) -> Option<Sample> {
    let (mut good, mut bad) = (valid_y, invalid_y);
    let mut best = ctx.eval(good)?;
    while (bad - good).abs() > 1e-11 {
        let mid = 0.5 * (good + bad);
        match ctx.eval(mid) {
            Some(s) => {
                good = mid;
                best = s;
            }
            None => bad = mid,
        }
    }
    Some(best)
}

fn segment(
    ctx: &TruthCtx,
    a: Sample,
    b: Sample,
    cam: [f64; 3],
    optics: &Optics,
    truth: &mut FrameTruth,
) {
    let (lo, hi) = if a.row <= b.row {
        (a.row, b.row)
    } else {
        (b.row, a.row)
    };
    let r0 = lo.ceil().max(0.0);
    let r1 = hi.floor().min(optics.height as f64 - 1.0);
    let mut r = r0;
    while r <= r1 {
        let target = r;
        r += 1.0;
        let s = if a.row == target {
            Some(a)
        } else if b.row == target {
            Some(b)
        } else {
            brent(|y| ctx.eval(y), |s| s.row - target, (a.y, a), (b.y, b))
        };
        // Across a jump of the height field (a riser) row(y) is discontinuous: Brent then
        // closes in on the jump without a root, and that row has no crossing here.
        let Some(s) = s.filter(|s| (s.row - target).abs() < 1e-6) else {
            continue;
        };
        if s.col < -0.5 || s.col > optics.width as f64 - 0.5 {
            continue;
        }
        let d2 = dist2(s.p, cam);
        let slot = &mut truth.rows[target as usize];
        let better = match *slot {
            RowTruth::NoLine => true,
            RowTruth::Line { point, .. } => d2 < dist2(point, cam) - 1e-12,
        };
        if better {
            *slot = RowTruth::Line {
                col: s.col,
                point: s.p,
            };
        }
    }
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}
