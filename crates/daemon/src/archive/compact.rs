//! Compact scans in the archive (docs/method.md 14h.2): serving a compacted scan's files
//! through a bounded cache of decoded originals, and `footscand archive compact`, which puts
//! every scan of an archive into compact form in place, scan by scan.
//!
//! The form itself, its manifest and its reader are footscan's (`footscan::compact`),
//! so the `footscan` CLI reads a compacted scan as the daemon does.

use super::{Archive, ArchiveError, ArchiveLock, Record, ScanId, TMP_PREFIX};
use footscan::compact::{self, CompactOptions, CompactReport, Manifest};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The cache of decoded originals, under the archive root: `.cache/<id>/<name>`.
pub const CACHE: &str = ".cache";
/// The most the cache holds unless told ([`Archive::set_cache_max_bytes`]); the files used
/// longest ago go first.
pub const CACHE_MAX_BYTES: u64 = 512 << 20;

/// What the cache knows of a file it holds, beside it as `NAME.meta.json`: the manifest's
/// SHA-256 it was made for (a scan compacted again gets new entries, and a stale file is
/// never served for them), and why the bytes are not the original's, if they are not.
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
struct CacheMeta {
    sha256: String,
    bytes: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    differs: Option<String>,
}

fn meta_path(cached: &Path) -> PathBuf {
    let mut s = cached.as_os_str().to_owned();
    s.push(".meta.json");
    PathBuf::from(s)
}

impl Archive {
    /// The path of a compacted scan's original `name`, decoded (or rebuilt) into the cache
    /// and checked against the manifest: None when the scan's manifest does not list it or
    /// its stored form does not give it back. A rebuild that no longer matches (the writers
    /// changed since the scan was compacted) is served all the same, its reason kept beside
    /// it ([`Self::rebuilt_note`]) and logged: the data are the scan's, and refusing the file
    /// would lose every compacted scan's model at each change of the model writer.
    pub(crate) fn cached_original(&self, record: &Record, name: &str) -> Option<PathBuf> {
        let dir = self.checked_dir(record)?;
        let entry = Manifest::load(&dir).ok()??.files.get(name).cloned()?;
        let cdir = self.root.join(CACHE).join(&record.id);
        let path = cdir.join(name);
        // One decoder at a time: two requests for the same file would write the same
        // temporary file, and a rebuild is CPU-bound anyway.
        let _one = self.cache_lock.lock().unwrap();
        let meta: Option<CacheMeta> = std::fs::read(meta_path(&path))
            .ok()
            .and_then(|b| serde_json::from_slice(&b).ok());
        if let (Ok(m), Some(meta)) = (path.symlink_metadata(), &meta) {
            if m.is_file() && m.len() == meta.bytes && meta.sha256 == entry.sha256 {
                // Used now: the last to be pruned.
                let _ = std::fs::File::open(&path)
                    .and_then(|f| f.set_modified(std::time::SystemTime::now()));
                return Some(path);
            }
        }
        let t = std::time::Instant::now();
        let made = std::fs::create_dir_all(&cdir)
            .and_then(|()| compact::restore_rebuilt(&dir, name, &entry, &cdir))
            .and_then(|r| {
                footscan_util::write_atomic(&path, &r.bytes)?;
                let meta = CacheMeta {
                    sha256: entry.sha256.clone(),
                    bytes: r.bytes.len() as u64,
                    differs: r.differs.clone(),
                };
                let json = serde_json::to_vec(&meta).expect("cache meta serialises");
                footscan_util::write_atomic(&meta_path(&path), &json)?;
                Ok(r.differs)
            });
        match made {
            Ok(differs) => {
                tracing::info!(
                    "archive: scan {} {name} restored from its compact form ({:?}) in {:.0} ms",
                    record.id,
                    entry.codec,
                    t.elapsed().as_secs_f64() * 1e3
                );
                if let Some(why) = differs {
                    tracing::warn!("archive: scan {} {name}: {why}", record.id);
                }
                let max = self
                    .cache_max_bytes
                    .load(std::sync::atomic::Ordering::Relaxed);
                prune_cache(&self.root.join(CACHE), max, &path);
                Some(path)
            }
            Err(e) => {
                tracing::error!(
                    "archive: scan {} {name}: its compact form does not give the file back: {e}",
                    record.id
                );
                None
            }
        }
    }

    /// The most the cache of decoded files holds (`[archive] cache_mb`).
    pub fn set_cache_max_bytes(&self, bytes: u64) {
        self.cache_max_bytes
            .store(bytes, std::sync::atomic::Ordering::Relaxed);
    }

    /// Why a file served from `path` is not byte for byte the scan's original: Some only for
    /// a rebuild in the cache that no longer matches its manifest.
    pub fn rebuilt_note(&self, path: &Path) -> Option<String> {
        if !path.starts_with(self.root.join(CACHE)) {
            return None;
        }
        let b = std::fs::read(meta_path(path)).ok()?;
        serde_json::from_slice::<CacheMeta>(&b).ok()?.differs
    }
}

/// Remove the cache's least recently used files until it holds at most `max` bytes, never
/// `keep` (the file just made).
pub fn prune_cache(cache: &Path, max: u64, keep: &Path) {
    let mut files: Vec<(std::time::SystemTime, u64, PathBuf)> = Vec::new();
    for d in std::fs::read_dir(cache).into_iter().flatten().flatten() {
        for f in std::fs::read_dir(d.path()).into_iter().flatten().flatten() {
            if let Ok(m) = f.metadata() {
                if m.is_file() {
                    files.push((
                        m.modified().unwrap_or(std::time::UNIX_EPOCH),
                        m.len(),
                        f.path(),
                    ));
                }
            }
        }
    }
    let mut total: u64 = files.iter().map(|f| f.1).sum();
    files.sort();
    for (_, len, p) in files {
        if total <= max {
            break;
        }
        if p != keep && p != meta_path(keep) && std::fs::remove_file(&p).is_ok() {
            total -= len;
            if let Some(parent) = p.parent() {
                let _ = std::fs::remove_dir(parent);
            }
        }
    }
}

/// The finished scan directories of the archive at `root`, oldest first.
pub fn scan_dirs(root: &Path) -> Result<Vec<(String, PathBuf)>, ArchiveError> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(root).map_err(super::io_at(root))? {
        let e = e.map_err(super::io_at(root))?;
        let name = e.file_name().to_string_lossy().into_owned();
        if name.starts_with(TMP_PREFIX) || ScanId::parse(&name).is_err() {
            continue;
        }
        if e.file_type().is_ok_and(|t| t.is_dir()) {
            out.push((name, e.path()));
        }
    }
    out.sort();
    Ok(out)
}

/// What `footscand archive compact` did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CompactRun {
    pub scans: usize,
    pub changed: usize,
    pub failed: Vec<(String, String)>,
    pub bytes_before: u64,
    pub bytes_after: u64,
    pub seconds: f64,
}

/// Compact every finished scan of the archive at `root` in place, oldest first, holding the
/// archive lock (a running daemon holds it: refused, naming it). `abort_at_scan` is the test
/// hook of the kill test: the process aborts, as a kill would, in the middle of that scan
/// (counted from 0), after its first stored file is written. `each` is told of every scan.
pub fn compact_archive(
    root: &Path,
    opts: &CompactOptions,
    abort_at_scan: Option<usize>,
    mut each: impl FnMut(&str, &Result<CompactReport, std::io::Error>),
) -> Result<CompactRun, ArchiveError> {
    let _lock = ArchiveLock::acquire(root, "footscand archive compact")?;
    let t = std::time::Instant::now();
    let mut run = CompactRun::default();
    for (k, (id, dir)) in scan_dirs(root)?.into_iter().enumerate() {
        let mut o = opts.clone();
        if abort_at_scan == Some(k) {
            o.stop_after_writes = Some(1);
        }
        let r = compact::compact_dir(&dir, &o);
        if abort_at_scan == Some(k) {
            eprintln!("footscand: test hook: aborting during scan {id}");
            std::process::abort();
        }
        each(&id, &r);
        run.scans += 1;
        match r {
            Ok(rep) => {
                run.changed += rep.changed as usize;
                run.bytes_before += rep.bytes_before;
                run.bytes_after += rep.bytes_after;
            }
            Err(e) => run.failed.push((id, e.to_string())),
        }
    }
    run.seconds = t.elapsed().as_secs_f64();
    Ok(run)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Over its limit the cache loses the files used longest ago, never the one just made
    /// nor what is kept beside it.
    #[test]
    fn the_cache_drops_the_least_recently_used_first() {
        let d = tempfile::tempdir().unwrap();
        let cache = d.path();
        let t0 = std::time::SystemTime::now() - std::time::Duration::from_secs(1000);
        let mut made = Vec::new();
        for (k, (scan, name)) in [("a", "grid.bin"), ("b", "model.stl"), ("c", "points.ply")]
            .iter()
            .enumerate()
        {
            std::fs::create_dir_all(cache.join(scan)).unwrap();
            let p = cache.join(scan).join(name);
            std::fs::write(&p, vec![0u8; 1000]).unwrap();
            // "a" used longest ago; the meta of "a" newer than every file.
            let f = std::fs::File::options().write(true).open(&p).unwrap();
            f.set_modified(t0 + std::time::Duration::from_secs(10 * k as u64))
                .unwrap();
            made.push(p);
        }
        let keep = made[0].clone();
        std::fs::write(meta_path(&keep), b"{}").unwrap();
        // 2000 bytes hold two files: b (the older of the others) goes, a is kept as the one
        // just made, and its meta with it.
        prune_cache(cache, 2100, &keep);
        assert!(keep.is_file() && meta_path(&keep).is_file());
        assert!(!made[1].exists() && !cache.join("b").exists());
        assert!(made[2].is_file());
        // Without a file to keep, the least recently used go until it fits.
        prune_cache(cache, 1100, &cache.join("none"));
        let left: Vec<bool> = made.iter().map(|p| p.exists()).collect();
        assert_eq!(left, [false, false, true], "{left:?}");
    }
}
