//! The scanner configuration file (config/sim.toml, config/footscan.toml).
//!
//! Unknown keys are errors everywhere, including inside a stage's parameters, and every error
//! names the file, the key, and its line and column.

use crate::pipeline::PipelineSpec;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ScanConfig {
    pub scanner: ScannerSection,
    #[serde(default)]
    pub scan: ScanSection,
    #[serde(default)]
    pub camera: CameraSection,
    #[serde(default)]
    pub sim: SimSection,
    /// The real camera and slider; required by `backend = "hardware"`.
    #[serde(default)]
    pub hardware: Option<HardwareSection>,
    /// The quality gate's thresholds (docs/method.md section 3.3).
    #[serde(default)]
    pub quality: super::quality::QualitySection,
    /// Limits a new calibration must meet and the daily check's tolerance.
    #[serde(default)]
    pub calibration: CalibrationSection,
    pub pipeline: PipelineSpec,
}

/// `[calibration]`: when a calibration is refused, and the daily check (`footscan verify`).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct CalibrationSection {
    /// Refuse a calibration any of whose fit residuals (`*_rms_px`) exceeds this (px).
    pub max_residual_px: f64,
    /// Refuse a calibration whose height uncertainty `u_h_mm` (eq. 30) exceeds this (mm).
    pub max_u_h_mm: f64,
    /// The daily check fails when a staircase step's height error exceeds this (mm) ...
    pub verify_tolerance_mm: f64,
    /// ... or the block's measured width is further than this from its stated width (mm;
    /// coarser: the width is measured to about a row at each side).
    pub verify_width_tolerance_mm: f64,
    /// The status warns when the last passing daily check is older than this (hours).
    pub verify_max_age_h: f64,
    /// Slider step of the daily check's staircase pass (mm).
    pub verify_step_mm: f64,
    /// The shop's calibration plan (TOML: its spacer heights and staircase block as
    /// measured, frames per step, slider positions), relative to this file; `footscan
    /// calibrate --plan` overrides it. Default: the built-in plan of the default scanner.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plan: Option<PathBuf>,
}

impl Default for CalibrationSection {
    fn default() -> Self {
        CalibrationSection {
            max_residual_px: 0.5,
            max_u_h_mm: 0.05,
            verify_tolerance_mm: 0.05,
            verify_width_tolerance_mm: 0.5,
            verify_max_age_h: 26.0,
            verify_step_mm: 1.0,
            plan: None,
        }
    }
}

/// A `[calibration]` value out of its range.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("calibration.{key} = {value}: valid is [{lo}, {hi}]")]
pub struct CalibrationRangeError {
    pub key: &'static str,
    pub value: f64,
    pub lo: f64,
    pub hi: f64,
}

impl CalibrationSection {
    /// Each value in its range; the error names the key.
    pub fn validate(&self) -> Result<(), CalibrationRangeError> {
        for (k, v, lo, hi) in [
            ("max_residual_px", self.max_residual_px, 1e-4, 100.0),
            ("max_u_h_mm", self.max_u_h_mm, 1e-4, 100.0),
            ("verify_tolerance_mm", self.verify_tolerance_mm, 1e-4, 10.0),
            (
                "verify_width_tolerance_mm",
                self.verify_width_tolerance_mm,
                1e-4,
                50.0,
            ),
            ("verify_max_age_h", self.verify_max_age_h, 0.01, 1e5),
            ("verify_step_mm", self.verify_step_mm, 0.05, 50.0),
        ] {
            if !(v.is_finite() && (lo..=hi).contains(&v)) {
                return Err(CalibrationRangeError {
                    key: k,
                    value: v,
                    lo,
                    hi,
                });
            }
        }
        Ok(())
    }
}

#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// Simulated camera and the GRBL emulator on a pseudo-terminal.
    Sim,
    /// A V4L2 camera and a GRBL controller on a serial port (`[hardware.camera]`,
    /// `[hardware.slider]`).
    Hardware,
}

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ScannerSection {
    pub backend: Backend,
    /// Calibration file, relative to the config file's directory; `--calibration` overrides
    /// it. Required by the hardware backend (the simulator defaults to its true model).
    #[serde(default)]
    pub calibration: Option<PathBuf>,
}

/// `[hardware]`: the devices of a real scanner.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct HardwareSection {
    pub camera: HardwareCamera,
    pub slider: HardwareSlider,
}

/// `[hardware.camera]`: the V4L2 capture node. Frame rate, exposure and gain are `[camera]`'s
/// (shared with the simulator: the scan feed is `scan.step_mm` x `camera.fps`).
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct HardwareCamera {
    /// e.g. `/dev/video0`, or a stable `/dev/v4l/by-id/...` path.
    pub device: PathBuf,
    pub width: u32,
    pub height: u32,
    /// `auto` (the first the device offers: GREY, Y16, Y12, Y10, YUYV, MJPG without a channel;
    /// RGB3, BGR3, Bayer, YUYV, MJPG with a colour one) or one of those, RGB3, BGR3, RGGB,
    /// BA81, GBRG, GRBG.
    #[serde(default = "default_pixel_format")]
    pub pixel_format: String,
    /// The grey channel the driver converts colour frames to, once per frame (luma, red,
    /// green, blue, red-minus-others, green-minus-others); unset: grey formats and the luma of
    /// YUYV/MJPG. The detect stages then see that channel as a grey frame.
    #[serde(default)]
    pub channel: Option<footscan_hal::Channel>,
    /// mmap buffers, 4 to 32.
    #[serde(default = "default_buffers")]
    pub buffers: u32,
    /// Input to select first (VIDIOC_S_INPUT), e.g. on a capture card.
    #[serde(default)]
    pub input: Option<u32>,
}

fn default_pixel_format() -> String {
    "auto".into()
}
fn default_buffers() -> u32 {
    4
}

/// `[hardware.slider]`: the GRBL 1.1 controller on a serial port.
#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct HardwareSlider {
    /// e.g. `/dev/ttyUSB0`; better a stable `/dev/serial/by-id/...` path, which comes back
    /// under the same name when the USB cable is replugged.
    pub port: String,
    pub baud: u32,
    /// Status polling of the driver's own waits (idle, feed hold, jog cancel), Hz. The scan
    /// move is polled at `scan.status_poll_hz`.
    pub poll_hz: f64,
    /// A command or `?` unanswered this long is a timeout (seconds).
    pub response_timeout_s: f64,
    /// Banner wait after a soft reset; boards that reset when the port opens (Arduino DTR)
    /// need their boot loader's ~2 s on top (seconds).
    pub reset_timeout_s: f64,
    /// `$H` must finish within this (seconds); a homing cycle still running then is aborted
    /// with a soft reset.
    pub homing_timeout_s: f64,
    /// Highest feed a scan may ask for, mm/min: `scan.approach_feed_mm_min` and the scan feed
    /// (`scan.step_mm` x `camera.fps` x 60) must not exceed it, and neither may it exceed the
    /// controller's `$110` (GRBL would silently clamp the feed and the frames would bunch).
    pub max_feed_mm_min: f64,
    /// The output the laser is wired to: `spindle` (M3 S`laser_power` / M5), `flood` (M8/M9)
    /// or `mist` (M7/M9, GRBL builds with ENABLE_M7); unset: the scan does not switch it.
    pub laser: Option<String>,
    /// `S` of M3 when the laser is on the spindle output (GRBL's `$30` is full power).
    pub laser_power: f64,
}

impl Default for HardwareSlider {
    fn default() -> Self {
        HardwareSlider {
            port: String::new(),
            baud: 115_200,
            poll_hz: 50.0,
            response_timeout_s: 2.0,
            reset_timeout_s: 5.0,
            homing_timeout_s: 60.0,
            max_feed_mm_min: 3000.0,
            laser: None,
            laser_power: 1000.0,
        }
    }
}

/// The driver's laser output of `[hardware.slider]` (None: unset or not a known output).
pub fn laser_output(s: &HardwareSlider) -> Option<footscan_grbl::LaserOutput> {
    use footscan_grbl::LaserOutput;
    Some(match s.laser.as_deref()? {
        "spindle" => LaserOutput::Spindle {
            power: s.laser_power,
        },
        "flood" => LaserOutput::Flood,
        "mist" => LaserOutput::Mist,
        _ => return None,
    })
}

/// Serial rates a GRBL board is built for (`BAUD_RATE` in its config.h).
pub const GRBL_BAUDS: [u32; 8] = [
    9600, 19_200, 38_400, 57_600, 115_200, 230_400, 250_000, 500_000,
];

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ScanSection {
    /// Slider positions of the first and last frame (mm, controller coordinates).
    pub start_mm: f64,
    pub end_mm: f64,
    /// Slider advance per frame (mm); the feed is step x camera fps.
    pub step_mm: f64,
    /// Feed for the move to the start position (mm/min).
    pub approach_feed_mm_min: f64,
    /// Slider status polling rate during the scan move (Hz).
    pub status_poll_hz: f64,
    /// Home the slider before scanning.
    pub home: bool,
    /// Laser-off frames: `none`, or `ends` (one at rest before the move and one after it; the
    /// first is subtracted from every frame by the detect stage, docs/method.md section 4.6).
    /// Needs a laser the controller switches (`hardware.slider.laser`, `sim.slider.laser`).
    /// Not every N frames: GRBL runs M3/M5/M8/M9 in step with the planner, so switching the
    /// laser would stop the scan move.
    pub background: ScanBackground,
}

/// `scan.background`.
#[derive(Clone, Copy, Debug, Default, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum ScanBackground {
    #[default]
    None,
    Ends,
}

impl Default for ScanSection {
    fn default() -> Self {
        ScanSection {
            start_mm: 0.0,
            end_mm: 320.0,
            step_mm: 0.5,
            approach_feed_mm_min: 3000.0,
            status_poll_hz: 100.0,
            home: true,
            background: ScanBackground::None,
        }
    }
}

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct CameraSection {
    pub fps: f64,
    pub exposure_us: u32,
    pub gain: f64,
}

impl Default for CameraSection {
    fn default() -> Self {
        CameraSection {
            fps: 50.0,
            exposure_us: 2000,
            gain: 1.0,
        }
    }
}

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimSection {
    pub seed: u64,
    /// What stands on the glass: "foot", "empty", "plate", "last" (parametric, `[sim.last]`)
    /// or "mesh" (a mesh file, `[sim.mesh]`).
    pub scene: SceneKind,
    /// Height of the plate for scene = "plate" (mm).
    pub plate_height_mm: f64,
    pub optics: footscan_sim::optics::Optics,
    pub noise: footscan_sim::render::NoiseConfig,
    pub foot: footscan_sim::foot::FootParams,
    pub last: footscan_sim::last::LastParams,
    pub mesh: footscan_sim::mesh_scene::MeshSceneConfig,
    pub slider: footscan_sim::grbl::EmulatorConfig,
    pub faults: SimFaults,
}

/// Faults injected into a simulated scan, in seconds after the scanner is opened (for tests
/// and for rehearsing how an operator sees a failing scan).
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct SimFaults {
    /// The controller raises ALARM:`slider_alarm_code`.
    pub slider_alarm_after_s: Option<f64>,
    pub slider_alarm_code: Option<u8>,
    /// The controller stops answering.
    pub slider_silent_after_s: Option<f64>,
    /// The serial line drops.
    pub slider_disconnect_after_s: Option<f64>,
    /// Line noise: the next `slider_corrupt_status_count` (default 5) status reports arrive
    /// corrupted (the driver asks again; the scan goes on).
    pub slider_corrupt_status_after_s: Option<f64>,
    pub slider_corrupt_status_count: Option<u32>,
    /// The camera cable is pulled.
    pub camera_unplug_after_s: Option<f64>,
}

impl Default for SimSection {
    fn default() -> Self {
        SimSection {
            seed: 1,
            scene: SceneKind::Foot,
            plate_height_mm: 10.0,
            optics: Default::default(),
            noise: Default::default(),
            foot: Default::default(),
            last: Default::default(),
            mesh: Default::default(),
            slider: Default::default(),
            faults: Default::default(),
        }
    }
}

#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum SceneKind {
    Foot,
    Empty,
    Plate,
    Last,
    Mesh,
}

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config {path}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("config {path}: {message}")]
    Invalid { path: PathBuf, message: String },
}

/// A parsed config with the text it came from, for locating keys in later errors.
#[derive(Clone, Debug)]
pub struct LoadedConfig {
    pub path: PathBuf,
    pub text: String,
    pub config: ScanConfig,
}

impl LoadedConfig {
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
        Self::parse(path, text)
    }

    pub fn parse(path: &Path, text: String) -> Result<Self, ConfigError> {
        let invalid = |message: String| ConfigError::Invalid {
            path: path.to_owned(),
            message,
        };
        let config: ScanConfig = toml::from_str(&text).map_err(|e| invalid(flatten(&e, &text)))?;
        let loaded = LoadedConfig {
            path: path.to_owned(),
            text,
            config,
        };
        loaded.validate().map_err(invalid)?;
        Ok(loaded)
    }

    fn validate(&self) -> Result<(), String> {
        let s = &self.config.scan;
        let c = &self.config.camera;
        let at = |key: &str| self.locate(&["scan", key]).unwrap_or_default();
        if !(s.step_mm > 0.0 && s.step_mm.is_finite()) {
            return Err(format!(
                "scan.step_mm = {}{}: must be > 0",
                s.step_mm,
                at("step_mm")
            ));
        }
        if s.end_mm <= s.start_mm {
            return Err(format!(
                "scan.end_mm = {}{} must be greater than scan.start_mm = {}",
                s.end_mm,
                at("end_mm"),
                s.start_mm
            ));
        }
        if !(s.status_poll_hz > 0.0 && s.status_poll_hz <= 1000.0) {
            return Err(format!(
                "scan.status_poll_hz = {}{}: valid range is (0, 1000]",
                s.status_poll_hz,
                at("status_poll_hz")
            ));
        }
        if !(c.fps > 0.0 && c.fps <= 10_000.0) {
            return Err(format!(
                "camera.fps = {}{}: valid range is (0, 10000]",
                c.fps,
                self.locate(&["camera", "fps"]).unwrap_or_default()
            ));
        }
        self.config.calibration.validate().map_err(|e| {
            format!(
                "{e}{}",
                self.locate(&["calibration", e.key]).unwrap_or_default()
            )
        })?;
        // A plan with a typo is named when the config is read, not at the first calibration.
        self.calibration_plan().map_err(|e| {
            format!(
                "calibration.plan{}: {e}",
                self.locate(&["calibration", "plan"]).unwrap_or_default()
            )
        })?;
        self.config.quality.validate().map_err(|e| {
            format!(
                "{e}{}",
                self.locate(&["quality", e.key()]).unwrap_or_default()
            )
        })?;
        if s.background == ScanBackground::Ends {
            let switched = match (&self.config.scanner.backend, &self.config.hardware) {
                (Backend::Sim, _) => {
                    self.config.sim.slider.laser != footscan_sim::grbl::LaserWiring::Always
                }
                (Backend::Hardware, h) => h.as_ref().is_some_and(|h| h.slider.laser.is_some()),
            };
            if !switched {
                return Err(format!(
                    "scan.background = \"ends\"{} needs a laser the controller switches: set hardware.slider.laser (\"spindle\", \"flood\" or \"mist\") or, simulated, sim.slider.laser (\"spindle\" or \"flood\")",
                    at("background")
                ));
            }
        }
        match (&self.config.scanner.backend, &self.config.hardware) {
            (Backend::Hardware, None) => {
                return Err(format!(
                    "scanner.backend = \"hardware\"{} needs [hardware.camera] and [hardware.slider] sections (see config/footscan.toml)",
                    self.locate(&["scanner", "backend"]).unwrap_or_default()
                ))
            }
            (_, Some(h)) => self.validate_hardware(h)?,
            _ => {}
        }
        Ok(())
    }

    fn validate_hardware(&self, h: &HardwareSection) -> Result<(), String> {
        let cam = |key: &str| {
            self.locate(&["hardware", "camera", key])
                .unwrap_or_default()
        };
        let sl = |key: &str| {
            self.locate(&["hardware", "slider", key])
                .unwrap_or_default()
        };
        let c = &h.camera;
        if c.device.as_os_str().is_empty() {
            return Err(format!(
                "hardware.camera.device{}: empty; name the capture node, e.g. \"/dev/video0\" (`v4l2-ctl --list-devices` lists them)",
                cam("device")
            ));
        }
        for (key, v) in [("width", c.width), ("height", c.height)] {
            if !(16..=16_384).contains(&v) {
                return Err(format!(
                    "hardware.camera.{key} = {v}{}: valid range is 16 to 16384 pixels",
                    cam(key)
                ));
            }
        }
        if !c.pixel_format.eq_ignore_ascii_case("auto")
            && footscan_v4l2::SourceFormat::parse(&c.pixel_format).is_none()
        {
            return Err(format!(
                "hardware.camera.pixel_format = {:?}{}: valid are \"auto\", {}",
                c.pixel_format,
                cam("pixel_format"),
                footscan_v4l2::SourceFormat::names()
            ));
        }
        if let Some(f) = footscan_v4l2::SourceFormat::parse(&c.pixel_format) {
            f.check_channel(c.channel).map_err(|e| {
                format!(
                    "hardware.camera.pixel_format = {:?}{}: {e} (hardware.camera.channel)",
                    c.pixel_format,
                    cam("pixel_format")
                )
            })?;
        }
        if !(4..=32).contains(&c.buffers) {
            return Err(format!(
                "hardware.camera.buffers = {}{}: valid range is 4 to 32",
                c.buffers,
                cam("buffers")
            ));
        }
        let s = &h.slider;
        if s.port.trim().is_empty() {
            return Err(format!(
                "hardware.slider.port{}: missing or empty; name the serial port, e.g. \"/dev/ttyUSB0\" or a /dev/serial/by-id/ path",
                sl("port")
            ));
        }
        if let Some(l) = &s.laser {
            if laser_output(s).is_none() {
                return Err(format!(
                    "hardware.slider.laser = {l:?}{}: valid are \"spindle\" (M3/M5), \"flood\" (M8/M9), \"mist\" (M7/M9)",
                    sl("laser")
                ));
            }
        }
        if !(s.laser_power > 0.0 && s.laser_power <= 100_000.0) {
            return Err(format!(
                "hardware.slider.laser_power = {}{}: valid range is (0, 100000] (GRBL's $30 is full power)",
                s.laser_power,
                sl("laser_power")
            ));
        }
        if !GRBL_BAUDS.contains(&s.baud) {
            return Err(format!(
                "hardware.slider.baud = {}{}: valid are {:?} (GRBL 1.1 defaults to 115200)",
                s.baud,
                sl("baud"),
                GRBL_BAUDS
            ));
        }
        if !(s.poll_hz > 0.0 && s.poll_hz <= 1000.0) {
            return Err(format!(
                "hardware.slider.poll_hz = {}{}: valid range is (0, 1000]",
                s.poll_hz,
                sl("poll_hz")
            ));
        }
        for (key, v) in [
            ("response_timeout_s", s.response_timeout_s),
            ("reset_timeout_s", s.reset_timeout_s),
            ("homing_timeout_s", s.homing_timeout_s),
        ] {
            if !(v > 0.0 && v <= 3600.0) {
                return Err(format!(
                    "hardware.slider.{key} = {v}{}: valid range is (0, 3600] seconds",
                    sl(key)
                ));
            }
        }
        if !(s.max_feed_mm_min > 0.0 && s.max_feed_mm_min.is_finite()) {
            return Err(format!(
                "hardware.slider.max_feed_mm_min = {}{}: must be > 0",
                s.max_feed_mm_min,
                sl("max_feed_mm_min")
            ));
        }
        let scan = &self.config.scan;
        let feed = scan.step_mm * self.config.camera.fps * 60.0;
        if feed > s.max_feed_mm_min {
            return Err(format!(
                "the scan feed scan.step_mm x camera.fps x 60 = {} x {} x 60 = {feed} mm/min exceeds hardware.slider.max_feed_mm_min = {}{}: lower the step or the frame rate, or raise the limit",
                scan.step_mm, self.config.camera.fps, s.max_feed_mm_min, sl("max_feed_mm_min")
            ));
        }
        if scan.approach_feed_mm_min > s.max_feed_mm_min {
            return Err(format!(
                "scan.approach_feed_mm_min = {}{} exceeds hardware.slider.max_feed_mm_min = {}",
                scan.approach_feed_mm_min,
                self.locate(&["scan", "approach_feed_mm_min"])
                    .unwrap_or_default(),
                s.max_feed_mm_min
            ));
        }
        Ok(())
    }

    /// The calibration file named by `scanner.calibration`, resolved against the config
    /// file's directory.
    pub fn calibration_path(&self) -> Option<PathBuf> {
        Some(self.resolve(self.config.scanner.calibration.as_ref()?))
    }

    /// The calibration plan `calibration.plan` names (resolved against the config file's
    /// directory, read and validated), else the built-in one.
    pub fn calibration_plan(
        &self,
    ) -> Result<crate::calib::CalibrationPlan, crate::calib::CalibError> {
        match &self.config.calibration.plan {
            Some(p) => crate::calib::CalibrationPlan::load(&self.resolve(p)),
            None => Ok(crate::calib::CalibrationPlan::default()),
        }
    }

    fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_owned()
        } else {
            self.path.parent().unwrap_or(Path::new(".")).join(p)
        }
    }

    /// " (line L, column C)" of a key path such as ["scan", "step_mm"], if present.
    pub fn locate(&self, keys: &[&str]) -> Option<String> {
        let mut offset = 0usize;
        let mut section: Vec<&str> = Vec::new();
        let target_section = &keys[..keys.len() - 1];
        let key = keys[keys.len() - 1];
        for line in self.text.split_inclusive('\n') {
            let t = line.trim();
            if let Some(h) = t.strip_prefix('[') {
                let h = h.trim_start_matches('[');
                let name = h.split(']').next().unwrap_or("").trim();
                section = name.split('.').map(str::trim).collect();
            } else if section == target_section {
                if let Some((k, _)) = t.split_once('=') {
                    if k.trim().trim_matches('"') == key {
                        let col = line.len() - line.trim_start().len();
                        return Some(line_col(&self.text, offset + col));
                    }
                }
            }
            offset += line.len();
        }
        None
    }

    /// " (line L, column C)" of `key` in the `index`-th `[[pipeline.stages]]` table.
    pub fn locate_stage_key(&self, index: usize, key: &str) -> Option<String> {
        let mut offset = 0usize;
        let mut stage: Option<usize> = None;
        let mut count = 0usize;
        for line in self.text.split_inclusive('\n') {
            let t = line.trim();
            if t.starts_with('[') {
                if t.replace(' ', "") == "[[pipeline.stages]]" {
                    stage = Some(count);
                    count += 1;
                } else {
                    stage = None;
                }
            } else if stage == Some(index) {
                if let Some((k, _)) = t.split_once('=') {
                    if k.trim().trim_matches('"') == key {
                        let col = line.len() - line.trim_start().len();
                        return Some(line_col(&self.text, offset + col));
                    }
                }
            }
            offset += line.len();
        }
        if key == "stage" || key.is_empty() {
            return None;
        }
        self.locate_stage_key(index, "stage")
    }
}

fn line_col(text: &str, offset: usize) -> String {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    format!(" (line {line}, column {col})")
}

/// toml's errors are multi-line with a source excerpt; say the same on one line.
fn flatten(e: &toml::de::Error, text: &str) -> String {
    match e.span() {
        Some(span) => format!("{}{}", e.message().trim_end(), line_col(text, span.start)),
        None => e.message().trim_end().to_string(),
    }
}
