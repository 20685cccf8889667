//! The daemon's scan job (run_scan on a thread, written into the archive) and the thread
//! launcher every job starts from; the calibration and daily-check jobs are in `guided.rs`.

use super::{Daemon, DaemonError, Event, Job, Progress};
use crate::archive::{ActiveScan, NewScan, ScanEnd, Status};
use footscan::scan::{run_scan, CancelToken, ScanOptions, ScanProgress};
use std::panic::AssertUnwindSafe;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Hand the memory a scan freed (frame buffers, the grid, the model) back to the system, so
/// resident memory between scans is what the daemon holds, not what the last scan peaked at.
fn release_free_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free heap pages to the kernel.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Starts the job threads (a scan and its pipeline, a calibration) from a thread of the
/// daemon's own priority. Linux threads inherit the nice value of the thread that creates
/// them, and jobs are started from the HTTP runtime's threads, which run at a lower priority
/// (`lower_priority` in main.rs) so that web clients cannot take the scanner's CPU: spawned
/// from there, the whole scan pipeline ran at that lower priority too, on a par with the
/// clients, and dropped frames under load. An unprivileged thread cannot raise its priority
/// back, so the threads are created by this one, made where the daemon was opened.
pub(super) struct Launcher {
    tx: std::sync::mpsc::Sender<Launch>,
}

type Launch = (
    String,
    Box<dyn FnOnce() + Send>,
    std::sync::mpsc::Sender<std::io::Result<std::thread::JoinHandle<()>>>,
);

impl Launcher {
    /// Call on a thread of the priority jobs should have.
    pub(super) fn new() -> std::io::Result<Launcher> {
        let (tx, rx) = std::sync::mpsc::channel::<Launch>();
        std::thread::Builder::new()
            .name("job-launcher".into())
            .spawn(move || {
                for (name, job, reply) in rx {
                    let _ = reply.send(std::thread::Builder::new().name(name).spawn(job));
                }
            })?;
        Ok(Launcher { tx })
    }

    /// Start `job` on a new thread named `name`.
    pub(super) fn spawn(
        &self,
        name: String,
        job: impl FnOnce() + Send + 'static,
    ) -> std::io::Result<std::thread::JoinHandle<()>> {
        let (reply, handle) = std::sync::mpsc::channel();
        let gone = || std::io::Error::other("the job launcher thread is gone");
        self.tx
            .send((name, Box::new(job), reply))
            .map_err(|_| gone())?;
        handle.recv().map_err(|_| gone())?
    }
}

/// Minimum spacing of progress events.
const PROGRESS_PERIOD: Duration = Duration::from_millis(100);

impl Daemon {
    fn busy(&self) -> Option<String> {
        let st = self.state.lock().unwrap();
        if st.shutting_down {
            return Some("the daemon is shutting down".into());
        }
        match &st.job {
            Some(Job::Scan { id, .. }) => Some(format!(
                "scan {id} is running: wait for it to end or cancel it (POST /api/scans/{id}/cancel)"
            )),
            Some(Job::Calibration { .. }) => Some(format!(
                "calibration {} is running: finish or abort it",
                st.calibrating.as_ref().map_or("", |c| c.id.as_str())
            )),
            None => None,
        }
    }

    /// Start a scan; returns its id. Busy while another job runs.
    pub fn start_scan(self: &Arc<Self>, meta: NewScan) -> Result<String, DaemonError> {
        let missing = super::preflight::missing_devices(&self.scanner);
        if !missing.is_empty() {
            let why: Vec<String> = missing.into_iter().map(|(_, w)| w).collect();
            return Err(DaemonError::Unavailable(why.join("; ")));
        }
        if let Some(why) = self.busy() {
            return Err(DaemonError::Busy(why));
        }
        let mut st = self.state.lock().unwrap();
        if st.job.is_some() || st.shutting_down {
            return Err(DaemonError::Busy("another job started just now".into()));
        }
        let active = self.archive.begin(meta)?;
        let id = active.record.id.clone();
        let cancel = CancelToken::default();
        let expected =
            footscan::scan::ScanPlan::from_config(&self.scanner.config).expected_frames();
        st.scan = Some(Progress {
            id: id.clone(),
            state: Status::Running,
            frames: 0,
            expected_frames: expected,
            points: 0,
            dropped: 0,
            elapsed_s: 0.0,
            reason: None,
            fault: None,
        });
        st.cancel_reason = None;
        let calibration = st.calibration.as_ref().map(|c| c.path.clone());
        let mut active = active;
        active.record.calibration = st.calibration.as_ref().and_then(|c| c.id.clone());
        let me = self.clone();
        let token = cancel.clone();
        let thread = self
            .launcher
            .spawn(format!("scan-{id}"), move || {
                me.run_scan_job(active, token, calibration)
            })
            .map_err(|source| DaemonError::Thread {
                what: "the scan thread".into(),
                source,
            })?;
        st.job = Some(Job::Scan {
            id: id.clone(),
            cancel,
            thread,
        });
        drop(st);
        tracing::info!("scan {id} started");
        self.emit(Event::State {
            id: id.clone(),
            state: Status::Running,
            reason: None,
        });
        Ok(id)
    }

    fn run_scan_job(
        self: Arc<Self>,
        active: ActiveScan,
        cancel: CancelToken,
        calibration: Option<PathBuf>,
    ) {
        let id = active.record.id.clone();
        let started = Instant::now();
        self.preview.reset_counts();
        let mut opts = ScanOptions::new(&active.dir);
        opts.calibration = calibration;
        opts.cancel = cancel;
        opts.tap = Some(self.preview.clone());
        // Checked against the measured foot: a mismatch is the verdict "side mismatch".
        opts.side = match active.record.side.as_str() {
            "left" => Some(footscan::measure::Side::Left),
            "right" => Some(footscan::measure::Side::Right),
            _ => None,
        };
        // heightmap.png's title names the subject.
        opts.subject = Some(active.record.subject.clone());
        let mut last_event: Option<Instant> = None;
        let on_progress = |p: &ScanProgress| {
            let prog = self.update_progress(&id, p, started);
            self.archive.note_progress(&id, prog.frames, prog.points);
            if last_event.is_none_or(|t| t.elapsed() >= PROGRESS_PERIOD) {
                last_event = Some(Instant::now());
                self.emit(Event::Progress(prog));
            }
        };
        let result = std::panic::catch_unwind(AssertUnwindSafe(|| {
            run_scan(&self.scanner, &opts, on_progress)
        }));
        let cancel_reason = self.state.lock().unwrap().cancel_reason.clone();
        let fault = match &result {
            Ok(Err(e)) => e.fault(),
            _ => None,
        };
        let mut outcome = match result {
            Ok(Ok(s)) => ScanEnd {
                status: s.status,
                reason: s.reason.clone(),
                frames: s.frames,
                points: s.points as u64,
            },
            Ok(Err(e)) => ScanEnd {
                status: Status::Failed,
                reason: Some(footscan_util::chain(&e)),
                frames: 0,
                points: 0,
            },
            Err(panic) => ScanEnd {
                status: Status::Failed,
                reason: Some(format!(
                    "internal error: the scan thread panicked: {}",
                    panic
                        .downcast_ref::<String>()
                        .map(String::as_str)
                        .or_else(|| panic.downcast_ref::<&str>().copied())
                        .unwrap_or("?")
                )),
                frames: 0,
                points: 0,
            },
        };
        if outcome.status == Status::Cancelled {
            outcome.reason = cancel_reason.or(outcome.reason);
        }
        if !outcome.status.is_usable() && outcome.frames == 0 {
            // scan.json has the counts of a failed scan; the progress has them otherwise.
            if let Some(p) = self.scan_progress() {
                outcome.frames = p.frames;
            }
        }
        let (status, reason) = match self.archive.finish(active, outcome.clone()) {
            Ok(r) => {
                self.fleet_enqueue(&r.id);
                self.compact_new_scan(&r.id);
                (r.status, r.reason)
            }
            Err(e) => {
                // The files stay in .tmp-<id>; the next start recovers them as interrupted.
                tracing::error!("scan {id}: archiving failed: {}", footscan_util::Chain(&e));
                (
                    Status::Failed,
                    Some(format!(
                        "{}; archiving failed: {}",
                        outcome.reason.as_deref().unwrap_or("scan ended"),
                        footscan_util::Chain(&e)
                    )),
                )
            }
        };
        let progress = {
            let mut st = self.state.lock().unwrap();
            let p = st.scan.get_or_insert_with(|| Progress {
                id: id.clone(),
                state: status,
                frames: 0,
                expected_frames: 0,
                points: 0,
                dropped: 0,
                elapsed_s: 0.0,
                reason: None,
                fault: None,
            });
            p.state = status;
            p.reason = reason.clone();
            p.fault = fault;
            p.frames = outcome.frames;
            if status.is_usable() {
                p.points = outcome.points;
            }
            p.elapsed_s = (started.elapsed().as_secs_f64() * 1000.0).round() / 1000.0;
            let p = p.clone();
            if matches!(&st.job, Some(super::Job::Scan { id: j, .. }) if *j == id) {
                st.job = None;
            }
            p
        };
        release_free_memory();
        tracing::info!(
            "scan {id} {}{}",
            status.as_str(),
            reason
                .as_deref()
                .map_or(String::new(), |r| format!(": {r}"))
        );
        self.emit(Event::Progress(progress));
        if matches!(status, Status::Failed | Status::Rescan) {
            self.emit(Event::Error {
                id: id.clone(),
                reason: reason.clone().unwrap_or_default(),
            });
        }
        self.emit(Event::State {
            id: id.clone(),
            state: status,
            reason: reason.clone(),
        });
    }

    fn update_progress(&self, id: &str, p: &ScanProgress, started: Instant) -> Progress {
        let mut st = self.state.lock().unwrap();
        let prog = Progress {
            id: id.to_string(),
            state: Status::Running,
            frames: p.frames,
            expected_frames: p.expected_frames,
            points: self.preview.points(),
            dropped: p.dropped,
            elapsed_s: (started.elapsed().as_secs_f64() * 1000.0).round() / 1000.0,
            reason: None,
            fault: None,
        };
        st.scan = Some(prog.clone());
        prog
    }
}
