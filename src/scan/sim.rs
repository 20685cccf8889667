//! The simulator backend: the GRBL emulator on a pseudo-terminal reached through the real
//! serial driver, and the simulated camera rendering the foot at the head's true position.

use super::config::{ScanConfig, SceneKind};
use super::{Devices, TruthSource};
use crate::calib::{Calibration, CameraModel};
use footscan_grbl::{GrblConfig, GrblSlider};
use footscan_hal::{Camera, Slider};
use footscan_sim::camera::{SimCamera, TruthLog};
use footscan_sim::foot::Foot;
use footscan_sim::grbl::GrblEmulator;
use footscan_sim::optics::Optics;
use footscan_sim::render::{Renderer, RowTruth, Scene};
use std::sync::Arc;
use std::time::Duration;

/// Keeps the emulator alive for the scan and holds the simulator's ground truth.
pub struct SimBackend {
    pub emulator: GrblEmulator,
    pub truth_log: TruthLog,
    pub foot: Option<Foot>,
}

/// Start the emulator, connect the GRBL driver to its pty, home, and build the camera.
pub fn open(
    cfg: &ScanConfig,
) -> Result<(Devices, SimBackend), Box<dyn std::error::Error + Send + Sync>> {
    let sim = &cfg.sim;
    let emulator = GrblEmulator::spawn(sim.slider.clone())
        .map_err(|e| format!("starting the GRBL emulator: {e}"))?;
    let mut slider = GrblSlider::new(
        emulator.port_path().to_string_lossy(),
        GrblConfig::default(),
    );
    slider.connect()?;
    if cfg.scan.home {
        slider.home(Duration::from_secs(30))?;
    }
    let (scene, foot) = match sim.scene {
        SceneKind::Foot => {
            let foot = Foot::new(sim.foot.clone())?;
            (Scene::Foot(foot.clone()), Some(foot))
        }
        SceneKind::Empty => (Scene::Empty, None),
        SceneKind::Plate => (
            Scene::Plate {
                height_mm: sim.plate_height_mm,
            },
            None,
        ),
    };
    let renderer = Renderer::new(sim.optics.clone(), sim.noise.clone(), scene, sim.seed)?;
    let mut camera = SimCamera::new(
        renderer,
        cfg.camera.fps,
        emulator.position_source(),
        sim.seed,
    )?;
    camera.set_exposure_us(cfg.camera.exposure_us)?;
    camera.set_gain(cfg.camera.gain)?;
    let truth_log = camera.truth_log();
    Ok((
        Devices {
            camera: Box::new(camera),
            slider: Box::new(slider),
        },
        SimBackend {
            emulator,
            truth_log,
            foot,
        },
    ))
}

/// The simulator's exact model, as a calibration file a scan can load.
pub fn true_calibration(cfg: &ScanConfig) -> Calibration {
    let o: &Optics = &cfg.sim.optics;
    Calibration {
        method: "simulator-truth".into(),
        date: crate::util::now_rfc3339(),
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
    }
}

impl TruthSource for TruthLog {
    fn frame(&self, seq: u64) -> Option<Vec<Option<[f64; 3]>>> {
        let t = self.get(seq)?;
        Some(
            t.rows
                .iter()
                .map(|r| match r {
                    RowTruth::Line { point, .. } => Some(*point),
                    RowTruth::NoLine => None,
                })
                .collect(),
        )
    }
}

pub fn truth_source(b: &SimBackend) -> Arc<dyn TruthSource> {
    Arc::new(b.truth_log.clone())
}
