//! The CAD files follow the results (issue 34 item 2). Building the closed solid and writing
//! STL, STEP and glTF took most of `model.bezier`'s 650-750 ms, and every stage after it (the
//! measurements, the plantar picture, the height map, the verdict) waited for it, while the
//! patient waited for the verdict. The stage now passes the grid and the model on as soon as
//! they exist and writes the files on a thread of its own; `run_scan` writes scan.json with
//! the verdict and the model "building", joins the job, and writes scan.json again.
//!
//! The foot is measured once: `measure.foot` hands its height map and measurements to the job
//! through [`FootShare`] (the solid is built on them), and the job measures only when no such
//! stage will (none in the pipeline, a different cell, heights without the model).

use crate::geom::HeightMap;
use crate::measure::Measurements;
use crate::surface::BezierNetwork;
use serde::Serialize;
use std::sync::{Arc, Condvar, Mutex};

/// A foot as `measure.foot` measured it, with the model its heights came from.
#[derive(Debug)]
pub struct MeasuredFoot {
    pub net: Arc<BezierNetwork>,
    pub map: HeightMap,
    pub measurements: Measurements,
}

#[derive(Debug, Default)]
enum Share {
    /// No stage said it would measure the foot the model's way.
    #[default]
    NoMeasurer,
    Pending,
    Ready(Option<Arc<MeasuredFoot>>),
}

/// The hand-over of the measured foot from `measure.foot` to the model job.
#[derive(Debug, Default)]
pub struct FootShare {
    state: Mutex<Share>,
    ready: Condvar,
}

impl FootShare {
    /// A stage that will [`Self::publish`] exists (called when the pipeline is built, before
    /// any job can wait).
    pub fn expect(&self) {
        let mut s = self.state.lock().unwrap();
        if matches!(*s, Share::NoMeasurer) {
            *s = Share::Pending;
        }
    }

    /// The measured foot, or None when it could not be measured (the job then measures, and
    /// reports why it could not). The first call counts.
    pub fn publish(&self, foot: Option<Arc<MeasuredFoot>>) {
        let mut s = self.state.lock().unwrap();
        if !matches!(*s, Share::Ready(_)) {
            *s = Share::Ready(foot);
            self.ready.notify_all();
        }
    }

    /// The measured foot once it is published; None at once if nobody will publish it.
    pub fn wait(&self) -> Option<Arc<MeasuredFoot>> {
        let mut s = self.state.lock().unwrap();
        loop {
            match &*s {
                Share::NoMeasurer => return None,
                Share::Ready(f) => return f.clone(),
                Share::Pending => s = self.ready.wait(s).unwrap(),
            }
        }
    }
}

/// Where the CAD files are, in scan.json (`model`) and the scan's progress.
#[derive(Clone, Copy, Debug, Serialize, PartialEq, Eq)]
#[serde(rename_all = "snake_case")]
pub enum ModelState {
    /// Being built and written after the results.
    Building,
    Written,
    /// No foot to put a frame on (an empty glass, a plate): the scan goes on without them.
    NotWritten,
    /// A file could not be written: the scan fails.
    Failed,
    /// The scan was cancelled or failed before the files were written.
    Abandoned,
}

impl ModelState {
    /// As scan.json spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            ModelState::Building => "building",
            ModelState::Written => "written",
            ModelState::NotWritten => "not_written",
            ModelState::Failed => "failed",
            ModelState::Abandoned => "abandoned",
        }
    }
}

/// The CAD files' progress.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ModelProgress {
    pub state: ModelState,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The files written (names in the scan directory).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub files: Vec<String>,
    /// Triangles of the STL solid.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub triangles: Option<usize>,
    /// Whether the foot was measured by the job itself (no `measure.foot` shared it).
    pub measured_again: bool,
}

impl ModelProgress {
    pub fn building() -> Self {
        ModelProgress {
            state: ModelState::Building,
            reason: None,
            files: Vec::new(),
            triangles: None,
            measured_again: false,
        }
    }
}

/// The model job of one scan: its progress, its thread, and the flag that abandons it.
#[derive(Debug, Default)]
pub struct ModelJob {
    pub foot: FootShare,
    progress: Mutex<Option<ModelProgress>>,
    thread: Mutex<Option<std::thread::JoinHandle<()>>>,
    abandon: std::sync::atomic::AtomicBool,
}

impl ModelJob {
    pub fn set_progress(&self, p: ModelProgress) {
        *self.progress.lock().unwrap() = Some(p);
    }

    /// None: no model stage ran.
    pub fn progress(&self) -> Option<ModelProgress> {
        self.progress.lock().unwrap().clone()
    }

    /// Run `work` on the job's thread (the progress is "building" until it sets it).
    pub fn start(&self, work: impl FnOnce() + Send + 'static) -> std::io::Result<()> {
        self.set_progress(ModelProgress::building());
        let h = std::thread::Builder::new()
            .name("model.files".into())
            .spawn(|| {
                // Ten nice levels below the scan: the stages that give the results (the
                // measurements' files, the height map, the summary) run beside it and the
                // patient waits on them, not on the CAD files (issue 34 item 2).
                if let Err(e) = footscan_util::priority::lower_this_thread(10) {
                    tracing::debug!("model.files: priority not lowered: {e}");
                }
                work()
            })?;
        if let Some(old) = self.thread.lock().unwrap().replace(h) {
            let _ = old.join();
        }
        Ok(())
    }

    /// Whether the scan gave the job up (checked between its steps).
    pub fn abandoned(&self) -> bool {
        self.abandon.load(std::sync::atomic::Ordering::SeqCst)
    }

    /// Wait for the job (after `abandon`: it stops at its next step) and return its outcome.
    pub fn join(&self, abandon: bool) -> Option<ModelProgress> {
        if abandon {
            self.abandon
                .store(true, std::sync::atomic::Ordering::SeqCst);
            // A job still waiting for the measured foot would wait for a stage that ended.
            self.foot.publish(None);
        }
        let h = self.thread.lock().unwrap().take();
        if let Some(h) = h {
            if h.join().is_err() {
                self.set_progress(ModelProgress {
                    state: ModelState::Failed,
                    reason: Some("internal error: the model thread panicked".into()),
                    ..ModelProgress::building()
                });
            }
        }
        self.progress()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_waiter_gets_what_is_published_and_nobody_waits_without_a_measurer() {
        let s = FootShare::default();
        assert!(s.wait().is_none(), "no measurer: no wait");
        let s = Arc::new(FootShare::default());
        s.expect();
        let s2 = s.clone();
        let t = std::thread::spawn(move || s2.wait().is_none());
        std::thread::sleep(std::time::Duration::from_millis(20));
        s.publish(None);
        assert!(t.join().unwrap());
    }
}
