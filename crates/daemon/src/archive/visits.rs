//! Visits: a patient's stay in the clinic, holding the patient's id (no more personal data than
//! the clinic types in), notes, the time, and at most one scan of each foot.
//!
//! Each visit is one JSON file `<archive>/visits/<id>.json`, written atomically; the files are
//! the truth. The index keeps a copy of each (written after the file, brought in line with the
//! files at every start and whenever the visits directory changed) so the API's list pages
//! from SQLite and "which visit holds this scan" is one indexed query: reading every file
//! per request grew with the clinic's years. A visit changed here is read from its file.
//! A scan belongs to one visit at most (moving it is explicit). Deleting a visit deletes
//! the scans it owns (its patient's, in no other visit) too, and is logged in
//! `<archive>/visits/deleted.log` (one JSON line: when, which visit, whose, which scans).
//!
//! Times are kept as UTC instants; the clinic's time zone ([`ClinicZone`], `[clinic]
//! time_zone` of the daemon config) gives each visit its local time and its local date, which
//! is what `?date=` searches by (a visit at 23:30 UTC in Berlin belongs to the next day).

use super::record::{ArchiveError, Record, Status};
use super::{file_stamp as stamp, io_at, Archive, ScanId};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::PathBuf;
use std::sync::Mutex;

pub const VISITS: &str = "visits";
pub const DELETED_LOG: &str = "deleted.log";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Visit {
    pub id: String,
    /// The patient's id as the clinic uses it (the scans' `subject`).
    pub patient: String,
    pub notes: String,
    /// RFC 3339 UTC; the API adds the clinic's local time ([`ClinicZone::visit_json`]).
    pub started: String,
    pub left: Option<String>,
    pub right: Option<String>,
}

/// The clinic's time zone: an IANA zone by name (`[clinic] time_zone`), else the machine's
/// (`TZ`, then /etc/localtime), else UTC.
#[derive(Clone, Debug)]
pub struct ClinicZone {
    /// The IANA name (or, for a machine zone without one, the `TZ` value).
    pub name: String,
    /// Where it came from: "config", "TZ", "/etc/localtime" or "default".
    pub source: &'static str,
    tz: jiff::tz::TimeZone,
}

impl ClinicZone {
    /// The zone called `name` in the IANA database; the error says what is valid.
    pub fn named(name: &str) -> Result<ClinicZone, String> {
        let bad = |why: String| {
            format!(
                "{name:?} is not a time zone of the IANA database ({why}); give a name such as \
                 \"Europe/Berlin\", \"America/New_York\" or \"UTC\" (the names are the files under \
                 /usr/share/zoneinfo)"
            )
        };
        // A path or a POSIX rule would be taken by some readers; the key wants a name.
        if name.is_empty() || name.starts_with('/') || name.contains(',') || name.contains("..") {
            return Err(bad("not a zone name".into()));
        }
        let tz = jiff::tz::TimeZone::get(name).map_err(|e| bad(e.to_string()))?;
        Ok(ClinicZone {
            name: tz.iana_name().unwrap_or(name).to_string(),
            source: "config",
            tz,
        })
    }

    /// The machine's zone (`TZ`, then /etc/localtime), else UTC.
    pub fn system() -> ClinicZone {
        let from_tz = std::env::var("TZ").ok().filter(|t| !t.is_empty());
        match jiff::tz::TimeZone::try_system() {
            Ok(tz) => ClinicZone {
                name: tz
                    .iana_name()
                    .map(str::to_string)
                    .or(from_tz.clone())
                    .unwrap_or_else(|| "/etc/localtime".into()),
                source: if from_tz.is_some() {
                    "TZ"
                } else {
                    "/etc/localtime"
                },
                tz,
            },
            Err(e) => {
                tracing::warn!("clinic time zone: the machine's is unknown ({e}); using UTC");
                ClinicZone::utc()
            }
        }
    }

    pub fn utc() -> ClinicZone {
        ClinicZone {
            name: "UTC".into(),
            source: "default",
            tz: jiff::tz::TimeZone::UTC,
        }
    }

    fn zoned(&self, utc: &str) -> Option<jiff::ZonedDateTime> {
        let t: jiff::Timestamp = utc.parse().ok()?;
        Some(t.to_zoned_datetime(self.tz.clone()))
    }

    /// An RFC 3339 UTC instant as the clinic's local time with its offset
    /// (`2026-11-25T00:30:00+01:00`); None when `utc` is not an instant.
    pub fn local(&self, utc: &str) -> Option<String> {
        Some(
            self.zoned(utc)?
                .strftime("%Y-%m-%dT%H:%M:%S%:z")
                .to_string(),
        )
    }

    /// The clinic's calendar date of an RFC 3339 UTC instant.
    pub fn local_date(&self, utc: &str) -> Option<jiff::civil::Date> {
        Some(self.zoned(utc)?.date())
    }

    /// The instant the clinic's local date `d` begins (its first valid time, on a day whose
    /// midnight a DST change skips).
    pub fn day_start(&self, d: jiff::civil::Date) -> Option<jiff::Timestamp> {
        Some(d.to_zoned_datetime(self.tz.clone()).ok()?.timestamp())
    }

    /// A visit as the API answers it: its fields plus `started_local` (the local time with
    /// its offset; null when `started` is unreadable) and `time_zone`.
    pub fn visit_json(&self, v: &Visit) -> serde_json::Value {
        let mut out = serde_json::to_value(v).expect("visit serialises");
        out["started_local"] = self.local(&v.started).into();
        out["time_zone"] = self.name.clone().into();
        out
    }
}

/// Why a visit request was refused (the API's 400/404/409).
#[derive(Debug, thiserror::Error)]
pub enum VisitError {
    #[error("visit {0} is not in the archive")]
    NotFound(String),
    #[error("{0}")]
    Conflict(String),
    #[error(transparent)]
    Archive(#[from] ArchiveError),
}

/// One writer of visit files at a time (read, change, write).
static VISITS_LOCK: Mutex<()> = Mutex::new(());

impl Archive {
    fn visits_dir(&self) -> Result<PathBuf, ArchiveError> {
        let d = self.root.join(VISITS);
        std::fs::create_dir_all(&d).map_err(io_at(&d))?;
        Ok(d)
    }

    fn write_visit(&self, v: &Visit) -> Result<(), ArchiveError> {
        let p = self.visits_dir()?.join(format!("{}.json", v.id));
        let json = serde_json::to_vec_pretty(v).expect("visit serialises");
        footscan_util::write_atomic(&p, &json).map_err(io_at(&p))?;
        self.index_visit(v, stamp(&p));
        Ok(())
    }

    /// The index's copy of a visit just written; a refused write is logged, and the next
    /// start rereads the file (its stamp differs).
    fn index_visit(&self, v: &Visit, stamp: Option<String>) {
        let stamp = stamp.unwrap_or_default();
        if let Err(e) = self.with_index(|i| i.upsert_visit(v, &stamp)) {
            tracing::error!("archive index: visit {} not indexed: {e}", v.id);
        }
    }

    /// The visits in the index brought in line with the files: those added, changed or
    /// removed behind the daemon's back (or while the index refused writes). A file is
    /// reread only when its length or modification time changed, so a start with 25,000
    /// visits costs their stat calls, not their parsing.
    pub(super) fn sync_visits(&self) -> Result<(), ArchiveError> {
        // Not created here: an archive without visits has none to sync.
        let dir = self.root.join(VISITS);
        // Read before the listing: a change during it is seen again next time.
        let seen = dir.metadata().and_then(|m| m.modified()).ok();
        let mut index = self.index.lock().unwrap();
        let (upserts, gone) = self.visit_changes(&index)?;
        *self.visits_seen.lock().unwrap() = seen;
        if upserts.is_empty() && gone.is_empty() {
            return Ok(());
        }
        tracing::info!(
            "archive index: {} visit(s) reread, {} gone",
            upserts.len(),
            gone.len()
        );
        index.sync_visits(&upserts, &gone).map_err(self.db_err())
    }

    /// What [`Self::sync_visits`] applies: visits to (re)index with their stamps, and ids
    /// whose file is gone.
    #[allow(clippy::type_complexity)]
    pub(super) fn visit_changes(
        &self,
        index: &super::index::Index,
    ) -> Result<(Vec<(Visit, String)>, Vec<String>), ArchiveError> {
        let mut known: std::collections::HashMap<String, String> = index
            .visit_stamps()
            .map_err(self.db_err())?
            .into_iter()
            .collect();
        let dir = self.root.join(VISITS);
        let entries = match std::fs::read_dir(&dir) {
            Ok(e) => Some(e),
            // No visits directory: no visits (every copy goes).
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(io_at(&dir)(e)),
        };
        let mut upserts = Vec::new();
        for e in entries.into_iter().flatten() {
            let e = e.map_err(io_at(&dir))?;
            let name = e.file_name().to_string_lossy().into_owned();
            let Some(id) = name.strip_suffix(".json") else {
                continue;
            };
            let Ok(id) = ScanId::parse(id) else { continue };
            let st = stamp(&e.path()).unwrap_or_default();
            if known.remove(id.as_str()).is_some_and(|k| k == st) {
                continue;
            }
            match self.visit(&id) {
                Ok(v) if v.id == id.as_str() => upserts.push((v, st)),
                Ok(v) => tracing::warn!("visits: {name} skipped: it names visit {}", v.id),
                Err(err) => tracing::warn!("visits: {name} skipped: {err}"),
            }
        }
        Ok((upserts, known.into_keys().collect()))
    }

    /// One page of the visits `q` asks for, newest first, from the index.
    pub fn visit_page(&self, q: &super::VisitQuery) -> Result<super::Page<Visit>, ArchiveError> {
        self.sync_visits_if_changed()?;
        let mut rows = self.with_index(|i| i.visit_page(q))?;
        let next = match q.limit {
            Some(l) if rows.len() > l => {
                rows.truncate(l);
                rows.last().map(|v| v.id.clone())
            }
            _ => None,
        };
        Ok(super::Page { items: rows, next })
    }

    /// A new visit for `patient` (validated by the caller), starting now.
    pub fn new_visit(&self, patient: &str, notes: &str) -> Result<Visit, ArchiveError> {
        let _one = VISITS_LOCK.lock().unwrap_or_else(|p| p.into_inner());
        let dir = self.visits_dir()?;
        let id = (0..16)
            .map(ScanId::generate)
            .find(|id| !dir.join(format!("{id}.json")).exists())
            .ok_or_else(|| io_at(&dir)(std::io::Error::other("no free visit id")))?;
        let v = Visit {
            id: id.to_string(),
            patient: patient.to_string(),
            notes: notes.to_string(),
            started: footscan_util::now_rfc3339(),
            left: None,
            right: None,
        };
        self.write_visit(&v)?;
        tracing::info!("visit {} of {} opened", v.id, v.patient);
        Ok(v)
    }

    pub fn visit(&self, id: &ScanId) -> Result<Visit, VisitError> {
        let p = self.visits_dir()?.join(format!("{id}.json"));
        let bytes = match std::fs::read(&p) {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(VisitError::NotFound(id.to_string()))
            }
            Err(e) => return Err(io_at(&p)(e).into()),
        };
        serde_json::from_slice(&bytes).map_err(|e| {
            ArchiveError::BadRecord {
                path: p,
                message: e.to_string(),
            }
            .into()
        })
    }

    /// Change a visit's notes.
    pub fn set_visit_notes(&self, id: &ScanId, notes: &str) -> Result<Visit, VisitError> {
        let _one = VISITS_LOCK.lock().unwrap_or_else(|p| p.into_inner());
        let mut v = self.visit(id)?;
        v.notes = notes.to_string();
        self.write_visit(&v)?;
        Ok(v)
    }

    /// Every visit listing scan `scan` (in either slot). Under the visits lock, there is at
    /// most one; archives written before a scan belonged to one visit may hold more.
    ///
    /// From the index's copy of the visits, brought in line with the files first if the
    /// visits directory changed since (reading every visit file took a second at 20,000).
    pub(super) fn visits_holding(&self, scan: &str) -> Result<Vec<Visit>, ArchiveError> {
        self.sync_visits_if_changed()?;
        self.with_index(|i| i.visits_holding(scan))
    }

    /// [`Self::sync_visits`] when the visits directory's modification time is not the one
    /// the last sync saw (a visit file added, replaced or removed since).
    fn sync_visits_if_changed(&self) -> Result<(), ArchiveError> {
        let dir = self.root.join(VISITS);
        let now = dir.metadata().and_then(|m| m.modified()).ok();
        if now.is_none() || now != *self.visits_seen.lock().unwrap() {
            self.sync_visits()?;
        }
        Ok(())
    }

    /// Put finished scan `scan` into the visit as its foot (by the record's side). The scan
    /// must be the visit's patient's; a foot already held is replaced (a rescan). A scan
    /// belongs to one visit: one held by another visit is refused unless `move_it`, which
    /// takes it out of that visit (said in the log).
    pub fn add_visit_scan(
        &self,
        id: &ScanId,
        scan: &ScanId,
        move_it: bool,
    ) -> Result<Visit, VisitError> {
        let _one = VISITS_LOCK.lock().unwrap_or_else(|p| p.into_inner());
        let mut v = self.visit(id)?;
        let r: Record = self.get(scan)?;
        let others: Vec<Visit> = self
            .visits_holding(&r.id)?
            .into_iter()
            .filter(|o| o.id != v.id)
            .collect();
        if !others.is_empty() && !move_it {
            let names: Vec<String> = others
                .iter()
                .map(|o| format!("{} of patient {:?}", o.id, o.patient))
                .collect();
            return Err(VisitError::Conflict(format!(
                "scan {scan} belongs to visit {}: a scan is in one visit at most; to move it \
                 here, post {{\"scan\": \"{scan}\", \"move\": true}}",
                names.join(", ")
            )));
        }
        if r.status == Status::Running {
            return Err(VisitError::Conflict(format!(
                "scan {scan} is still running: add it once it has ended"
            )));
        }
        if r.subject != v.patient {
            return Err(VisitError::Conflict(format!(
                "scan {scan} is of subject {:?}, the visit of patient {:?}: correct the scan's \
                 subject first",
                r.subject, v.patient
            )));
        }
        // Out of its other slot first (its side was corrected since it was put in).
        for slot in [&mut v.left, &mut v.right] {
            if slot.as_deref() == Some(r.id.as_str()) {
                *slot = None;
            }
        }
        match r.side.as_str() {
            "left" => v.left = Some(r.id.clone()),
            "right" => v.right = Some(r.id.clone()),
            s => {
                return Err(VisitError::Conflict(format!(
                    "scan {scan} has side {s:?}, not left or right"
                )))
            }
        }
        for mut o in others {
            for slot in [&mut o.left, &mut o.right] {
                if slot.as_deref() == Some(r.id.as_str()) {
                    *slot = None;
                }
            }
            self.write_visit(&o)?;
            tracing::warn!(
                "scan {} moved on request from visit {} (patient {}) to visit {} (patient {})",
                r.id,
                o.id,
                o.patient,
                v.id,
                v.patient
            );
        }
        self.write_visit(&v)?;
        Ok(v)
    }

    /// [`Archive::amend`] a scan's record, keeping its visits in line: a corrected side
    /// moves the scan to that slot of its visit (replacing a scan held there, as a rescan
    /// does, which stays in the archive), and a subject corrected away from a visit's
    /// patient takes the scan out of that visit. Returns the record, its changes and the
    /// visits changed (as they are now).
    #[allow(clippy::type_complexity)]
    pub fn amend_with_visits<E>(
        &self,
        id: &ScanId,
        why: &str,
        edit: impl FnOnce(&mut Record) -> Result<(), E>,
    ) -> Result<Result<(Record, Vec<super::Change>, Vec<Visit>), E>, ArchiveError> {
        let _one = VISITS_LOCK.lock().unwrap_or_else(|p| p.into_inner());
        let (rec, changes) = match self.amend(id, why, edit)? {
            Ok(x) => x,
            Err(e) => return Ok(Err(e)),
        };
        let mut changed = Vec::new();
        for mut v in self.visits_holding(&rec.id)? {
            let before = v.clone();
            for slot in [&mut v.left, &mut v.right] {
                if slot.as_deref() == Some(rec.id.as_str()) {
                    *slot = None;
                }
            }
            if rec.subject == v.patient {
                match rec.side.as_str() {
                    "left" => v.left = Some(rec.id.clone()),
                    "right" => v.right = Some(rec.id.clone()),
                    _ => {}
                }
            }
            if v != before {
                self.write_visit(&v)?;
                tracing::info!(
                    "visit {}: scan {} now {}",
                    v.id,
                    rec.id,
                    if rec.subject == v.patient {
                        format!("in its {} slot", rec.side)
                    } else {
                        format!("out of it (subject corrected to {})", rec.subject)
                    }
                );
                changed.push(v);
            }
        }
        Ok(Ok((rec, changes, changed)))
    }

    /// Delete a visit with its scans' directories (and their index rows); logged. Returns the
    /// scans deleted. Unless `refuse` gives a reason for the visit as it stands (read once,
    /// under the lock that orders visit writes, so a scan put in meanwhile is seen): then a
    /// [`VisitError::Conflict`] with that reason, and nothing is deleted.
    pub fn delete_visit(
        &self,
        id: &ScanId,
        refuse: impl Fn(&Visit) -> Option<String>,
    ) -> Result<Vec<String>, VisitError> {
        let _one = VISITS_LOCK.lock().unwrap_or_else(|p| p.into_inner());
        let v = self.visit(id)?;
        if let Some(why) = refuse(&v) {
            return Err(VisitError::Conflict(why));
        }
        // Only scans the visit owns are deleted: its patient's, and listed by no other visit
        // (archives from before a scan belonged to one visit may list one twice).
        let mut deleted = Vec::new();
        let mut kept = Vec::new();
        for sid in [&v.left, &v.right].into_iter().flatten() {
            let Ok(sid) = ScanId::parse(sid) else {
                continue;
            };
            let Ok(r) = self.get(&sid) else { continue };
            let elsewhere = self.visits_holding(&r.id)?.iter().any(|o| o.id != v.id);
            if elsewhere || r.subject != v.patient {
                tracing::warn!(
                    "visit {}: scan {} (subject {}) kept: not the visit's own",
                    v.id,
                    r.id,
                    r.subject
                );
                kept.push(r.id);
                continue;
            }
            if let Some(dir) = self.checked_dir(&r) {
                std::fs::remove_dir_all(&dir).map_err(io_at(&dir))?;
            }
            let key = r.id.clone();
            self.with_index(|i| i.delete(&key))?;
            deleted.push(r.id);
        }
        let dir = self.visits_dir()?;
        let log = dir.join(DELETED_LOG);
        let line = serde_json::json!({
            "at": footscan_util::now_rfc3339(),
            "visit": v.id,
            "patient": v.patient,
            "scans": deleted,
            "kept": kept,
        });
        std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .and_then(|mut f| {
                writeln!(f, "{line}")?;
                f.sync_all()
            })
            .map_err(io_at(&log))?;
        let p = dir.join(format!("{}.json", v.id));
        std::fs::remove_file(&p).map_err(io_at(&p))?;
        let vid = v.id.clone();
        if let Err(e) = self.with_index(|i| i.delete_visit(&vid)) {
            tracing::error!("archive index: deleted visit {vid} not dropped from the index: {e}");
        }
        tracing::warn!(
            "visit {} of {} deleted on request, with scans {:?}",
            v.id,
            v.patient,
            deleted
        );
        Ok(deleted)
    }
}
