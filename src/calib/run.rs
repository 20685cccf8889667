//! A calibration from end to end: acquire through the scanner (the simulator backend here),
//! fit with the chosen method, and produce the [`Calibration`] a scan loads.

use super::acquire::{self, CalibrationRig, DeviceRig, InsystemData, RenderRig, SimOperator};
use super::bezier_depth::BezierDepth;
use super::insystem::{fit_insystem, InsystemFit, InsystemOptions};
use super::{CalibError, Calibration, CalibrationPlan};
use crate::detect::Detector;
use crate::scan::ScanConfig;
use footscan_grbl::{GrblConfig, GrblSlider};
use footscan_hal::{Camera, Slider};
use footscan_sim::camera::SimCamera;
use footscan_sim::grbl::GrblEmulator;
use footscan_sim::render::{Renderer, Scene};
use footscan_sim::targets::Staircase;
use std::sync::Arc;
use std::time::Duration;

/// How the scanner is calibrated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The general model fitted to the plate and staircase seen through the scanner itself.
    Insystem,
    /// Heights from the Bezier depth network (x and y from the in-system model).
    Bezier,
    /// OpenCV checkerboard calibration and a laser plane fitted on the board.
    Opencv,
}

impl Method {
    pub const ALL: [Method; 3] = [Method::Insystem, Method::Bezier, Method::Opencv];

    pub fn name(self) -> &'static str {
        match self {
            Method::Insystem => "insystem",
            Method::Bezier => "bezier",
            Method::Opencv => "opencv",
        }
    }
}

impl std::str::FromStr for Method {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| format!("unknown method `{s}`: one of insystem, bezier, opencv"))
    }
}

/// The detector calibration uses: the most accurate of [`crate::detect::NAMES`] on the
/// simulated line (see `footscan bench detect`).
pub const DETECTOR: &str = "bezier-plus";

/// A detector by name with its default parameters.
pub fn detector(name: &str) -> Result<Box<dyn Detector>, CalibError> {
    crate::detect::build(name, &Default::default())
        .map_err(|e| CalibError::Plan(format!("calibration detector: {e}")))
}

/// A calibration and what was learnt making it.
#[derive(Clone, Debug)]
pub struct Outcome {
    pub calibration: Calibration,
    /// The in-system fit (methods insystem and bezier).
    pub insystem: Option<InsystemFit>,
}

/// The simulator as a calibration rig: the GRBL emulator behind the real serial driver, the
/// simulated camera, and an operator who swaps the scene. Keeps the emulator alive.
pub struct SimRig {
    pub rig: DeviceRig,
    _emulator: Arc<GrblEmulator>,
}

/// Open the simulated scanner of `cfg` as a calibration rig.
pub fn open_sim_rig(cfg: &ScanConfig, plan: &CalibrationPlan) -> Result<SimRig, CalibError> {
    let sim = &cfg.sim;
    let sim_err = |e: &dyn std::fmt::Display| CalibError::Sim(e.to_string());
    let emulator = Arc::new(
        GrblEmulator::spawn(sim.slider.clone())
            .map_err(|e| CalibError::Sim(format!("starting the GRBL emulator: {e}")))?,
    );
    let mut slider = GrblSlider::new(
        emulator.port_path().to_string_lossy(),
        GrblConfig::default(),
    );
    slider.connect()?;
    if cfg.scan.home {
        slider.home(Duration::from_secs(30))?;
    }
    let renderer = Renderer::new(
        sim.optics.clone(),
        sim.noise.clone(),
        Scene::Empty,
        sim.seed,
    )
    .map_err(|e| sim_err(&e))?;
    let mut camera = SimCamera::new(
        renderer,
        cfg.camera.fps,
        emulator.position_source(),
        sim.seed,
    )?;
    camera.set_exposure_us(cfg.camera.exposure_us)?;
    camera.set_gain(cfg.camera.gain)?;
    let staircase =
        Staircase::new(plan.staircase.clone(), plan.sim.staircase).map_err(|e| sim_err(&e))?;
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

/// Acquire the in-system data through `rig` with the calibration detector.
pub fn acquire_insystem(
    rig: &mut dyn CalibrationRig,
    plan: &CalibrationPlan,
    progress: acquire::Progress,
) -> Result<InsystemData, CalibError> {
    let mut det = detector(DETECTOR)?;
    acquire::acquire_insystem(rig, plan, det.as_mut(), progress)
}

/// Fit `method` (insystem or bezier) to in-system data.
pub fn from_insystem(
    data: &InsystemData,
    method: Method,
    plan: &CalibrationPlan,
) -> Result<Outcome, CalibError> {
    let fit = fit_insystem(data, &InsystemOptions::default())?;
    let mut calibration = Calibration {
        method: Method::Insystem.name().into(),
        date: crate::util::now_rfc3339(),
        model: fit.model.clone(),
        stddev: fit.stddev.clone(),
        residuals: fit.residuals.clone(),
        bezier: None,
    };
    match method {
        Method::Insystem => {}
        Method::Bezier => {
            let net = BezierDepth::fit(
                &data.plates,
                plan.bezier_degree_v,
                plan.bezier_smooth_degree,
            )?;
            calibration.method = Method::Bezier.name().into();
            let r = &mut calibration.residuals;
            r.insert("bezier_condition".into(), net.condition);
            r.insert("bezier_blocks".into(), net.blocks.len() as f64);
            r.insert(
                "bezier_u_h_detection_mm".into(),
                net.detection_uncertainty(fit.detection_noise_px),
            );
            calibration.bezier = Some(net);
        }
        Method::Opencv => {
            return Err(CalibError::Plan(
                "method opencv does not use in-system data".into(),
            ))
        }
    }
    check_before_saving(&calibration)?;
    Ok(Outcome {
        calibration,
        insystem: Some(fit),
    })
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
    let shots = super::opencv::render_shots(cfg, plan, progress)?;
    let mut det = detector(DETECTOR)?;
    progress("OpenCV calibration", 1, 1);
    let calibration = super::opencv::calibrate(&shots, &plan.board, det.as_mut())?;
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

/// The last line of defence before a file is written: a valid model and finite figures.
pub fn check_before_saving(c: &Calibration) -> Result<(), CalibError> {
    c.model
        .validate()
        .map_err(|e| CalibError::Implausible(format!("model: {e}")))?;
    if let Some((k, v)) = c.stddev.iter().find(|(_, v)| !v.is_finite()) {
        return Err(CalibError::Implausible(format!(
            "standard deviation of {k} is {v}: the data do not determine it"
        )));
    }
    let m = &c.model;
    if !(m.cx > 0.0 && m.cx < m.width as f64 && m.cy > 0.0 && m.cy < m.height as f64) {
        return Err(CalibError::Implausible(format!(
            "principal point ({:.1}, {:.1}) outside the {}x{} image",
            m.cx, m.cy, m.width, m.height
        )));
    }
    Ok(())
}
