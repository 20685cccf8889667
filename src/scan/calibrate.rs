//! A calibration from end to end on the simulated scanner: open its devices (the same
//! [`open_sim_devices`] a scan uses) or render its frames directly, acquire, fit with the chosen
//! method, and produce the [`Calibration`](crate::calib::Calibration) a scan loads. The fits
//! themselves live in [`crate::calib`]; their pieces are re-exported here so one module names
//! the whole procedure.

use super::backend::sim::{open_sim_devices, SimDevices, SimOpenError};
use super::ScanConfig;
use crate::calib::acquire::{self, DeviceRig, RenderRig, SimOperator};
pub use crate::calib::run::{
    acquire_insystem, check_before_saving, detector, from_insystem, Method, Outcome, DETECTOR,
};
use crate::calib::{CalibError, CalibrationPlan};
use footscan_sim::grbl::GrblEmulator;
use footscan_sim::render::Scene;
use footscan_sim::targets::Staircase;
use std::sync::Arc;
#[cfg(feature = "opencv")]
use {
    crate::calib::opencv::{BoardImage, BoardShots, Role},
    footscan_sim::targets::{BoardRenderer, Lighting},
};

impl From<SimOpenError> for CalibError {
    fn from(e: SimOpenError) -> Self {
        match e {
            SimOpenError::Device(h) => CalibError::Device(h),
            other => CalibError::Sim(other.to_string()),
        }
    }
}

/// The simulator as a calibration rig: the GRBL emulator behind the real serial driver, the
/// simulated camera, and an operator who swaps the scene. Keeps the emulator alive.
pub struct SimRig {
    pub rig: DeviceRig,
    _emulator: Arc<GrblEmulator>,
}

/// Open the simulated scanner of `cfg` as a calibration rig.
pub fn open_sim_rig(cfg: &ScanConfig, plan: &CalibrationPlan) -> Result<SimRig, CalibError> {
    let SimDevices {
        emulator,
        slider,
        camera,
    } = open_sim_devices(cfg, Scene::Empty)?;
    let staircase = Staircase::new(plan.staircase.clone(), plan.sim.staircase)
        .map_err(|e| CalibError::Sim(e.to_string()))?;
    let operator = SimOperator::new(camera.scene_handle(), staircase);
    Ok(SimRig {
        rig: DeviceRig::new(
            Box::new(camera),
            Box::new(slider),
            Box::new(operator),
            cfg.scan.approach_feed_mm_min,
        ),
        _emulator: emulator,
    })
}

/// A rig that renders the simulated scanner's frames directly (no real-time devices).
pub fn render_rig(cfg: &ScanConfig, plan: &CalibrationPlan) -> Result<RenderRig, CalibError> {
    let staircase = Staircase::new(plan.staircase.clone(), plan.sim.staircase)
        .map_err(|e| CalibError::Sim(e.to_string()))?;
    RenderRig::new(
        cfg.sim.optics.clone(),
        cfg.sim.noise.clone(),
        cfg.sim.seed,
        staircase,
        cfg.sim.slider.slider_scale,
    )
}

/// Calibrate the simulated scanner of `cfg` with `method`, acquiring through its devices
/// (insystem, bezier) or from rendered board shots (opencv).
pub fn calibrate_sim(
    cfg: &ScanConfig,
    method: Method,
    plan: &CalibrationPlan,
    progress: acquire::Progress,
) -> Result<Outcome, CalibError> {
    plan.validate()?;
    match method {
        Method::Insystem | Method::Bezier => {
            plan.check_insystem()?;
            let mut sim = open_sim_rig(cfg, plan)?;
            let data = acquire_insystem(&mut sim.rig, plan, progress)?;
            drop(sim);
            progress("fitting", 1, 1);
            from_insystem(&data, method, plan)
        }
        Method::Opencv => opencv_sim(cfg, plan, progress),
    }
}

#[cfg(feature = "opencv")]
fn opencv_sim(
    cfg: &ScanConfig,
    plan: &CalibrationPlan,
    progress: acquire::Progress,
) -> Result<Outcome, CalibError> {
    let shots = render_shots(cfg, plan, progress)?;
    let mut det = detector(DETECTOR)?;
    progress("OpenCV calibration", 1, 1);
    let calibration = crate::calib::opencv::calibrate(&shots, &plan.board, det.as_mut())?;
    check_before_saving(&calibration)?;
    Ok(Outcome {
        calibration,
        insystem: None,
    })
}

#[cfg(not(feature = "opencv"))]
fn opencv_sim(
    _cfg: &ScanConfig,
    _plan: &CalibrationPlan,
    _progress: acquire::Progress,
) -> Result<Outcome, CalibError> {
    Err(CalibError::OpenCvDisabled)
}

/// Render the plan's board shots with the simulated camera.
#[cfg(feature = "opencv")]
pub fn render_shots(
    cfg: &ScanConfig,
    plan: &CalibrationPlan,
    progress: acquire::Progress,
) -> Result<BoardShots, CalibError> {
    let sim = &cfg.sim;
    let r = BoardRenderer::new(sim.optics.clone(), sim.noise.clone(), sim.seed)
        .map_err(|e| CalibError::Sim(e.to_string()))?;
    let s = &plan.sim;
    let scale = sim.slider.slider_scale;
    let lamp = |laser| Lighting {
        lamp_dn: s.lamp_dn,
        laser,
    };
    let total = s.board_poses.len() + 2;
    let mut images = Vec::new();
    let mut index = 0u64;
    let mut shot = |pose, x: f64, laser: bool| {
        index += 1;
        r.render(&plan.board, pose, scale * x, lamp(laser), index)
            .pixels
    };
    for (k, pose) in s.board_poses.iter().enumerate() {
        progress("board shots", k, total);
        let ambient = shot(pose, s.board_x_mm, false);
        let laser = Some(shot(pose, s.board_x_mm, true));
        images.push(BoardImage {
            role: Role::Pose,
            x_mm: s.board_x_mm,
            ambient,
            laser,
        });
    }
    for (k, &x) in s.board_flat_x_mm.iter().enumerate() {
        progress("board shots", s.board_poses.len() + k, total);
        let ambient = shot(&s.board_flat, x, false);
        images.push(BoardImage {
            role: Role::Flat(k),
            x_mm: x,
            ambient,
            laser: None,
        });
    }
    Ok(BoardShots {
        width: sim.optics.width,
        height: sim.optics.height,
        images,
    })
}
