//! The scan archive: one directory per scan under the archive root and a SQLite index.
//!
//! A scan is written into `.tmp-<id>` and only becomes `<id>` once it has ended (complete,
//! failed or cancelled): its files are fsynced, `record.json` is written atomically, the
//! directory is fsynced and renamed, the root is fsynced, and only then is the index updated.
//! So a crash leaves either a `.tmp-` directory (recovered as failed at the next start, its
//! files kept) or a finished directory with its record: nothing half-written is ever listed
//! as complete. The index is a cache of the records and [`Archive::rebuild`] recreates it.
//!
//! A scan directory holds a small reserve file while it runs; it is deleted before the
//! record is written, so a scan that filled the disk can still be closed with its reason.

pub mod calibrations;
pub mod compact;
mod history;
mod id;
mod index;
mod outbox;
mod query;
mod record;
pub mod retention;
pub mod usage;
mod visits;

pub use history::{Change, HISTORY};
pub use id::{valid_file_name, IdError, ScanId};
pub use outbox::{OutboxCounts, OutboxEntry};
pub use query::{id_bound, Page, ScanQuery, VisitQuery, MAX_LIMIT};
pub use record::{ArchiveError, NewScan, Record, ScanEnd, Status};
pub use visits::{ClinicZone, Visit, VisitError};

use footscan::scandata::ScanDir;
use index::Index;
use serde::Serialize;
use std::collections::HashMap;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Bytes kept free inside a running scan's directory for its record and the index update.
const RESERVE_BYTES: usize = 256 * 1024;
const RESERVE: &str = ".reserve";
const TMP_PREFIX: &str = ".tmp-";
pub const RECORD: &str = ScanDir::RECORD;
pub const INDEX: &str = "index.sqlite";
/// The lock file: held (flock, exclusive) by the one process writing into the archive, and
/// naming it (`pid <n> <program>`) for whoever finds it taken.
pub const LOCK: &str = ".lock";
/// The most a JSON file of a scan's may hold to be read back (the daemon writes kilobytes:
/// a summary, measurements, a history of corrections, a last job).
pub const MAX_JSON_ARTIFACT: u64 = 16 << 20;
/// Reason given to scans found unfinished at startup with nothing saying how they ended:
/// neither the daemon's record nor the pipeline's summary was written.
pub const INTERRUPTED: &str = "interrupted: the daemon stopped during the scan";
/// Reason given to scans found unfinished at startup whose pipeline had ended (scan.json
/// written) but whose record was not: the archive failed, or the daemon stopped while
/// archiving. Followed by what scan.json says.
pub const NOT_ARCHIVED: &str = "the scan ended but was not archived";
/// Spacing of the running scan's frame count in the index (kept for recovery).
const PROGRESS_PERIOD: Duration = Duration::from_secs(1);

fn io_at(path: &Path) -> impl FnOnce(std::io::Error) -> ArchiveError + '_ {
    move |source| ArchiveError::Io {
        path: path.to_owned(),
        source,
    }
}

/// A file's length, inode, modification and change times (ns): what tells the index that a
/// record.json or a visit file changed since it was read (an atomic write is a new inode, and
/// an edit in place moves both times).
pub(crate) fn file_stamp(p: &Path) -> Option<String> {
    use std::os::unix::fs::MetadataExt;
    let m = p.symlink_metadata().ok()?;
    Some(format!(
        "{} {} {}.{:09} {}.{:09}",
        m.len(),
        m.ino(),
        m.mtime(),
        m.mtime_nsec(),
        m.ctime(),
        m.ctime_nsec()
    ))
}

/// `f` is the file at `path` (not unlinked, not replaced by another since it was opened).
fn linked_as(f: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (f.metadata(), path.symlink_metadata()) {
        (Ok(a), Ok(b)) => a.nlink() > 0 && a.ino() == b.ino() && a.dev() == b.dev(),
        _ => false,
    }
}

/// Replace the contents of `f` by `bytes` in place (its blocks, no new ones for a shorter
/// content) and fsync.
fn overwrite(f: &File, bytes: &[u8]) -> std::io::Result<()> {
    use std::os::unix::fs::FileExt;
    f.write_all_at(bytes, 0)?;
    f.set_len(bytes.len() as u64)?;
    f.sync_all()
}

/// A scan being written: its directory is `.tmp-<id>` until [`Archive::finish`].
#[derive(Debug)]
pub struct ActiveScan {
    pub record: Record,
    pub dir: PathBuf,
    /// The directory's `.reserve`, held open from the start: the record is written into its
    /// blocks and the file renamed to record.json, so a full disk, or a directory that turned
    /// read-only under a running scan (permissions are checked at open, not at write), still
    /// takes the scan's end; where even the rename is refused, recovery reads the end from
    /// `.reserve` itself.
    reserve: Option<File>,
}

/// An artifact of a finished scan.
#[derive(Clone, Debug, Serialize)]
pub struct Artifact {
    pub name: String,
    pub bytes: u64,
    pub content_type: &'static str,
}

pub struct Archive {
    root: PathBuf,
    /// `root` with symlinks resolved: every scan directory must resolve directly inside it.
    real_root: PathBuf,
    index: Mutex<Index>,
    /// Final records the index refused (the scan directory holds them as record.json when it
    /// could be written): listed instead of the index row until a later write succeeds, so a
    /// scan whose archiving failed is not shown as running.
    unindexed: Mutex<HashMap<String, Record>>,
    /// What the archive repaired (a damaged index moved aside), for the status.
    notices: Mutex<Vec<String>>,
    last_progress: Mutex<Option<Instant>>,
    /// The visits directory's modification time when the index's visits were last brought
    /// in line with its files (archive/visits.rs): a file added, replaced or removed since
    /// changes it, and the next list syncs first.
    visits_seen: Mutex<Option<std::time::SystemTime>>,
    /// Held while a compacted scan's file is decoded into the cache (archive/compact.rs).
    cache_lock: Mutex<()>,
    /// The most that cache holds (`[archive] cache_mb`).
    cache_max_bytes: std::sync::atomic::AtomicU64,
    /// The last retention run's report (archive/retention.rs), for the status.
    retention: Mutex<Option<retention::RetentionRun>>,
    /// The archive lock, released when the archive is dropped (or the process dies).
    _lock: ArchiveLock,
}

/// An exclusive hold on an archive: two writers would recover (and move) each other's
/// running scans. The kernel drops it when the process exits, however it exits.
#[derive(Debug)]
pub struct ArchiveLock {
    _file: File,
}

impl ArchiveLock {
    /// Take the lock of the archive at `root` for `program`, without waiting: a held lock is
    /// an error naming the holder's pid and program.
    pub fn acquire(root: &Path, program: &str) -> Result<ArchiveLock, ArchiveError> {
        use std::io::{Read, Seek};
        let path = root.join(LOCK);
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(io_at(&path))?;
        match file.try_lock() {
            Ok(()) => {
                let me = format!("pid {} {program}\n", std::process::id());
                file.set_len(0)
                    .and_then(|_| file.rewind())
                    .and_then(|_| file.write_all(me.as_bytes()))
                    .map_err(io_at(&path))?;
                Ok(ArchiveLock { _file: file })
            }
            Err(std::fs::TryLockError::WouldBlock) => {
                let mut text = String::new();
                let _ = file.read_to_string(&mut text);
                let holder = text.trim();
                Err(ArchiveError::Locked {
                    root: root.to_owned(),
                    holder: if holder.is_empty() {
                        "another process (it has not written its pid yet)".into()
                    } else {
                        holder.chars().take(200).collect()
                    },
                })
            }
            Err(std::fs::TryLockError::Error(e)) => Err(io_at(&path)(e)),
        }
    }
}

impl Archive {
    /// Open (creating) the archive at `root`: unfinished `.tmp-` scans are closed as failed
    /// (with the reason they recorded, else [`NOT_ARCHIVED`] or [`INTERRUPTED`]), and the
    /// index is brought in line with the directories; a damaged index is moved aside
    /// (`index.sqlite.corrupt-<time>`) and rebuilt, since it is only a cache.
    ///
    /// The archive lock is taken first, before anything is read or moved: a second process
    /// on the same archive gets [`ArchiveError::Locked`] naming the first.
    pub fn open(root: &Path) -> Result<Archive, ArchiveError> {
        std::fs::create_dir_all(root).map_err(io_at(root))?;
        let program = std::env::current_exe()
            .ok()
            .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
            .unwrap_or_else(|| "footscand".into());
        let lock = ArchiveLock::acquire(root, &program)?;
        let real_root = root.canonicalize().map_err(io_at(root))?;
        let db = root.join(INDEX);
        let mut notices = Vec::new();
        let index = match Index::open(&db) {
            Ok(i) => i,
            Err(index::OpenError::Corrupt(why)) => {
                notices.push(move_aside(root, &why)?);
                Index::open(&db).map_err(index::OpenError::into_archive)?
            }
            Err(e) => return Err(e.into_archive()),
        };
        let archive = Archive {
            root: root.to_owned(),
            real_root,
            index: Mutex::new(index),
            unindexed: Mutex::default(),
            notices: Mutex::new(notices),
            last_progress: Mutex::default(),
            visits_seen: Mutex::default(),
            cache_lock: Mutex::default(),
            cache_max_bytes: std::sync::atomic::AtomicU64::new(compact::CACHE_MAX_BYTES),
            retention: Mutex::default(),
            _lock: lock,
        };
        archive.recover()?;
        archive.sync_scans()?;
        // The visits' copies are only for listing: visits the archive cannot read (a file
        // where the directory should be) fail their own requests, not the daemon's start.
        if let Err(e) = archive.sync_visits() {
            tracing::warn!("archive: visits not indexed: {}", footscan_util::Chain(&e));
        }
        Ok(archive)
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// What the archive had to repair since it was opened (shown in /api/status).
    pub fn notices(&self) -> Vec<String> {
        self.notices.lock().unwrap().clone()
    }

    fn db_err(&self) -> impl Fn(rusqlite::Error) -> ArchiveError + '_ {
        |source| ArchiveError::Index {
            path: self.root.join(INDEX),
            source,
        }
    }

    /// Run `f` on the index; an index found damaged is moved aside, rebuilt from the scan
    /// directories, and `f` run again.
    fn with_index<T>(
        &self,
        f: impl Fn(&mut Index) -> rusqlite::Result<T>,
    ) -> Result<T, ArchiveError> {
        let mut index = self.index.lock().unwrap();
        match f(&mut index) {
            Err(e) if index::is_corrupt(&e) => {
                self.repair(&mut index, &e.to_string())?;
                f(&mut index).map_err(self.db_err())
            }
            r => r.map_err(self.db_err()),
        }
    }

    /// Replace a damaged index by a new one filled from the scan directories.
    fn repair(&self, index: &mut Index, why: &str) -> Result<(), ArchiveError> {
        let note = move_aside(&self.root, why)?;
        *index = Index::open(&self.root.join(INDEX)).map_err(index::OpenError::into_archive)?;
        let records = self.scan_records()?;
        index.replace_all(&records).map_err(self.db_err())?;
        let (upserts, gone) = self.visit_changes(index)?;
        index.sync_visits(&upserts, &gone).map_err(self.db_err())?;
        self.notices.lock().unwrap().push(note);
        Ok(())
    }

    /// Create the temporary directory of a new scan and list it as running.
    pub fn begin(&self, meta: NewScan) -> Result<ActiveScan, ArchiveError> {
        let (id, dir) = (0..16)
            .map(ScanId::generate)
            .map(|id| {
                let dir = self.root.join(format!("{TMP_PREFIX}{id}"));
                (id, dir)
            })
            .find(|(id, dir)| {
                dir.symlink_metadata().is_err()
                    && self.root.join(id.as_str()).symlink_metadata().is_err()
            })
            .ok_or_else(|| ArchiveError::Io {
                path: self.root.clone(),
                source: std::io::Error::other("no free scan id"),
            })?;
        std::fs::create_dir(&dir).map_err(io_at(&dir))?;
        let reserve = dir.join(RESERVE);
        let res = (|| {
            let mut f = std::fs::OpenOptions::new()
                .read(true)
                .write(true)
                .create_new(true)
                .open(&reserve)?;
            f.write_all(&vec![0u8; RESERVE_BYTES])?;
            f.sync_all()?;
            Ok::<_, std::io::Error>(f)
        })();
        let reserve = match res {
            Ok(f) => f,
            Err(e) => {
                let _ = std::fs::remove_dir_all(&dir);
                return Err(io_at(&reserve)(e));
            }
        };
        let record = Record::running(id.to_string(), meta);
        self.index_upsert(&record);
        *self.last_progress.lock().unwrap() = Some(Instant::now());
        Ok(ActiveScan {
            record,
            dir,
            reserve: Some(reserve),
        })
    }

    /// Note a running scan's frame and point counts in the index (at most once a second,
    /// off the caller's thread), so a scan killed before its summary keeps them.
    pub fn note_progress(self: &Arc<Self>, id: &str, frames: u64, points: u64) {
        {
            let mut last = self.last_progress.lock().unwrap();
            if last.is_some_and(|t| t.elapsed() < PROGRESS_PERIOD) {
                return;
            }
            *last = Some(Instant::now());
        }
        let (me, id) = (self.clone(), id.to_string());
        std::thread::spawn(move || {
            // Skipped while the index is busy: a note is not worth queueing behind a write.
            let Ok(index) = me.index.try_lock() else {
                return;
            };
            if let Err(e) = index.note_progress(&id, frames, points) {
                tracing::debug!("archive index: progress of scan {id} not noted: {e}");
            }
        });
    }

    /// Close a scan: fsync its files, write record.json, rename the directory to its id,
    /// then update the index. Returns the final record.
    ///
    /// When archiving fails, the scan is closed as failed with the reason, written into its
    /// directory (record.json, read by recovery at the next start) as far as it can be, and
    /// listed so until then even if the index cannot be written.
    pub fn finish(&self, scan: ActiveScan, outcome: ScanEnd) -> Result<Record, ArchiveError> {
        let mut record = scan.record;
        record.status = outcome.status;
        record.reason = outcome.reason;
        record.frames = outcome.frames;
        record.points = outcome.points;
        record.finished = Some(footscan_util::now_rfc3339());
        match self.seal(&scan.dir, &record, scan.reserve.as_ref()) {
            Ok(_) => {
                self.index_upsert(&record);
                Ok(record)
            }
            Err(e) => {
                record.status = Status::Failed;
                record.reason = Some(format!(
                    "{}; archiving failed: {}",
                    record.reason.as_deref().unwrap_or("scan ended"),
                    footscan_util::Chain(&e)
                ));
                if scan.dir.is_dir() {
                    let rec_path = scan.dir.join(RECORD);
                    let json = serde_json::to_vec_pretty(&record).expect("record serialises");
                    if let Err(we) = footscan_util::write_atomic(&rec_path, &json) {
                        // The reserve's own blocks, through the descriptor opened at the
                        // start: what recovery reads when record.json is missing.
                        let kept = scan
                            .reserve
                            .as_ref()
                            .filter(|f| linked_as(f, &scan.dir.join(RESERVE)))
                            .map(|f| overwrite(f, &json));
                        match kept {
                            Some(Ok(())) => tracing::warn!(
                                "archive: scan {}: record.json refused ({we}); the end is \
                                 kept in {RESERVE} for the next start",
                                record.id
                            ),
                            _ => tracing::error!(
                                "archive: scan {}: the failure could not be recorded in {}: \
                                 {we}",
                                record.id,
                                rec_path.display()
                            ),
                        }
                    }
                }
                self.index_upsert(&record);
                Err(e)
            }
        }
    }

    /// The fsync-record-rename sequence shared by finish and recovery. With the scan's
    /// reserve at hand, record.json is the reserve itself, overwritten and renamed (no new
    /// block is needed, nor a directory open for writing files); else the reserve is removed
    /// to make room and the record written anew.
    fn seal(
        &self,
        dir: &Path,
        record: &Record,
        reserve: Option<&File>,
    ) -> Result<PathBuf, ArchiveError> {
        let json = serde_json::to_vec_pretty(record).expect("record serialises");
        let rec_path = dir.join(RECORD);
        let res_path = dir.join(RESERVE);
        let reserve = reserve.filter(|f| linked_as(f, &res_path));
        if reserve.is_none() {
            let _ = std::fs::remove_file(&res_path);
        }
        for entry in std::fs::read_dir(dir).map_err(io_at(dir))? {
            let entry = entry.map_err(io_at(dir))?;
            if entry.file_type().map_err(io_at(dir))?.is_file() && entry.file_name() != RESERVE {
                let p = entry.path();
                File::open(&p)
                    .and_then(|f| f.sync_all())
                    .map_err(io_at(&p))?;
            }
        }
        // The files are on disk before the record that says the scan is whole.
        match reserve {
            Some(f) => overwrite(f, &json)
                .and_then(|()| std::fs::rename(&res_path, &rec_path))
                .map_err(io_at(&rec_path))?,
            None => footscan_util::write_atomic(&rec_path, &json).map_err(io_at(&rec_path))?,
        }
        sync_dir(dir)?;
        let done = self.root.join(&record.id);
        std::fs::rename(dir, &done).map_err(io_at(&done))?;
        sync_dir(&self.root)?;
        Ok(done)
    }

    /// Close every `.tmp-` scan left unfinished, as failed, with the most honest reason at
    /// hand: the daemon's own record in the directory (a scan whose archiving failed), else
    /// the end the index recorded when the directory could not take it, else the pipeline's
    /// summary (the scan ended but was never archived), else [`INTERRUPTED`]
    /// with the frame count the index last noted.
    fn recover(&self) -> Result<(), ArchiveError> {
        for entry in std::fs::read_dir(&self.root).map_err(io_at(&self.root))? {
            let entry = entry.map_err(io_at(&self.root))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let Some(id) = name.strip_prefix(TMP_PREFIX) else {
                continue;
            };
            let is_dir = entry.file_type().is_ok_and(|t| t.is_dir());
            if ScanId::parse(id).is_err() || !is_dir {
                tracing::warn!(
                    "archive: ignoring {name}: not a scan directory (symlinks are refused)"
                );
                continue;
            }
            let dir = entry.path();
            // record.json, else the end kept in the reserve when record.json was refused.
            let own = [RECORD, RESERVE]
                .iter()
                .find_map(|name| {
                    let b = std::fs::read(dir.join(name)).ok()?;
                    serde_json::from_slice::<Record>(&b).ok()
                })
                .filter(|r| r.id == id && r.status != Status::Running);
            let indexed = self.with_index(|i| i.get(id)).ok().flatten();
            let record = match (own, indexed) {
                (Some(r), _) => r,
                // The directory could not take its record (turned read-only) but the index
                // took the end: that is the first, real reason; keep it.
                (None, Some(r)) if r.status != Status::Running => r,
                (None, indexed) => {
                    let mut r = indexed.unwrap_or_else(|| {
                        Record::running(
                            id.to_string(),
                            NewScan {
                                subject: "unknown".into(),
                                side: "unknown".into(),
                                notes: String::new(),
                            },
                        )
                    });
                    match read_summary(&dir) {
                        Some(s) => {
                            r.frames = s.frames;
                            r.points = s.points;
                            r.reason = Some(format!(
                                "{NOT_ARCHIVED} (its summary says {}{}): the archive could \
                                 not be written or the daemon stopped while archiving",
                                s.status,
                                s.reason.map_or(String::new(), |x| format!(": {x}"))
                            ));
                        }
                        None => r.reason = Some(INTERRUPTED.into()),
                    }
                    r.status = Status::Failed;
                    r.finished = Some(footscan_util::now_rfc3339());
                    r
                }
            };
            tracing::warn!(
                "archive: scan {id} was left unfinished; kept as {}: {}",
                record.status.as_str(),
                record.reason.as_deref().unwrap_or("")
            );
            self.seal(&dir, &record, None)?;
        }
        Ok(())
    }

    /// The records of the finished scan directories (real directories named by a valid id,
    /// each with its own record.json); anything else is skipped with a warning.
    fn scan_records(&self) -> Result<Vec<(Record, Option<String>)>, ArchiveError> {
        self.read_records(|_, _| true)
    }

    /// The records of the finished scan directories for which `wanted(id, stamp of its
    /// record.json)` holds, with their stamps; the others are skipped unread.
    fn read_records(
        &self,
        mut wanted: impl FnMut(&str, Option<&str>) -> bool,
    ) -> Result<Vec<(Record, Option<String>)>, ArchiveError> {
        let mut records = Vec::new();
        for entry in std::fs::read_dir(&self.root).map_err(io_at(&self.root))? {
            let entry = entry.map_err(io_at(&self.root))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let Ok(id) = ScanId::parse(&name) else {
                continue;
            };
            if !entry.file_type().is_ok_and(|t| t.is_dir()) {
                tracing::warn!(
                    "archive: {} skipped: not a directory (symlinked scan directories are refused)",
                    entry.path().display()
                );
                continue;
            }
            let path = entry.path().join(RECORD);
            let stamp = file_stamp(&path);
            if !wanted(id.as_str(), stamp.as_deref()) {
                continue;
            }
            let text = match std::fs::read(&path) {
                Ok(t) => t,
                Err(e) => {
                    tracing::warn!("archive: {} skipped: {e}", path.display());
                    continue;
                }
            };
            match serde_json::from_slice::<Record>(&text) {
                Ok(r) if r.id == id.as_str() => records.push((r, stamp)),
                Ok(r) => tracing::warn!(
                    "archive: {} skipped: it names scan {}",
                    path.display(),
                    r.id
                ),
                Err(e) => tracing::warn!("archive: {} skipped: {e}", path.display()),
            }
        }
        Ok(records)
    }

    /// Recreate the index from the scan directories' record.json files.
    pub fn rebuild(&self) -> Result<usize, ArchiveError> {
        let mut records = self.scan_records()?;
        // Scans running right now live only in the index: keep them.
        let running: Vec<(Record, Option<String>)> = self
            .with_index(|i| i.list())?
            .into_iter()
            .filter(|r| {
                r.status == Status::Running
                    && self.root.join(format!("{TMP_PREFIX}{}", r.id)).is_dir()
            })
            .map(|r| (r, None))
            .collect();
        records.extend(running);
        self.with_index(|i| i.replace_all(&records))?;
        Ok(records.len())
    }

    /// Bring the index in line with the directories, as [`Self::rebuild`] does, reading
    /// only the record.json files changed since the index took them (their stamps differ):
    /// what opening costs is a stat per scan, not a read and parse (docs/method.md, "The
    /// archive at 50,000 scans"). Rows without a directory go; running scans with their
    /// `.tmp-` directory stay.
    fn sync_scans(&self) -> Result<(), ArchiveError> {
        let mut known: HashMap<String, (String, Option<String>)> = self
            .with_index(|i| i.scan_stamps())?
            .into_iter()
            .map(|(id, status, stamp)| (id, (status, stamp)))
            .collect();
        let mut present = std::collections::HashSet::new();
        let mut asked = std::collections::HashSet::new();
        let upserts = self.read_records(|id, stamp| {
            present.insert(id.to_string());
            let changed = match (known.get(id), stamp) {
                (Some((_, Some(k))), Some(s)) => k != s,
                _ => true,
            };
            if changed {
                asked.insert(id.to_string());
            }
            changed
        })?;
        let read: std::collections::HashSet<&str> =
            upserts.iter().map(|(r, _)| r.id.as_str()).collect();
        // Gone: a row without its directory (but a running scan's `.tmp-`), or whose record
        // changed and no longer reads (a rebuild leaves it out too).
        known.retain(|id, (status, _)| {
            let running = status == Status::Running.as_str()
                && self.root.join(format!("{TMP_PREFIX}{id}")).is_dir();
            !running
                && (!present.contains(id.as_str())
                    || asked.contains(id.as_str()) && !read.contains(id.as_str()))
        });
        let gone: Vec<String> = known.into_keys().collect();
        let upserts: Vec<(Record, String)> = upserts
            .into_iter()
            .map(|(r, s)| (r, s.unwrap_or_default()))
            .collect();
        if !upserts.is_empty() || !gone.is_empty() {
            tracing::info!(
                "archive index: {} record(s) reread, {} gone",
                upserts.len(),
                gone.len()
            );
        }
        self.with_index(|i| i.sync_scans(&upserts, &gone))
    }

    /// Every scan, newest first. A finished scan whose directory is gone (deleted behind
    /// the daemon's back) or is not a real directory inside the archive is dropped from the
    /// index, not listed.
    pub fn list(&self) -> Result<Vec<Record>, ArchiveError> {
        let mut out = self.with_index(|i| i.list())?;
        self.overlay(&mut out);
        out.retain(|r| self.present(r));
        Ok(out)
    }

    /// One page of the scans `q` asks for, newest first, from the index; a listed scan whose
    /// directory is gone leaves the index (as in [`Self::list`]) and the page is asked again,
    /// so a page is full whenever more scans match.
    pub fn list_page(&self, q: &ScanQuery) -> Result<Page<Record>, ArchiveError> {
        let mut attempt = 0;
        loop {
            attempt += 1;
            let mut rows = self.with_index(|i| i.page(q))?;
            self.overlay(&mut rows);
            let n = rows.len();
            rows.retain(|r| self.present(r));
            if rows.len() < n && attempt <= 3 {
                // present() dropped the gone rows from the index: the next query refills
                // the page (a few times at most, should the index refuse the deletions).
                continue;
            }
            let next = match q.limit {
                Some(l) if rows.len() > l => {
                    rows.truncate(l);
                    rows.last().map(|r| r.id.clone())
                }
                _ => None,
            };
            return Ok(Page { items: rows, next });
        }
    }

    pub fn get(&self, id: &ScanId) -> Result<Record, ArchiveError> {
        let r = self.with_index(|i| i.get(id.as_str()))?;
        let mut v: Vec<Record> = r.into_iter().collect();
        self.overlay(&mut v);
        v.into_iter()
            .find(|r| self.present(r))
            .ok_or_else(|| ArchiveError::NotFound(id.to_string()))
    }

    /// Records the index refused replace their rows.
    fn overlay(&self, v: &mut [Record]) {
        let unindexed = self.unindexed.lock().unwrap();
        if unindexed.is_empty() {
            return;
        }
        for r in v.iter_mut() {
            if let Some(x) = unindexed.get(&r.id) {
                *r = x.clone();
            }
        }
    }

    /// Whether a listed scan still has its directory (a running one always counts); a gone
    /// one leaves the index.
    fn present(&self, r: &Record) -> bool {
        if r.status == Status::Running || self.checked_dir(r).is_some() {
            return true;
        }
        tracing::warn!(
            "archive: scan {} dropped from the index: {} is missing or not a directory inside the archive",
            r.id,
            self.dir(r).display()
        );
        let id = r.id.clone();
        if let Err(e) = self.with_index(|i| i.delete(&id)) {
            tracing::error!("archive index: could not drop scan {id}: {e}");
        }
        false
    }

    /// The directory holding a scan's files (the temporary one while it runs).
    pub fn dir(&self, record: &Record) -> PathBuf {
        let tmp = self.root.join(format!("{TMP_PREFIX}{}", record.id));
        let done = self.root.join(&record.id);
        match record.status {
            Status::Running => tmp,
            // Closed but not renamed (archiving failed): its files are still in .tmp-<id>.
            _ if done.symlink_metadata().is_err() && tmp.is_dir() => tmp,
            _ => done,
        }
    }

    /// The scan's directory if it is a real directory directly inside the archive: not a
    /// symlink, and not resolving anywhere else (a symlink to /etc must serve nothing).
    pub fn checked_dir(&self, record: &Record) -> Option<PathBuf> {
        let dir = self.dir(record);
        let meta = dir.symlink_metadata().ok()?;
        if !meta.is_dir() {
            return None;
        }
        let real = dir.canonicalize().ok()?;
        (real.parent() == Some(self.real_root.as_path())).then_some(dir)
    }

    /// The downloadable files of a scan, by name. A compacted scan lists its original files
    /// with their original lengths (its manifest and stored forms are not listed).
    pub fn artifacts(&self, record: &Record) -> Result<Vec<Artifact>, ArchiveError> {
        let dir = self.checked_dir(record).ok_or_else(|| ArchiveError::Io {
            path: self.dir(record),
            source: std::io::Error::other(
                "missing, or not a directory inside the archive (symlinks are refused)",
            ),
        })?;
        let mut out: Vec<Artifact> = footscan::compact::listing(&dir)
            .map_err(io_at(&dir))?
            .into_iter()
            .filter(|(name, _, _)| valid_file_name(name))
            .map(|(name, bytes, _)| Artifact {
                content_type: content_type(&name),
                name,
                bytes,
            })
            .collect();
        out.sort_by(|a, b| a.name.cmp(&b.name));
        Ok(out)
    }

    /// The path of artifact `name` of a scan, if it exists as a regular file (not a
    /// symlink) in the scan's checked directory (name validated here too); for a file a
    /// compacted scan keeps in compact form, the original decoded into the archive's cache
    /// (archive/compact.rs), byte for byte the file it was.
    pub fn artifact_path(&self, record: &Record, name: &str) -> Option<PathBuf> {
        // The compact form's own files (its manifest, the stored forms) are not the scan's:
        // not listed, and not served by name either.
        if !valid_file_name(name) || footscan::compact::is_compact_file(name) {
            return None;
        }
        let p = self.checked_dir(record)?.join(name);
        match p.symlink_metadata() {
            Ok(m) => m.is_file().then_some(p),
            Err(_) => self.cached_original(record, name),
        }
    }

    /// The bytes of a scan's JSON artifact `name` (summary, measurements, history), read
    /// through [`Self::read_inside`]; None when missing, a symlink, or longer than
    /// [`MAX_JSON_ARTIFACT`].
    pub fn artifact_bytes(&self, record: &Record, name: &str) -> Option<Vec<u8>> {
        let p = self.artifact_path(record, name)?;
        self.read_inside(&p, MAX_JSON_ARTIFACT).ok()
    }

    /// Open `path` (a file under the archive's root) for reading without following any
    /// symlink below the root (footscan_util::beneath: openat2 RESOLVE_BENEATH with no
    /// symlinks, the copy the plugins' WASI grant uses), so a component swapped for a symlink
    /// (a scan's `last/` pointing outside the archive) fails with ELOOP instead of being
    /// served, and no check-then-open race remains. Only regular files open.
    pub fn open_inside(&self, path: &Path) -> std::io::Result<File> {
        use footscan_util::beneath::{open_beneath, Links};
        use std::os::fd::AsFd;
        let rel = path.strip_prefix(&self.root).map_err(|_| {
            std::io::Error::new(
                std::io::ErrorKind::PermissionDenied,
                format!("{} is not under the archive", path.display()),
            )
        })?;
        // The root itself is the configured path (it may be a symlink the admin chose).
        let root = File::open(&self.root)?;
        let f = open_beneath(
            root.as_fd(),
            rel,
            libc::O_RDONLY | libc::O_NONBLOCK,
            0,
            Links::None,
        )?;
        if !f.metadata()?.is_file() {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!("{} is not a regular file", path.display()),
            ));
        }
        Ok(f)
    }

    /// The bytes of `path` (a file under the archive's root), opened as [`Self::open_inside`]
    /// does, and refused when longer than `max` (a record or summary the daemon wrote is
    /// kilobytes; anything longer was not written by it).
    pub fn read_inside(&self, path: &Path, max: u64) -> std::io::Result<Vec<u8>> {
        use std::io::Read;
        let f = self.open_inside(path)?;
        let len = f.metadata()?.len();
        if len > max {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!(
                    "{} holds {len} bytes, more than the {max} such a file can hold",
                    path.display()
                ),
            ));
        }
        let mut out = Vec::with_capacity(len as usize);
        f.take(max).read_to_end(&mut out)?;
        Ok(out)
    }

    /// Write `r` into the index; a refused write keeps `r` in memory (listed instead of the
    /// row) and is retried with the next write. The directory is the truth: rebuild repairs
    /// the index at the next start.
    fn index_upsert(&self, r: &Record) {
        let pending: Vec<Record> = {
            let mut u = self.unindexed.lock().unwrap();
            u.remove(&r.id);
            u.values().cloned().collect()
        };
        for rec in pending.iter().chain(std::iter::once(r)) {
            let stamp = match rec.status {
                Status::Running => None,
                _ => file_stamp(&self.root.join(&rec.id).join(RECORD)),
            };
            match self.with_index(|i| i.upsert(rec, stamp.as_deref())) {
                Ok(()) => {
                    self.unindexed.lock().unwrap().remove(&rec.id);
                }
                Err(e) => {
                    tracing::error!(
                        "archive index: could not record scan {} as {}: {e}",
                        rec.id,
                        rec.status.as_str()
                    );
                    if rec.status != Status::Running {
                        self.unindexed
                            .lock()
                            .unwrap()
                            .insert(rec.id.clone(), rec.clone());
                    }
                }
            }
        }
    }
}

/// Move a damaged index (and its journal) aside as `index.sqlite.corrupt-<time>`; the
/// notice saying so.
fn move_aside(root: &Path, why: &str) -> Result<String, ArchiveError> {
    let stamp = id::compact_utc_now();
    let db = root.join(INDEX);
    let aside = root.join(format!("{INDEX}.corrupt-{stamp}"));
    std::fs::rename(&db, &aside).map_err(io_at(&db))?;
    let journal = root.join(format!("{INDEX}-journal"));
    if journal.symlink_metadata().is_ok() {
        let _ = std::fs::rename(
            &journal,
            root.join(format!("{INDEX}-journal.corrupt-{stamp}")),
        );
    }
    let note = format!(
        "the index {} was damaged ({why}); moved to {} and rebuilt from the scan directories",
        db.display(),
        aside.display()
    );
    tracing::error!("archive: {note}");
    Ok(note)
}

/// What a scan directory's scan.json (the pipeline's summary) says.
struct Summary {
    status: String,
    reason: Option<String>,
    frames: u64,
    points: u64,
}

fn read_summary(dir: &Path) -> Option<Summary> {
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(ScanDir::new(dir).summary_path()).ok()?).ok()?;
    Some(Summary {
        status: v["status"].as_str().unwrap_or("?").to_string(),
        reason: v["reason"].as_str().map(str::to_string),
        frames: v["frames"].as_u64()?,
        points: v["points"].as_u64()?,
    })
}

fn sync_dir(dir: &Path) -> Result<(), ArchiveError> {
    File::open(dir)
        .and_then(|f| f.sync_all())
        .map_err(io_at(dir))
}

/// The Content-Type of an artifact by its extension.
pub fn content_type(name: &str) -> &'static str {
    match name.rsplit_once('.').map(|(_, e)| e) {
        Some("ply") => "application/x-ply",
        Some("stl") => "model/stl",
        Some("obj") => "model/obj",
        Some("json") => "application/json",
        Some("png") => "image/png",
        Some("toml") => "application/toml",
        Some("csv") => "text/csv",
        Some("igs" | "iges") => "model/iges",
        Some("step" | "stp") => "model/step",
        Some("glb") => "model/gltf-binary",
        Some("3mf") => "model/3mf",
        _ => "application/octet-stream",
    }
}
