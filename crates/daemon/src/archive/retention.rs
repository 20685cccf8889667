//! Retention (`[archive] keep_raw_days`, `keep_days`, `max_gb`; docs/method.md 14h.2): what
//! the clinic keeps and for how long, run by the daemon at start and then periodically at a
//! low priority. Every drop is logged and listed in the run's report (`GET /api/status`,
//! `archive.retention`).
//!
//! A scan is protected when it is in a visit, has a last (`last/`) or an insole (`insole/`),
//! or is not yet pushed to the fleet (its outbox entry pending, or, with [fleet] on, none at all): a protected scan a
//! rule would drop is kept and listed as kept, with the rule and what protects it.
//!
//! After `keep_raw_days` a scan loses its raw data: grid.bin, points.ply, model.stl and
//! truth.json, in either form (original or compact). What stays: record.json, scan.json,
//! measurements.json, the history, the pictures, the calibration, model.step and model.glb
//! (a glb kept as "rebuilt from the grid" is stored as gzip first, since the grid goes), and
//! the jobs' subdirectories. After `keep_days` the whole scan goes. Over `max_gb`, whole
//! scans go oldest first until the scans fit.

use super::compact::{scan_dirs, CACHE};
use super::{io_at, Archive, ArchiveError};
use footscan::compact::{self, Codec, Manifest};
use footscan::scandata::ScanDir;
use serde::Serialize;
use std::collections::{BTreeMap, HashSet};
use std::path::Path;

/// Protected scans kept listed in a run's report (and logged one by one); the rest are
/// counted. A clinic keeping every visit's scans would otherwise log thousands every hour.
pub const KEPT_LISTED: usize = 100;

/// The rules of one run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Rules {
    pub keep_raw_days: Option<f64>,
    pub keep_days: Option<f64>,
    pub max_gb: Option<f64>,
    /// With [fleet] on, a scan the outbox has no entry for is not pushed yet.
    pub fleet: bool,
}

/// The files a scan loses after keep_raw_days (their compact forms with them).
pub const RAW: [&str; 4] = [
    ScanDir::GRID,
    ScanDir::POINTS,
    ScanDir::MODEL_STL,
    ScanDir::TRUTH,
];

#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Dropped {
    pub id: String,
    /// "scan" (the whole scan) or "raw data" (the files of [`RAW`]).
    pub what: &'static str,
    /// The rule that dropped it, e.g. "keep_days = 3650".
    pub rule: String,
    /// Bytes on disk freed.
    pub bytes: u64,
}

#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Kept {
    pub id: String,
    pub what: &'static str,
    pub rule: String,
    /// What protects it: "in visit <id>", "has a last", "has an insole", "not yet pushed to
    /// the fleet".
    pub protected_by: Vec<String>,
}

/// What one retention run did.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RetentionRun {
    pub at: String,
    pub rules: Rules,
    pub seconds: f64,
    pub scans: usize,
    /// Bytes on disk of the scans before and after.
    pub bytes_before: u64,
    pub bytes_after: u64,
    pub dropped: Vec<Dropped>,
    /// Protected scans a rule would have dropped: the first [`KEPT_LISTED`], and how many.
    pub kept: Vec<Kept>,
    pub kept_total: usize,
    /// Over max_gb after the run (only protected scans were left to drop).
    pub over_max_gb: bool,
    pub errors: Vec<String>,
}

/// Bytes on disk (allocated blocks) of everything under `p`.
fn disk(p: &Path) -> u64 {
    use std::os::unix::fs::MetadataExt;
    let Ok(m) = p.symlink_metadata() else {
        return 0;
    };
    if m.is_dir() {
        std::fs::read_dir(p)
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| disk(&e.path()))
            .sum::<u64>()
            + m.blocks() * 512
    } else {
        m.blocks() * 512
    }
}

/// Seconds since the epoch of a scan id's start time (`YYYYMMDDTHHMMSSZ-xxxx`).
fn id_time(id: &str) -> Option<i64> {
    let g = |r: std::ops::Range<usize>| id.get(r);
    let text = format!(
        "{}-{}-{}T{}:{}:{}Z",
        g(0..4)?,
        g(4..6)?,
        g(6..8)?,
        g(9..11)?,
        g(11..13)?,
        g(13..15)?
    );
    Some(text.parse::<jiff::Timestamp>().ok()?.as_second())
}

impl Archive {
    /// Ids of scans in a visit, by visit id.
    fn visit_scans(&self) -> Result<BTreeMap<String, String>, ArchiveError> {
        self.with_index(|i| {
            let mut st = i
                .conn()
                .prepare("SELECT id, left_scan, right_scan FROM visits")?;
            let mut out = BTreeMap::new();
            for row in st.query_map([], |r| {
                Ok((
                    r.get::<_, String>(0)?,
                    r.get::<_, Option<String>>(1)?,
                    r.get::<_, Option<String>>(2)?,
                ))
            })? {
                let (v, l, rt) = row?;
                for s in [l, rt].into_iter().flatten() {
                    out.insert(s, v.clone());
                }
            }
            Ok(out)
        })
    }

    /// The outbox's entries by state: (pending, done).
    fn outbox_states(&self) -> Result<(HashSet<String>, HashSet<String>), ArchiveError> {
        self.outbox_counts()?; // creates the table
        self.with_index(|i| {
            let mut st = i
                .conn()
                .prepare("SELECT scan_id, state FROM fleet_outbox")?;
            let (mut pending, mut done) = (HashSet::new(), HashSet::new());
            for row in st.query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, String>(1)?)))? {
                let (id, state) = row?;
                if state == "pending" {
                    pending.insert(id);
                } else {
                    done.insert(id);
                }
            }
            Ok((pending, done))
        })
    }

    /// Remove a whole scan: renamed out of the ids first (so it is gone at once for every
    /// reader), then deleted, its index row and cached files with it.
    fn drop_scan(&self, id: &str) -> Result<(), ArchiveError> {
        let dir = self.root.join(id);
        let gone = self.root.join(format!(".dropped-{id}"));
        std::fs::rename(&dir, &gone).map_err(io_at(&dir))?;
        super::sync_dir(&self.root)?;
        std::fs::remove_dir_all(&gone).map_err(io_at(&gone))?;
        let _ = std::fs::remove_dir_all(self.root.join(CACHE).join(id));
        let id = id.to_string();
        self.with_index(|i| i.delete(&id))?;
        Ok(())
    }

    /// Remove a scan's raw data ([`RAW`]); a glb the manifest rebuilds from the grid is
    /// stored first. Returns whether anything went.
    fn drop_raw(&self, id: &str, dir: &Path) -> std::io::Result<bool> {
        let mut man = Manifest::load(dir)?;
        let mut any = false;
        if let Some(m) = man.as_mut() {
            let mut changed = false;
            for (name, e) in m.files.iter_mut() {
                if e.stored.is_none() && !RAW.contains(&name.as_str()) {
                    // Rebuilt from the grid, which goes: stored as gzip now. A rebuild
                    // that no longer matches (the writers changed since compaction) is the
                    // best that will ever be had once the grid is gone: kept, with why.
                    let r = compact::restore_rebuilt(dir, name, e, dir)?;
                    let bytes = r.bytes;
                    if let Some(why) = r.differs {
                        tracing::warn!("retention: scan {id} {name}: {why}; stored as rebuilt");
                        e.bytes = bytes.len() as u64;
                        e.sha256 = compact::sha256_hex(&bytes);
                        e.note = Some(why);
                    }
                    let s = compact::stored_name(name, Codec::Gzip);
                    footscan_util::write_atomic(
                        &dir.join(&s),
                        &compact::gzip(&bytes, compact::GZIP_LEVEL),
                    )?;
                    e.codec = Codec::Gzip;
                    e.stored = Some(s);
                    e.cell_mm = None;
                    changed = true;
                }
            }
            let before = m.files.len();
            let mut stored: Vec<String> = Vec::new();
            m.files.retain(|name, e| {
                let raw = RAW.contains(&name.as_str());
                if raw {
                    stored.extend(e.stored.clone());
                }
                !raw
            });
            if changed || m.files.len() != before {
                let json = serde_json::to_vec_pretty(&m).expect("manifest serialises");
                footscan_util::write_atomic(&dir.join(compact::MANIFEST), &json)?;
            }
            any |= m.files.len() != before;
            for s in stored {
                let _ = std::fs::remove_file(dir.join(s));
            }
        }
        for name in RAW {
            for f in [
                name.to_string(),
                compact::stored_name(name, Codec::Gzip),
                compact::stored_name(name, Codec::GridShuffleGzip),
            ] {
                match std::fs::remove_file(dir.join(&f)) {
                    Ok(()) => any = true,
                    Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                    Err(e) => return Err(e),
                }
            }
        }
        let _ = std::fs::remove_dir_all(self.root.join(CACHE).join(id));
        std::fs::File::open(dir)?.sync_all()?;
        Ok(any)
    }

    /// Whether the scan in `dir` still has raw data.
    fn has_raw(dir: &Path) -> bool {
        RAW.iter().any(|n| {
            [
                n.to_string(),
                compact::stored_name(n, Codec::Gzip),
                compact::stored_name(n, Codec::GridShuffleGzip),
            ]
            .iter()
            .any(|f| dir.join(f).exists())
        })
    }

    /// Apply `rules` at `now` (seconds since the epoch). Never fails as a whole: what could
    /// not be done is in the report's errors.
    pub fn retain(&self, rules: &Rules, now: i64) -> RetentionRun {
        let t = std::time::Instant::now();
        let mut run = RetentionRun {
            at: footscan_util::now_rfc3339(),
            rules: rules.clone(),
            ..Default::default()
        };
        let scans = match scan_dirs(&self.root) {
            Ok(s) => s,
            Err(e) => {
                run.errors.push(e.to_string());
                return run;
            }
        };
        let visits = self.visit_scans().unwrap_or_else(|e| {
            run.errors.push(format!("visits: {e}"));
            BTreeMap::new()
        });
        let (pending, done) = self.outbox_states().unwrap_or_else(|e| {
            run.errors.push(format!("fleet outbox: {e}"));
            Default::default()
        });
        let protection = |id: &str, dir: &Path| {
            let mut p = Vec::new();
            if let Some(v) = visits.get(id) {
                p.push(format!("in visit {v}"));
            }
            if dir.join(crate::daemon::lastjob::LAST_DIR).exists() {
                p.push("has a last".to_string());
            }
            // An insole was made for a patient from this scan, as a last is for a shoe.
            if dir.join(crate::daemon::insolejob::INSOLE_DIR).exists() {
                p.push("has an insole".to_string());
            }
            if pending.contains(id) || (rules.fleet && !done.contains(id)) {
                p.push("not yet pushed to the fleet".to_string());
            }
            p
        };
        run.scans = scans.len();
        let mut sizes: Vec<(String, std::path::PathBuf, u64)> = scans
            .into_iter()
            .map(|(id, dir)| {
                let b = disk(&dir);
                (id, dir, b)
            })
            .collect();
        run.bytes_before = sizes.iter().map(|s| s.2).sum();
        let age_days = |id: &str| id_time(id).map(|s| (now - s) as f64 / 86400.0);
        let mut gone: HashSet<String> = HashSet::new();
        for (id, dir, bytes) in sizes.iter_mut() {
            let Some(age) = age_days(id) else { continue };
            if let Some(k) = rules.keep_days.filter(|k| age > *k) {
                let rule = format!("keep_days = {k}");
                let p = protection(id, dir);
                if !p.is_empty() {
                    // Kept whole: its raw data too (the same protection), said once.
                    run.kept.push(Kept {
                        id: id.clone(),
                        what: "scan",
                        rule,
                        protected_by: p,
                    });
                    continue;
                } else {
                    match self.drop_scan(id) {
                        Ok(()) => {
                            run.dropped.push(Dropped {
                                id: id.clone(),
                                what: "scan",
                                rule,
                                bytes: *bytes,
                            });
                            gone.insert(id.clone());
                            *bytes = 0;
                        }
                        Err(e) => run.errors.push(format!("scan {id}: {e}")),
                    }
                    continue;
                }
            }
            if let Some(k) = rules.keep_raw_days.filter(|k| age > *k) {
                if !Self::has_raw(dir) {
                    continue;
                }
                let rule = format!("keep_raw_days = {k}");
                let p = protection(id, dir);
                if !p.is_empty() {
                    run.kept.push(Kept {
                        id: id.clone(),
                        what: "raw data",
                        rule,
                        protected_by: p,
                    });
                    continue;
                }
                match self.drop_raw(id, dir) {
                    Ok(true) => {
                        let after = disk(dir);
                        run.dropped.push(Dropped {
                            id: id.clone(),
                            what: "raw data",
                            rule,
                            bytes: bytes.saturating_sub(after),
                        });
                        *bytes = after;
                    }
                    Ok(false) => {}
                    Err(e) => run.errors.push(format!("scan {id}: raw data: {e}")),
                }
            }
        }
        if let Some(gb) = rules.max_gb {
            let max = (gb * 1e9) as u64;
            let mut total: u64 = sizes.iter().map(|s| s.2).sum();
            for (id, dir, bytes) in sizes.iter_mut() {
                if total <= max {
                    break;
                }
                if gone.contains(id.as_str()) {
                    continue;
                }
                let rule = format!("max_gb = {gb}");
                let p = protection(id, dir);
                if !p.is_empty() {
                    // Said once a run: a scan kept against keep_days is not listed again.
                    if run.kept.iter().any(|k| k.id == *id && k.what == "scan") {
                        continue;
                    }
                    run.kept.push(Kept {
                        id: id.clone(),
                        what: "scan",
                        rule,
                        protected_by: p,
                    });
                    continue;
                }
                match self.drop_scan(id) {
                    Ok(()) => {
                        run.dropped.push(Dropped {
                            id: id.clone(),
                            what: "scan",
                            rule,
                            bytes: *bytes,
                        });
                        total -= *bytes;
                        *bytes = 0;
                        gone.insert(id.clone());
                    }
                    Err(e) => run.errors.push(format!("scan {id}: {e}")),
                }
            }
            run.over_max_gb = total > max;
        }
        run.bytes_after = sizes.iter().map(|s| s.2).sum();
        run.seconds = t.elapsed().as_secs_f64();
        for d in &run.dropped {
            tracing::info!(
                "archive retention: scan {} {} dropped ({}, {:.1} MB)",
                d.id,
                if d.what == "scan" {
                    "wholly"
                } else {
                    "raw data"
                },
                d.rule,
                d.bytes as f64 / 1e6
            );
        }
        run.kept_total = run.kept.len();
        run.kept.truncate(KEPT_LISTED);
        for k in run.kept.iter().take(20) {
            tracing::warn!(
                "archive retention: scan {} {} kept against {}: {}",
                k.id,
                k.what,
                k.rule,
                k.protected_by.join(", ")
            );
        }
        if run.kept_total > 20 {
            tracing::warn!(
                "archive retention: {} more protected scans kept against a rule (the first \
                 {KEPT_LISTED} are listed on /api/status)",
                run.kept_total - 20
            );
        }
        if run.over_max_gb {
            tracing::warn!(
                "archive retention: the scans still take {:.2} GB, over max_gb = {}: only \
                 protected scans are left to drop",
                run.bytes_after as f64 / 1e9,
                rules.max_gb.unwrap_or(0.0)
            );
        }
        for e in &run.errors {
            tracing::error!("archive retention: {e}");
        }
        *self.retention.lock().unwrap() = Some(run.clone());
        run
    }

    /// The last retention run's report, if one ran.
    pub fn last_retention(&self) -> Option<RetentionRun> {
        self.retention.lock().unwrap().clone()
    }
}

/// Now, in seconds since the epoch.
pub fn now_secs() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs() as i64)
}

#[cfg(test)]
mod tests {
    #[test]
    fn id_times() {
        assert_eq!(super::id_time("19700102T000000Z-0000"), Some(86400));
        assert_eq!(super::id_time("bad"), None);
    }
}
