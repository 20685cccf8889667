//! In-system calibration (docs/method.md section 6; the plantar scanner paper's section 4,
//! recast): the scanner calibrates itself from the line on a flat plate at known heights, a
//! staircase gauge block of known step heights, step lengths and width, and its own slider
//! positions.
//!
//! 1. Start: the closed forms of eq. 20-21 per row ([`super::closed_form`]) give c_x, D and
//!    F L; the block's known width gives F (and so L), the block's sides seen at several
//!    heights give c_y, its sides and risers its pose.
//! 2. A Levenberg-Marquardt fit of the general model of docs/method.md section 2.3 over every
//!    row of every target: F, c_x, c_y, D, L, k1, k2, the laser plane's yaw and pitch, the
//!    slider scale, and the block's pose (x, y, yaw) as nuisance parameters. Residuals: the
//!    height of each plate and step row against its known height (in px of column through
//!    dh/dc), and the row of each end of the line at a side or riser of the block against the
//!    model's prediction of that edge (half a row from the last row that shows the line).
//! 3. The covariance of the fit (residuals in units of their measured noise: the spread of
//!    repeated plate frames, and 1/sqrt(12) row for an end) gives a standard deviation per
//!    parameter and, propagated through the triangulation, a height uncertainty (eq. 30-31).
//!
//! # What the laser line cannot tell (the gauge)
//! Every observation is a point of the laser plane, which moves with the camera: the data fix
//! the mapping from the laser plane to the image (a homography plus distortion), nothing
//! else. A rotation of the camera about its own centre by a small angle t about the y axis
//! changes that mapping only by a shift of c_x by about -F tan t, of D by about +L tan t and of
//! the laser pitch (second-order terms: ~1e-6 px); likewise rotation about x against c_y, and
//! roll against the laser yaw. The camera tilts are therefore fixed at zero: the fitted c_x,
//! c_y, D and laser tilts are those of the equivalent untilted camera, which triangulates every
//! point of the laser plane to within the fit's residuals. With a camera tilted by t about y
//! (0.3 deg on the default simulated scanner) the fitted c_x differs from the lens's principal
//! point by F tan t (10.5 px) and D by L tan t (0.37 mm): not an error of any height, but not
//! the lens's own c_x either. The paper's claim that f and the pixel size are found separately
//! (eq. 22-24, by moving the lens) does not apply here: only F = f/eta is observable.

use super::closed_form;
use super::data::{InsystemData, PlateObservation};
use super::lm;
use super::stair::{self, Edge};
use super::{CalibError, CameraModel};
use footscan_geom::P3;
use footscan_targets::Placement;
use nalgebra::DMatrix;
use std::collections::BTreeMap;

/// Tuning of the fit.
#[derive(Clone, Debug, PartialEq)]
pub struct InsystemOptions {
    /// Use every n-th row of a staircase piece for the height residuals.
    pub stair_row_stride: usize,
    /// Rows next to a piece's end left out of the height residuals.
    pub end_margin_rows: usize,
    /// Solver budget (function evaluations per parameter).
    pub patience: usize,
}

impl Default for InsystemOptions {
    fn default() -> Self {
        InsystemOptions {
            stair_row_stride: 4,
            end_margin_rows: 3,
            patience: 100,
        }
    }
}

/// Fitted parameters in order: the model's, then the block's pose. The order is the layout of
/// [`FitParams::to_vec`] and of [`InsystemFit::covariance`].
pub const PARAMS: [&str; 13] = [
    "f_px",
    "cx",
    "cy",
    "d_mm",
    "l_mm",
    "k1",
    "k2",
    "laser_tilt_deg[0]",
    "laser_tilt_deg[1]",
    "slider_scale",
    "staircase.x_mm",
    "staircase.y_mm",
    "staircase.yaw_deg",
];
const MODEL_PARAMS: usize = 10;
/// Finite-difference steps of the solver, in [`PARAMS`] order.
const STEPS: [f64; 13] = [
    1e-3, 1e-3, 1e-3, 1e-4, 1e-4, 1e-6, 1e-6, 1e-5, 1e-5, 1e-8, 1e-4, 1e-4, 1e-5,
];

/// The unknowns of the in-system fit by name. The solver sees them as a vector in [`PARAMS`]
/// order; everything else reads them by field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitParams {
    pub f_px: f64,
    pub cx: f64,
    pub cy: f64,
    pub d_mm: f64,
    pub l_mm: f64,
    pub k1: f64,
    pub k2: f64,
    pub laser_tilt_deg: [f64; 2],
    pub slider_scale: f64,
    /// The staircase block's pose (a nuisance parameter of the fit).
    pub block: Placement,
}

impl FitParams {
    /// From a vector in [`PARAMS`] order (the model's ten alone give a zero block pose).
    pub fn from_slice(x: &[f64]) -> FitParams {
        let at = |k: usize| x.get(k).copied().unwrap_or(0.0);
        FitParams {
            f_px: x[0],
            cx: x[1],
            cy: x[2],
            d_mm: x[3],
            l_mm: x[4],
            k1: x[5],
            k2: x[6],
            laser_tilt_deg: [x[7], x[8]],
            slider_scale: x[9],
            block: Placement {
                x_mm: at(10),
                y_mm: at(11),
                yaw_deg: at(12),
            },
        }
    }

    /// The vector in [`PARAMS`] order.
    pub fn to_vec(&self) -> Vec<f64> {
        vec![
            self.f_px,
            self.cx,
            self.cy,
            self.d_mm,
            self.l_mm,
            self.k1,
            self.k2,
            self.laser_tilt_deg[0],
            self.laser_tilt_deg[1],
            self.slider_scale,
            self.block.x_mm,
            self.block.y_mm,
            self.block.yaw_deg,
        ]
    }

    /// The camera model of an image of `width` x `height`: no tangential distortion and no
    /// camera tilt (the untilted equivalent, see the module docs).
    pub fn model(&self, width: u32, height: u32) -> CameraModel {
        CameraModel {
            width,
            height,
            f_px: self.f_px,
            cx: self.cx,
            cy: self.cy,
            d_mm: self.d_mm,
            l_mm: self.l_mm,
            k1: self.k1,
            k2: self.k2,
            p1: 0.0,
            p2: 0.0,
            camera_tilt_deg: [0.0; 3],
            laser_tilt_deg: self.laser_tilt_deg,
            slider_scale: self.slider_scale,
        }
    }

    fn pose(&self) -> [f64; 3] {
        [self.block.x_mm, self.block.y_mm, self.block.yaw_deg]
    }
}

/// The result of an in-system calibration.
#[derive(Clone, Debug)]
pub struct InsystemFit {
    pub model: CameraModel,
    /// Standard deviation of every fitted model parameter (names as in the model).
    pub stddev: BTreeMap<String, f64>,
    /// Residual RMS by target and the paper's checks (see [`fit_insystem`]).
    pub residuals: BTreeMap<String, f64>,
    /// The staircase's pose found by the fit, with standard deviations.
    pub block: Placement,
    pub block_stddev: [f64; 3],
    /// The per-row closed forms the fit started from.
    pub closed_form: closed_form::Summary,
    /// The model the fit started from.
    pub start: CameraModel,
    /// Covariance of [`PARAMS`].
    pub covariance: DMatrix<f64>,
    /// Condition number of the scaled normal matrix.
    pub condition: f64,
    pub evaluations: usize,
    /// Single-frame detection noise measured on the plate (px).
    pub detection_noise_px: f64,
}

struct RowObs {
    x_mm: f64,
    row: f64,
    col: f64,
    h: f64,
    /// 1 / (|dh/dc| sigma_col): turns a height error into a normalised column residual.
    weight: f64,
    plate: Option<usize>,
}

#[derive(Clone, Copy)]
enum EdgeKind {
    Side { w: f64 },
    Riser { u: f64 },
}

struct EdgeObs {
    x_mm: f64,
    h: f64,
    kind: EdgeKind,
    row: f64,
}

/// Quantisation of an end to whole rows: uniform over one row.
const EDGE_SIGMA: f64 = 0.288_675_134_594_812_9;
/// Normalised residuals beyond which an observation is left out of the second fit: an end
/// more than 1.15 rows from its edge (the quantisation allows 0.5), a row 6 sigma off.
const EDGE_OUTLIER: f64 = 4.0;
const ROW_OUTLIER: f64 = 6.0;

/// Calibrate from in-system data. Residual keys: `plate_<h>mm_rms_px` (column residual RMS per
/// plate height), `staircase_rows_rms_px`, `staircase_edges_rms_px` (rows),
/// `closed_form_cx_spread_px` and `closed_form_d_spread_mm` (spread of the per-row eq. 20-21
/// solutions), `parallel_x_rms_mm` and `parallel_y_rms_mm` (eq. 18-19: departure of k(s) and
/// q(t) from first order), `detection_noise_px`, `u_h_detection_mm` (one frame, h = 0),
/// `u_h_model_mm` (calibration parameters), `u_h_mm` (both, eq. 30), `fit_reduced_chi2`.
pub fn fit_insystem(
    data: &InsystemData,
    opts: &InsystemOptions,
) -> Result<InsystemFit, CalibError> {
    let (w, h) = (data.width, data.height);
    let plates = usable_plates(data)?;
    // 1. The start: closed forms, the staircase's scale and pose.
    let start = starting_point(data, &plates)?;
    let start_model = start.params.model(w, h);
    // 2. Observations and weights.
    let noise = pooled_noise(&plates);
    let (mut obs, mut edges) = observations(data, &plates, &start, &start_model, noise, opts);
    // 3. The fit, then once more without the observations the model cannot explain.
    let (sol, dropped) = solve_robust(&mut obs, &mut edges, &start.params, w, h, opts)?;
    let fitted = FitParams::from_slice(&sol.x);
    let model = fitted.model(w, h);
    model
        .validate()
        .map_err(|e| CalibError::Implausible(format!("fitted model: {e}")))?;
    // 4. Residuals by target and the paper's checks.
    let mut residuals = residual_table(&obs, &edges, &sol, &plates, noise)?;
    residuals.insert(
        "closed_form_cx_spread_px".into(),
        start.closed_form.cx_spread,
    );
    residuals.insert("closed_form_d_spread_mm".into(), start.closed_form.d_spread);
    residuals.insert("parallel_x_rms_mm".into(), parallel_x(&plates, &model));
    residuals.insert("parallel_y_rms_mm".into(), parallel_y(&edges, &model));
    residuals.insert("fit_reduced_chi2".into(), sol.reduced_chi2);
    residuals.insert("outliers_dropped".into(), dropped as f64);
    // 5. Uncertainty (eq. 30-31).
    let u = super::uncertainty::height_uncertainty(
        &model,
        &sol.covariance
            .view((0, 0), (MODEL_PARAMS, MODEL_PARAMS))
            .into_owned(),
        &plates,
        noise,
        &|x| FitParams::from_slice(x).model(w, h),
        &sol.x[..MODEL_PARAMS],
        &STEPS[..MODEL_PARAMS],
    );
    residuals.insert("detection_noise_px".into(), noise);
    residuals.insert("u_h_detection_mm".into(), u.detection_mm);
    residuals.insert("u_h_model_mm".into(), u.model_mm);
    residuals.insert("u_h_mm".into(), u.total_mm);
    let sd = |k: usize| sol.covariance[(k, k)].max(0.0).sqrt();
    let stddev = (0..MODEL_PARAMS)
        .map(|k| (PARAMS[k].to_string(), sd(k)))
        .collect();
    Ok(InsystemFit {
        model,
        stddev,
        residuals,
        block: fitted.block,
        block_stddev: [sd(10), sd(11), sd(12)],
        closed_form: start.closed_form,
        start: start_model,
        covariance: sol.covariance,
        condition: sol.condition,
        evaluations: sol.evaluations,
        detection_noise_px: noise,
    })
}

/// The plates whose line was seen (every one must be), at three distinct heights or more.
fn usable_plates(data: &InsystemData) -> Result<Vec<PlateObservation>, CalibError> {
    let seen = |p: &PlateObservation| p.col.iter().filter(|c| c.is_finite()).count();
    if let Some(p) = data.plates.iter().find(|p| seen(p) < 16) {
        return Err(CalibError::NoUsableRows {
            target: format!("the plate at {} mm", p.height_mm),
            detail: format!(
                "the line was found in {} rows over {} frames: check that the plate is in view \
                 and lit by the laser, and the detector threshold",
                seen(p),
                p.frames
            ),
        });
    }
    let mut distinct: Vec<f64> = data.plates.iter().map(|p| p.height_mm).collect();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    if distinct.len() < 3 {
        return Err(CalibError::TooFewHeights {
            got: distinct.len(),
            need: 3,
            heights: format!("{distinct:?} mm"),
        });
    }
    Ok(data.plates.clone())
}

/// Where the fit starts, and the staircase pieces it was found from.
struct Start {
    closed_form: closed_form::Summary,
    pieces: Vec<stair::Piece>,
    params: FitParams,
}

/// Step 1: the per-row closed forms give c_x, D and F L; the block's known width gives F (and
/// so L); its sides and risers give its pose.
fn starting_point(data: &InsystemData, plates: &[PlateObservation]) -> Result<Start, CalibError> {
    let (w, h) = (data.width, data.height);
    let rows = closed_form::per_row(plates);
    let cf = closed_form::summarize(&rows).ok_or_else(|| CalibError::NoUsableRows {
        target: "the plate".into(),
        detail: "no row has the line at three heights".into(),
    })?;
    let z_ideal = |_: usize, c: f64| cf.fl / (c - cf.cx) - cf.d_mm;
    let steps = stair::assign_steps(data, &z_ideal);
    let pieces = stair::pieces(&steps);
    if pieces.is_empty() {
        return Err(CalibError::NoUsableRows {
            target: "the staircase gauge block".into(),
            detail: format!(
                "no frame of the {}-frame pass shows the line on a step at one of the drawing's \
                 heights {:?} mm",
                data.stair.len(),
                data.staircase.heights_mm
            ),
        });
    }
    let f0 = stair::scale(data, &pieces, cf.d_mm)?;
    let mut params = FitParams {
        f_px: f0,
        cx: cf.cx,
        cy: 0.5 * (h as f64 - 1.0),
        d_mm: cf.d_mm,
        l_mm: cf.fl / f0,
        k1: 0.0,
        k2: 0.0,
        laser_tilt_deg: [0.0; 2],
        slider_scale: 1.0,
        block: Placement {
            x_mm: 0.0,
            y_mm: 0.0,
            yaw_deg: 0.0,
        },
    };
    let pose = stair::block_pose(data, &pieces, &params.model(w, h))?;
    params.block = Placement {
        x_mm: pose.0,
        y_mm: pose.1,
        yaw_deg: pose.2,
    };
    Ok(Start {
        closed_form: cf,
        pieces,
        params,
    })
}

/// Step 2: every plate row, every `stair_row_stride`-th row of a staircase piece (away from its
/// ends), each weighted by its column noise turned into height; and the ends of the pieces at
/// the block's sides and risers.
fn observations(
    data: &InsystemData,
    plates: &[PlateObservation],
    start: &Start,
    start_model: &CameraModel,
    noise: f64,
    opts: &InsystemOptions,
) -> (Vec<RowObs>, Vec<EdgeObs>) {
    let tri0 = start_model.triangulator();
    let slope = |x_mm: f64, row: f64, col: f64| -> Option<f64> {
        let a = tri0.point(x_mm, col - 0.5, row)?[2];
        let b = tri0.point(x_mm, col + 0.5, row)?[2];
        Some((b - a).abs())
    };
    let mut obs = Vec::new();
    for (k, p) in plates.iter().enumerate() {
        let sigma = plate_sigma(p);
        for (r, &c) in p.col.iter().enumerate() {
            if let (true, Some(g)) = (c.is_finite(), slope(0.0, r as f64, c)) {
                obs.push(RowObs {
                    x_mm: 0.0,
                    row: r as f64,
                    col: c,
                    h: p.height_mm,
                    weight: 1.0 / (g * sigma),
                    plate: Some(k),
                });
            }
        }
    }
    let g_heights = &data.staircase.heights_mm;
    let stride = opts.stair_row_stride.max(1);
    for p in &start.pieces {
        let f = &data.stair[p.frame];
        let hj = g_heights[p.step];
        let m = opts.end_margin_rows;
        let mut r = p.first + m;
        while r + m <= p.last {
            if let Some(g) = slope(f.x_mm, r as f64, f.col[r]) {
                obs.push(RowObs {
                    x_mm: f.x_mm,
                    row: r as f64,
                    col: f.col[r],
                    h: hj,
                    weight: 1.0 / (g * noise.max(0.01)),
                    plate: None,
                });
            }
            r += stride;
        }
    }
    let pose = start.params.block;
    let mut edges = Vec::new();
    for e in stair::identify_ends(
        data,
        &start.pieces,
        start_model,
        (pose.x_mm, pose.y_mm, pose.yaw_deg),
        1.5,
    ) {
        let p = &start.pieces[e.piece];
        let row = if e.first { p.first } else { p.last };
        edges.push(EdgeObs {
            x_mm: data.stair[p.frame].x_mm,
            h: g_heights[p.step],
            kind: match e.edge {
                Edge::Side { w } => EdgeKind::Side { w },
                Edge::Face { u } => EdgeKind::Riser { u },
            },
            row: if e.first {
                row as f64 - 0.5
            } else {
                row as f64 + 0.5
            },
        });
    }
    (obs, edges)
}

/// Step 3: the Levenberg-Marquardt fit, then once more without the observations the model
/// cannot explain (a detector glitch, an end next to something the identification missed).
/// Returns the solution and how many observations were left out.
fn solve_robust(
    obs: &mut Vec<RowObs>,
    edges: &mut Vec<EdgeObs>,
    x0: &FitParams,
    w: u32,
    h: u32,
    opts: &InsystemOptions,
) -> Result<(lm::Solution, usize), CalibError> {
    let solve = |obs: &[RowObs], edges: &[EdgeObs], x0: &[f64]| {
        let residual = |x: &[f64], out: &mut Vec<f64>| {
            out.clear();
            let p = FitParams::from_slice(x);
            let m = p.model(w, h);
            let tri = m.triangulator();
            for o in obs {
                out.push(match tri.point(o.x_mm, o.col, o.row) {
                    Some(p) => (p[2] - o.h) * o.weight,
                    None => 1e6,
                });
            }
            for e in edges {
                out.push(match edge_row(&m, p.pose(), e) {
                    Some(r) => (r - e.row) / EDGE_SIGMA,
                    None => 1e6,
                });
            }
        };
        lm::solve(&residual, x0, &STEPS, opts.patience).map_err(|source| CalibError::NotConverged {
            what: "the in-system fit of the general model".into(),
            source,
        })
    };
    let sol = solve(obs, edges, &x0.to_vec())?;
    let (n_obs, n_edges) = (obs.len(), edges.len());
    let mut keep = sol.residuals.iter().map(|r| r.abs());
    let keep_obs: Vec<bool> = keep.by_ref().take(n_obs).map(|r| r < ROW_OUTLIER).collect();
    let keep_edges: Vec<bool> = keep.map(|r| r < EDGE_OUTLIER).collect();
    let dropped = keep_obs.iter().chain(&keep_edges).filter(|k| !**k).count();
    if dropped * 100 > n_obs + n_edges {
        return Err(CalibError::Implausible(format!(
            "{dropped} of {} observations ({:.1} %) are far from the best fit of the model: \
             the line positions are not those of a scanner seeing the plan's targets (wrong \
             heights or block, a detector failing, or a moving target)",
            n_obs + n_edges,
            100.0 * dropped as f64 / (n_obs + n_edges) as f64
        )));
    }
    if dropped == 0 {
        return Ok((sol, 0));
    }
    let mut k = keep_obs.iter();
    obs.retain(|_| *k.next().unwrap_or(&true));
    let mut k = keep_edges.iter();
    edges.retain(|_| *k.next().unwrap_or(&true));
    Ok((solve(obs, edges, &sol.x)?, dropped))
}

/// Step 4: residual RMS by target in px (rows for the ends); a plate far from the fitted model
/// means the data are not those of a scanner.
fn residual_table(
    obs: &[RowObs],
    edges: &[EdgeObs],
    sol: &lm::Solution,
    plates: &[PlateObservation],
    noise: f64,
) -> Result<BTreeMap<String, f64>, CalibError> {
    let mut residuals = BTreeMap::new();
    let mut per_plate = vec![(0.0, 0usize); plates.len()];
    let mut stair_rows = (0.0, 0usize);
    for (o, r) in obs.iter().zip(&sol.residuals) {
        let sigma = match o.plate {
            Some(k) => plate_sigma(&plates[k]),
            None => noise.max(0.01),
        };
        let px = r * sigma;
        let acc = match o.plate {
            Some(k) => &mut per_plate[k],
            None => &mut stair_rows,
        };
        acc.0 += px * px;
        acc.1 += 1;
    }
    let rms_of = |(s, n): &(f64, usize)| (s / (*n).max(1) as f64).sqrt();
    for (p, acc) in plates.iter().zip(&per_plate) {
        residuals.insert(format!("plate_{}mm_rms_px", p.height_mm), rms_of(acc));
    }
    residuals.insert("staircase_rows_rms_px".into(), rms_of(&stair_rows));
    let edge_res = &sol.residuals[obs.len()..obs.len() + edges.len()];
    residuals.insert("staircase_edges_rms_px".into(), rms(edge_res) * EDGE_SIGMA);
    let worst_plate = per_plate.iter().map(rms_of).fold(0.0, f64::max);
    if worst_plate > 1.0 {
        return Err(CalibError::Implausible(format!(
            "a plate's line is {worst_plate:.2} px RMS from the fitted model (expected a few \
             hundredths): the data do not fit a scanner; check the targets and the detector"
        )));
    }
    Ok(residuals)
}

/// A plate row's column noise: the single-frame spread over the frames averaged, floored.
fn plate_sigma(p: &PlateObservation) -> f64 {
    (pooled_noise(std::slice::from_ref(p)) / (p.frames as f64).sqrt()).max(0.003)
}

/// Single-frame detection noise: RMS over rows of the per-row spread of repeated frames.
pub fn pooled_noise(plates: &[PlateObservation]) -> f64 {
    let v: Vec<f64> = plates
        .iter()
        .flat_map(|p| p.std.iter().copied())
        .filter(|s| s.is_finite())
        .collect();
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|s| s * s).sum::<f64>() / v.len() as f64).sqrt()
}

fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Predicted image row of the edge point: where the laser plane at the step's height meets a
/// side (w = const) or a riser (u = const) of the block at pose (x0, y0, yaw).
fn edge_row(m: &CameraModel, pose: [f64; 3], e: &EdgeObs) -> Option<f64> {
    let [x0, y0, yaw] = pose;
    let (sn, cs) = yaw.to_radians().sin_cos();
    let ta = m.laser_tilt_deg[0].to_radians().tan();
    let tb = m.laser_tilt_deg[1].to_radians().tan();
    // Laser line at height h: x = xs + ta y.
    let xs = m.slider_scale * e.x_mm + m.l_mm + tb * e.h;
    let y = match e.kind {
        EdgeKind::Side { w } => {
            let den = cs - ta * sn;
            (den.abs() > 1e-9).then(|| (w + y0 * cs + (xs - x0) * sn) / den)?
        }
        EdgeKind::Riser { u } => {
            let den = ta * cs + sn;
            (den.abs() > 1e-6).then(|| (u - (xs - x0) * cs + y0 * sn) / den)?
        }
    };
    m.project(e.x_mm, P3::new(xs + ta * y, y, e.h))
        .map(|p| p[1])
}

/// Eq. 18 as a check: per row, k = (c - c_x) h / F against s = c_0 - c should be a straight
/// line; RMS of the departure (mm) over all rows, from the plate data.
fn parallel_x(plates: &[PlateObservation], m: &CameraModel) -> f64 {
    let Some(base) = plates
        .iter()
        .min_by(|a, b| a.height_mm.total_cmp(&b.height_mm))
    else {
        return f64::NAN;
    };
    let rows = base.col.len();
    let mut sum = 0.0;
    let mut n = 0usize;
    for r in 0..rows {
        let pts: Vec<(f64, f64)> = plates
            .iter()
            .filter(|p| p.col[r].is_finite() && base.col[r].is_finite())
            .map(|p| {
                let k = (p.col[r] - m.cx) * p.height_mm / m.f_px;
                (base.col[r] - p.col[r], k)
            })
            .collect();
        if pts.len() < 3 {
            continue;
        }
        for res in line_residuals(&pts) {
            sum += res * res;
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        (sum / n as f64).sqrt()
    }
}

/// Eq. 19 as a check: along each side of the block, q = (r - c_y)(D + h) / F (the world y the
/// ideal model gives the side's row) against the laser's x should be a straight line over all
/// steps; RMS of the departure (mm).
fn parallel_y(edges: &[EdgeObs], m: &CameraModel) -> f64 {
    let mut all = Vec::new();
    for side in [0.0, 1.0] {
        let pts: Vec<(f64, f64)> = edges
            .iter()
            .filter_map(|e| match e.kind {
                EdgeKind::Side { w } if (w > 0.0) == (side > 0.0) => Some((
                    m.slider_scale * e.x_mm + m.l_mm,
                    (e.row - m.cy) * (m.d_mm + e.h) / m.f_px,
                )),
                _ => None,
            })
            .collect();
        if pts.len() >= 3 {
            all.extend(line_residuals(&pts));
        }
    }
    if all.is_empty() {
        f64::NAN
    } else {
        rms(&all)
    }
}

/// Residuals of the least-squares straight line through `pts`.
fn line_residuals(pts: &[(f64, f64)]) -> Vec<f64> {
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p.0).sum::<f64>() / n;
    let my = pts.iter().map(|p| p.1).sum::<f64>() / n;
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    pts.iter().map(|p| p.1 - my - b * (p.0 - mx)).collect()
}
