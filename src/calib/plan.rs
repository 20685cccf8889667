//! What a calibration acquires: the targets, their known dimensions, and (for the simulator)
//! where the simulated operator puts them.

use super::CalibError;
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
    /// Where the simulated operator puts the targets (unknown to the calibration).
    pub sim: SimPlacements,
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
                .map(|&(x, y, z, rx, ry, rz)| board_pose_at(&board, [x, y], z, [rx, ry, rz]))
                .collect(),
            board_x_mm: 100.0,
            board_flat: board_pose_at(&board, [115.0, 2.0], 0.0, [0.0, 0.0, 1.0]),
            board_flat_x_mm: [92.0, 108.0],
            lamp_dn: 110.0,
        }
    }
}

/// The pose that puts the centre of the inner corners of `board` over world (x, y), rotated by
/// `rotation_deg`, with the lowest point of the board `z_min` above the glass.
pub fn board_pose_at(
    board: &Checkerboard,
    centre_xy: [f64; 2],
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
        origin_mm: [centre_xy[0] - c[0], centre_xy[1] - c[1], z_min - lowest],
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
        Ok(())
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
