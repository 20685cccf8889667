//! What can be checked before the first scan: the scanner config's stage names, the scan
//! range against the simulated slider's travel (config errors: the daemon refuses to start),
//! and whether the hardware devices exist (they may be plugged in later: reported absent in
//! the status, and scans refused with 503 naming the device until they appear).

use footscan::scan::config::Backend;
use footscan::scan::LoadedConfig;
use std::path::Path;

/// Config errors found without running a scan, each naming the key and what is valid.
pub fn check_config(cfg: &LoadedConfig) -> Result<(), String> {
    let c = &cfg.config;
    let registry = footscan::scan::registry();
    for (i, s) in c.pipeline.stages.iter().enumerate() {
        if !registry.contains(&s.stage) {
            return Err(format!(
                "scanner config {}: pipeline stage {} is {:?}, which is not a stage; valid: {}",
                cfg.path.display(),
                i + 1,
                s.stage,
                registry.names().join(", ")
            ));
        }
    }
    if c.scanner.backend == Backend::Sim {
        let travel = c.sim.slider.travel_mm;
        let (a, b) = (c.scan.start_mm, c.scan.end_mm);
        if a < 0.0 || b > travel {
            return Err(format!(
                "scanner config {}: the scan range [{a}, {b}] mm (scan.start_mm, scan.end_mm) \
                 leaves the slider's travel [0, {travel}] mm (sim.slider.travel_mm)",
                cfg.path.display()
            ));
        }
    }
    Ok(())
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
