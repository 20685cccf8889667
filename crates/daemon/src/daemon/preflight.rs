//! What can be checked before the first scan. Config errors (unknown stages or stage
//! parameters, impossible optics, a scan range beyond the simulated slider's travel, a missing
//! or mismatched calibration) stop the daemon at start: otherwise it would report itself
//! healthy and fail every scan. Hardware devices are only looked for: they may be plugged in
//! later, so a missing one is reported absent in the status and scans are refused with 503
//! naming it until it appears.

use footscan::calib::{Calibration, CalibrationError};
use footscan::pipeline::{BoxError, BuildError, PipelineSpec};
use footscan::scan::config::Backend;
use footscan::scan::{LoadedConfig, ScanContext, ScanPlan};
use footscan_sim::optics::SimError;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// Why the daemon does not start on a scanner config: each names the file, the key and what
/// is valid.
#[derive(Debug, thiserror::Error)]
pub enum PreflightError {
    #[error(
        "scanner config {}: the hardware backend needs a calibration file: set \
         scanner.calibration there or `calibration` in [daemon] of the daemon config \
         (`footscan calibrate` writes one)",
        file.display()
    )]
    NoCalibration { file: PathBuf },
    /// `from` says which key named the file (and in which config).
    #[error("the calibration named by {from}")]
    Calibration {
        from: String,
        #[source]
        source: CalibrationError,
    },
    #[error(
        "calibration {} (from {from}) is for a {}x{} camera, but hardware.camera in {} is \
         {}x{}: calibrate this camera or set its width and height",
        path.display(), calibrated.0, calibrated.1, file.display(), camera.0, camera.1
    )]
    CameraSize {
        path: PathBuf,
        from: String,
        calibrated: (u32, u32),
        file: PathBuf,
        camera: (u32, u32),
    },
    #[error(
        "scanner config {}: the scan range [{start}, {end}] mm (scan.start_mm, scan.end_mm) \
         leaves the slider's travel [0, {travel}] mm (sim.slider.travel_mm)",
        file.display()
    )]
    ScanRange {
        file: PathBuf,
        start: f64,
        end: f64,
        travel: f64,
    },
    /// A `[sim.*]` section (`section` is e.g. "sim.optics") fails its own check.
    #[error("scanner config {}: [{section}]", file.display())]
    Sim {
        file: PathBuf,
        section: &'static str,
        #[source]
        source: SimError,
    },
    #[error(
        "scanner config {}: [sim.optics]: the laser line on the glass falls outside the \
         {width}x{height} image (at {at}), so no frame can see it: check l_mm = {l_mm}, \
         d_mm = {d_mm}, f_px = {f_px}, cx = {cx} and the tilts",
        file.display()
    )]
    LaserOffImage {
        file: PathBuf,
        width: u32,
        height: u32,
        /// Where it falls, in words.
        at: String,
        l_mm: f64,
        d_mm: f64,
        f_px: f64,
        cx: f64,
    },
    #[error(
        "scanner config {}: pipeline stage {number} is {name:?}{at}, which is not a stage; \
         valid: {}",
        file.display(), valid.join(", ")
    )]
    UnknownStage {
        file: PathBuf,
        /// 1-based, as a reader counts the `[[pipeline.stages]]` tables.
        number: usize,
        name: String,
        /// " (line N)" when the line is known, else empty.
        at: String,
        valid: Vec<String>,
    },
    #[error("scanner config {}: pipeline stage {number} ({name:?}){at}", file.display())]
    Stage {
        file: PathBuf,
        number: usize,
        name: String,
        at: String,
        #[source]
        source: StageProblem,
    },
}

/// What is wrong with one pipeline stage of the scanner config.
#[derive(Debug, thiserror::Error)]
pub enum StageProblem {
    #[error("unknown field `{0}`, there are no fields")]
    AcquireField(String),
    /// The stage's factory refused its parameters or the files they name.
    #[error(transparent)]
    Factory(BoxError),
    #[error(transparent)]
    Build(BuildError),
    #[error("a source; only the first stage may be one")]
    SourceNotFirst,
    #[error("not a source; the first stage must be one (acquire)")]
    FirstNotSource,
}

/// The calibration scans will use: `daemon` (the daemon's own, which overrides the scanner
/// config's), else `scanner.calibration`, else (simulator only) the simulator's true model.
/// Each error names the file and the key it came from.
pub fn scan_calibration(
    cfg: &LoadedConfig,
    daemon: Option<(&Path, &str)>,
) -> Result<Calibration, Box<PreflightError>> {
    let file = cfg.path.display();
    let from = match daemon {
        Some((p, from)) => Some((p.to_path_buf(), from.to_string())),
        None => cfg
            .calibration_path()
            .map(|p| (p, format!("scanner.calibration in {file}"))),
    };
    let Some((path, from)) = from else {
        return match cfg.config.scanner.backend {
            Backend::Sim => Ok(footscan::scan::sim::true_calibration(&cfg.config)),
            Backend::Hardware => Err(PreflightError::NoCalibration {
                file: cfg.path.clone(),
            }
            .into()),
        };
    };
    let cal = Calibration::load(&path).map_err(|source| PreflightError::Calibration {
        from: from.clone(),
        source,
    })?;
    if let (Backend::Hardware, Some(hw)) = (cfg.config.scanner.backend, &cfg.config.hardware) {
        let m = &cal.model;
        if (m.width, m.height) != (hw.camera.width, hw.camera.height) {
            return Err(PreflightError::CameraSize {
                path,
                from,
                calibrated: (m.width, m.height),
                file: cfg.path.clone(),
                camera: (hw.camera.width, hw.camera.height),
            }
            .into());
        }
    }
    Ok(cal)
}

/// Config errors found without running a scan, each naming the file, the key and what is
/// valid. `calibration` is what [`scan_calibration`] resolved.
pub fn check_config(
    cfg: &LoadedConfig,
    calibration: &Calibration,
) -> Result<(), Box<PreflightError>> {
    check_stages(cfg, calibration)?;
    let c = &cfg.config;
    if c.scanner.backend == Backend::Sim {
        let file = || cfg.path.clone();
        let travel = c.sim.slider.travel_mm;
        let (a, b) = (c.scan.start_mm, c.scan.end_mm);
        if a < 0.0 || b > travel {
            return Err(PreflightError::ScanRange {
                file: file(),
                start: a,
                end: b,
                travel,
            }
            .into());
        }
        let sim = |section| {
            move |source| PreflightError::Sim {
                file: file(),
                section,
                source,
            }
        };
        let o = &c.sim.optics;
        o.validate().map_err(sim("sim.optics"))?;
        c.sim.noise.validate().map_err(sim("sim.noise"))?;
        // The laser line on the empty glass must be in the picture, or no row ever sees it.
        let mid = 0.5 * (a + b) * c.sim.slider.slider_scale;
        let glass = [o.laser_x(mid, 0.0, 0.0), 0.0, 0.0];
        let seen = o.project(mid, glass).filter(|[col, row]| {
            (0.0..o.width as f64).contains(col) && (0.0..o.height as f64).contains(row)
        });
        if seen.is_none() {
            return Err(PreflightError::LaserOffImage {
                file: file(),
                width: o.width,
                height: o.height,
                at: o
                    .project(mid, glass)
                    .map_or("no point in front of the camera".into(), |[x, y]| {
                        format!("column {x:.0}, row {y:.0}")
                    }),
                l_mm: o.l_mm,
                d_mm: o.d_mm,
                f_px: o.f_px,
                cx: o.cx,
            }
            .into());
        }
    }
    Ok(())
}

/// Every stage name and every stage's parameters, by running each stage's factory on its own
/// (factories check their parameters and read the files they name, e.g. a last or a
/// calibration; none opens a device or writes a file). The acquire stage, the one factory that
/// takes the devices, is checked for parameters only: it has none.
fn check_stages(cfg: &LoadedConfig, calibration: &Calibration) -> Result<(), Box<PreflightError>> {
    let registry = footscan::scan::registry();
    let spec = &cfg.config.pipeline;
    for (i, s) in spec.stages.iter().enumerate() {
        if !registry.contains(&s.stage) {
            return Err(PreflightError::UnknownStage {
                file: cfg.path.clone(),
                number: i + 1,
                name: s.stage.clone(),
                at: cfg.locate_stage_key(i, "stage").unwrap_or_default(),
                valid: registry.names().iter().map(|n| n.to_string()).collect(),
            }
            .into());
        }
    }
    let scratch = std::env::temp_dir().join("footscand-preflight");
    let ctx = ScanContext {
        out_dir: scratch,
        plan: ScanPlan::from_config(&cfg.config),
        devices: Mutex::new(None),
        calibration: Some(calibration.clone()),
        truth: None,
        counters: Arc::default(),
        tap: None,
        label: Default::default(),
    };
    for (i, s) in spec.stages.iter().enumerate() {
        // The line is that of the key the problem names (serde quotes it in backticks).
        let wrong = |why: StageProblem| {
            let text = why.to_string();
            let key = backticked(&text).unwrap_or("stage");
            PreflightError::Stage {
                file: cfg.path.clone(),
                number: i + 1,
                name: s.stage.clone(),
                at: cfg.locate_stage_key(i, key).unwrap_or_default(),
                source: why,
            }
        };
        let source = if s.stage == "acquire" {
            if let Some(key) = s.params.keys().next() {
                return Err(wrong(StageProblem::AcquireField(key.clone())).into());
            }
            true
        } else {
            let one = PipelineSpec {
                capacity: spec.capacity.max(1),
                stages: vec![s.clone()],
            };
            match registry.build(&one, &ctx) {
                Ok(_) => true,
                Err(BuildError::FirstNotSource { .. }) => false,
                Err(BuildError::Factory { source, .. }) => {
                    return Err(wrong(StageProblem::Factory(source)).into())
                }
                Err(e) => return Err(wrong(StageProblem::Build(e)).into()),
            }
        };
        if source != (i == 0) {
            return Err(wrong(if source {
                StageProblem::SourceNotFirst
            } else {
                StageProblem::FirstNotSource
            })
            .into());
        }
    }
    Ok(())
}

/// The first word quoted in backticks (serde names unknown fields this way).
fn backticked(msg: &str) -> Option<&str> {
    let start = msg.find('`')? + 1;
    let len = msg[start..].find('`')?;
    Some(&msg[start..start + len])
}

/// Hardware devices whose device node is missing now, as (role, message).
pub fn missing_devices(cfg: &LoadedConfig) -> Vec<(&'static str, String)> {
    let c = &cfg.config;
    let mut out = Vec::new();
    if c.scanner.backend != Backend::Hardware {
        return out;
    }
    if let Some(hw) = &c.hardware {
        if !hw.camera.device.exists() {
            out.push((
                "camera",
                format!(
                    "the camera {} is not present (hardware.camera.device in {}): plug it in",
                    hw.camera.device.display(),
                    cfg.path.display()
                ),
            ));
        }
        if !Path::new(&hw.slider.port).exists() {
            out.push((
                "slider",
                format!(
                    "the slider's serial port {} is not present (hardware.slider.port in {}): \
                     plug it in",
                    hw.slider.port,
                    cfg.path.display()
                ),
            ));
        }
    }
    out
}
