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
    pub pipeline: PipelineSpec,
}

#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Backend {
    /// Simulated camera and the GRBL emulator on a pseudo-terminal.
    Sim,
}

#[derive(Clone, Debug, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ScannerSection {
    pub backend: Backend,
}

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
    /// What stands on the glass: "foot", "empty" or "plate".
    pub scene: SceneKind,
    /// Height of the plate for scene = "plate" (mm).
    pub plate_height_mm: f64,
    pub optics: footscan_sim::optics::Optics,
    pub noise: footscan_sim::render::NoiseConfig,
    pub foot: footscan_sim::foot::FootParams,
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
}

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config {path}: {source}")]
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
        Ok(())
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
