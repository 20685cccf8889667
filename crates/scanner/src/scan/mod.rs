//! A scan from end to end: devices, the stage registry, the threaded pipeline, the files.

mod backend;
pub mod calibrate;
pub mod config;
pub mod early;
mod error;
pub mod item;
pub mod model_job;
pub mod quality;
mod registry;
mod run;
pub mod stages;
pub mod summary;

pub use crate::scandata::ScanGrid;
pub use backend::{hardware, open_backend, sim, Devices, OpenBackend};
pub use calibrate::{calibrate, calibrate_unattended};
pub use config::{LoadedConfig, ScanConfig};
pub use error::{
    DeviceError, DeviceFault, DeviceRole, FaultKind, ScanError, ScanFault, SetupError,
};
pub use quality::{Quality, QualityError, QualitySection, ScanStatus};
pub use registry::{params, registry, ScanContext};
pub use run::{run_scan, CancelToken, ScanOptions, ScanProgress};
pub use summary::{PluginRecord, ScanSummary, TruthSource, TruthStats};

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Duration;

/// The motion of one scan, derived from the config.
#[derive(Clone, Debug)]
pub struct ScanPlan {
    pub start_mm: f64,
    pub end_mm: f64,
    pub step_mm: f64,
    /// step x fps x 60.
    pub feed_mm_min: f64,
    pub approach_feed_mm_min: f64,
    pub poll_period: Duration,
    pub frame_timeout: Duration,
    pub move_timeout: Duration,
    /// The controller switches the laser: on for the scan, off after it.
    pub laser: bool,
    /// A laser-off frame at rest before and after the move (`scan.background = "ends"`).
    pub laser_off_ends: bool,
    pub quality: QualitySection,
}

impl ScanPlan {
    pub fn from_config(c: &ScanConfig) -> Self {
        let s = &c.scan;
        let feed = s.step_mm * c.camera.fps * 60.0;
        let travel_s = (s.end_mm - s.start_mm).abs() / (feed / 60.0);
        ScanPlan {
            start_mm: s.start_mm,
            end_mm: s.end_mm,
            step_mm: s.step_mm,
            feed_mm_min: feed,
            approach_feed_mm_min: s.approach_feed_mm_min,
            poll_period: Duration::from_secs_f64(1.0 / s.status_poll_hz),
            frame_timeout: Duration::from_secs_f64((10.0 / c.camera.fps).max(1.0)),
            move_timeout: Duration::from_secs_f64(travel_s.max(10.0) * 2.0 + 10.0),
            laser: match (&c.scanner.backend, &c.hardware) {
                (config::Backend::Sim, _) => {
                    c.sim.slider.laser != footscan_sim::grbl::LaserWiring::Always
                }
                (config::Backend::Hardware, h) => {
                    h.as_ref().is_some_and(|h| h.slider.laser.is_some())
                }
            },
            laser_off_ends: s.background == config::ScanBackground::Ends,
            quality: c.quality.clone(),
        }
    }

    /// Frames a complete scan yields at the nominal step.
    pub fn expected_frames(&self) -> u64 {
        ((self.end_mm - self.start_mm) / self.step_mm).floor() as u64 + 1
    }
}

/// Live counts of the acquisition, for progress and the summary.
#[derive(Debug, Default)]
pub struct ScanCounters {
    frames: AtomicU64,
    dropped: AtomicU64,
    stationary: AtomicU64,
    laser_off_frames: AtomicU64,
    laser_off_rows: AtomicU64,
    /// What the accumulate stage found about gaps, lost rows and cuts (the quality gate's).
    quality: Mutex<Option<Quality>>,
    /// The side of the measured foot, from `measure.foot`.
    foot_side: Mutex<Option<crate::measure::Side>>,
    /// The measured foot's doubtful figures, from `measure.foot`.
    measure_warnings: Mutex<Vec<String>>,
    /// What the per-scan and sink plugin stages did, for scan.json.
    plugins: Mutex<Vec<summary::PluginRecord>>,
    /// When the last frame was acquired: the results are timed from it.
    last_frame: Mutex<Option<std::time::Instant>>,
    /// The CAD files, written after the results by `model.bezier`'s job.
    pub model: model_job::ModelJob,
    /// The model's height map, filled while the frames come (for `measure.foot`).
    pub early: early::EarlyHeights,
}

impl ScanCounters {
    pub fn add_frame(&self) {
        self.frames.fetch_add(1, Ordering::Relaxed);
        *self.last_frame.lock().unwrap() = Some(std::time::Instant::now());
    }
    /// When the last frame was acquired (None before the first).
    pub fn last_frame_at(&self) -> Option<std::time::Instant> {
        *self.last_frame.lock().unwrap()
    }
    pub fn add_dropped(&self, n: u64) {
        self.dropped.fetch_add(n, Ordering::Relaxed);
    }
    pub fn add_stationary(&self, n: u64) {
        self.stationary.fetch_add(n, Ordering::Relaxed);
    }
    pub fn frames(&self) -> u64 {
        self.frames.load(Ordering::Relaxed)
    }
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
    pub fn stationary(&self) -> u64 {
        self.stationary.load(Ordering::Relaxed)
    }
    /// A laser-off frame in which the detector found a line in `rows_found` rows.
    pub fn add_laser_off(&self, rows_found: u64) {
        self.laser_off_frames.fetch_add(1, Ordering::Relaxed);
        self.laser_off_rows.fetch_add(rows_found, Ordering::Relaxed);
    }
    pub fn set_quality(&self, q: Quality) {
        *self.quality.lock().unwrap() = Some(q);
    }
    pub fn quality(&self) -> Option<Quality> {
        self.quality.lock().unwrap().clone()
    }
    pub fn set_foot_side(&self, s: crate::measure::Side) {
        *self.foot_side.lock().unwrap() = Some(s);
    }
    pub fn foot_side(&self) -> Option<crate::measure::Side> {
        *self.foot_side.lock().unwrap()
    }
    pub fn set_measure_warnings(&self, w: Vec<String>) {
        *self.measure_warnings.lock().unwrap() = w;
    }
    pub fn measure_warnings(&self) -> Vec<String> {
        self.measure_warnings.lock().unwrap().clone()
    }
    pub fn add_plugin(&self, r: summary::PluginRecord) {
        self.plugins.lock().unwrap().push(r);
    }
    pub fn plugins(&self) -> Vec<summary::PluginRecord> {
        self.plugins.lock().unwrap().clone()
    }
    /// Laser-off frames and the rows found in them.
    pub fn laser_off(&self) -> (u64, u64) {
        (
            self.laser_off_frames.load(Ordering::Relaxed),
            self.laser_off_rows.load(Ordering::Relaxed),
        )
    }
}
