//! The fleet pusher: a thread that drains the archive's outbox into the fleet database
//! (crates/fleet), in order, one scan per transaction, retrying with exponential backoff
//! while the database is unreachable or refuses. A scan only ever waits for a local SQLite
//! insert ([`Daemon::fleet_enqueue`]); the network is this thread's alone, and it runs ten
//! nice levels below the daemon so that hashing and sending do not take the scan's CPU.
//!
//! The schema is brought up to date (or refused, naming both versions) on each new
//! connection. A scan the database refuses for good (the same scanner name and scan id with
//! other files) is marked rejected and the queue moves on; everything else is retried.

use super::Daemon;
use crate::archive::{Archive, OutboxCounts, ScanId};
use footscan_fleet::{FleetError, LocalFile, ScanUpload, Settings};
use serde::Serialize;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

/// First wait after a failure; doubled up to `retry_max_s` of [fleet].
const FIRST_BACKOFF: Duration = Duration::from_millis(250);
/// Longest idle wait before the outbox is looked at again without being woken.
const IDLE_POLL: Duration = Duration::from_secs(30);

/// What /api/status shows of the fleet (never the password).
#[derive(Clone, Debug, Default, Serialize)]
pub struct FleetStatus {
    pub target: String,
    pub scanner: String,
    pub clinic: String,
    /// "starting", "idle", "pushing", "retrying" (unreachable or refused; see last_error).
    pub state: &'static str,
    /// Scans waiting to be pushed.
    pub backlog: u64,
    pub pushed: u64,
    pub rejected: u64,
    /// Schema version of the database when last connected.
    pub schema_version: Option<i32>,
    pub last_push: Option<String>,
    pub last_push_scan: Option<String>,
    pub last_error: Option<String>,
    pub last_error_at: Option<String>,
    /// Consecutive failed attempts.
    pub failures: u32,
}

struct Shared {
    status: Mutex<FleetStatus>,
    /// Set by an enqueue (or shutdown) to wake the pusher from its idle wait.
    wake: Mutex<bool>,
    cv: Condvar,
}

/// The running pusher (absent when [fleet] is off).
pub struct Fleet {
    shared: Arc<Shared>,
    /// For the read-only view (each query opens its own connection: the pusher's is its own).
    settings: Settings,
}

impl Fleet {
    /// Start the pusher thread for `settings` on `archive`.
    pub fn start(settings: Settings, archive: Arc<Archive>) -> std::io::Result<Fleet> {
        let shared = Arc::new(Shared {
            status: Mutex::new(FleetStatus {
                target: settings.target(),
                scanner: settings.scanner.clone(),
                clinic: settings.clinic.clone(),
                state: "starting",
                ..FleetStatus::default()
            }),
            wake: Mutex::new(false),
            cv: Condvar::new(),
        });
        tracing::info!(
            "fleet: pushing scans to {} as scanner {} of clinic {}",
            settings.target(),
            settings.scanner,
            settings.clinic
        );
        let sh = shared.clone();
        let view = settings.clone();
        std::thread::Builder::new()
            .name("fleet-push".into())
            .spawn(move || {
                lower_own_priority();
                Pusher {
                    settings,
                    archive,
                    shared: sh,
                    client: None,
                    backoff: FIRST_BACKOFF,
                }
                .run()
            })?;
        Ok(Fleet {
            shared,
            settings: view,
        })
    }

    fn wake(&self) {
        *self.shared.wake.lock().unwrap() = true;
        self.shared.cv.notify_all();
    }

    pub fn status(&self) -> FleetStatus {
        self.shared.status.lock().unwrap().clone()
    }
}

impl Daemon {
    /// Queue an ended scan for the fleet (a local insert) and wake the pusher. Without
    /// [fleet], nothing.
    pub(super) fn fleet_enqueue(&self, id: &str) {
        let Some(f) = &self.fleet else { return };
        if let Err(e) = self.archive.outbox_enqueue(id) {
            // The next start queues every ended scan not queued yet.
            tracing::error!("fleet: scan {id} not queued ({e}); it will be at the next start");
        }
        f.wake();
    }

    /// The fleet's state for /api/status; None without [fleet].
    pub fn fleet_status(&self) -> Option<FleetStatus> {
        self.fleet.as_ref().map(Fleet::status)
    }

    /// The fleet database's scans (every scanner's) matching `filter`, read on a connection
    /// of its own; None without [fleet]. Blocking: call it off the async runtime.
    pub fn fleet_list(
        &self,
        filter: &footscan_fleet::Filter,
    ) -> Option<Result<Vec<footscan_fleet::ScanRow>, footscan_fleet::FleetError>> {
        let f = self.fleet.as_ref()?;
        Some(
            footscan_fleet::connect(&f.settings)
                .and_then(|mut c| footscan_fleet::list(&mut c, filter)),
        )
    }
}

struct Pusher {
    settings: Settings,
    archive: Arc<Archive>,
    shared: Arc<Shared>,
    client: Option<footscan_fleet::Client>,
    backoff: Duration,
}

impl Pusher {
    fn run(mut self) {
        match self.archive.outbox_enqueue_all() {
            Ok(0) => {}
            Ok(n) => tracing::info!("fleet: {n} scans of the archive queued"),
            Err(e) => tracing::error!("fleet: cannot queue the archive's scans: {e}"),
        }
        loop {
            self.refresh_counts();
            let entry = match self.archive.outbox_next() {
                Ok(e) => e,
                Err(e) => {
                    self.failed(&format!("outbox: {e}"));
                    continue;
                }
            };
            let Some(entry) = entry else {
                self.set(|s| s.state = "idle");
                self.idle_wait();
                continue;
            };
            self.set(|s| s.state = "pushing");
            match self.push_one(&entry.scan_id) {
                Ok(done) => {
                    let rejected = done.err();
                    if let Err(e) = self.archive.outbox_done(entry.seq, rejected.as_deref()) {
                        self.failed(&format!("outbox: {e}"));
                        continue;
                    }
                    self.backoff = FIRST_BACKOFF;
                    let now = footscan_util::now_rfc3339();
                    self.set(|s| {
                        s.failures = 0;
                        match &rejected {
                            None => {
                                s.last_push = Some(now.clone());
                                s.last_push_scan = Some(entry.scan_id.clone());
                            }
                            Some(why) => {
                                s.last_error = Some(why.clone());
                                s.last_error_at = Some(now.clone());
                            }
                        }
                    });
                }
                Err(e) => {
                    let text = e.to_string();
                    let _ = self.archive.outbox_attempt_failed(entry.seq, &text);
                    self.client = None;
                    self.failed(&text);
                }
            }
        }
    }

    /// Push one queued scan: Ok(Ok) pushed (or already there), Ok(Err(why)) refused for
    /// good (not retried), Err retry later.
    fn push_one(&mut self, id: &str) -> Result<Result<(), String>, FleetError> {
        let gone = |why: String| Ok(Err(format!("scan {id} not pushed: {why}")));
        let Ok(sid) = ScanId::parse(id) else {
            return gone("not a scan id".into());
        };
        let record = match self.archive.get(&sid) {
            Ok(r) => r,
            Err(crate::archive::ArchiveError::NotFound(_)) => {
                return gone("no longer in the archive".into())
            }
            Err(e) => {
                return Err(FleetError::Io {
                    path: self.archive.root().to_owned(),
                    source: std::io::Error::other(e.to_string()),
                })
            }
        };
        let arts = self
            .archive
            .artifacts(&record)
            .map_err(|e| FleetError::Io {
                path: self.archive.dir(&record),
                source: std::io::Error::other(e.to_string()),
            })?;
        let files = arts
            .iter()
            .filter_map(|a| {
                Some(LocalFile {
                    path: self.archive.artifact_path(&record, &a.name)?,
                    name: a.name.clone(),
                    content_type: a.content_type.to_string(),
                })
            })
            .collect();
        let upload = ScanUpload {
            scanner: self.settings.scanner.clone(),
            clinic: self.settings.clinic.clone(),
            scan_id: record.id.clone(),
            subject: record.subject.clone(),
            side: record.side.clone(),
            notes: record.notes.clone(),
            status: record.status.as_str().to_string(),
            reason: record.reason.clone(),
            started: record.started.clone(),
            finished: record.finished.clone(),
            frames: record.frames,
            points: record.points,
            record: serde_json::to_value(&record).expect("record serialises"),
            files,
        };
        let client = self.connected()?;
        let t0 = Instant::now();
        match footscan_fleet::push(client, &upload) {
            Ok(o) => {
                tracing::info!(
                    "fleet: scan {id} {} ({} files, {} new blobs, {} bytes sent, {:.0} ms)",
                    if o.inserted {
                        "pushed"
                    } else {
                        "was already in the database"
                    },
                    o.files,
                    o.blobs_sent,
                    o.bytes_sent,
                    t0.elapsed().as_secs_f64() * 1e3
                );
                Ok(Ok(()))
            }
            Err(e @ (FleetError::Conflict { .. } | FleetError::Mismatch { .. })) => {
                tracing::error!("fleet: {e}");
                Ok(Err(e.to_string()))
            }
            Err(e) => Err(e),
        }
    }

    /// The open connection, or a new one with the schema brought up to date.
    fn connected(&mut self) -> Result<&mut footscan_fleet::Client, FleetError> {
        if self.client.as_ref().is_some_and(|c| c.is_closed()) {
            self.client = None;
        }
        if self.client.is_none() {
            let mut c = footscan_fleet::connect(&self.settings)?;
            let st = footscan_fleet::migrate(&mut c, None)?;
            if !st.applied.is_empty() {
                tracing::info!("fleet: database schema brought to version {}", st.version);
            }
            self.set(|s| s.schema_version = Some(st.version));
            self.client = Some(c);
        }
        Ok(self.client.as_mut().expect("connected"))
    }

    fn set(&self, f: impl FnOnce(&mut FleetStatus)) {
        f(&mut self.shared.status.lock().unwrap());
    }

    fn refresh_counts(&self) {
        match self.archive.outbox_counts() {
            Ok(OutboxCounts {
                pending,
                pushed,
                rejected,
            }) => self.set(|s| {
                s.backlog = pending;
                s.pushed = pushed;
                s.rejected = rejected;
            }),
            Err(e) => tracing::warn!("fleet: outbox counts: {e}"),
        }
    }

    /// Note a failure and wait the backoff (doubled for the next one).
    fn failed(&mut self, why: &str) {
        let wait = self.backoff;
        self.backoff = (self.backoff * 2).min(self.settings.retry_max);
        let now = footscan_util::now_rfc3339();
        let failures = {
            let mut s = self.shared.status.lock().unwrap();
            s.state = "retrying";
            s.last_error = Some(why.to_string());
            s.last_error_at = Some(now);
            s.failures += 1;
            s.failures
        };
        // Every failure while few, then one in ten: an outage of hours must not flood the log.
        if failures <= 3 || failures % 10 == 0 {
            tracing::warn!(
                "fleet: {why} (attempt {failures}; next in {:.1} s)",
                wait.as_secs_f64()
            );
        }
        std::thread::sleep(wait);
    }

    fn idle_wait(&self) {
        let mut w = self.shared.wake.lock().unwrap();
        if !*w {
            w = self.shared.cv.wait_timeout(w, IDLE_POLL).unwrap().0;
        }
        *w = false;
    }
}

/// Ten nice levels below the daemon for this thread.
fn lower_own_priority() {
    if let Err(e) = footscan_util::priority::lower_this_thread(10) {
        tracing::warn!(
            "fleet: cannot lower the pusher's priority ({e}): it competes with the scan for the CPU"
        );
    }
}
