//! The hardware backend: a V4L2 camera and a GRBL 1.1 slider on a serial port. With hardware
//! there is no ground truth and no default calibration: a calibration file is required
//! (`--calibration` or `scanner.calibration`).
//!
//! Opening order: the camera first (no motion), then the slider (reset, settings checked
//! against the scan, homing), so a scanner that cannot see never moves.
//!
//! Unlock policy: the backend never sends `$X`. A controller that comes up alarm-locked
//! (homing enabled, or an earlier alarm) is homed when `scan.home` is true; otherwise opening
//! fails and says so, because a position that was never homed cannot label frames.

use super::Devices;
use crate::scan::config::{CameraSection, HardwareCamera, HardwareSlider, ScanConfig, ScanSection};
use footscan_grbl::{GrblConfig, GrblSlider};
use footscan_hal::{HalError, Slider};
use footscan_v4l2::{SourceFormat, V4l2Camera, V4l2Config};
use std::time::Duration;

/// Why a hardware device could not be opened; each message names the device and what to try.
#[derive(Debug, thiserror::Error)]
pub enum HardwareError {
    #[error("camera {device}: {detail}; {hint}")]
    Camera {
        device: String,
        detail: String,
        #[source]
        source: Box<HalError>,
        hint: String,
    },
    #[error("slider {port}: {detail}; {hint}")]
    Slider {
        port: String,
        detail: String,
        #[source]
        source: Box<HalError>,
        hint: String,
    },
    #[error("slider {port}: {0}", port = .1)]
    SliderCheck(String, String),
}

/// The driver settings of `[hardware.slider]`.
pub fn grbl_config(s: &HardwareSlider) -> GrblConfig {
    GrblConfig {
        baud: s.baud,
        response_timeout: Duration::from_secs_f64(s.response_timeout_s),
        reset_timeout: Duration::from_secs_f64(s.reset_timeout_s),
        homing_timeout: Duration::from_secs_f64(s.homing_timeout_s),
        poll_interval: Duration::from_secs_f64(1.0 / s.poll_hz),
        laser: crate::scan::config::laser_output(s),
        ..GrblConfig::default()
    }
}

/// The driver settings of `[hardware.camera]` and `[camera]`.
pub fn v4l2_config(c: &HardwareCamera, cam: &CameraSection) -> V4l2Config {
    V4l2Config {
        path: c.device.clone(),
        width: c.width,
        height: c.height,
        formats: SourceFormat::parse(&c.pixel_format).into_iter().collect(),
        channel: c.channel,
        fps: Some(cam.fps),
        buffers: c.buffers,
        exposure_us: Some(cam.exposure_us),
        gain: Some(cam.gain),
        input: c.input,
        dv_timings: false,
    }
}

/// The error's text without the `device: ` prefix the HAL puts first (the caller names it).
fn detail(e: &HalError, device: &str) -> String {
    let s = footscan_util::chain(e);
    s.strip_prefix(device)
        .and_then(|r| r.strip_prefix(": "))
        .map(str::to_string)
        .unwrap_or(s)
}

fn camera_hint(e: &HalError) -> String {
    let list = "`v4l2-ctl --list-devices` lists the cameras (set hardware.camera.device)";
    match e {
        HalError::Disconnected { .. } => {
            let nodes: Vec<String> = footscan_v4l2::discover::video_nodes()
                .iter()
                .map(|p| p.display().to_string())
                .collect();
            let present = if nodes.is_empty() {
                "no /dev/video* node exists".to_string()
            } else {
                format!("present: {}", nodes.join(", "))
            };
            format!("is it plugged in? {list}; {present}")
        }
        HalError::Io { source, .. }
            if source.kind() == std::io::ErrorKind::PermissionDenied =>
        {
            format!("add the user to the `video` group; {list}")
        }
        HalError::InvalidArgument { .. } => {
            "`v4l2-ctl -d DEVICE --list-formats-ext` lists what it offers (hardware.camera.width, height, pixel_format; camera.fps)".into()
        }
        _ => list.into(),
    }
}

/// Open and set up the V4L2 camera.
pub fn open_camera(c: &HardwareCamera, cam: &CameraSection) -> Result<V4l2Camera, HardwareError> {
    let device = c.device.display().to_string();
    V4l2Camera::open(&v4l2_config(c, cam)).map_err(|source| HardwareError::Camera {
        detail: detail(&source, &device),
        device,
        hint: camera_hint(&source),
        source: Box::new(source),
    })
}

fn slider_hint(e: &HalError) -> String {
    match e {
        HalError::Disconnected { .. } => {
            "is the controller plugged in? `ls -l /dev/serial/by-id/` lists the serial ports (set hardware.slider.port)".into()
        }
        HalError::Io { source, .. }
            if source.kind() == std::io::ErrorKind::PermissionDenied =>
        {
            "add the user to the `dialout` group".into()
        }
        HalError::Timeout { .. } => {
            "no GRBL banner: check hardware.slider.baud and that the board runs GRBL 1.1 (boards that reset on open need hardware.slider.reset_timeout_s >= 3)".into()
        }
        HalError::BadData { .. } => {
            "the device does not speak GRBL 1.1 at this rate (check hardware.slider.baud)".into()
        }
        HalError::Alarm { .. } => {
            "home the machine (scan.home = true) or clear the alarm at the controller".into()
        }
        _ => "see the GRBL 1.1 documentation for the code".into(),
    }
}

/// Open the GRBL slider: connect (soft reset, banner, `$I`), check `$$` against the scan
/// (feed within `$110`, range within `$130` when soft limits are on), home if `scan.home`.
pub fn open_slider(
    s: &HardwareSlider,
    scan: &ScanSection,
    scan_feed_mm_min: f64,
) -> Result<GrblSlider, HardwareError> {
    let mut slider = GrblSlider::new(&s.port, grbl_config(s));
    let fail = |source: HalError| HardwareError::Slider {
        port: s.port.clone(),
        detail: detail(&source, &s.port),
        hint: slider_hint(&source),
        source: Box::new(source),
    };
    let info = slider.connect().map_err(fail)?;
    tracing::info!(
        "slider {}: {}; laser mode ($32) {}",
        info.port,
        info.banner,
        match info.laser_mode {
            Some(true) => "on",
            Some(false) => "off",
            None => "not reported",
        }
    );
    let settings = slider.read_settings().map_err(fail)?;
    let check = |m: String| HardwareError::SliderCheck(m, s.port.clone());
    if let Some(max) = settings.max_rate(0) {
        for (what, feed) in [
            ("the scan feed", scan_feed_mm_min),
            ("scan.approach_feed_mm_min", scan.approach_feed_mm_min),
        ] {
            if feed > max + 1e-9 {
                return Err(check(format!(
                    "{what} of {feed} mm/min exceeds the controller's X max rate $110 = {max} mm/min (GRBL would clamp it)"
                )));
            }
        }
    }
    if settings.soft_limits() {
        if let Some(travel) = settings.max_travel(0) {
            let (lo, hi) = (
                scan.start_mm.min(scan.end_mm),
                scan.start_mm.max(scan.end_mm),
            );
            if lo < 0.0 || hi > travel {
                return Err(check(format!(
                    "scan range {}..{} mm is outside the controller's travel 0..{travel} mm ($130, soft limits on)",
                    scan.start_mm, scan.end_mm
                )));
            }
        }
    }
    if matches!(
        grbl_config(s).laser,
        Some(footscan_grbl::LaserOutput::Spindle { .. })
    ) && settings.raw.get(&32).is_some_and(|&v| v != 0.0)
    {
        return Err(check(
            "hardware.slider.laser = \"spindle\" but the controller is in laser mode ($32=1), which keeps the spindle output off while the axes stand still (no laser for the laser-off/at-rest frames): set $32=0 or wire the laser to a coolant output".into(),
        ));
    }
    if scan.home && !settings.homing_enabled() {
        return Err(check(
            "scan.home = true but the controller's homing cycle is disabled ($22=0): enable it ($22=1, with limit switches) or set scan.home = false".into(),
        ));
    }
    if scan.home {
        slider.home_configured().map_err(fail)?;
    } else if let Some(code) = slider.alarm() {
        return Err(fail(HalError::Alarm {
            device: s.port.clone(),
            code,
            message: format!(
                "{} (scan.home = false and this backend never unlocks with $X on its own)",
                footscan_grbl::alarm_message(code)
            ),
        }));
    }
    Ok(slider)
}

/// Open both devices of `[hardware]`: camera first, then the slider.
pub fn open(cfg: &ScanConfig) -> Result<Devices, HardwareError> {
    let hw = cfg
        .hardware
        .as_ref()
        .expect("validated: backend = \"hardware\" has a [hardware] section");
    let camera = open_camera(&hw.camera, &cfg.camera)?;
    let feed = cfg.scan.step_mm * cfg.camera.fps * 60.0;
    let slider = open_slider(&hw.slider, &cfg.scan, feed)?;
    Ok(Devices {
        camera: Box::new(camera),
        slider: Box::new(slider),
    })
}
