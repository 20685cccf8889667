//! Runs one scan: backend, calibration, pipeline, summary; the scan directory keeps the
//! reason of a failed scan.

use super::config::LoadedConfig;
use super::error::ScanError;
use super::item::Item;
use super::model_job::ModelState;
use super::quality::{judge, ScanStatus, SideCheck};
use super::summary::{ScanSummary, StageReport};
use super::{registry, ScanContext, ScanCounters, ScanPlan};
use crate::pipeline::{BuildError, PipelineError, StageStats};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub struct ScanOptions {
    pub out_dir: PathBuf,
    /// A calibration file (overrides the config's `scanner.calibration`); default for
    /// simulated scans: the simulator's true model; required for hardware.
    pub calibration: Option<PathBuf>,
    /// Set from anywhere to stop the scan: the slider is stopped, nothing is written as
    /// complete, and scan.json says "cancelled".
    pub cancel: CancelToken,
    /// Sees every frame and its detected line (footscand's live preview); never blocks.
    pub tap: Option<Arc<dyn super::stages::FrameTap>>,
    /// The foot the operator says is on the glass; a measured foot of the other side makes
    /// the verdict "side mismatch" (docs/method.md section 3.3).
    pub side: Option<crate::measure::Side>,
    /// The subject (patient id) the scan is of, for the titles of its images.
    pub subject: Option<String>,
}

impl ScanOptions {
    pub fn new(out_dir: impl Into<PathBuf>) -> Self {
        ScanOptions {
            out_dir: out_dir.into(),
            calibration: None,
            cancel: CancelToken::default(),
            tap: None,
            side: None,
            subject: None,
        }
    }
}

/// A shareable "stop the scan" flag.
#[derive(Clone, Debug, Default)]
pub struct CancelToken(Arc<AtomicBool>);

impl CancelToken {
    pub fn cancel(&self) {
        self.0.store(true, Ordering::SeqCst);
    }
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}

/// Progress as the scan runs.
#[derive(Clone, Debug)]
pub struct ScanProgress {
    pub frames: u64,
    pub expected_frames: u64,
    pub dropped: u64,
    pub stages: Vec<StageStats>,
    /// The CAD files, once `model.bezier` has started them.
    pub model: Option<super::model_job::ModelProgress>,
}

/// Scan with `cfg`, writing into `opts.out_dir`; `progress` is called a few times a second.
pub fn run_scan(
    cfg: &LoadedConfig,
    opts: &ScanOptions,
    mut progress: impl FnMut(&ScanProgress),
) -> Result<ScanSummary, ScanError> {
    let started = Instant::now();
    std::fs::create_dir_all(&opts.out_dir).map_err(|source| ScanError::OutDir {
        path: opts.out_dir.clone(),
        source,
    })?;
    let plan = ScanPlan::from_config(&cfg.config);
    let counters = Arc::new(ScanCounters::default());
    let result = (|| -> Result<ScanSummary, ScanError> {
        let (devices, backend, calibration) =
            super::backend::open_backend(cfg, opts.calibration.as_deref())?;
        if let Some(foot) = &backend.foot {
            let path = crate::scandata::ScanDir::new(&opts.out_dir).truth_path();
            let json = serde_json::to_vec_pretty(&foot.truth()).expect("truth serialises");
            crate::io::write_atomic(&path, &json)
                .map_err(|source| ScanError::Write { path, source })?;
        }
        let cal_path = crate::scandata::ScanDir::new(&opts.out_dir)
            .file(crate::scandata::ScanDir::CALIBRATION);
        calibration
            .save(&cal_path)
            .map_err(|e| ScanError::Setup(footscan_util::chain(&e).into()))?;
        let ctx = ScanContext {
            out_dir: opts.out_dir.clone(),
            plan: plan.clone(),
            devices: Mutex::new(Some(devices)),
            calibration: Some(calibration),
            truth: backend.truth_source(),
            counters: counters.clone(),
            tap: opts.tap.clone(),
            label: crate::io::HeightMapLabel {
                chosen: opts.side,
                measured: None,
                subject: opts.subject.clone(),
            },
        };
        let pipeline = registry()
            .build(&cfg.config.pipeline, &ctx)
            .map_err(|e| ScanError::Config(describe_build_error(cfg, &e)))?;
        let running = pipeline.start();
        while !running.is_finished() {
            if opts.cancel.is_cancelled() {
                running.cancel();
            }
            progress(&ScanProgress {
                frames: counters.frames(),
                expected_frames: plan.expected_frames(),
                dropped: counters.dropped(),
                stages: running.stats(),
                model: counters.model.progress(),
            });
            // Progress every 100 ms, but the end seen within 5: the results wait on it.
            let t = Instant::now();
            while t.elapsed() < Duration::from_millis(100) && !running.is_finished() {
                std::thread::sleep(Duration::from_millis(5));
            }
        }
        let report = running.wait()?;
        drop(backend);
        let mut summary = report
            .outputs
            .into_iter()
            .find_map(|i| match i {
                Item::Summary(s) => Some(*s),
                _ => None,
            })
            .unwrap_or_else(|| ScanSummary::without_grid(report.cancelled));
        if report.cancelled {
            summary.status = ScanStatus::Cancelled;
            summary.reason = Some("cancelled before the scan completed".into());
        }
        summary.stages = report.stages.iter().map(stage_report).collect();
        Ok(summary)
    })();
    let mut summary = match result {
        Ok(s) => s,
        Err(e) => {
            let mut s = ScanSummary::failed(&footscan_util::chain(&e));
            if let ScanError::Pipeline(PipelineError::Stage { stats, .. }) = &e {
                s.stages = stats.iter().map(stage_report).collect();
            }
            s.model = counters.model.join(true);
            finish(&mut s, &counters, started);
            write_summary(&opts.out_dir, &s)?;
            return Err(e);
        }
    };
    finish(&mut summary, &counters, started);
    if summary.status == ScanStatus::Complete {
        gate(&mut summary, &counters, &plan, opts.side);
    }
    // The results, with the CAD files still being written: the verdict does not wait for
    // them (model_job.rs).
    let cancelled = summary.status == ScanStatus::Cancelled;
    summary.model = counters.model.progress();
    let last_frame = counters.last_frame_at();
    let after_last = |t: Instant| last_frame.map(|l| t.saturating_duration_since(l).as_secs_f64());
    summary.timeline = last_frame.map(|l| super::summary::Timeline {
        last_frame_s: l.saturating_duration_since(started).as_secs_f64(),
        results_after_last_frame_s: after_last(Instant::now()).unwrap_or(0.0),
        model_after_last_frame_s: None,
    });
    if summary.model.is_some() {
        write_summary(&opts.out_dir, &summary)?;
        progress(&ScanProgress {
            frames: counters.frames(),
            expected_frames: plan.expected_frames(),
            dropped: counters.dropped(),
            stages: Vec::new(),
            model: summary.model.clone(),
        });
        summary.model = counters.model.join(cancelled);
        if let Some(t) = &mut summary.timeline {
            t.model_after_last_frame_s = after_last(Instant::now());
        }
        summary.seconds = started.elapsed().as_secs_f64();
        if let Some(m) = summary
            .model
            .as_ref()
            .filter(|m| m.state == ModelState::Failed)
        {
            // The verdict stood, but a file the scan was asked for is missing.
            summary.status = ScanStatus::Failed;
            summary.reason = m.reason.clone();
        }
    }
    write_summary(&opts.out_dir, &summary)?;
    Ok(summary)
}

/// The quality gate on a scan that ran to its end: the verdict and its reason.
fn gate(
    s: &mut ScanSummary,
    counters: &ScanCounters,
    plan: &ScanPlan,
    chosen: Option<crate::measure::Side>,
) {
    let Some(mut q) = counters.quality() else {
        return; // no grid: nothing to judge
    };
    q.dropped_frames = s.dropped_frames;
    let name = |side: crate::measure::Side| side.as_str().to_string();
    let measured = counters.foot_side();
    q.measure_warnings = counters.measure_warnings();
    q.side = measured.map(|d| SideCheck {
        chosen: chosen.map(name),
        detected: name(d),
    });
    let (status, reason) = judge(&mut q, &plan.quality, s.frames, measured.is_some());
    s.status = status;
    s.reason = reason;
    s.quality = Some(q);
}

fn finish(s: &mut ScanSummary, counters: &ScanCounters, started: Instant) {
    s.plugins = counters.plugins();
    s.frames = counters.frames();
    s.dropped_frames = counters.dropped();
    s.stationary_frames = counters.stationary();
    let (frames, rows_found) = counters.laser_off();
    s.laser_off =
        (frames > 0).then_some(crate::scan::summary::LaserOffStats { frames, rows_found });
    s.seconds = started.elapsed().as_secs_f64();
}

fn write_summary(dir: &Path, s: &ScanSummary) -> Result<(), ScanError> {
    let path = crate::scandata::ScanDir::new(dir).summary_path();
    let json = serde_json::to_vec_pretty(s).expect("summary serialises");
    crate::io::write_atomic(&path, &json).map_err(|source| ScanError::Write { path, source })
}

fn stage_report(s: &StageStats) -> StageReport {
    StageReport {
        name: s.name.clone(),
        input: s.input,
        output: s.output,
        dropped: s.dropped,
        mean_latency_ms: s.mean_latency_ms,
        max_latency_ms: s.max_latency_ms,
        blocked_ms: s.blocked_ms,
    }
}

/// Build errors with the config file, line and column of the offending key.
pub fn describe_build_error(cfg: &LoadedConfig, e: &BuildError) -> String {
    let file = cfg.path.display();
    match e {
        BuildError::Factory { index, source, .. } => {
            let msg = source.to_string();
            let key = backticked(&msg).unwrap_or("stage");
            let at = cfg.locate_stage_key(*index, key).unwrap_or_default();
            format!("config {file}: {e}: {msg}{at}")
        }
        BuildError::UnknownStage { index, .. } => {
            let at = cfg.locate_stage_key(*index, "stage").unwrap_or_default();
            format!("config {file}: {e}{at}")
        }
        _ => format!("config {file}: {e}"),
    }
}

/// The first `word` quoted in backticks (serde names unknown fields this way).
fn backticked(msg: &str) -> Option<&str> {
    let start = msg.find('`')? + 1;
    let len = msg[start..].find('`')?;
    Some(&msg[start..start + len])
}
