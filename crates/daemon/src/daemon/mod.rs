//! The footscand service: the scanner config, the archive, at most one running job (a scan or
//! a calibration, each on its own thread: the scan pipeline is synchronous), a broadcast
//! channel of events, and the live preview. The HTTP layer (`crate::api`) is a thin shell.

pub mod config;
mod fleet;
mod jobs;
pub mod preflight;
pub mod preview;

pub use config::{DaemonConfig, DaemonConfigError};
pub use fleet::FleetStatus;
pub use preview::Preview;

use crate::archive::{Archive, ArchiveError, Status};
use footscan::scan::{CancelToken, LoadedConfig, ScanFault};
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

/// A calibration job as the API shows it.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct CalibrationJob {
    pub id: String,
    pub method: String,
    pub state: Status,
    pub reason: Option<String>,
}

/// The calibration later scans use.
#[derive(Clone, Debug, Serialize)]
pub struct CalibrationInfo {
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
    Calibration(CalibrationJob),
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

#[derive(Debug, thiserror::Error)]
pub enum DaemonError {
    #[error("{0}")]
    Busy(String),
    #[error("{0}")]
    NotFound(String),
    #[error("{0}")]
    NotRunning(String),
    #[error(transparent)]
    Archive(#[from] ArchiveError),
    #[error("{0}")]
    Setup(String),
    #[error("{0}")]
    Unsupported(String),
    /// A device the scan needs is missing (it may be plugged in later).
    #[error("{0}")]
    Unavailable(String),
}

/// The running job.
enum Job {
    Scan {
        id: String,
        cancel: CancelToken,
        thread: std::thread::JoinHandle<()>,
    },
    /// Never joined: calibration cannot be cancelled and writes nothing until it succeeded,
    /// so shutdown leaves it.
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
}

impl Daemon {
    /// Load the scanner config and the calibration, open (and recover) the archive. Jobs
    /// will run at the priority of the calling thread.
    pub fn open(config: DaemonConfig) -> Result<Arc<Daemon>, DaemonError> {
        let scanner = LoadedConfig::load(&config.scanner_config)
            .map_err(|e| DaemonError::Setup(e.to_string()))?;
        // A calibration made by the daemon wins over the configured one (it is newer).
        let current = jobs::current_calibration_path(&config.archive);
        let daemon_cal = if current.is_file() {
            Some((current, "the daemon's last calibration".to_string()))
        } else {
            config.calibration.clone().map(|p| {
                let from = format!("calibration in [daemon] of {}", config.path.display());
                (p, from)
            })
        };
        let cal = preflight::scan_calibration(
            &scanner,
            daemon_cal.as_ref().map(|(p, f)| (p.as_path(), f.as_str())),
        )
        .map_err(DaemonError::Setup)?;
        preflight::check_config(&scanner, &cal).map_err(DaemonError::Setup)?;
        for (_, why) in preflight::missing_devices(&scanner) {
            tracing::warn!("{why}; scans are refused until it is present");
        }
        let archive = Arc::new(Archive::open(&config.archive)?);
        let calibration = daemon_cal.map(|(path, _)| CalibrationInfo {
            method: cal.method,
            date: cal.date,
            path,
        });
        // The last scan, as status shows it until the next one starts.
        let last_scan = archive.list()?.into_iter().next().map(|r| {
            let summary: Option<serde_json::Value> = archive
                .artifact_path(&r, "scan.json")
                .and_then(|p| std::fs::read(p).ok())
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
            .map_err(|e| DaemonError::Setup(format!("cannot start the fleet pusher: {e}")))?;
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
            launcher: jobs::Launcher::new()
                .map_err(|e| DaemonError::Setup(format!("cannot start the job launcher: {e}")))?,
            fleet,
        }))
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
