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

mod id;
mod index;
mod record;

pub use id::{valid_file_name, IdError, ScanId};
pub use record::{ArchiveError, NewScan, Outcome, Record, Status};

use index::Index;
use serde::Serialize;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Bytes kept free inside a running scan's directory for its record and the index update.
const RESERVE_BYTES: usize = 256 * 1024;
const RESERVE: &str = ".reserve";
const TMP_PREFIX: &str = ".tmp-";
pub const RECORD: &str = "record.json";
pub const INDEX: &str = "index.sqlite";
/// Reason given to scans found unfinished at startup.
pub const INTERRUPTED: &str = "interrupted: the daemon stopped during the scan";

fn io_at(path: &Path) -> impl FnOnce(std::io::Error) -> ArchiveError + '_ {
    move |source| ArchiveError::Io {
        path: path.to_owned(),
        source,
    }
}

/// A scan being written: its directory is `.tmp-<id>` until [`Archive::finish`].
#[derive(Debug)]
pub struct ActiveScan {
    pub record: Record,
    pub dir: PathBuf,
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
    index: Mutex<Index>,
}

impl Archive {
    /// Open (creating) the archive at `root`: unfinished `.tmp-` scans are closed as failed
    /// with [`INTERRUPTED`], and the index is brought in line with the directories.
    pub fn open(root: &Path) -> Result<Archive, ArchiveError> {
        std::fs::create_dir_all(root).map_err(io_at(root))?;
        let db = root.join(INDEX);
        let archive = Archive {
            root: root.to_owned(),
            index: Mutex::new(Index::open(&db)?),
        };
        archive.recover()?;
        archive.rebuild()?;
        Ok(archive)
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    /// Create the temporary directory of a new scan and list it as running.
    pub fn begin(&self, meta: NewScan) -> Result<ActiveScan, ArchiveError> {
        let (id, dir) = (0..16)
            .map(ScanId::generate)
            .map(|id| {
                let dir = self.root.join(format!("{TMP_PREFIX}{id}"));
                (id, dir)
            })
            .find(|(id, dir)| !dir.exists() && !self.root.join(id.as_str()).exists())
            .ok_or_else(|| ArchiveError::Io {
                path: self.root.clone(),
                source: std::io::Error::other("no free scan id"),
            })?;
        std::fs::create_dir(&dir).map_err(io_at(&dir))?;
        let reserve = dir.join(RESERVE);
        let res = (|| {
            let mut f = File::create(&reserve)?;
            f.write_all(&vec![0u8; RESERVE_BYTES])?;
            f.sync_all()
        })();
        if let Err(e) = res {
            let _ = std::fs::remove_dir_all(&dir);
            return Err(io_at(&reserve)(e));
        }
        let record = Record::running(id.to_string(), meta);
        self.index_upsert(&record);
        Ok(ActiveScan { record, dir })
    }

    /// Close a scan: fsync its files, write record.json, rename the directory to its id,
    /// then update the index. Returns the final record.
    pub fn finish(&self, scan: ActiveScan, outcome: Outcome) -> Result<Record, ArchiveError> {
        let mut record = scan.record;
        record.status = outcome.status;
        record.reason = outcome.reason;
        record.frames = outcome.frames;
        record.points = outcome.points;
        record.finished = Some(footscan::util::now_rfc3339());
        match self.seal(&scan.dir, &record) {
            Ok(_) => {
                self.index_upsert(&record);
                Ok(record)
            }
            Err(e) => {
                // Not listed as running forever: failed, files left in .tmp-<id> (recovered at
                // the next start), the reason saying why.
                record.status = Status::Failed;
                record.reason = Some(format!(
                    "{}; archiving failed: {e}",
                    record.reason.as_deref().unwrap_or("scan ended")
                ));
                self.index_upsert(&record);
                Err(e)
            }
        }
    }

    /// The fsync-record-rename sequence shared by finish and recovery.
    fn seal(&self, dir: &Path, record: &Record) -> Result<PathBuf, ArchiveError> {
        let _ = std::fs::remove_file(dir.join(RESERVE));
        for entry in std::fs::read_dir(dir).map_err(io_at(dir))? {
            let entry = entry.map_err(io_at(dir))?;
            if entry.file_type().map_err(io_at(dir))?.is_file() {
                let p = entry.path();
                File::open(&p)
                    .and_then(|f| f.sync_all())
                    .map_err(io_at(&p))?;
            }
        }
        let rec_path = dir.join(RECORD);
        let json = serde_json::to_vec_pretty(record).expect("record serialises");
        footscan::io::write_atomic(&rec_path, &json).map_err(io_at(&rec_path))?;
        sync_dir(dir)?;
        let done = self.root.join(&record.id);
        std::fs::rename(dir, &done).map_err(io_at(&done))?;
        sync_dir(&self.root)?;
        Ok(done)
    }

    /// Close every `.tmp-` scan left by a daemon that stopped mid-scan, as failed.
    fn recover(&self) -> Result<(), ArchiveError> {
        for entry in std::fs::read_dir(&self.root).map_err(io_at(&self.root))? {
            let entry = entry.map_err(io_at(&self.root))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let Some(id) = name.strip_prefix(TMP_PREFIX) else {
                continue;
            };
            if ScanId::parse(id).is_err() || !entry.path().is_dir() {
                tracing::warn!("archive: ignoring {name}: not a scan directory");
                continue;
            }
            let dir = entry.path();
            let mut record = match self.index.lock().unwrap().get(id) {
                Ok(Some(r)) => r,
                _ => Record::running(
                    id.to_string(),
                    NewScan {
                        subject: "unknown".into(),
                        side: "unknown".into(),
                        notes: String::new(),
                    },
                ),
            };
            // A scan the daemon already closed but could not rename keeps its own reason.
            if record.status == Status::Running || record.reason.is_none() {
                record.reason = Some(INTERRUPTED.into());
            }
            record.status = Status::Failed;
            record.finished = Some(footscan::util::now_rfc3339());
            if let Some(s) = read_summary(&dir) {
                record.frames = s.0;
                record.points = s.1;
            }
            tracing::warn!("archive: scan {id} was interrupted; kept as failed");
            self.seal(&dir, &record)?;
        }
        Ok(())
    }

    /// Recreate the index from the scan directories' record.json files.
    pub fn rebuild(&self) -> Result<usize, ArchiveError> {
        let mut records = Vec::new();
        for entry in std::fs::read_dir(&self.root).map_err(io_at(&self.root))? {
            let entry = entry.map_err(io_at(&self.root))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let Ok(id) = ScanId::parse(&name) else {
                continue;
            };
            let path = entry.path().join(RECORD);
            let text = match std::fs::read(&path) {
                Ok(t) => t,
                Err(e) => {
                    tracing::warn!("archive: {} skipped: {e}", path.display());
                    continue;
                }
            };
            match serde_json::from_slice::<Record>(&text) {
                Ok(r) if r.id == id.as_str() => records.push(r),
                Ok(r) => tracing::warn!(
                    "archive: {} skipped: it names scan {}",
                    path.display(),
                    r.id
                ),
                Err(e) => tracing::warn!("archive: {} skipped: {e}", path.display()),
            }
        }
        // Scans running right now live only in the index: keep them.
        let mut index = self.index.lock().unwrap();
        let db = |e| ArchiveError::Index {
            path: self.root.join(INDEX),
            source: e,
        };
        let running: Vec<Record> = index
            .list()
            .map_err(db)?
            .into_iter()
            .filter(|r| {
                r.status == Status::Running
                    && self.root.join(format!("{TMP_PREFIX}{}", r.id)).is_dir()
            })
            .collect();
        records.extend(running);
        index.replace_all(&records).map_err(db)?;
        Ok(records.len())
    }

    /// Every scan, newest first.
    pub fn list(&self) -> Result<Vec<Record>, ArchiveError> {
        self.index
            .lock()
            .unwrap()
            .list()
            .map_err(|e| ArchiveError::Index {
                path: self.root.join(INDEX),
                source: e,
            })
    }

    pub fn get(&self, id: &ScanId) -> Result<Record, ArchiveError> {
        self.index
            .lock()
            .unwrap()
            .get(id.as_str())
            .map_err(|e| ArchiveError::Index {
                path: self.root.join(INDEX),
                source: e,
            })?
            .ok_or_else(|| ArchiveError::NotFound(id.to_string()))
    }

    /// The directory holding a scan's files (the temporary one while it runs).
    pub fn dir(&self, record: &Record) -> PathBuf {
        let tmp = self.root.join(format!("{TMP_PREFIX}{}", record.id));
        let done = self.root.join(&record.id);
        match record.status {
            Status::Running => tmp,
            // Closed but not renamed (archiving failed): its files are still in .tmp-<id>.
            _ if !done.exists() && tmp.is_dir() => tmp,
            _ => done,
        }
    }

    /// The downloadable files of a scan, by name.
    pub fn artifacts(&self, record: &Record) -> Result<Vec<Artifact>, ArchiveError> {
        let dir = self.dir(record);
        let mut out = Vec::new();
        for entry in std::fs::read_dir(&dir).map_err(io_at(&dir))? {
            let entry = entry.map_err(io_at(&dir))?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let meta = entry.metadata().map_err(io_at(&dir))?;
            if meta.is_file() && valid_file_name(&name) {
                out.push(Artifact {
                    content_type: content_type(&name),
                    name,
                    bytes: meta.len(),
                });
            }
        }
        out.sort_by(|a, b| a.name.cmp(&b.name));
        Ok(out)
    }

    /// The path of artifact `name` of a scan, if it exists (name validated here too).
    pub fn artifact_path(&self, record: &Record, name: &str) -> Option<PathBuf> {
        if !valid_file_name(name) {
            return None;
        }
        let p = self.dir(record).join(name);
        p.symlink_metadata().ok().filter(|m| m.is_file()).map(|_| p)
    }

    fn index_upsert(&self, r: &Record) {
        // The directory is the truth: a failed index write is repaired by the next rebuild.
        if let Err(e) = self.index.lock().unwrap().upsert(r) {
            tracing::error!(
                "archive index: could not record scan {} as {}: {e}",
                r.id,
                r.status.as_str()
            );
        }
    }
}

/// (frames, points) from a scan directory's scan.json, if it has one.
fn read_summary(dir: &Path) -> Option<(u64, u64)> {
    let v: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("scan.json")).ok()?).ok()?;
    Some((v["frames"].as_u64()?, v["points"].as_u64()?))
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
        _ => "application/octet-stream",
    }
}
