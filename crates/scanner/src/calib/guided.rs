//! The guided in-system calibration: one procedure for every backend.
//!
//! The plan becomes a list of [`Step`]s (the plate on each set of spacers, the staircase
//! gauge, the empty glass). For each step the rig's operator puts the target on the glass (a
//! person on hardware, the simulator's scene swap), a [`Guide`] asks for confirmation (the
//! console, the daemon's HTTP job, or nobody with `--yes`), the step is acquired through the
//! rig, and what the frames show is checked before the procedure moves on: a plate is a flat
//! line at its stated height, every step of the staircase is there at its full width, nothing
//! stands on the empty glass. A failed check or a device fault ends the step with a message
//! saying what was expected and what was seen; the guide decides to repeat or abort it, and the
//! steps already taken are kept.
//!
//! Heights in the checks come from a check model: the scanner's earlier calibration if it has
//! one, else the plan's nominal design values. They are taken relative to the first plate (the
//! matte sheet on the glass), which cancels the check model's offset; the allowance grows with
//! the height because its scale may be a few percent off.

pub use super::acquire::check_controller;
use super::acquire::{average_frames, CalibrationRig, Target};
use super::data::{InsystemData, PlateObservation, StairFrame};
use super::plan::{CalibrationPlan, StepChecks};
use super::{CalibError, CameraModel, Triangulator};
use crate::detect::{Detector, LinePeak};
use footscan_geom::P3;
use footscan_targets::StaircaseGeometry;
use serde::Serialize;

/// What one step acquires.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum StepKind {
    /// The plate on spacers of this height (0: a matte sheet on the glass).
    Plate { height_mm: f64 },
    /// The staircase gauge block over the pass.
    Staircase,
    /// The empty platform.
    Glass,
}

/// One step of the procedure, as the operator is shown it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Step {
    /// 0-based position in the procedure.
    pub index: usize,
    /// Steps in the procedure.
    pub of: usize,
    #[serde(flatten)]
    pub kind: StepKind,
    /// Short name ("plate at 14 mm").
    pub title: String,
    /// What to put on the glass, and how.
    pub instruction: String,
    /// Slider positions (controller mm) and frames taken at each.
    pub positions_mm: Vec<f64>,
    pub frames_per_position: usize,
}

impl Step {
    /// What the rig's operator is asked to place.
    pub fn target(&self) -> Target {
        match self.kind {
            StepKind::Plate { height_mm } => Target::Plate { height_mm },
            StepKind::Staircase => Target::Staircase,
            StepKind::Glass => Target::Empty,
        }
    }

    /// Frames the step takes.
    pub fn frames(&self) -> usize {
        self.positions_mm.len() * self.frames_per_position
    }
}

/// The steps of `plan`: each plate height, the staircase pass, the glass pass.
pub fn steps(plan: &CalibrationPlan) -> Vec<Step> {
    let mut out = Vec::new();
    for &h in &plan.plate_heights_mm {
        let instruction = if h == 0.0 {
            "Lay the matte sheet flat on the glass (no spacers), across the whole width where \
             the laser line falls."
                .to_string()
        } else {
            format!(
                "Put the plate on the {h} mm spacers, flat, across the whole width of the glass \
                 where the laser line falls."
            )
        };
        out.push((
            StepKind::Plate { height_mm: h },
            format!("plate at {h} mm"),
            instruction,
            vec![plan.plate_x_mm],
            plan.frames_per_height,
        ));
    }
    out.push((
        StepKind::Staircase,
        "staircase gauge".into(),
        staircase_instruction(&plan.staircase, plan.stair_start_mm, plan.stair_end_mm),
        plan.stair_positions(),
        1,
    ));
    if !plan.glass_positions_mm.is_empty() {
        out.push((
            StepKind::Glass,
            "empty platform".into(),
            "Take everything off the glass.".into(),
            plan.glass_positions_mm.clone(),
            plan.glass_frames,
        ));
    }
    let of = out.len();
    out.into_iter()
        .enumerate()
        .map(
            |(index, (kind, title, instruction, positions_mm, frames_per_position))| Step {
                index,
                of,
                kind,
                title,
                instruction,
                positions_mm,
                frames_per_position,
            },
        )
        .collect()
}

/// Where the staircase goes for a pass over `start..end` (controller mm).
pub fn staircase_instruction(g: &StaircaseGeometry, start: f64, end: f64) -> String {
    format!(
        "Take the plate off and put the staircase gauge block ({} steps, {:.0} mm long, {} mm \
         wide) on the glass along the slider, between x = {start} and {end} mm of the pass and \
         across the middle of the glass, so that its whole width is in view.",
        g.heights_mm.len(),
        g.length(),
        g.width_mm
    )
}

/// The operator's answer when a step is shown.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Ready {
    /// The target is in place: acquire.
    Go,
    Abort,
}

/// The operator's answer once a step has been acquired and checked.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Decision {
    /// Keep the step and go on (honoured only when its check passed).
    Accept,
    Repeat,
    Abort,
}

/// What a step saw, checked against what it expected.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Seen {
    pub passed: bool,
    pub expected: String,
    pub seen: String,
    /// Why the check failed and what to do, when it did.
    pub problem: Option<String>,
}

/// How a step ended.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum StepResult {
    Checked(Seen),
    /// A camera or slider fault ended the step; the steps taken before are kept.
    Fault {
        reason: String,
    },
}

impl StepResult {
    pub fn passed(&self) -> bool {
        matches!(self, StepResult::Checked(s) if s.passed)
    }

    /// One line: what was expected and what was seen, or the fault.
    pub fn message(&self) -> String {
        match self {
            StepResult::Checked(s) => match &s.problem {
                None => format!("saw {}", s.seen),
                Some(p) => format!("expected {}; saw {}: {p}", s.expected, s.seen),
            },
            StepResult::Fault { reason } => format!("the step ended with a fault: {reason}"),
        }
    }
}

/// Whoever confirms the steps: the console, the daemon's HTTP job, or a script.
pub trait Guide {
    /// Show `step` (`attempt` counts from 1) and wait until the operator says the target is
    /// in place.
    fn ready(&mut self, step: &Step, attempt: usize) -> Result<Ready, CalibError>;
    /// Frames taken so far in the step.
    fn progress(&mut self, _step: &Step, _done: usize, _total: usize) {}
    /// What the step saw; the answer decides whether it is kept, repeated or the procedure
    /// aborted. A failed check is never kept, whatever the answer.
    fn review(&mut self, step: &Step, result: &StepResult) -> Result<Decision, CalibError>;
}

/// Confirms every step and keeps every passing one; a failing step is repeated until it has
/// been tried `max_attempts` times, then the procedure aborts with its message. For scripts
/// (`--yes`) and the simulator's own operator.
pub struct AutoGuide<'a> {
    pub max_attempts: usize,
    /// Every step's result, in order (repeats included).
    pub log: Vec<(Step, StepResult)>,
    pub on_event: Option<crate::calib::acquire::Progress<'a>>,
}

impl<'a> AutoGuide<'a> {
    pub fn new(max_attempts: usize) -> Self {
        AutoGuide {
            max_attempts: max_attempts.max(1),
            log: Vec::new(),
            on_event: None,
        }
    }
}

impl Guide for AutoGuide<'_> {
    fn ready(&mut self, _step: &Step, _attempt: usize) -> Result<Ready, CalibError> {
        Ok(Ready::Go)
    }

    fn progress(&mut self, step: &Step, done: usize, total: usize) {
        if let Some(p) = &mut self.on_event {
            p(&step.title, done, total);
        }
    }

    fn review(&mut self, step: &Step, result: &StepResult) -> Result<Decision, CalibError> {
        self.log.push((step.clone(), result.clone()));
        let attempts = self
            .log
            .iter()
            .filter(|(s, _)| s.index == step.index)
            .count();
        Ok(if result.passed() {
            Decision::Accept
        } else if attempts < self.max_attempts {
            Decision::Repeat
        } else {
            Decision::Abort
        })
    }
}

/// The model the checks triangulate with, and heights relative to the first plate.
pub struct CheckModel {
    tri: Triangulator,
    /// True when the model is the plan's nominal design (no earlier calibration).
    pub nominal: bool,
    /// Per row: (check model's height of the reference line, stated reference height).
    reference: Option<(Vec<f64>, f64)>,
    median_offset: f64,
}

impl CheckModel {
    pub fn new(model: &CameraModel, nominal: bool) -> Self {
        CheckModel {
            tri: model.triangulator(),
            nominal,
            reference: None,
            median_offset: 0.0,
        }
    }

    /// Heights from now on are relative to this line, seen at `height_mm`.
    fn set_reference(&mut self, plate: &PlateObservation, x_mm: f64) {
        let z: Vec<f64> = (0..plate.col.len())
            .map(|r| {
                self.abs_point(x_mm, plate.col[r], r)
                    .map_or(f64::NAN, |p| p[2])
            })
            .collect();
        let mut off: Vec<f64> = z
            .iter()
            .filter(|v| v.is_finite())
            .map(|v| v - plate.height_mm)
            .collect();
        self.median_offset = median(&mut off).unwrap_or(0.0);
        self.reference = Some((z, plate.height_mm));
    }

    fn abs_point(&self, x_mm: f64, col: f64, row: usize) -> Option<P3> {
        if !col.is_finite() {
            return None;
        }
        self.tri.point(x_mm, col, row as f64)
    }

    /// The point seen at (`col`, `row`), its height relative to the reference when there is one.
    pub fn point(&self, x_mm: f64, col: f64, row: usize) -> Option<P3> {
        let mut p = self.abs_point(x_mm, col, row)?;
        if let Some((z, h0)) = &self.reference {
            let off = z
                .get(row)
                .filter(|v| v.is_finite())
                .map_or(self.median_offset, |v| v - h0);
            p.z -= off;
        }
        Some(p)
    }

    /// y of the image's first and last row at the glass (the field across the slider).
    pub fn field_y(&self, height: u32) -> (f64, f64) {
        let m = self.tri.model();
        let y = |r: f64| {
            self.tri
                .point(0.0, m.cx + m.f_px * m.l_mm / m.d_mm, r)
                .map_or(f64::NAN, |p| p[1])
        };
        let (a, b) = (y(0.0), y(height as f64 - 1.0));
        (a.min(b), a.max(b))
    }
}

fn median(v: &mut [f64]) -> Option<f64> {
    percentile(v, 0.5)
}

/// The `q` quantile of the finite values (sorted in place).
fn percentile(v: &mut [f64], q: f64) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    Some(v[k])
}

/// The allowance for a height `h` stated above the reference `h0`.
fn tolerance(c: &StepChecks, h: f64, h0: f64) -> f64 {
    c.height_mm + c.height_rel * (h - h0).abs()
}

/// Check a plate seen at `x_mm`: found in enough rows, flat, at its height.
pub fn check_plate(
    plate: &PlateObservation,
    x_mm: f64,
    model: &CheckModel,
    checks: &StepChecks,
) -> Seen {
    let h = plate.height_mm;
    let rows = plate.col.len();
    let (h0, first) = match &model.reference {
        Some((_, h0)) => (*h0, false),
        None => (h, true),
    };
    let tol = if first && model.nominal {
        checks.nominal_offset_mm
    } else {
        tolerance(checks, h, h0)
    };
    let expected = format!(
        "a flat line at {h} mm (within {tol:.2} mm) in at least {:.0} % of the {rows} rows",
        100.0 * checks.min_rows_fraction
    );
    let rz: Vec<(f64, f64)> = (0..rows)
        .filter_map(|r| model.point(x_mm, plate.col[r], r).map(|p| (r as f64, p[2])))
        .collect();
    let mut z: Vec<f64> = rz.iter().map(|p| p.1).collect();
    let found = z.len();
    let fail = |seen: String, problem: String| Seen {
        passed: false,
        expected: expected.clone(),
        seen,
        problem: Some(problem),
    };
    if found == 0 {
        return fail(
            "no laser line in any row".into(),
            "is anything on the glass? Put the plate in place (and check that the laser is on)"
                .into(),
        );
    }
    let lo = percentile(&mut z, 0.05).unwrap_or(f64::NAN);
    let hi = percentile(&mut z, 0.95).unwrap_or(f64::NAN);
    let mid = median(&mut z).unwrap_or(f64::NAN);
    // The first plate is the reference: its heights through the check model still carry the
    // model's own errors (lens distortion the design values lack), smooth along the line, so
    // its flatness is its departure from a smooth curve. Later plates are relative to it.
    let spread = if first {
        let mut res = smooth_residuals(&rz, rows as f64);
        percentile(&mut res, 0.95).unwrap_or(f64::NAN)
            - percentile(&mut res, 0.05).unwrap_or(f64::NAN)
    } else {
        hi - lo
    };
    let seen =
        format!("a line at {mid:.2} mm in {found} of {rows} rows (heights {lo:.2} to {hi:.2} mm)");
    if (found as f64) < checks.min_rows_fraction * rows as f64 {
        return fail(
            seen,
            format!(
                "the line covers only {:.0} % of the rows: the plate must lie across the whole \
                 width of the glass under the laser line",
                100.0 * found as f64 / rows as f64
            ),
        );
    }
    if spread.is_nan() || spread > checks.flat_mm {
        return fail(
            seen,
            format!(
                "not flat: its heights spread over {spread:.2} mm (allowed {} mm): is it \
                 resting on all its spacers, and is nothing else in the line?",
                checks.flat_mm
            ),
        );
    }
    if (mid - h).abs() > tol {
        let why = if first && model.nominal {
            "the first plate lies on the glass itself (no spacers)".to_string()
        } else {
            let rel = if first { h } else { h0 };
            format!(
                "heights are measured from the first plate ({rel} mm); check the spacers: \
                 these are {:+.2} mm off",
                mid - h
            )
        };
        return fail(
            seen,
            format!("the plate is at {mid:.2} mm, not {h} mm: {why}"),
        );
    }
    Seen {
        passed: true,
        expected,
        seen,
        problem: None,
    }
}

/// Residuals of `(row, z)` from a quartic in the row (rows scaled to [-1, 1] over `rows`).
fn smooth_residuals(rz: &[(f64, f64)], rows: f64) -> Vec<f64> {
    const N: usize = 5;
    let t = |r: f64| 2.0 * r / rows.max(1.0) - 1.0;
    let a = nalgebra::DMatrix::from_fn(rz.len(), N, |i, k| t(rz[i].0).powi(k as i32));
    let b = nalgebra::DVector::from_iterator(rz.len(), rz.iter().map(|p| p.1));
    let Ok(c) = a.clone().svd(true, true).solve(&b, 1e-12) else {
        return rz.iter().map(|p| p.1).collect();
    };
    (a * c - b).iter().copied().collect()
}

/// What the staircase pass showed, step by step.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StairSeen {
    /// Points found near each step's stated height.
    pub points: Vec<usize>,
    /// The block's widest cross-section seen on each step (mm; NaN for steps at the glass or
    /// not seen).
    pub width_mm: Vec<f64>,
}

/// Steps with at least this many points count as seen.
const MIN_STEP_POINTS: usize = 30;

/// Check the staircase pass: every step present, the whole width in view.
pub fn check_staircase(
    frames: &[StairFrame],
    g: &StaircaseGeometry,
    model: &CheckModel,
    checks: &StepChecks,
    height: u32,
) -> (Seen, StairSeen) {
    let h0 = model.reference.as_ref().map_or(0.0, |r| r.1);
    let n = g.heights_mm.len();
    let mut points = vec![0usize; n];
    let mut width = vec![f64::NAN; n];
    let mut any = 0usize;
    let mut others: Vec<f64> = Vec::new();
    for f in frames {
        let mut ys: Vec<(f64, f64)> = vec![(f64::INFINITY, f64::NEG_INFINITY); n];
        for (r, &c) in f.col.iter().enumerate() {
            let Some(p) = model.point(f.x_mm, c, r) else {
                continue;
            };
            any += 1;
            let j = (0..n)
                .filter(|&j| {
                    (p[2] - g.heights_mm[j]).abs() <= tolerance(checks, g.heights_mm[j], h0)
                })
                .min_by(|&a, &b| {
                    (p[2] - g.heights_mm[a])
                        .abs()
                        .total_cmp(&(p[2] - g.heights_mm[b]).abs())
                });
            match j {
                Some(j) => {
                    points[j] += 1;
                    ys[j].0 = ys[j].0.min(p[1]);
                    ys[j].1 = ys[j].1.max(p[1]);
                }
                None => others.push(p[2]),
            }
        }
        for j in 0..n {
            if g.heights_mm[j] > checks.empty_mm && ys[j].1 > ys[j].0 {
                let w = ys[j].1 - ys[j].0;
                if width[j].is_nan() || width[j] < w {
                    width[j] = w;
                }
            }
        }
    }
    let list = |v: &[f64]| {
        v.iter()
            .map(|h| format!("{h}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let (a, b) = (
        frames.first().map_or(0.0, |f| f.x_mm),
        frames.last().map_or(0.0, |f| f.x_mm),
    );
    let expected = format!(
        "the staircase's steps at {} mm, {} mm wide, over the pass x {a:.1}..{b:.1} mm",
        list(&g.heights_mm),
        g.width_mm
    );
    let seen_steps: Vec<f64> = (0..n)
        .filter(|&j| points[j] >= MIN_STEP_POINTS)
        .map(|j| g.heights_mm[j])
        .collect();
    let missing: Vec<f64> = (0..n)
        .filter(|&j| points[j] < MIN_STEP_POINTS)
        .map(|j| g.heights_mm[j])
        .collect();
    let widest = width
        .iter()
        .copied()
        .filter(|w| w.is_finite())
        .fold(f64::NAN, f64::max);
    let seen = if any == 0 {
        "no laser line in any frame".to_string()
    } else {
        let mut s = format!("steps at {} mm", list(&seen_steps));
        if widest.is_finite() {
            s += &format!(", at most {widest:.1} mm wide");
        }
        if !others.is_empty() {
            let lo = percentile(&mut others, 0.0).unwrap_or(f64::NAN);
            let hi = percentile(&mut others, 1.0).unwrap_or(f64::NAN);
            s += &format!(
                "; {} points at no step's height ({lo:.1} to {hi:.1} mm)",
                others.len()
            );
        }
        s
    };
    let stair = StairSeen {
        points: points.clone(),
        width_mm: width.clone(),
    };
    let (y0, y1) = model.field_y(height);
    let fail = |problem: String| Seen {
        passed: false,
        expected: expected.clone(),
        seen: seen.clone(),
        problem: Some(problem),
    };
    if any == 0 {
        return (
            fail("is anything on the glass? Put the staircase gauge block in place".into()),
            stair,
        );
    }
    if seen_steps.iter().all(|&h| h <= checks.empty_mm) {
        return (
            fail(format!(
                "none of the raised steps is in view: the block must stand inside the pass x \
                 {a:.0}..{b:.0} mm and across y {y0:.0}..{y1:.0} mm at the glass"
            )),
            stair,
        );
    }
    if !missing.is_empty() {
        return (
            fail(format!(
                "steps at {} mm are missing: the block is partly outside the field; it must \
                 stand inside the pass x {a:.0}..{b:.0} mm and across y {y0:.0}..{y1:.0} mm",
                list(&missing)
            )),
            stair,
        );
    }
    if widest.is_finite() && widest < g.width_mm - checks.width_mm {
        return (
            fail(format!(
                "the block is seen {widest:.1} mm wide, its drawing says {} mm: it sticks out of \
                 the camera's field (y {y0:.0}..{y1:.0} mm at the glass); move it towards the \
                 middle",
                g.width_mm
            )),
            stair,
        );
    }
    (
        Seen {
            passed: true,
            expected,
            seen,
            problem: None,
        },
        stair,
    )
}

/// Check the empty platform: no line above the glass.
pub fn check_glass(frames: &[StairFrame], model: &CheckModel, checks: &StepChecks) -> Seen {
    let expected = format!(
        "an empty platform: no line more than {} mm above the glass",
        checks.empty_mm
    );
    let (mut above, mut at_glass, mut top, mut top_x) = (0usize, 0usize, f64::NEG_INFINITY, 0.0);
    for f in frames {
        for (r, &c) in f.col.iter().enumerate() {
            if let Some(p) = model.point(f.x_mm, c, r) {
                if p[2] > checks.empty_mm {
                    above += 1;
                    if p[2] > top {
                        top = p[2];
                        top_x = f.x_mm;
                    }
                } else {
                    at_glass += 1;
                }
            }
        }
    }
    if above > 0 {
        return Seen {
            passed: false,
            expected,
            seen: format!(
                "a line up to {top:.1} mm above the glass in {above} rows (highest with the head \
                 at x = {top_x:.0} mm)"
            ),
            problem: Some("something is still on the glass: take everything off".into()),
        };
    }
    Seen {
        passed: true,
        expected,
        seen: if at_glass == 0 {
            "no line".into()
        } else {
            format!("only the glass ({at_glass} rows at its height)")
        },
        problem: None,
    }
}

/// What one step took.
#[derive(Clone, Debug)]
pub enum StepData {
    Plate(PlateObservation),
    Frames(Vec<StairFrame>),
}

/// One kept step, for the calibration's record.
#[derive(Clone, Debug, Serialize)]
pub struct StepRecord {
    pub index: usize,
    pub title: String,
    pub attempts: usize,
    pub seen: String,
}

/// The guided procedure's result: the fit's data and what each step saw.
#[derive(Clone, Debug)]
pub struct GuidedData {
    pub data: InsystemData,
    pub steps: Vec<StepRecord>,
}

/// Acquire one step through `rig`.
fn acquire_step(
    rig: &mut dyn CalibrationRig,
    step: &Step,
    detector: &mut dyn Detector,
    guide: &mut dyn Guide,
    size: &mut (u32, u32),
) -> Result<StepData, CalibError> {
    let total = step.frames();
    let mut lines: Vec<LinePeak> = Vec::new();
    let mut done = 0usize;
    let mut detect = |f: &footscan_hal::Frame| -> Vec<f64> {
        *size = (f.width, f.height);
        lines.clear();
        lines.resize(f.height as usize, LinePeak::NONE);
        detector.detect(f, &mut lines);
        lines
            .iter()
            .map(|l| if l.is_valid() { l.col } else { f64::NAN })
            .collect()
    };
    guide.progress(step, 0, total);
    match step.kind {
        StepKind::Plate { height_mm } => {
            let mut per_frame = Vec::new();
            rig.capture(step.positions_mm[0], step.frames_per_position, &mut |f| {
                per_frame.push(detect(f));
            })?;
            guide.progress(step, total, total);
            Ok(StepData::Plate(average_frames(height_mm, &per_frame)))
        }
        StepKind::Staircase | StepKind::Glass => {
            let mut frames = Vec::new();
            for &x in &step.positions_mm {
                let mut cols = Vec::new();
                let reported = rig.capture(x, step.frames_per_position, &mut |f| {
                    cols.push(detect(f));
                })?;
                for col in cols {
                    frames.push(StairFrame {
                        x_mm: reported,
                        col,
                    });
                }
                done += step.frames_per_position;
                guide.progress(step, done, total);
            }
            Ok(StepData::Frames(frames))
        }
    }
}

/// The data of each kept step (in order), their records, and the frame size.
pub type StepsTaken = (Vec<StepData>, Vec<StepRecord>, (u32, u32));

/// Everything a guided run needs besides the rig and the guide.
pub struct GuidedRun<'a> {
    pub plan: &'a CalibrationPlan,
    /// The scanner's earlier calibration (the check model), if any.
    pub prior: Option<&'a CameraModel>,
    pub detector: &'a mut dyn Detector,
}

/// Run `steps` through `rig`, each confirmed and reviewed by `guide`; returns each step's
/// data (in order). Plates set the check model's reference (the first one) as they are kept.
pub fn run_steps(
    rig: &mut dyn CalibrationRig,
    steps: &[Step],
    run: &mut GuidedRun,
    check: &mut Option<CheckModel>,
    guide: &mut dyn Guide,
) -> Result<StepsTaken, CalibError> {
    let positions: Vec<f64> = steps
        .iter()
        .flat_map(|s| s.positions_mm.iter().copied())
        .collect();
    rig.check_moves(&positions)?;
    let mut size = (0u32, 0u32);
    let mut kept = Vec::new();
    let mut records = Vec::new();
    for step in steps {
        let mut attempt = 0;
        loop {
            attempt += 1;
            rig.place(&step.target())?;
            if guide.ready(step, attempt)? == Ready::Abort {
                return Err(CalibError::Aborted {
                    step: step.index + 1,
                    title: step.title.clone(),
                    reason: "the operator aborted".into(),
                });
            }
            let (result, data) = match acquire_step(rig, step, &mut *run.detector, guide, &mut size)
            {
                Ok(d) => {
                    let m = check.get_or_insert_with(|| match run.prior {
                        Some(p) => CheckModel::new(p, false),
                        None => CheckModel::new(&run.plan.nominal.model(size.0, size.1), true),
                    });
                    let c = &run.plan.checks;
                    let seen = match (&step.kind, &d) {
                        (StepKind::Plate { .. }, StepData::Plate(p)) => {
                            check_plate(p, step.positions_mm[0], m, c)
                        }
                        (StepKind::Staircase, StepData::Frames(f)) => {
                            check_staircase(f, &run.plan.staircase, m, c, size.1).0
                        }
                        (StepKind::Glass, StepData::Frames(f)) => check_glass(f, m, c),
                        _ => unreachable!("acquire_step returns the step's kind of data"),
                    };
                    (StepResult::Checked(seen), Some(d))
                }
                Err(CalibError::Device(e)) => (
                    StepResult::Fault {
                        reason: footscan_util::chain(&e),
                    },
                    None,
                ),
                Err(e) => return Err(e),
            };
            let decision = guide.review(step, &result)?;
            match (decision, data) {
                (Decision::Accept, Some(d)) if result.passed() => {
                    if let (StepData::Plate(p), Some(m)) = (&d, check.as_mut()) {
                        if m.reference.is_none() {
                            m.set_reference(p, step.positions_mm[0]);
                        }
                    }
                    records.push(StepRecord {
                        index: step.index,
                        title: step.title.clone(),
                        attempts: attempt,
                        seen: match &result {
                            StepResult::Checked(s) => s.seen.clone(),
                            StepResult::Fault { reason } => reason.clone(),
                        },
                    });
                    kept.push(d);
                    break;
                }
                (Decision::Abort, _) => {
                    return Err(CalibError::Aborted {
                        step: step.index + 1,
                        title: step.title.clone(),
                        reason: result.message(),
                    })
                }
                _ => {
                    if matches!(result, StepResult::Fault { .. }) {
                        rig.recover()?;
                    }
                }
            }
        }
    }
    Ok((kept, records, size))
}

/// The whole guided in-system acquisition: every step of `run.plan`, then the fit's data.
pub fn acquire_guided(
    rig: &mut dyn CalibrationRig,
    run: &mut GuidedRun,
    guide: &mut dyn Guide,
) -> Result<GuidedData, CalibError> {
    run.plan.validate()?;
    run.plan.check_insystem()?;
    let steps = steps(run.plan);
    let mut check = None;
    let (kept, records, size) = run_steps(rig, &steps, run, &mut check, guide)?;
    let mut plates = Vec::new();
    let mut stair = Vec::new();
    for (step, d) in steps.iter().zip(kept) {
        match (&step.kind, d) {
            (StepKind::Plate { .. }, StepData::Plate(p)) => plates.push(p),
            (StepKind::Staircase, StepData::Frames(f)) => stair = f,
            _ => {}
        }
    }
    Ok(GuidedData {
        data: InsystemData {
            width: size.0,
            height: size.1,
            plates,
            stair,
            staircase: run.plan.staircase.clone(),
        },
        steps: records,
    })
}
