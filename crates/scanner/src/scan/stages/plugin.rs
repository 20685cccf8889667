//! The `wasm` and `exec` stages' detector: a WebAssembly module or an external process
//! (crate `footscan-plugins`) seen through the same [`LinePeak`] rows as the built-in detectors, so triangulation, the live
//! preview and the archive cannot tell them apart.
//!
//! Unlike [`crate::detect::Detector`], a plugin can fail on any frame (a trap, a limit, output
//! the ABI forbids); the failure ends the scan with the plugin's own reason.

use crate::detect::{LinePeak, Reject};
use crate::pipeline::BoxError;
use footscan_hal::{Frame, Pixels};
use footscan_plugins::exec::ExecDetector;
use footscan_plugins::wasm::{self, RowOut, WasmDetector};

enum Inner {
    Wasm(WasmDetector),
    Exec(ExecDetector),
}

/// A plugin's detector, with its output buffer kept between frames.
pub struct PluginDetector {
    inner: Inner,
    rows: Vec<RowOut>,
}

const REJECTS: [Reject; 5] = [
    Reject::BelowThreshold,
    Reject::Saturated,
    Reject::Ambiguous,
    Reject::Border,
    Reject::Isolated,
];

impl PluginDetector {
    pub fn new(inner: WasmDetector) -> Self {
        Self::with(Inner::Wasm(inner))
    }

    pub fn exec(inner: ExecDetector) -> Self {
        Self::with(Inner::Exec(inner))
    }

    fn with(inner: Inner) -> Self {
        // The ABI's codes 1..=5 are these rejects in this order (docs/plugins.md).
        debug_assert_eq!(wasm::REJECT_CODES[1..].len(), REJECTS.len());
        Self {
            inner,
            rows: Vec::new(),
        }
    }

    /// Fill `out` (one per row of `frame`) or fail naming the plugin.
    pub fn detect(&mut self, frame: &Frame, out: &mut [LinePeak]) -> Result<(), BoxError> {
        let px = match &frame.pixels {
            Pixels::Gray8(p) => wasm::Pixels::Gray8(p),
            Pixels::Gray16(p) => wasm::Pixels::Gray16(p),
        };
        self.rows.resize(out.len(), EMPTY);
        match &mut self.inner {
            Inner::Wasm(d) => d.detect(frame.width, frame.height, px, &mut self.rows)?,
            Inner::Exec(d) => d.detect(frame.width, frame.height, px, &mut self.rows)?,
        }
        for (o, r) in out.iter_mut().zip(&self.rows) {
            *o = match r.reject {
                0 => LinePeak {
                    col: r.col,
                    intensity: r.intensity,
                    width: r.width,
                    quality: r.quality,
                    reject: None,
                },
                code => LinePeak::rejected(REJECTS[code as usize - 1], r.intensity),
            };
        }
        Ok(())
    }
}

const EMPTY: RowOut = RowOut {
    col: f64::NAN,
    intensity: 0.0,
    width: 0.0,
    quality: 0.0,
    reject: 1,
};

/// Why a per-scan or sink plugin stage failed. Each message names the plugin; a cause is its
/// source, not repeated in the message.
#[derive(Debug, thiserror::Error)]
pub enum PluginStageError {
    /// The plugin did not run to its end (its error names it).
    #[error(transparent)]
    Run(#[from] footscan_plugins::PluginError),
    /// A per-scan plugin's report is not `key value` lines; `problem` says which line.
    #[error("plugin {plugin} {problem}")]
    Values { plugin: String, problem: String },
    /// A sink plugin's report could not be kept in the scan directory.
    #[error("plugin {plugin}: its report could not be written to {}", path.display())]
    Report {
        plugin: String,
        path: std::path::PathBuf,
        source: std::io::Error,
    },
    /// The stage never met the item it runs on; `missing` says where to place it.
    #[error("plugin {plugin} {missing}")]
    NeverRan {
        plugin: String,
        missing: &'static str,
    },
}

/// A per-scan or sink plugin: a wasm module's instance or a process.
pub enum PluginRunner {
    Wasm(footscan_plugins::wasm::WasmRunner),
    Exec(ExecDetector),
}

impl PluginRunner {
    fn run(
        &mut self,
        input: &[u8],
        dir: Option<&std::path::Path>,
    ) -> Result<Vec<u8>, footscan_plugins::PluginError> {
        match self {
            Self::Wasm(w) => w.run(input),
            Self::Exec(e) => e.run(input, dir),
        }
    }
}

/// What every per-scan and sink plugin stage shares: who it is, whether the scan needs it,
/// and where its outcome is recorded.
pub struct PluginInfo {
    /// `wasm` or `exec`.
    pub stage: &'static str,
    /// The module's file or the command, as messages name it.
    pub plugin: String,
    /// `required = false`: a failure skips the stage instead of failing the scan.
    pub required: bool,
    pub counters: std::sync::Arc<crate::scan::ScanCounters>,
}

impl PluginInfo {
    fn record(&self, place: &str) -> crate::scan::PluginRecord {
        crate::scan::PluginRecord {
            stage: self.stage.to_string(),
            plugin: self.plugin.clone(),
            place: place.to_string(),
            status: "ok".into(),
            reason: None,
            values: Default::default(),
            report: None,
        }
    }

    /// A failure: the scan's error when the stage is required, else a skip kept in scan.json
    /// and the log.
    /// A once-per-scan stage (`place` "scan" or "sink") has met the item it waits for when
    /// `ran` is its run's result: marked done, and a failure handled as [`Self::failed`].
    fn once_seen(
        &self,
        done: &mut bool,
        place: &str,
        ran: Option<Result<(), PluginStageError>>,
    ) -> Result<(), BoxError> {
        let Some(ran) = ran else {
            return Ok(());
        };
        *done = true;
        ran.or_else(|why| self.failed(place, why))
    }

    /// At the end of the scan: a once-per-scan stage that never met its item fails with
    /// `missing` (where to place it).
    fn once_finished(
        &self,
        done: bool,
        place: &str,
        missing: &'static str,
    ) -> Result<(), BoxError> {
        if done {
            return Ok(());
        }
        self.failed(
            place,
            PluginStageError::NeverRan {
                plugin: self.plugin.clone(),
                missing,
            },
        )
    }

    fn failed(&self, place: &str, why: PluginStageError) -> Result<(), BoxError> {
        if self.required {
            return Err(why.into());
        }
        let why = footscan_util::chain(&why);
        tracing::warn!(stage = self.stage, plugin = %self.plugin, "optional {place} stage skipped: {why}");
        self.counters.add_plugin(crate::scan::PluginRecord {
            status: "skipped".into(),
            reason: Some(why),
            ..self.record(place)
        });
        Ok(())
    }
}

/// A per-scan plugin stage: the grid's valid points in (x y z, f64 little-endian each), the
/// `key value` lines it reports added to scan.json.
pub struct PluginScanStage {
    pub info: PluginInfo,
    pub runner: PluginRunner,
    done: bool,
}

impl PluginScanStage {
    pub fn new(info: PluginInfo, runner: PluginRunner) -> Self {
        Self {
            info,
            runner,
            done: false,
        }
    }

    fn run(&mut self, grid: &crate::scandata::ScanGrid) -> Result<(), PluginStageError> {
        let mut input = Vec::with_capacity(grid.valid_count() * 24);
        for (_, _, p, _) in grid.valid() {
            for v in p.iter() {
                input.extend_from_slice(&v.to_le_bytes());
            }
        }
        let report = self.runner.run(&input, None)?;
        let values = footscan_plugins::parse_values(&report).map_err(|problem| {
            PluginStageError::Values {
                plugin: self.info.plugin.clone(),
                problem,
            }
        })?;
        self.info.counters.add_plugin(crate::scan::PluginRecord {
            values: values.into_iter().collect(),
            ..self.info.record("scan")
        });
        Ok(())
    }
}

impl crate::pipeline::Stage<crate::scan::item::Item> for PluginScanStage {
    fn process(
        &mut self,
        item: crate::scan::item::Item,
        out: &mut crate::pipeline::Emitter<crate::scan::item::Item>,
    ) -> Result<(), BoxError> {
        let ran = match &item {
            crate::scan::item::Item::Grid(grid) => Some(self.run(grid)),
            _ => None,
        };
        self.info.once_seen(&mut self.done, "scan", ran)?;
        let _ = out.emit(item);
        Ok(())
    }

    fn finish(
        &mut self,
        _out: &mut crate::pipeline::Emitter<crate::scan::item::Item>,
    ) -> Result<(), BoxError> {
        self.info.once_finished(
            self.done,
            "scan",
            "received no scan grid: place the per-scan stage after accumulate",
        )
    }
}

/// A sink plugin stage: the scan summary in (JSON, as scan.json holds it before the quality
/// gate), the scan directory readable, its report written to `report` in the scan directory.
pub struct PluginSinkStage {
    pub info: PluginInfo,
    pub runner: PluginRunner,
    pub out_dir: std::path::PathBuf,
    pub report: std::path::PathBuf,
    done: bool,
}

impl PluginSinkStage {
    pub fn new(
        info: PluginInfo,
        runner: PluginRunner,
        out_dir: std::path::PathBuf,
        report: std::path::PathBuf,
    ) -> Self {
        Self {
            info,
            runner,
            out_dir,
            report,
            done: false,
        }
    }

    fn run(&mut self, summary: &crate::scan::ScanSummary) -> Result<(), PluginStageError> {
        let mut s = summary.clone();
        s.plugins = self.info.counters.plugins();
        let input = serde_json::to_vec(&s).expect("the summary serialises");
        let report = self.runner.run(&input, Some(&self.out_dir))?;
        crate::io::write_atomic(&self.report, &report).map_err(|source| {
            PluginStageError::Report {
                plugin: self.info.plugin.clone(),
                path: self.report.clone(),
                source,
            }
        })?;
        self.info.counters.add_plugin(crate::scan::PluginRecord {
            report: self
                .report
                .file_name()
                .map(|f| f.to_string_lossy().into_owned()),
            ..self.info.record("sink")
        });
        Ok(())
    }
}

impl crate::pipeline::Stage<crate::scan::item::Item> for PluginSinkStage {
    fn process(
        &mut self,
        item: crate::scan::item::Item,
        out: &mut crate::pipeline::Emitter<crate::scan::item::Item>,
    ) -> Result<(), BoxError> {
        let ran = match &item {
            crate::scan::item::Item::Summary(s) => Some(self.run(s)),
            _ => None,
        };
        self.info.once_seen(&mut self.done, "sink", ran)?;
        let _ = out.emit(item);
        Ok(())
    }

    fn finish(
        &mut self,
        _out: &mut crate::pipeline::Emitter<crate::scan::item::Item>,
    ) -> Result<(), BoxError> {
        self.info.once_finished(
            self.done,
            "sink",
            "received no scan summary: place the sink after sink.summary",
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(required: bool) -> PluginInfo {
        PluginInfo {
            stage: "exec",
            plugin: "post.py".into(),
            required,
            counters: Default::default(),
        }
    }

    /// A skipped optional stage keeps its failure and its cause in scan.json, each said once.
    #[test]
    fn a_skipped_stage_keeps_its_reason_with_the_cause_once() {
        let i = info(false);
        let why = PluginStageError::Report {
            plugin: i.plugin.clone(),
            path: "/scan/post-report.txt".into(),
            source: std::io::Error::other("disk full"),
        };
        i.failed("sink", why).unwrap();
        let r = i.counters.plugins();
        assert_eq!(r[0].status, "skipped");
        assert_eq!(
            r[0].reason.as_deref(),
            Some("plugin post.py: its report could not be written to /scan/post-report.txt: disk full")
        );
    }

    /// A required stage fails the scan with a typed error, its cause as its source.
    #[test]
    fn a_required_stage_fails_with_the_typed_error() {
        let i = info(true);
        let e = i
            .once_finished(
                false,
                "scan",
                "received no scan grid: place it after accumulate",
            )
            .unwrap_err();
        let e = e.downcast_ref::<PluginStageError>().expect("typed");
        assert!(matches!(e, PluginStageError::NeverRan { .. }), "{e:?}");
        assert_eq!(
            e.to_string(),
            "plugin post.py received no scan grid: place it after accumulate"
        );
        assert!(i.counters.plugins().is_empty());
    }
}
