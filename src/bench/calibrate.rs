//! `footscan bench calibrate`: every calibration method side by side on the default simulated
//! scanner: each recovered parameter against the simulator's truth, and the height error on a
//! held-out validation scan (a staircase whose steps lie between the calibration heights, and
//! the simulated foot).
//!
//! The validation height error is measured twice: `val_*` triangulates the exact line position
//! of every row (the calibration's own error, free of detection noise); `val_detected_*` runs
//! the calibration detector on the rendered noisy frames (what a scan would see).

use footscan::calib::{untilted_equivalent, CalibError, Calibration, CalibrationPlan};
use footscan::detect::LinePeak;
use footscan::scan::calibrate::{self as run, Method};
use footscan::scan::{sim, ScanConfig};
use footscan_hal::{Frame, Timestamp};
use footscan_sim::foot::Foot;
use footscan_sim::render::{Renderer, RowTruth, Scene};
use footscan_sim::targets::Staircase;
use footscan_targets::{Placement, StaircaseGeometry};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Instant;

/// One parameter against the truth.
#[derive(Clone, Debug, Serialize)]
pub struct ParamError {
    pub value: f64,
    pub truth: f64,
    /// |value - truth| / |truth|; null where the truth is 0.
    pub rel_error: Option<f64>,
    pub abs_error: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct MethodRow {
    pub method: String,
    pub params: BTreeMap<String, ParamError>,
    /// The method's model and the truth both reduced to their untilted equivalents
    /// ([`footscan::calib::untilted_equivalent`]): the parameters laser-line data determine.
    pub params_untilted: BTreeMap<String, ParamError>,
    /// Height error on the validation scans (staircase and foot), exact line positions.
    pub val_rms_mm: f64,
    pub val_max_mm: f64,
    pub val_staircase_rms_mm: f64,
    pub val_staircase_max_mm: f64,
    pub val_foot_rms_mm: f64,
    pub val_foot_max_mm: f64,
    /// The same with the detector on the noisy frames.
    pub val_detected_rms_mm: f64,
    pub val_detected_max_mm: f64,
    /// Points compared (exact / detected).
    pub val_points: usize,
    pub val_detected_points: usize,
    pub residuals: BTreeMap<String, f64>,
    pub stddev: BTreeMap<String, f64>,
    /// Acquisition and fit, seconds.
    pub seconds: f64,
    /// Why the method gave no calibration.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// How to run the benchmark.
#[derive(Clone, Debug)]
pub struct BenchOptions {
    pub methods: Vec<Method>,
    /// Acquire by rendering frames directly instead of through the real-time simulated devices.
    pub direct: bool,
}

/// The held-out staircase: steps half-way between the plan's plate heights.
pub fn validation_staircase() -> Staircase {
    Staircase::new(
        StaircaseGeometry {
            heights_mm: vec![3.5, 10.5, 17.5, 24.5, 31.5, 38.5],
            lengths_mm: vec![14.0; 6],
            width_mm: 60.0,
        },
        Placement {
            x_mm: 120.0,
            y_mm: -32.0,
            yaw_deg: -2.0,
        },
    )
    .expect("valid validation staircase")
}

/// One validation frame: slider position, true column and height per row, detected column.
struct ValFrame {
    x_mm: f64,
    truth: Vec<Option<(f64, f64)>>,
    detected: Vec<f64>,
}

fn validation_frames(
    cfg: &ScanConfig,
    scene: Scene,
    xs: &[f64],
    seed_offset: u64,
) -> Result<Vec<ValFrame>, CalibError> {
    let sim_cfg = &cfg.sim;
    let mut r = Renderer::new(
        sim_cfg.optics.clone(),
        sim_cfg.noise.clone(),
        scene,
        sim_cfg.seed + seed_offset,
    )
    .map_err(|e| CalibError::Sim(e.to_string()))?;
    let mut det = run::detector(run::DETECTOR)?;
    let scale = sim_cfg.slider.slider_scale;
    let (w, h) = (sim_cfg.optics.width, sim_cfg.optics.height);
    let mut lines = vec![LinePeak::NONE; h as usize];
    let mut out = Vec::new();
    for (k, &x) in xs.iter().enumerate() {
        let (px, t) = r.render(scale * x, k as u64);
        det.detect(
            &Frame::new(k as u64, Timestamp::default(), w, h, px),
            &mut lines,
        );
        out.push(ValFrame {
            x_mm: x,
            truth: t
                .rows
                .iter()
                .map(|rt| match rt {
                    RowTruth::Line { col, point } => Some((*col, point[2])),
                    RowTruth::NoLine => None,
                })
                .collect(),
            detected: lines
                .iter()
                .map(|l| if l.is_valid() { l.col } else { f64::NAN })
                .collect(),
        });
    }
    Ok(out)
}

#[derive(Default)]
struct Err2 {
    sum: f64,
    max: f64,
    n: usize,
}

impl Err2 {
    fn add(&mut self, e: f64) {
        self.sum += e * e;
        self.max = self.max.max(e.abs());
        self.n += 1;
    }
    /// Both sets of errors together.
    fn merged(&self, o: &Err2) -> Err2 {
        Err2 {
            sum: self.sum + o.sum,
            max: self.max.max(o.max),
            n: self.n + o.n,
        }
    }
    fn rms(&self) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            (self.sum / self.n as f64).sqrt()
        }
    }
}

/// Height errors of `cal` on the frames: (exact columns, detected columns).
fn height_errors(cal: &Calibration, frames: &[ValFrame]) -> (Err2, Err2) {
    let tri = cal.triangulator();
    let (mut exact, mut detected) = (Err2::default(), Err2::default());
    for f in frames {
        for (r, t) in f.truth.iter().enumerate() {
            let Some((col, z)) = *t else { continue };
            if let Some(p) = tri.point(f.x_mm, col, r as f64) {
                exact.add(p[2] - z);
            }
            let c = f.detected[r];
            if c.is_finite() {
                if let Some(p) = tri.point(f.x_mm, c, r as f64) {
                    detected.add(p[2] - z);
                }
            }
        }
    }
    (exact, detected)
}

/// The model's parameters, in the order the table prints them.
const MODEL_PARAMS: [&str; 15] = [
    "f_px",
    "cx",
    "cy",
    "d_mm",
    "l_mm",
    "k1",
    "k2",
    "p1",
    "p2",
    "camera_tilt_deg[0]",
    "camera_tilt_deg[1]",
    "camera_tilt_deg[2]",
    "laser_tilt_deg[0]",
    "laser_tilt_deg[1]",
    "slider_scale",
];

/// Every parameter of `cal` against `truth`.
pub fn compare_params(cal: &Calibration, truth: &Calibration) -> BTreeMap<String, ParamError> {
    let named = |c: &Calibration| {
        let m = &c.model;
        let values = [
            m.f_px,
            m.cx,
            m.cy,
            m.d_mm,
            m.l_mm,
            m.k1,
            m.k2,
            m.p1,
            m.p2,
            m.camera_tilt_deg[0],
            m.camera_tilt_deg[1],
            m.camera_tilt_deg[2],
            m.laser_tilt_deg[0],
            m.laser_tilt_deg[1],
            m.slider_scale,
        ];
        MODEL_PARAMS.into_iter().zip(values)
    };
    named(cal)
        .zip(named(truth))
        .map(|((k, v), (_, t))| {
            let abs_error = (v - t).abs();
            (
                k.to_string(),
                ParamError {
                    value: v,
                    truth: t,
                    rel_error: (t != 0.0).then(|| abs_error / t.abs()),
                    abs_error,
                },
            )
        })
        .collect()
}

/// Run the benchmark; `progress(what, done, total)`.
pub fn run(
    cfg: &ScanConfig,
    plan: &CalibrationPlan,
    opts: &BenchOptions,
    progress: &mut dyn FnMut(&str, usize, usize),
) -> Result<Vec<MethodRow>, CalibError> {
    let truth = sim::true_calibration(cfg);
    let truth_untilted = untilted_equivalent(&truth.model)
        .ok()
        .map(|(m, _)| Calibration {
            model: m,
            ..truth.clone()
        });
    // Validation scans, shared by every method.
    progress("validation scans", 0, 2);
    let stair_x: Vec<f64> = (0..=95).map(|i| 45.0 + i as f64).collect();
    let stairs = validation_frames(
        cfg,
        Scene::Surface(Arc::new(validation_staircase())),
        &stair_x,
        1000,
    )?;
    progress("validation scans", 1, 2);
    let foot = Foot::new(cfg.sim.foot.clone()).map_err(|e| CalibError::Sim(e.to_string()))?;
    let foot_x: Vec<f64> = (0..=160).map(|i| i as f64 * 2.0).collect();
    let feet = validation_frames(cfg, Scene::Foot(foot), &foot_x, 2000)?;
    // Calibrations.
    let mut outcomes: Vec<(Method, Result<Calibration, CalibError>, f64)> = Vec::new();
    let wants = |m: Method| opts.methods.contains(&m);
    if wants(Method::Insystem) || wants(Method::Bezier) {
        let t0 = Instant::now();
        let data = if opts.direct {
            let mut rig = run::render_rig(cfg, plan)?;
            run::acquire_insystem(&mut rig, plan, progress)
        } else {
            let mut sim = run::open_sim_rig(cfg, plan)?;
            run::acquire_insystem(&mut sim.rig, plan, progress)
        };
        let acquire_s = t0.elapsed().as_secs_f64();
        for m in [Method::Insystem, Method::Bezier] {
            if !wants(m) {
                continue;
            }
            let t = Instant::now();
            let r = match &data {
                Ok(d) => run::from_insystem(d, m, plan).map(|o| o.calibration),
                Err(e) => Err(CalibError::Plan(format!("acquisition failed: {e}"))),
            };
            outcomes.push((m, r, acquire_s + t.elapsed().as_secs_f64()));
        }
    }
    if wants(Method::Opencv) {
        let t = Instant::now();
        let r =
            run::calibrate_unattended(cfg, Method::Opencv, plan, progress).map(|o| o.calibration);
        outcomes.push((Method::Opencv, r, t.elapsed().as_secs_f64()));
    }
    let mut rows = Vec::new();
    for (m, r, seconds) in outcomes {
        progress("validation", rows.len(), opts.methods.len());
        let mut row = MethodRow {
            method: m.name().into(),
            params: BTreeMap::new(),
            params_untilted: BTreeMap::new(),
            val_rms_mm: f64::NAN,
            val_max_mm: f64::NAN,
            val_staircase_rms_mm: f64::NAN,
            val_staircase_max_mm: f64::NAN,
            val_foot_rms_mm: f64::NAN,
            val_foot_max_mm: f64::NAN,
            val_detected_rms_mm: f64::NAN,
            val_detected_max_mm: f64::NAN,
            val_points: 0,
            val_detected_points: 0,
            residuals: BTreeMap::new(),
            stddev: BTreeMap::new(),
            seconds,
            error: None,
        };
        match r {
            Err(e) => row.error = Some(e.to_string()),
            Ok(cal) => {
                row.params = compare_params(&cal, &truth);
                if let (Ok((em, _)), Some(et)) = (untilted_equivalent(&cal.model), &truth_untilted)
                {
                    let mut e = cal.clone();
                    e.model = em;
                    row.params_untilted = compare_params(&e, et);
                    row.params_untilted
                        .retain(|k, _| UNTILTED.contains(&k.as_str()));
                }
                let (se, sd) = height_errors(&cal, &stairs);
                let (fe, fd) = height_errors(&cal, &feet);
                row.val_staircase_rms_mm = se.rms();
                row.val_staircase_max_mm = se.max;
                row.val_foot_rms_mm = fe.rms();
                row.val_foot_max_mm = fe.max;
                let all = se.merged(&fe);
                row.val_rms_mm = all.rms();
                row.val_max_mm = all.max;
                row.val_points = all.n;
                let det = sd.merged(&fd);
                row.val_detected_rms_mm = det.rms();
                row.val_detected_max_mm = det.max;
                row.val_detected_points = det.n;
                row.residuals = cal.residuals.clone();
                row.stddev = cal.stddev.clone();
            }
        }
        rows.push(row);
    }
    Ok(rows)
}

/// The side-by-side table.
pub fn table(rows: &[MethodRow]) -> String {
    let mut s = String::new();
    let head: Vec<&str> = rows.iter().map(|r| r.method.as_str()).collect();
    s += &format!("{:<20} {:>12}", "parameter", "truth");
    for h in &head {
        s += &format!(" {:>24}", h);
    }
    s += "\n";
    s += &param_rows(rows, |r| &r.params);
    if rows.iter().any(|r| !r.params_untilted.is_empty()) {
        s += "untilted equivalents (camera tilt folded into c_x, c_y, D, L, k: what laser-line data determine)\n";
        s += &param_rows(rows, |r| &r.params_untilted);
    }
    let line = |label: &str, f: &dyn Fn(&MethodRow) -> f64| {
        let mut l = format!("{:<33}", label);
        for r in rows {
            l += &format!(" {:>24.4}", f(r));
        }
        l + "\n"
    };
    s += &line("validation height RMS (mm)", &|r| r.val_rms_mm);
    s += &line("validation height max (mm)", &|r| r.val_max_mm);
    s += &line("  staircase RMS / max (mm)", &|r| r.val_staircase_rms_mm);
    s += &line("", &|r| r.val_staircase_max_mm);
    s += &line("  foot RMS / max (mm)", &|r| r.val_foot_rms_mm);
    s += &line("", &|r| r.val_foot_max_mm);
    s += &line("with detection: RMS (mm)", &|r| r.val_detected_rms_mm);
    s += &line("with detection: max (mm)", &|r| r.val_detected_max_mm);
    s += &line("seconds", &|r| r.seconds);
    for r in rows {
        if let Some(e) = &r.error {
            s += &format!("{}: failed: {e}\n", r.method);
        }
    }
    s
}

/// The parameters of an untilted equivalent that differ from the model's own.
const UNTILTED: [&str; 8] = [
    "f_px",
    "cx",
    "cy",
    "d_mm",
    "l_mm",
    "k1",
    "k2",
    "laser_tilt_deg[0]",
];

/// One table row per parameter: truth, then each method's value and error.
fn param_rows(
    rows: &[MethodRow],
    params: impl Fn(&MethodRow) -> &BTreeMap<String, ParamError>,
) -> String {
    let mut s = String::new();
    let names: Vec<String> = rows
        .iter()
        .find(|r| !params(r).is_empty())
        .map(|r| params(r).keys().cloned().collect())
        .unwrap_or_default();
    for name in MODEL_PARAMS
        .iter()
        .filter(|n| names.iter().any(|k| k == *n))
    {
        let truth = rows
            .iter()
            .find_map(|r| params(r).get(*name))
            .map_or(f64::NAN, |p| p.truth);
        s += &format!("{:<20} {:>12.6}", name, truth);
        for r in rows {
            s += &match params(r).get(*name) {
                Some(p) => {
                    let err = match p.rel_error {
                        Some(e) if ["f_px", "d_mm", "l_mm", "slider_scale"].contains(name) => {
                            format!("{:.3}%", e * 100.0)
                        }
                        _ => format!("{:+.3}", p.value - p.truth),
                    };
                    format!(" {:>14.6} {:>9}", p.value, err)
                }
                None => format!(" {:>24}", "-"),
            };
        }
        s += "\n";
    }
    s
}
