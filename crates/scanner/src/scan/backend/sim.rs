//! The simulator backend: the GRBL emulator on a pseudo-terminal reached through the real
//! serial driver, and the simulated camera rendering the foot at the head's true position.

use super::Devices;
use crate::calib::{Calibration, CameraModel};
use crate::scan::config::{ScanConfig, SceneKind, SimFaults};
use crate::scan::summary::TruthSource;
use footscan_grbl::{GrblConfig, GrblSlider, LaserOutput};
use footscan_hal::{Camera, HalError, Slider};
use footscan_sim::camera::{CameraFaults, SimCamera, TruthLog};
use footscan_sim::foot::Foot;
use footscan_sim::grbl::{Fault, GrblEmulator, LaserWiring};
use footscan_sim::optics::Optics;
use footscan_sim::render::{Renderer, RowTruth, Scene};
use std::sync::Arc;
use std::time::Duration;

/// Keeps the emulator alive for the scan and holds the simulator's ground truth.
pub struct SimBackend {
    pub emulator: Arc<GrblEmulator>,
    pub truth_log: TruthLog,
    pub foot: Option<Foot>,
    /// Dropping it ends the fault timer.
    _faults: Option<crossbeam_channel::Sender<()>>,
}

/// Inject the configured faults on a timer that ends when the backend is dropped.
fn schedule_faults(
    f: &SimFaults,
    emulator: &Arc<GrblEmulator>,
    camera: CameraFaults,
) -> Option<crossbeam_channel::Sender<()>> {
    let mut plan: Vec<(f64, Box<dyn FnOnce() + Send>)> = Vec::new();
    if let Some(t) = f.slider_alarm_after_s {
        let (e, code) = (emulator.clone(), f.slider_alarm_code.unwrap_or(1));
        plan.push((t, Box::new(move || e.inject(Fault::Alarm(code)))));
    }
    if let Some(t) = f.slider_silent_after_s {
        let e = emulator.clone();
        plan.push((t, Box::new(move || e.inject(Fault::Silence(true)))));
    }
    if let Some(t) = f.slider_corrupt_status_after_s {
        let (e, n) = (emulator.clone(), f.slider_corrupt_status_count.unwrap_or(5));
        plan.push((t, Box::new(move || e.inject(Fault::CorruptStatus(n)))));
    }
    if let Some(t) = f.slider_disconnect_after_s {
        let e = emulator.clone();
        plan.push((t, Box::new(move || e.inject(Fault::Disconnect))));
    }
    if let Some(t) = f.camera_unplug_after_s {
        plan.push((t, Box::new(move || camera.unplug())));
    }
    if plan.is_empty() {
        return None;
    }
    plan.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (tx, rx) = crossbeam_channel::bounded::<()>(0);
    let start = std::time::Instant::now();
    std::thread::Builder::new()
        .name("sim-faults".into())
        .spawn(move || {
            for (t, inject) in plan {
                let wait = Duration::from_secs_f64(t.max(0.0)).saturating_sub(start.elapsed());
                if rx.recv_timeout(wait) != Err(crossbeam_channel::RecvTimeoutError::Timeout) {
                    return; // backend dropped: the scan is over
                }
                tracing::info!(after_s = t, "injecting simulated fault");
                inject();
            }
        })
        .expect("spawn fault timer");
    Some(tx)
}

/// Why the simulated scanner could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum SimOpenError {
    #[error("starting the GRBL emulator")]
    Emulator(#[source] std::io::Error),
    #[error(transparent)]
    Device(#[from] HalError),
    /// The scene or the renderer rejected the configuration.
    #[error("{0}")]
    Scene(String),
}

/// The simulated scanner's devices: the GRBL emulator (kept alive here) behind the real serial
/// driver, and the simulated camera rendering `scene` at the head's true position.
pub struct SimDevices {
    pub emulator: Arc<GrblEmulator>,
    pub slider: GrblSlider,
    pub camera: SimCamera,
}

/// Start the emulator, connect the GRBL driver to its pty, home (if `scan.home`), and build
/// the camera with the config's exposure and gain: the one way scans and calibration open
/// the simulator.
pub fn open_sim_devices(cfg: &ScanConfig, scene: Scene) -> Result<SimDevices, SimOpenError> {
    let sim = &cfg.sim;
    let emulator =
        Arc::new(GrblEmulator::spawn(sim.slider.clone()).map_err(SimOpenError::Emulator)?);
    // The driver switches whichever output the simulated laser is wired to.
    let laser = match sim.slider.laser {
        LaserWiring::Always => None,
        LaserWiring::Spindle => Some(LaserOutput::Spindle { power: 1000.0 }),
        LaserWiring::Flood => Some(LaserOutput::Flood),
    };
    let mut slider = GrblSlider::new(
        emulator.port_path().to_string_lossy(),
        GrblConfig {
            laser,
            ..GrblConfig::default()
        },
    );
    slider.connect()?;
    if cfg.scan.home {
        slider.home(Duration::from_secs(30))?;
    }
    let renderer = Renderer::new(sim.optics.clone(), sim.noise.clone(), scene, sim.seed)
        .map_err(|e| SimOpenError::Scene(footscan_util::chain(&e)))?;
    let mut camera = SimCamera::new(
        renderer,
        cfg.camera.fps,
        emulator.position_source(),
        sim.seed,
    )?;
    camera.set_laser_source(emulator.laser_source());
    camera.set_exposure_us(cfg.camera.exposure_us)?;
    camera.set_gain(cfg.camera.gain)?;
    Ok(SimDevices {
        emulator,
        slider,
        camera,
    })
}

/// Open the simulated scanner of a scan: its scene, devices and ground truth.
pub fn open(cfg: &ScanConfig) -> Result<(Devices, SimBackend), SimOpenError> {
    let sim = &cfg.sim;
    let (scene, foot) = match sim.scene {
        SceneKind::Foot => {
            let foot = Foot::new(sim.foot.clone())
                .map_err(|e| SimOpenError::Scene(footscan_util::chain(&e)))?;
            (Scene::Foot(foot.clone()), Some(foot))
        }
        SceneKind::Empty => (Scene::Empty, None),
        SceneKind::Last => {
            let surface = footscan_sim::last::Last::new(sim.last.clone())
                .and_then(|l| l.surface())
                .map_err(|e| {
                    SimOpenError::Scene(format!("[sim.last]: {}", footscan_util::Chain(&e)))
                })?;
            (Scene::Surface(Arc::new(surface)), None)
        }
        SceneKind::Mesh => {
            let surface = sim
                .mesh
                .load()
                .map_err(|e| SimOpenError::Scene(footscan_util::chain(&e)))?;
            (Scene::Surface(Arc::new(surface)), None)
        }
        SceneKind::Plate => (
            Scene::Plate {
                height_mm: sim.plate_height_mm,
            },
            None,
        ),
    };
    let SimDevices {
        emulator,
        slider,
        camera,
    } = open_sim_devices(cfg, scene)?;
    let truth_log = camera.truth_log();
    let faults = schedule_faults(&sim.faults, &emulator, camera.faults());
    Ok((
        Devices {
            camera: Box::new(camera),
            slider: Box::new(slider),
        },
        SimBackend {
            emulator,
            truth_log,
            foot,
            _faults: faults,
        },
    ))
}

/// The simulator's exact model, as a calibration file a scan can load.
pub fn true_calibration(cfg: &ScanConfig) -> Calibration {
    let o: &Optics = &cfg.sim.optics;
    Calibration {
        method: "simulator-truth".into(),
        date: footscan_util::now_rfc3339(),
        model: CameraModel {
            width: o.width,
            height: o.height,
            f_px: o.f_px,
            cx: o.cx,
            cy: o.cy,
            d_mm: o.d_mm,
            l_mm: o.l_mm,
            k1: o.k1,
            k2: o.k2,
            p1: o.p1,
            p2: o.p2,
            camera_tilt_deg: o.camera_tilt_deg,
            laser_tilt_deg: o.laser_tilt_deg,
            slider_scale: cfg.sim.slider.slider_scale,
        },
        stddev: Default::default(),
        residuals: Default::default(),
        bezier: None,
    }
}

impl TruthSource for TruthLog {
    fn frame(&self, seq: u64) -> Option<Vec<Option<footscan_geom::P3>>> {
        let t = self.get(seq)?;
        Some(
            t.rows
                .iter()
                .map(|r| match r {
                    RowTruth::Line { point, .. } => Some((*point).into()),
                    RowTruth::NoLine => None,
                })
                .collect(),
        )
    }
}

pub fn truth_source(b: &SimBackend) -> Arc<dyn TruthSource> {
    Arc::new(b.truth_log.clone())
}
