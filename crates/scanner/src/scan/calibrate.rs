//! A calibration from end to end on any backend: open the scanner's devices through the
//! same backend code a scan uses ([`open_rig`]: the simulator's GRBL emulator and camera with
//! its scene-swapping operator, or the V4L2 camera and GRBL slider with a person placing the
//! targets), run the guided procedure ([`crate::calib::guided`]) with whoever confirms the
//! steps, fit with the chosen method, and produce the [`Calibration`] a scan loads. The fits
//! live in [`crate::calib`]; their pieces are re-exported here so one module names the whole
//! procedure. The OpenCV checkerboard reference stays a simulator-only comparison.

use super::backend::sim::{open_sim_devices, SimDevices, SimOpenError};
use super::config::Backend;
use super::{LoadedConfig, ScanConfig};
use crate::calib::acquire::{self, DeviceRig, Mistakes, Operator, Person, RenderRig, SimOperator};
use crate::calib::guided::{
    acquire_guided, run_steps, staircase_instruction, AutoGuide, Guide, GuidedRun, Step, StepData,
    StepKind,
};
pub use crate::calib::run::{
    check_before_saving, check_limits, detector, from_insystem, Calibrated, Method, DETECTOR,
};
use crate::calib::verify::CheckReport;
use crate::calib::{CalibError, Calibration, CalibrationPlan, CameraModel};
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

/// What the simulator backend adds to a rig: the emulator (kept alive; a test may inject
/// faults) and the mistakes its operator will make.
pub struct SimParts {
    pub emulator: Arc<GrblEmulator>,
    pub mistakes: Mistakes,
}

/// The scanner as a calibration rig, whatever its backend.
pub struct OpenRig {
    pub rig: DeviceRig,
    /// Set on the simulator backend.
    pub sim: Option<SimParts>,
}

/// Open the scanner of `cfg` as a calibration rig: the devices come from the same backend
/// code as a scan's (`open_sim_devices`, `hardware::open`); on hardware a person places the
/// targets, in the simulator its operator swaps the scene.
pub fn open_rig(cfg: &ScanConfig, plan: &CalibrationPlan) -> Result<OpenRig, CalibError> {
    let (camera, slider, operator, sim): (_, _, Box<dyn Operator>, _) = match cfg.scanner.backend {
        Backend::Sim => {
            let SimDevices {
                emulator,
                slider,
                camera,
            } = open_sim_devices(cfg, Scene::Empty)?;
            let staircase = Staircase::new(plan.staircase.clone(), plan.sim.staircase)
                .map_err(|e| CalibError::Sim(e.to_string()))?;
            let operator = SimOperator::new(camera.scene_handle(), staircase);
            let mistakes = operator.mistakes.clone();
            (
                Box::new(camera) as Box<dyn footscan_hal::Camera>,
                Box::new(slider) as Box<dyn footscan_hal::Slider>,
                Box::new(operator),
                Some(SimParts { emulator, mistakes }),
            )
        }
        Backend::Hardware => {
            let d = super::hardware::open(cfg).map_err(|e| CalibError::Open(e.to_string()))?;
            (d.camera, d.slider, Box::new(Person), None)
        }
    };
    let mut rig = DeviceRig::new(camera, slider, operator, cfg.scan.approach_feed_mm_min);
    rig.laser = super::ScanPlan::from_config(cfg).laser;
    Ok(OpenRig { rig, sim })
}

/// Open the simulated scanner of `cfg` as a calibration rig (a config whose backend is not
/// the simulator is opened as the simulator all the same: for benchmarks).
pub fn open_sim_rig(cfg: &ScanConfig, plan: &CalibrationPlan) -> Result<OpenRig, CalibError> {
    let mut c = cfg.clone();
    c.scanner.backend = Backend::Sim;
    open_rig(&c, plan)
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

/// The scanner's current calibration (`scanner.calibration`), the model the guided steps
/// check with; None when none is configured (the checks then use the plan's nominal design).
pub fn prior_calibration(cfg: &LoadedConfig) -> Result<Option<Calibration>, CalibError> {
    match cfg.calibration_path() {
        Some(p) => Calibration::load(&p).map(Some).map_err(|e| {
            CalibError::Plan(format!(
                "the current calibration: {}",
                footscan_util::Chain(&e)
            ))
        }),
        None => Ok(None),
    }
}

/// Acquire the in-system data through `rig` with the guided procedure, every step confirmed
/// and kept by `guide`, using the calibration detector.
pub fn acquire_with(
    rig: &mut dyn acquire::CalibrationRig,
    plan: &CalibrationPlan,
    prior: Option<&CameraModel>,
    guide: &mut dyn Guide,
) -> Result<crate::calib::guided::GuidedData, CalibError> {
    let mut det = detector(DETECTOR)?;
    acquire_guided(
        rig,
        &mut GuidedRun {
            plan,
            prior,
            detector: det.as_mut(),
        },
        guide,
    )
}

/// The guided procedure through `rig`, then the fit of `method` (insystem or bezier).
pub fn calibrate_with(
    rig: &mut dyn acquire::CalibrationRig,
    method: Method,
    plan: &CalibrationPlan,
    prior: Option<&CameraModel>,
    guide: &mut dyn Guide,
) -> Result<Calibrated, CalibError> {
    let guided = acquire_with(rig, plan, prior, guide)?;
    let mut out = from_insystem(&guided.data, method, plan)?;
    out.steps = guided.steps;
    Ok(out)
}

/// Acquire the in-system data through `rig` with nobody to ask: every step confirmed, a step
/// whose check fails aborts with its message. `progress(step title, done, total)`.
pub fn acquire_insystem(
    rig: &mut dyn acquire::CalibrationRig,
    plan: &CalibrationPlan,
    progress: acquire::Progress,
) -> Result<acquire::InsystemData, CalibError> {
    let mut guide = AutoGuide::new(1);
    guide.on_event = Some(progress);
    Ok(acquire_with(rig, plan, None, &mut guide)?.data)
}

/// Calibrate the scanner of `cfg` with `method`: open its devices ([`open_rig`], any backend),
/// run the guided procedure with `guide`, fit. `prior` is the current calibration (the check
/// model). Method opencv renders board shots and runs on the simulator only.
pub fn calibrate(
    cfg: &ScanConfig,
    method: Method,
    plan: &CalibrationPlan,
    prior: Option<&CameraModel>,
    guide: &mut dyn Guide,
) -> Result<Calibrated, CalibError> {
    plan.validate()?;
    match method {
        Method::Insystem | Method::Bezier => {
            plan.check_insystem()?;
            let mut open = open_rig(cfg, plan)?;
            calibrate_with(&mut open.rig, method, plan, prior, guide)
        }
        Method::Opencv => {
            if cfg.scanner.backend != Backend::Sim {
                return Err(CalibError::Plan(
                    "method opencv is the simulator's checkerboard reference; calibrate a \
                     hardware scanner with insystem or bezier"
                        .into(),
                ));
            }
            opencv_sim(cfg, plan, &mut |_, _, _| {})
        }
    }
}

/// The daily check's one step: the staircase pass of `plan` at `step_mm`.
pub fn verify_steps(plan: &CalibrationPlan, step_mm: f64) -> Vec<Step> {
    let n = ((plan.stair_end_mm - plan.stair_start_mm) / step_mm).floor() as usize;
    vec![Step {
        index: 0,
        of: 1,
        kind: StepKind::Staircase,
        title: "staircase gauge (daily check)".into(),
        instruction: staircase_instruction(&plan.staircase, plan.stair_start_mm, plan.stair_end_mm),
        positions_mm: (0..=n)
            .map(|i| plan.stair_start_mm + i as f64 * step_mm)
            .collect(),
        frames_per_position: 1,
    }]
}

/// The daily check through `rig`: the staircase pass (checked like a calibration step, with
/// `cal` as the check model), measured with `cal` against the gauge of `plan`.
pub fn verify_with(
    rig: &mut dyn acquire::CalibrationRig,
    cal: &Calibration,
    plan: &CalibrationPlan,
    section: &super::config::CalibrationSection,
    guide: &mut dyn Guide,
) -> Result<CheckReport, CalibError> {
    plan.validate()?;
    // The pass's own check only asks whether the gauge is there and whole: it must not fail
    // on the calibration error the daily check is there to measure. Heights are given up to
    // just under half the closest spacing of two steps.
    let mut hs = plan.staircase.heights_mm.clone();
    hs.sort_by(f64::total_cmp);
    let gap = hs
        .windows(2)
        .map(|w| w[1] - w[0])
        .fold(f64::INFINITY, f64::min);
    let mut plan = plan.clone();
    plan.checks.height_mm = (0.45 * gap).clamp(plan.checks.height_mm, 5.0);
    plan.checks.height_rel = 0.0;
    let plan = &plan;
    let steps = verify_steps(plan, section.verify_step_mm);
    let mut det = detector(DETECTOR)?;
    let mut run = GuidedRun {
        plan,
        prior: Some(&cal.model),
        detector: det.as_mut(),
    };
    let mut check = None;
    let (kept, _, _) = run_steps(rig, &steps, &mut run, &mut check, guide)?;
    let frames = match kept.into_iter().next() {
        Some(StepData::Frames(f)) => f,
        _ => unreachable!("the staircase step keeps frames"),
    };
    Ok(crate::calib::verify::check(
        &frames,
        &plan.staircase,
        cal,
        section.verify_tolerance_mm,
        section.verify_width_tolerance_mm,
    ))
}

/// The daily check of the scanner of `cfg` (any backend) with calibration `cal`.
pub fn verify(
    cfg: &ScanConfig,
    cal: &Calibration,
    plan: &CalibrationPlan,
    guide: &mut dyn Guide,
) -> Result<CheckReport, CalibError> {
    let mut open = open_rig(cfg, plan)?;
    verify_with(&mut open.rig, cal, plan, &cfg.calibration, guide)
}

/// [`calibrate`] with nobody to ask (every step confirmed; a failing check aborts), reporting
/// `progress(step title, done, total)`.
pub fn calibrate_unattended(
    cfg: &ScanConfig,
    method: Method,
    plan: &CalibrationPlan,
    progress: acquire::Progress,
) -> Result<Calibrated, CalibError> {
    if method == Method::Opencv {
        plan.validate()?;
        return opencv_sim(cfg, plan, progress);
    }
    let mut guide = AutoGuide::new(1);
    guide.on_event = Some(progress);
    calibrate(cfg, method, plan, None, &mut guide)
}

#[cfg(feature = "opencv")]
fn opencv_sim(
    cfg: &ScanConfig,
    plan: &CalibrationPlan,
    progress: acquire::Progress,
) -> Result<Calibrated, CalibError> {
    let shots = render_shots(cfg, plan, progress)?;
    let mut det = detector(DETECTOR)?;
    progress("OpenCV calibration", 1, 1);
    let calibration = crate::calib::opencv::calibrate(&shots, &plan.board, det.as_mut())?;
    check_before_saving(&calibration)?;
    Ok(Calibrated {
        calibration,
        insystem: None,
        steps: Vec::new(),
    })
}

#[cfg(not(feature = "opencv"))]
fn opencv_sim(
    _cfg: &ScanConfig,
    _plan: &CalibrationPlan,
    _progress: acquire::Progress,
) -> Result<Calibrated, CalibError> {
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
