//! What can be checked before the first scan. Config errors (unknown stages or stage
//! parameters, impossible optics, a scan range beyond the simulated slider's travel, a missing
//! or mismatched calibration) stop the daemon at start: otherwise it would report itself
//! healthy and fail every scan. Hardware devices are only looked for: they may be plugged in
//! later, so a missing one is reported absent in the status and scans are refused with 503
//! naming it until it appears.

use footscan::calib::Calibration;
use footscan::pipeline::{BuildError, PipelineSpec};
use footscan::scan::config::Backend;
use footscan::scan::{LoadedConfig, ScanContext, ScanPlan};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// The calibration scans will use: `daemon` (the daemon's own, which overrides the scanner
/// config's), else `scanner.calibration`, else (simulator only) the simulator's true model.
/// Each error names the file and the key it came from.
pub fn scan_calibration(
    cfg: &LoadedConfig,
    daemon: Option<(&Path, &str)>,
) -> Result<Calibration, String> {
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
            Backend::Hardware => Err(format!(
                "scanner config {file}: the hardware backend needs a calibration file: set \
                 scanner.calibration there or `calibration` in [daemon] of the daemon config \
                 (`footscan calibrate` writes one)"
            )),
        };
    };
    let cal = Calibration::load(&path)
        .map_err(|e| format!("{} (from {from})", footscan_util::Chain(&e)))?;
    if let (Backend::Hardware, Some(hw)) = (cfg.config.scanner.backend, &cfg.config.hardware) {
        let m = &cal.model;
        if (m.width, m.height) != (hw.camera.width, hw.camera.height) {
            return Err(format!(
                "calibration {} (from {from}) is for a {}x{} camera, but hardware.camera in \
                 {file} is {}x{}: calibrate this camera or set its width and height",
                path.display(),
                m.width,
                m.height,
                hw.camera.width,
                hw.camera.height
            ));
        }
    }
    Ok(cal)
}

/// Config errors found without running a scan, each naming the file, the key and what is
/// valid. `calibration` is what [`scan_calibration`] resolved.
pub fn check_config(cfg: &LoadedConfig, calibration: &Calibration) -> Result<(), String> {
    check_stages(cfg, calibration)?;
    let c = &cfg.config;
    if c.scanner.backend == Backend::Sim {
        let file = cfg.path.display();
        let travel = c.sim.slider.travel_mm;
        let (a, b) = (c.scan.start_mm, c.scan.end_mm);
        if a < 0.0 || b > travel {
            return Err(format!(
                "scanner config {file}: the scan range [{a}, {b}] mm (scan.start_mm, \
                 scan.end_mm) leaves the slider's travel [0, {travel}] mm (sim.slider.travel_mm)"
            ));
        }
        let o = &c.sim.optics;
        o.validate()
            .map_err(|e| format!("scanner config {file}: [sim.optics]: {e}"))?;
        c.sim
            .noise
            .validate()
            .map_err(|e| format!("scanner config {file}: [sim.noise]: {e}"))?;
        // The laser line on the empty glass must be in the picture, or no row ever sees it.
        let mid = 0.5 * (a + b) * c.sim.slider.slider_scale;
        let glass = [o.laser_x(mid, 0.0, 0.0), 0.0, 0.0];
        let seen = o.project(mid, glass).filter(|[col, row]| {
            (0.0..o.width as f64).contains(col) && (0.0..o.height as f64).contains(row)
        });
        if seen.is_none() {
            return Err(format!(
                "scanner config {file}: [sim.optics]: the laser line on the glass falls outside \
                 the {}x{} image (at {}), so no frame can see it: check l_mm = {}, d_mm = {}, \
                 f_px = {}, cx = {} and the tilts",
                o.width,
                o.height,
                o.project(mid, glass)
                    .map_or("no point in front of the camera".into(), |[x, y]| format!(
                        "column {x:.0}, row {y:.0}"
                    )),
                o.l_mm,
                o.d_mm,
                o.f_px,
                o.cx
            ));
        }
    }
    Ok(())
}

/// Every stage name and every stage's parameters, by running each stage's factory on its own
/// (factories check their parameters and read the files they name, e.g. a last or a
/// calibration; none opens a device or writes a file). The acquire stage, the one factory that
/// takes the devices, is checked for parameters only: it has none.
fn check_stages(cfg: &LoadedConfig, calibration: &Calibration) -> Result<(), String> {
    let file = cfg.path.display();
    let registry = footscan::scan::registry();
    let spec = &cfg.config.pipeline;
    for (i, s) in spec.stages.iter().enumerate() {
        if !registry.contains(&s.stage) {
            return Err(format!(
                "scanner config {file}: pipeline stage {} is {:?}{}, which is not a stage; \
                 valid: {}",
                i + 1,
                s.stage,
                cfg.locate_stage_key(i, "stage").unwrap_or_default(),
                registry.names().join(", ")
            ));
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
        let wrong = |why: String| {
            let key = backticked(&why).unwrap_or("stage");
            format!(
                "scanner config {file}: pipeline stage {} ({:?}){}: {why}",
                i + 1,
                s.stage,
                cfg.locate_stage_key(i, key).unwrap_or_default()
            )
        };
        let source = if s.stage == "acquire" {
            if let Some(key) = s.params.keys().next() {
                return Err(wrong(format!("unknown field `{key}`, there are no fields")));
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
                Err(BuildError::Factory { source, .. }) => return Err(wrong(source.to_string())),
                Err(e) => return Err(wrong(e.to_string())),
            }
        };
        if source != (i == 0) {
            return Err(wrong(if source {
                "a source; only the first stage may be one".into()
            } else {
                "not a source; the first stage must be one (acquire)".into()
            }));
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
