//! The footscand service: the scanner config, the archive, at most one running job (a scan or
//! a calibration, each on its own thread: the scan pipeline is synchronous), a broadcast
//! channel of events, and the live preview. The HTTP layer (`crate::api`) is a thin shell.

pub mod config;
pub mod fitview;
mod fleet;
pub mod guided;
pub mod insolejob;
mod jobs;
pub mod lastjob;
pub mod preflight;
pub mod preview;
pub mod scanjob;

pub use config::{DaemonConfig, DaemonConfigError};
pub use fleet::FleetStatus;
pub use preview::Preview;

use crate::archive::calibrations::Calibrations;
use crate::archive::{Archive, ArchiveError, Status};
use footscan::scan::{CancelToken, LoadedConfig, ScanFault};
use footscan::scandata::ScanDir;
use serde::Serialize;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Instant;
use tokio::sync::broadcast;

/// Reason a scan gets when the daemon stops during it.
pub const SHUTDOWN_REASON: &str = "daemon shutting down";
/// Reason a scan gets when the operator cancels it.
pub const CANCEL_REASON: &str = "cancelled by the operator";

/// A scan's progress as the API shows it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Progress {
    pub id: String,
    pub state: Status,
    pub frames: u64,
    pub expected_frames: u64,
    pub points: u64,
    pub dropped: u64,
    pub elapsed_s: f64,
    pub reason: Option<String>,
    /// The device fault that ended the scan, if one did (typed, for the device status; the
    /// reason says it in words). Not known for scans of an earlier daemon run.
    #[serde(skip)]
    pub fault: Option<ScanFault>,
}

/// A calibration or daily-check job as the API shows it (GET /api/calibrations/job and the
/// `calibration` event): the step shown, what it saw, what the job waits for.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CalibrationJob {
    pub id: String,
    /// `calibration` or `verify` (the daily check).
    pub kind: String,
    pub method: String,
    pub state: Status,
    pub reason: Option<String>,
    /// Whether the operator confirms each step over the API.
    pub guided: bool,
    pub confirmed_by: String,
    /// `starting`, `place` (waits for confirm/abort), `acquiring`, `review` (waits for
    /// confirm/repeat/abort), `fitting`, `done`.
    pub phase: String,
    /// The step shown: what to place, where the slider goes.
    pub step: Option<footscan::calib::guided::Step>,
    /// Attempt at the step, from 1.
    pub attempt: usize,
    pub frames: usize,
    pub total_frames: usize,
    /// What the step saw against what it expected, once taken.
    pub result: Option<footscan::calib::guided::StepResult>,
    /// What to do now, in words.
    pub message: Option<String>,
    /// The steps kept so far.
    pub kept: Vec<String>,
    /// The calibration made (kind calibration) or checked (kind verify).
    pub calibration_id: Option<String>,
    /// The daily check's report.
    pub report: Option<serde_json::Value>,
}

/// The calibration later scans use.
#[derive(Clone, Debug, Serialize)]
pub struct CalibrationInfo {
    /// Its id in the archive's calibration history (None: a configured file, or an archive's
    /// `current.toml` from before the history).
    pub id: Option<String>,
    pub method: String,
    pub date: String,
    pub path: PathBuf,
}

/// What the event stream carries; the variant is the SSE event name.
#[derive(Clone, Debug)]
pub enum Event {
    Progress(Progress),
    State {
        id: String,
        state: Status,
        reason: Option<String>,
    },
    Error {
        id: String,
        reason: String,
    },
    Calibration(Box<CalibrationJob>),
}

impl Event {
    pub fn name(&self) -> &'static str {
        match self {
            Event::Progress(_) => "progress",
            Event::State { .. } => "state",
            Event::Error { .. } => "error",
            Event::Calibration(_) => "calibration",
        }
    }
    pub fn json(&self) -> String {
        let v = match self {
            Event::Progress(p) => serde_json::to_value(p),
            Event::State { id, state, reason } => {
                Ok(serde_json::json!({"id": id, "state": state, "reason": reason}))
            }
            Event::Error { id, reason } => Ok(serde_json::json!({"id": id, "reason": reason})),
            Event::Calibration(c) => serde_json::to_value(c),
        };
        v.expect("event serialises").to_string()
    }
}

/// Why the daemon refused or failed a request. The first kinds hold a message composed from
/// the daemon's state (what is busy, what is missing and how to go on); the others hold the
/// error that caused them, printed after their own words by the edge (the API, the log).
/// The API maps each to a status in one place (api/error.rs).
#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    #[error("{0}")]
    Busy(String),
    #[error("{0}")]
    NotFound(String),
    #[error("{0}")]
    NotRunning(String),
    /// The request does not fit the resource's state (a scan not measured, still running).
    #[error("{0}")]
    Conflict(String),
    #[error(transparent)]
    Archive(#[from] ArchiveError),
    #[error("{0}")]
    Unsupported(String),
    #[error("{0}")]
    BadRequest(String),
    /// A device the scan needs is missing (it may be plugged in later).
    #[error("{0}")]
    Unavailable(String),
    #[error(transparent)]
    ScannerConfig(#[from] footscan::scan::config::ConfigError),
    /// The scanner config or its calibration fails a check made before any scan (the
    /// message names the file, the key and what is valid).
    /// Boxed: the largest error here, and rare.
    #[error(transparent)]
    Preflight(Box<preflight::PreflightError>),
    /// The comfort rule file of `[lasts] rules` (the message names it and what is valid).
    #[error(transparent)]
    Rules(#[from] footscan_last::customize::rules::RulesError),
    #[error("cannot start {what}")]
    Thread {
        what: String,
        #[source]
        source: std::io::Error,
    },
    #[error(transparent)]
    Calibration(#[from] footscan::calib::CalibrationError),
    #[error(transparent)]
    Calib(#[from] footscan::calib::CalibError),
    /// The scan's plantar surface could not be read for a last.
    #[error(transparent)]
    Plantar(footscan::lastcustom::ClinicLastError),
    #[error("stock lasts {}", dir.display())]
    StockLasts {
        dir: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}", path.display())]
    JobRead {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("cannot write {}", path.display())]
    JobWrite {
        path: std::path::PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}", path.display())]
    JobJson {
        path: std::path::PathBuf,
        #[source]
        source: serde_json::Error,
    },
}

impl From<Box<preflight::PreflightError>> for DaemonError {
    fn from(e: Box<preflight::PreflightError>) -> Self {
        DaemonError::Preflight(e)
    }
}

/// The running job.
enum Job {
    Scan {
        id: String,
        cancel: CancelToken,
        thread: std::thread::JoinHandle<()>,
    },
    /// Never joined: a calibration writes nothing until it succeeded, so shutdown leaves it
    /// (a guided one waiting for the operator ends: its answers channel closes).
    Calibration {
        _thread: std::thread::JoinHandle<()>,
    },
}

#[derive(Default)]
struct State {
    job: Option<Job>,
    /// The running scan, or the last one.
    scan: Option<Progress>,
    /// Set when the scan is cancelled: the reason recorded with it.
    cancel_reason: Option<String>,
    calibrating: Option<CalibrationJob>,
    /// The running guided job's answers.
    guide: Option<guided::AnswerTx>,
    calibration: Option<CalibrationInfo>,
    shutting_down: bool,
}

pub struct Daemon {
    pub config: DaemonConfig,
    pub scanner: LoadedConfig,
    pub archive: Arc<Archive>,
    pub preview: Arc<Preview>,
    events: broadcast::Sender<Event>,
    state: Mutex<State>,
    started: Instant,
    launcher: jobs::Launcher,
    /// The fleet pusher, when [fleet] is on.
    fleet: Option<fleet::Fleet>,
    /// The scans the jobs on finished scans (a last, an insole) are making files for.
    scan_jobs: scanjob::Running,
    /// The certificate in use when serving HTTPS (set once at start), for the status page.
    pub tls: std::sync::OnceLock<crate::api::tls::TlsInfo>,
}

impl Daemon {
    /// Load the scanner config and the calibration, open (and recover) the archive. Jobs
    /// will run at the priority of the calling thread.
    pub fn open(config: DaemonConfig) -> Result<Arc<Daemon>, DaemonError> {
        let scanner = LoadedConfig::load(&config.scanner_config)?;
        // A calibration made by the daemon wins over the configured one (it is newer).
        let history = Calibrations::new(&config.archive);
        let (cal_id, daemon_cal) = match history.current() {
            Some((id, path)) => (
                id,
                Some((path, "the daemon's last calibration".to_string())),
            ),
            None => (
                None,
                config.calibration.clone().map(|p| {
                    let from = format!("calibration in [daemon] of {}", config.path.display());
                    (p, from)
                }),
            ),
        };
        let cal = preflight::scan_calibration(
            &scanner,
            daemon_cal.as_ref().map(|(p, f)| (p.as_path(), f.as_str())),
        )?;
        preflight::check_config(&scanner, &cal)?;
        for (_, why) in preflight::missing_devices(&scanner) {
            tracing::warn!("{why}; scans are refused until it is present");
        }
        let archive = Arc::new(Archive::open(&config.archive)?);
        archive.set_cache_max_bytes(config.archive_policy.cache_bytes);
        let calibration = daemon_cal.map(|(path, _)| CalibrationInfo {
            id: cal_id,
            method: cal.method,
            date: cal.date,
            path,
        });
        // The last scan, as status shows it until the next one starts.
        // (One row from the index: listing 50,000 to take the first cost a second.)
        let newest = crate::archive::ScanQuery {
            limit: Some(1),
            ..Default::default()
        };
        let last_scan = archive
            .list_page(&newest)?
            .items
            .into_iter()
            .next()
            .map(|r| {
                let summary: Option<serde_json::Value> = archive
                    .artifact_bytes(&r, ScanDir::SUMMARY)
                    .and_then(|b| serde_json::from_slice(&b).ok());
                let num = |k: &str| summary.as_ref().and_then(|s| s[k].as_f64());
                Progress {
                    id: r.id.clone(),
                    state: r.status,
                    frames: r.frames,
                    expected_frames: footscan::scan::ScanPlan::from_config(&scanner.config)
                        .expected_frames(),
                    points: r.points,
                    dropped: num("dropped_frames").unwrap_or(0.0) as u64,
                    elapsed_s: num("seconds").unwrap_or(0.0),
                    reason: r.reason,
                    fault: None,
                }
            });
        let fleet = config
            .fleet
            .clone()
            .map(|s| fleet::Fleet::start(s, archive.clone()))
            .transpose()
            .map_err(|source| DaemonError::Thread {
                what: "the fleet pusher".into(),
                source,
            })?;
        if config.archive_policy.retains() {
            start_retention(&archive, &config).map_err(|source| DaemonError::Thread {
                what: "the archive's retention".into(),
                source,
            })?;
        }
        let (events, _) = broadcast::channel(256);
        Ok(Arc::new(Daemon {
            config,
            scanner,
            archive,
            preview: Arc::new(Preview::default()),
            events,
            state: Mutex::new(State {
                calibration,
                scan: last_scan,
                ..State::default()
            }),
            started: Instant::now(),
            launcher: jobs::Launcher::new().map_err(|source| DaemonError::Thread {
                what: "the job launcher".into(),
                source,
            })?,
            fleet,
            scan_jobs: scanjob::Running::default(),
            tls: std::sync::OnceLock::new(),
        }))
    }

    /// Put a scan that just ended into compact form (`[archive] compact`, on by default), on
    /// a thread of its own at a lower priority, once no job runs (the scan's own job ends
    /// first; a scan started meanwhile is not competed with): the scan is already listed and
    /// served from its original files until then, and a reader takes either form
    /// (docs/method.md 14h.2).
    pub(crate) fn compact_new_scan(self: &Arc<Self>, id: &str) {
        if !self.config.archive_policy.compact {
            return;
        }
        let dir = self.archive.root().join(id);
        let id = id.to_string();
        let me = Arc::downgrade(self);
        let spawned = std::thread::Builder::new()
            .name("compact".into())
            .spawn(move || {
                let _ = footscan_util::priority::lower_this_thread(10);
                let t = Instant::now();
                // Wait for the scanner to be idle (at most 30 minutes; a daemon shutting down
                // leaves the scan as it is: the reader takes either form, a later run of
                // `footscand archive compact` finishes it).
                loop {
                    let Some(d) = me.upgrade() else { return };
                    let busy = {
                        let st = d.state.lock().unwrap();
                        if st.shutting_down {
                            return;
                        }
                        st.job.is_some()
                    };
                    if !busy || t.elapsed() > std::time::Duration::from_secs(1800) {
                        break;
                    }
                    drop(d);
                    std::thread::sleep(std::time::Duration::from_millis(250));
                }
                let opts = footscan::compact::CompactOptions::default();
                match footscan::compact::compact_dir(&dir, &opts) {
                    Ok(r) => tracing::info!(
                        "archive: scan {id} compacted: {:.1} MB -> {:.1} MB in {:.2} s",
                        r.bytes_before as f64 / 1e6,
                        r.bytes_after as f64 / 1e6,
                        r.seconds
                    ),
                    Err(e) => tracing::error!(
                        "archive: scan {id} not compacted (its files stay as they are): {e}"
                    ),
                }
            });
        if let Err(e) = spawned {
            tracing::error!(
                "archive: a scan in {} not compacted: no thread: {e}",
                self.archive.root().display()
            );
        }
    }

    /// A scan's record and directory, refused (409) unless it has measurements.json: what
    /// `need` (a report, a last) is made from.
    pub fn measured_scan(
        &self,
        id: &crate::archive::ScanId,
        need: &str,
    ) -> Result<(crate::archive::Record, PathBuf), DaemonError> {
        let rec = self.archive.get(id)?;
        let dir = self
            .archive
            .checked_dir(&rec)
            .ok_or_else(|| DaemonError::NotFound(format!("scan {id}: its directory is missing")))?;
        if self
            .archive
            .artifact_path(&rec, ScanDir::MEASUREMENTS)
            .is_none()
        {
            return Err(DaemonError::Conflict(format!(
                "scan {id} ({}) has no measurements.json: {need} needs a measured foot",
                rec.status.as_str()
            )));
        }
        Ok((rec, dir))
    }

    pub fn subscribe(&self) -> broadcast::Receiver<Event> {
        self.events.subscribe()
    }

    fn emit(&self, e: Event) {
        let _ = self.events.send(e); // no subscriber is fine
    }

    pub fn uptime_s(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }

    /// The running or last scan.
    pub fn scan_progress(&self) -> Option<Progress> {
        self.state.lock().unwrap().scan.clone()
    }

    pub fn calibrating(&self) -> Option<CalibrationJob> {
        self.state.lock().unwrap().calibrating.clone()
    }

    pub fn calibration(&self) -> Option<CalibrationInfo> {
        self.state.lock().unwrap().calibration.clone()
    }

    pub fn is_scanning(&self) -> bool {
        matches!(self.state.lock().unwrap().job, Some(Job::Scan { .. }))
    }

    /// Cancel the running scan `id`.
    pub fn cancel_scan(&self, id: &str) -> Result<(), DaemonError> {
        let mut st = self.state.lock().unwrap();
        match &st.job {
            Some(Job::Scan {
                id: running,
                cancel,
                ..
            }) if running == id => {
                cancel.cancel();
                st.cancel_reason.get_or_insert_with(|| CANCEL_REASON.into());
                Ok(())
            }
            _ => Err(DaemonError::NotRunning(format!(
                "scan {id} is not running: only the running scan can be cancelled"
            ))),
        }
    }

    /// Stop taking jobs, cancel the running scan (archived as cancelled with
    /// [`SHUTDOWN_REASON`]) and wait for it to be archived. A running calibration is not
    /// waited for: it writes nothing until it has succeeded.
    pub fn shutdown(&self) {
        self.end_guides();
        let thread = {
            let mut st = self.state.lock().unwrap();
            st.shutting_down = true;
            match st.job.take() {
                Some(Job::Scan { cancel, thread, .. }) => {
                    cancel.cancel();
                    st.cancel_reason = Some(SHUTDOWN_REASON.into());
                    Some(thread)
                }
                other => {
                    st.job = other;
                    None
                }
            }
        };
        if let Some(t) = thread {
            tracing::info!("shutdown: waiting for the running scan to be archived");
            let _ = t.join();
        }
    }
}

/// Run the archive's retention at start and then every `retention_interval_h`, on a thread
/// at a lower priority (archive/retention.rs).
fn start_retention(archive: &Arc<Archive>, config: &DaemonConfig) -> std::io::Result<()> {
    let p = &config.archive_policy;
    let rules = crate::archive::retention::Rules {
        keep_raw_days: p.keep_raw_days,
        keep_days: p.keep_days,
        max_gb: p.max_gb,
        fleet: config.fleet.is_some(),
    };
    let every = std::time::Duration::from_secs_f64(p.retention_interval_h * 3600.0);
    let archive = Arc::downgrade(archive);
    std::thread::Builder::new()
        .name("retention".into())
        .spawn(move || {
            let _ = footscan_util::priority::lower_this_thread(10);
            loop {
                let Some(a) = archive.upgrade() else { return };
                a.retain(&rules, crate::archive::retention::now_secs());
                drop(a);
                std::thread::sleep(every);
            }
        })
        .map(|_| ())
}
