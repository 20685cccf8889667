//! What a calibration acquires: the targets, their known dimensions, and (for the simulator)
//! where the simulated operator puts them.

use super::CalibError;
use footscan_geom::P2;
use footscan_targets::{BoardPose, Checkerboard, Placement, StaircaseGeometry};
use serde::{Deserialize, Serialize};

/// The calibration procedure. Defaults are the procedure for the default simulated scanner
/// (docs/method.md section 6.1); `footscan calibrate --plan FILE` reads one from TOML.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct CalibrationPlan {
    /// Heights of the flat plate (spacers under it), mm. At least 3 distinct; the first one
    /// should be 0 (a matte sheet on the glass: the glass line of the Bezier network).
    pub plate_heights_mm: Vec<f64>,
    /// Frames per plate height (their spread is the detection noise of eq. 30).
    pub frames_per_height: usize,
    /// Slider position for the plate frames (controller mm).
    pub plate_x_mm: f64,
    /// The staircase gauge block, as its drawing gives it.
    pub staircase: StaircaseGeometry,
    /// Slider range and step of the staircase pass (step mode, controller mm).
    pub stair_start_mm: f64,
    pub stair_end_mm: f64,
    pub stair_step_mm: f64,
    /// Degree in v of the Bezier depth network's row blocks (<= 8; see
    /// [`super::bezier_depth`]).
    pub bezier_degree_v: usize,
    /// Degree of the polynomial each plate line is smoothed with along the rows before the
    /// Bezier network interpolates it (0: the raw per-row positions).
    pub bezier_smooth_degree: usize,
    /// The checkerboard of the OpenCV reference.
    pub board: Checkerboard,
    /// The empty-platform glass pass that ends the guided procedure: slider positions
    /// (controller mm) and frames at each. Only checked (nothing may stand on the glass).
    pub glass_positions_mm: Vec<f64>,
    pub glass_frames: usize,
    /// The shop's stated uncertainty of its spacer and staircase dimensions (mm): recorded
    /// with every calibration, and the floor of any daily-check tolerance.
    pub gauge_tolerance_mm: f64,
    /// What each guided step must see before the procedure moves on.
    pub checks: StepChecks,
    /// The scanner's design values: the model the step checks use when no earlier
    /// calibration exists.
    pub nominal: NominalOptics,
    /// Where the simulated operator puts the targets (unknown to the calibration).
    pub sim: SimPlacements,
}

/// Tolerances of the guided steps' checks. Heights are measured relative to the first plate
/// (so an offset of the check model cancels); the allowance grows with the height difference
/// because the check model's scale may be a few percent off (design values).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct StepChecks {
    /// A plate or step may be this far from its stated height (mm) ...
    pub height_mm: f64,
    /// ... plus this fraction of its height above the first plate.
    pub height_rel: f64,
    /// The first plate against the check model's absolute heights when that model is the
    /// nominal design (mm); with an earlier calibration `height_mm` applies.
    pub nominal_offset_mm: f64,
    /// A plate's line must be found in at least this fraction of the image rows ...
    pub min_rows_fraction: f64,
    /// ... and its heights spread (5th to 95th percentile) by no more than this (mm).
    pub flat_mm: f64,
    /// The staircase's width may be seen this much narrower than stated before the block is
    /// called partly out of the field (mm).
    pub width_mm: f64,
    /// On the empty platform a line this far above the glass is an object (mm).
    pub empty_mm: f64,
}

impl Default for StepChecks {
    fn default() -> Self {
        StepChecks {
            height_mm: 0.8,
            height_rel: 0.04,
            nominal_offset_mm: 10.0,
            min_rows_fraction: 0.5,
            flat_mm: 1.0,
            width_mm: 4.0,
            empty_mm: 2.0,
        }
    }
}

/// Design values of the optics (the untilted model, no distortion, principal point at the
/// image centre): what the checks triangulate with before the scanner has a calibration.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct NominalOptics {
    pub f_px: f64,
    pub d_mm: f64,
    pub l_mm: f64,
}

impl Default for NominalOptics {
    fn default() -> Self {
        NominalOptics {
            f_px: 2000.0,
            d_mm: 250.0,
            l_mm: 70.0,
        }
    }
}

impl NominalOptics {
    /// The design model for a `width` x `height` camera.
    pub fn model(&self, width: u32, height: u32) -> super::CameraModel {
        super::CameraModel {
            width,
            height,
            f_px: self.f_px,
            cx: 0.5 * (width as f64 - 1.0),
            cy: 0.5 * (height as f64 - 1.0),
            d_mm: self.d_mm,
            l_mm: self.l_mm,
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            camera_tilt_deg: [0.0; 3],
            laser_tilt_deg: [0.0; 2],
            slider_scale: 1.0,
        }
    }
}

/// Placements used only by the simulator backend.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SimPlacements {
    pub staircase: Placement,
    /// Checkerboard poses for the OpenCV reference; each is shot with the head at `board_x_mm`.
    pub board_poses: Vec<BoardPose>,
    /// Slider position for the board shots (controller mm).
    pub board_x_mm: f64,
    /// The board lying flat on the glass, shot at two slider positions: the world frame (glass
    /// normal, D) and the slider direction and scale for the OpenCV reference.
    pub board_flat: BoardPose,
    pub board_flat_x_mm: [f64; 2],
    /// Lamp level of the board shots (DN for albedo 1).
    pub lamp_dn: f64,
}

impl Default for CalibrationPlan {
    fn default() -> Self {
        CalibrationPlan {
            plate_heights_mm: vec![0.0, 7.0, 14.0, 21.0, 28.0, 35.0, 42.0, 49.0],
            frames_per_height: 16,
            plate_x_mm: 100.0,
            // Steps over the whole height range (the sides seen at many heights locate c_y),
            // out of order along the block: the risers then sit at heights that are not
            // proportional to their positions, which separates the slider scale from the laser
            // plane's pitch (both move a riser's apparent x).
            staircase: StaircaseGeometry {
                heights_mm: vec![21.0, 0.0, 42.0, 7.0, 35.0, 14.0, 49.0, 28.0],
                lengths_mm: vec![10.0; 8],
                width_mm: 60.0,
            },
            stair_start_mm: 40.0,
            stair_end_mm: 140.0,
            stair_step_mm: 0.25,
            bezier_degree_v: 4,
            bezier_smooth_degree: 8,
            board: Checkerboard::default(),
            glass_positions_mm: vec![40.0, 100.0, 160.0],
            glass_frames: 2,
            gauge_tolerance_mm: 0.005,
            checks: StepChecks::default(),
            nominal: NominalOptics::default(),
            sim: SimPlacements::default(),
        }
    }
}

impl Default for SimPlacements {
    fn default() -> Self {
        // The camera at x = 100 sees x in about [20, 180] and y in about [-60, 60] at the glass;
        // the laser line is at x = 170. Each board is centred near the right of the view so
        // that the line crosses it, tilted in every direction so that OpenCV sees perspective,
        // and raised so that its lowest point is `z_min` above the glass.
        let board = Checkerboard::default();
        let shots = [
            // (centre x, centre y, z_min, rx, ry, rz)
            (122.0, 0.0, 2.0, 0.0, 0.0, 0.0),
            (124.0, 4.0, 6.0, 18.0, 0.0, 0.0),
            (120.0, -4.0, 2.0, -18.0, 0.0, 0.0),
            (126.0, 0.0, 4.0, 0.0, 20.0, 0.0),
            (118.0, 2.0, 12.0, 0.0, -20.0, 0.0),
            (124.0, 6.0, 8.0, 12.0, 12.0, 8.0),
            (120.0, -6.0, 3.0, -12.0, -12.0, -6.0),
            (126.0, -2.0, 10.0, 10.0, -15.0, 15.0),
            (118.0, 3.0, 5.0, -15.0, 10.0, -12.0),
            (122.0, -3.0, 15.0, 22.0, 8.0, 4.0),
            (120.0, 0.0, 20.0, -8.0, 22.0, -4.0),
            (124.0, 5.0, 1.0, 6.0, -6.0, 25.0),
        ];
        SimPlacements {
            staircase: Placement {
                x_mm: 122.0,
                y_mm: -27.0,
                yaw_deg: 3.0,
            },
            board_poses: shots
                .iter()
                .map(|&(x, y, z, rx, ry, rz)| board_pose_at(&board, P2::new(x, y), z, [rx, ry, rz]))
                .collect(),
            board_x_mm: 100.0,
            board_flat: board_pose_at(&board, P2::new(115.0, 2.0), 0.0, [0.0, 0.0, 1.0]),
            board_flat_x_mm: [92.0, 108.0],
            lamp_dn: 110.0,
        }
    }
}

/// The pose that puts the centre of the inner corners of `board` over world (x, y), rotated by
/// `rotation_deg`, with the lowest point of the board `z_min` above the glass.
pub fn board_pose_at(
    board: &Checkerboard,
    centre_xy: P2,
    z_min: f64,
    rotation_deg: [f64; 3],
) -> BoardPose {
    let s = board.square_mm;
    let (uc, vc) = (
        (board.inner_cols - 1) as f64 * s / 2.0,
        (board.inner_rows - 1) as f64 * s / 2.0,
    );
    let at_origin = BoardPose {
        origin_mm: [0.0; 3],
        rotation_deg,
    };
    let c = at_origin.world(uc, vc);
    let [u0, u1, v0, v1] = board.extent();
    let lowest = [(u0, v0), (u1, v0), (u0, v1), (u1, v1)]
        .iter()
        .map(|&(u, v)| at_origin.world(u, v)[2])
        .fold(f64::INFINITY, f64::min);
    BoardPose {
        origin_mm: [centre_xy.x - c[0], centre_xy.y - c[1], z_min - lowest],
        rotation_deg,
    }
}

impl CalibrationPlan {
    /// Read a plan from TOML (unknown keys are errors).
    pub fn load(path: &std::path::Path) -> Result<Self, CalibError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| CalibError::Plan(format!("cannot read {}: {e}", path.display())))?;
        let plan: CalibrationPlan = toml::from_str(&text)
            .map_err(|e| CalibError::Plan(format!("{}: {}", path.display(), e.message())))?;
        plan.validate()?;
        Ok(plan)
    }

    pub fn validate(&self) -> Result<(), CalibError> {
        let bad = |m: String| Err(CalibError::Plan(m));
        if self.frames_per_height < 2 {
            return bad(format!(
                "frames_per_height = {}: at least 2 (their spread is the detection noise)",
                self.frames_per_height
            ));
        }
        if let Some(h) = self
            .plate_heights_mm
            .iter()
            .find(|h| !(h.is_finite() && (0.0..=200.0).contains(*h)))
        {
            return bad(format!("plate_heights_mm: {h} is not in [0, 200] mm"));
        }
        self.staircase
            .validate()
            .map_err(|e| CalibError::Plan(e.to_string()))?;
        if !(self.stair_step_mm > 0.0 && self.stair_end_mm > self.stair_start_mm) {
            return bad(format!(
                "staircase pass {}..{} mm step {} mm: need end > start and step > 0",
                self.stair_start_mm, self.stair_end_mm, self.stair_step_mm
            ));
        }
        if !(1..=super::bezier_depth::MAX_DEGREE).contains(&self.bezier_degree_v) {
            return bad(format!(
                "bezier_degree_v = {}: valid range is 1..=8",
                self.bezier_degree_v
            ));
        }
        self.board
            .validate()
            .map_err(|e| CalibError::Plan(e.to_string()))?;
        if self.glass_frames == 0 && !self.glass_positions_mm.is_empty() {
            return bad("glass_frames = 0: at least 1 per glass position".into());
        }
        if !(self.gauge_tolerance_mm >= 0.0 && self.gauge_tolerance_mm < 1.0) {
            return bad(format!(
                "gauge_tolerance_mm = {}: valid is [0, 1) mm",
                self.gauge_tolerance_mm
            ));
        }
        let c = &self.checks;
        for (k, v, lo, hi) in [
            ("checks.height_mm", c.height_mm, 0.01, 20.0),
            ("checks.height_rel", c.height_rel, 0.0, 0.5),
            ("checks.nominal_offset_mm", c.nominal_offset_mm, 0.01, 100.0),
            ("checks.min_rows_fraction", c.min_rows_fraction, 0.0, 1.0),
            ("checks.flat_mm", c.flat_mm, 0.01, 50.0),
            ("checks.width_mm", c.width_mm, 0.0, 1000.0),
            ("checks.empty_mm", c.empty_mm, 0.01, 100.0),
            ("nominal.f_px", self.nominal.f_px, 10.0, 1e6),
            ("nominal.d_mm", self.nominal.d_mm, 1.0, 1e4),
            ("nominal.l_mm", self.nominal.l_mm, 1.0, 1e4),
        ] {
            if !(v.is_finite() && (lo..=hi).contains(&v)) {
                return bad(format!("{k} = {v}: valid is [{lo}, {hi}]"));
            }
        }
        Ok(())
    }

    /// Every slider position the guided procedure moves to (plate, staircase pass, glass
    /// pass), controller mm.
    pub fn all_positions(&self) -> Vec<f64> {
        let mut p = vec![self.plate_x_mm];
        p.extend(self.stair_positions());
        p.extend(&self.glass_positions_mm);
        p
    }

    /// What the in-system methods need from the plan, checked before anything is acquired.
    pub fn check_insystem(&self) -> Result<(), CalibError> {
        let mut h = self.plate_heights_mm.clone();
        h.sort_by(f64::total_cmp);
        h.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
        if h.len() < 3 {
            return Err(CalibError::TooFewHeights {
                got: h.len(),
                need: 3,
                heights: format!("plate_heights_mm = {h:?}"),
            });
        }
        if h.len() > super::bezier_depth::MAX_DEGREE + 1 {
            return Err(CalibError::Plan(format!(
                "plate_heights_mm: {} heights; the Bezier network interpolates at most {}",
                h.len(),
                super::bezier_depth::MAX_DEGREE + 1
            )));
        }
        Ok(())
    }

    /// Slider positions of the staircase pass.
    pub fn stair_positions(&self) -> Vec<f64> {
        let n = ((self.stair_end_mm - self.stair_start_mm) / self.stair_step_mm).floor() as usize;
        (0..=n)
            .map(|i| self.stair_start_mm + i as f64 * self.stair_step_mm)
            .collect()
    }
}
