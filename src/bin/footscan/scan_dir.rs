//! `footscan scan --out DIR` never mixes two scans in DIR. The scan is written into a fresh
//! sibling folder, `DIR.partial-<pid>`, and moved to DIR when it ends, whatever its verdict
//! (complete, warnings, rescan, failed, cancelled: DIR always holds the newest attempt, its
//! scan.json saying how it went). A scan DIR held before is kept beside it, renamed
//! `DIR.previous-<UTC time>` (said on stderr), and so is whatever else a DIR held. The root
//! and home folders and the working directory (or a folder holding it) are refused before the
//! scan starts. A scan that wrote nothing leaves DIR as it was; one that never ended (killed)
//! stays in its `.partial-<pid>` folder.

use anyhow::{bail, Context, Result};
use std::path::{Path, PathBuf};

/// A scan being written into a staging folder beside its destination.
pub struct Staged {
    /// Where the scan ends up (`--out`).
    pub dest: PathBuf,
    /// Where it is written meanwhile.
    pub partial: PathBuf,
}

/// What [`Staged::finish`] did.
pub struct Placed {
    /// Where the scan DIR held before now is.
    pub previous: Option<PathBuf>,
}

/// `DIR` as a sibling with `suffix` appended to its name (`/a/scan` -> `/a/scan.previous-...`).
fn sibling(dest: &Path, suffix: &str) -> Result<PathBuf> {
    let name = dest
        .file_name()
        .with_context(|| format!("--out {}: not a folder name", dest.display()))?;
    let mut n = name.to_os_string();
    n.push(suffix);
    Ok(dest.with_file_name(n))
}

/// Whether `dir` has no entries.
fn is_empty_dir(dir: &Path) -> std::io::Result<bool> {
    Ok(std::fs::read_dir(dir)?.next().is_none())
}

/// A name `base`, `base-2`, `base-3`, ... that does not exist yet.
fn unused(base: PathBuf) -> PathBuf {
    if std::fs::symlink_metadata(&base).is_err() {
        return base;
    }
    (2..)
        .map(|k| {
            let mut n = base.as_os_str().to_os_string();
            n.push(format!("-{k}"));
            PathBuf::from(n)
        })
        .find(|p| std::fs::symlink_metadata(p).is_err())
        .expect("some name is free")
}

/// Now as a UTC time for a folder name: `20260125T101502Z`.
fn utc_stamp() -> String {
    footscan_util::now_rfc3339().replace(['-', ':'], "")
}

impl Staged {
    /// Check `dest` and create its staging folder. Refuses a `dest` that is a file, the root
    /// or home folder, or the working directory or one holding it (moving those aside would
    /// surprise).
    pub fn begin(dest: &Path) -> Result<Staged> {
        // `--out .` or `--out scans/..` name the folder by its full path.
        let dest = if dest.file_name().is_none() {
            std::fs::canonicalize(dest).with_context(|| format!("--out {}", dest.display()))?
        } else {
            dest.to_path_buf()
        };
        match std::fs::metadata(&dest) {
            Ok(m) if !m.is_dir() => bail!(
                "--out {}: a file is there; --out names a scan folder (new, or one whose \
                 content is kept as {}.previous-<UTC time>)",
                dest.display(),
                dest.display()
            ),
            Ok(_) => {
                // Its content will be moved aside whole: not a folder a person works in.
                let real = std::fs::canonicalize(&dest)
                    .with_context(|| format!("--out {}", dest.display()))?;
                let cwd = std::env::current_dir()
                    .ok()
                    .and_then(|c| c.canonicalize().ok());
                let home = std::env::var_os("HOME").and_then(|h| Path::new(&h).canonicalize().ok());
                let why = if real.parent().is_none() {
                    Some("the root folder")
                } else if cwd.as_deref().is_some_and(|c| c.starts_with(&real)) {
                    Some("the working directory or a folder holding it")
                } else if home.as_deref() == Some(real.as_path()) {
                    Some("the home folder")
                } else {
                    None
                };
                if let Some(why) = why {
                    bail!(
                        "--out {}: that is {why}; --out names a scan folder, whose earlier \
                         content is moved aside (kept as {}.previous-<UTC time>): name a \
                         folder of its own, e.g. {}",
                        dest.display(),
                        dest.display(),
                        real.join("scan").display()
                    );
                }
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e).with_context(|| format!("--out {}", dest.display())),
        }
        let partial = unused(sibling(&dest, &format!(".partial-{}", std::process::id()))?);
        if let Some(parent) = partial.parent().filter(|p| !p.as_os_str().is_empty()) {
            std::fs::create_dir_all(parent)
                .with_context(|| format!("creating the folder of --out {}", dest.display()))?;
        }
        for stale in unfinished(&dest) {
            eprintln!(
                "note: {} holds a scan that never ended (its program was stopped); it is left \
                 as it is",
                stale.display()
            );
        }
        std::fs::create_dir(&partial)
            .with_context(|| format!("creating the scan folder {}", partial.display()))?;
        Ok(Staged { dest, partial })
    }

    /// Move the finished scan to its destination, the scan there before aside as
    /// `DIR.previous-<UTC time>`. A staging folder left empty (the scan wrote nothing) is
    /// removed and the destination left as it was.
    pub fn finish(self) -> Result<Placed> {
        if is_empty_dir(&self.partial).unwrap_or(false) {
            std::fs::remove_dir(&self.partial)
                .with_context(|| format!("removing the empty {}", self.partial.display()))?;
            return Ok(Placed { previous: None });
        }
        let previous = match std::fs::symlink_metadata(&self.dest) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
            Err(e) => return Err(e).with_context(|| format!("--out {}", self.dest.display())),
            Ok(m) if m.is_dir() && is_empty_dir(&self.dest).unwrap_or(false) => {
                std::fs::remove_dir(&self.dest)
                    .with_context(|| format!("removing the empty {}", self.dest.display()))?;
                None
            }
            Ok(_) => {
                let prev = unused(sibling(&self.dest, &format!(".previous-{}", utc_stamp()))?);
                std::fs::rename(&self.dest, &prev).with_context(|| {
                    format!(
                        "moving the earlier scan {} aside to {} (this scan is kept in {})",
                        self.dest.display(),
                        prev.display(),
                        self.partial.display()
                    )
                })?;
                Some(prev)
            }
        };
        std::fs::rename(&self.partial, &self.dest).with_context(|| {
            format!(
                "moving the scan {} to {}",
                self.partial.display(),
                self.dest.display()
            )
        })?;
        sync_parent(&self.dest);
        Ok(Placed { previous })
    }
}

/// Make the renames durable: fsync the folder holding them (best effort).
fn sync_parent(p: &Path) {
    if let Some(parent) = p.parent().filter(|p| !p.as_os_str().is_empty()) {
        if let Ok(d) = std::fs::File::open(parent) {
            let _ = d.sync_all();
        }
    }
}

/// Staging folders of `dest` left by earlier runs that never ended.
fn unfinished(dest: &Path) -> Vec<PathBuf> {
    let (Some(parent), Some(name)) = (dest.parent(), dest.file_name()) else {
        return Vec::new();
    };
    let parent = if parent.as_os_str().is_empty() {
        Path::new(".")
    } else {
        parent
    };
    let prefix = format!("{}.partial-", name.to_string_lossy());
    let mut v: Vec<PathBuf> = std::fs::read_dir(parent)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
                .map(|e| e.path())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use footscan::scandata::ScanDir;

    const SUMMARY: &str = ScanDir::SUMMARY;
    const POINTS: &str = ScanDir::POINTS;

    fn files(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn swap_keeps_what_was_there_and_refuses_working_folders() {
        let t = tempfile::tempdir().unwrap();
        let dest = t.path().join("scan");
        // First scan: a new folder.
        let s = Staged::begin(&dest).unwrap();
        assert!(!dest.exists());
        std::fs::write(s.partial.join(SUMMARY), "1").unwrap();
        std::fs::write(s.partial.join(POINTS), "1").unwrap();
        assert!(s.finish().unwrap().previous.is_none());
        assert_eq!(files(&dest), [POINTS, SUMMARY]);
        // Second: fewer files; the first kept whole beside it.
        let s = Staged::begin(&dest).unwrap();
        std::fs::write(s.partial.join(SUMMARY), "2").unwrap();
        let prev = s.finish().unwrap().previous.unwrap();
        assert_eq!(files(&dest), [SUMMARY]);
        assert_eq!(std::fs::read_to_string(dest.join(SUMMARY)).unwrap(), "2");
        assert_eq!(files(&prev), [POINTS, SUMMARY]);
        assert!(prev
            .file_name()
            .unwrap()
            .to_string_lossy()
            .starts_with("scan.previous-20"));
        // A scan that wrote nothing changes nothing.
        let s = Staged::begin(&dest).unwrap();
        let partial = s.partial.clone();
        assert!(s.finish().unwrap().previous.is_none());
        assert!(!partial.exists());
        assert_eq!(files(&dest), [SUMMARY]);
        // Other files in --out: kept whole beside it too.
        let other = t.path().join("notes");
        std::fs::create_dir(&other).unwrap();
        std::fs::write(other.join("a.txt"), "x").unwrap();
        let s = Staged::begin(&other).unwrap();
        std::fs::write(s.partial.join(SUMMARY), "3").unwrap();
        let prev = s.finish().unwrap().previous.unwrap();
        assert_eq!(files(&other), [SUMMARY]);
        assert_eq!(files(&prev), ["a.txt"]);
        // A file, the root, the working directory and what holds it: refused.
        std::fs::write(t.path().join("file"), "x").unwrap();
        assert!(Staged::begin(&t.path().join("file")).is_err());
        assert!(Staged::begin(Path::new("/")).is_err());
        assert!(Staged::begin(Path::new(".")).is_err());
        let cwd = std::env::current_dir().unwrap();
        let e = Staged::begin(cwd.parent().unwrap())
            .err()
            .unwrap()
            .to_string();
        assert!(e.contains("working directory"), "{e}");
        // Nothing left behind but the scans, what they replaced and the file.
        assert_eq!(files(t.path()).len(), 5, "{:?}", files(t.path()));
    }
}
