//! Compaction of a scan directory and the files rebuilt from its grid (docs/method.md
//! section 14h.2). The stored forms and their manifest are [`crate::scandata::stored`]'s; this
//! module sits above the models because a rebuild runs the point sink and the foot model.
//!
//! A reader asks for the original name ([`ScanDir::read_file`]): the original when it is
//! there, else its stored form decoded (or rebuilt) and checked against the manifest's
//! SHA-256, so the bytes are the original's or an error. Compaction ([`compact_dir`]) writes
//! every stored form (fsynced, renamed into place), then the manifest (atomically), and only
//! then removes the originals, so at every instant each file is readable from its original,
//! its stored form, or both: a compaction killed at any point loses nothing and a rerun
//! finishes it.

pub use crate::scandata::stored::*;
use crate::scandata::{ScanDir, ScanGrid};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

impl ScanDir {
    /// The original bytes of the file `name`: the file itself when it is there, else, in a
    /// compacted scan, its stored form decoded or the file rebuilt from the grid, checked
    /// against the manifest's length and SHA-256. NotFound when neither is there.
    /// ([`ScanDir::read_stored`] reads every file but the rebuilt ones without the models.)
    pub fn read_file(&self, name: &str) -> std::io::Result<Vec<u8>> {
        match self.read_stored(name) {
            Err(e) if e.kind() == std::io::ErrorKind::Unsupported => {
                let entry = Manifest::load(self.path())?
                    .and_then(|m| m.files.get(name).cloned())
                    .ok_or(e)?;
                restore(self.path(), name, &entry, &std::env::temp_dir())
            }
            r => r,
        }
    }
}

/// Which footscan compacts (recorded per file in the manifest).
pub const MADE_BY: &str = concat!("footscan ", env!("CARGO_PKG_VERSION"));

/// A compacted file given back: its bytes, and why they are not the original's when a
/// rebuild no longer gives the original byte for byte.
#[derive(Clone, Debug)]
pub struct Restored {
    pub bytes: Vec<u8>,
    pub differs: Option<String>,
}

/// The original bytes of `name` from its entry in the compacted scan at `dir`: the stored
/// form decoded, or the file rebuilt from the grid (scratch files in `scratch`), checked
/// against the manifest. A rebuild that does not match is an error here; see
/// [`restore_rebuilt`].
pub fn restore(dir: &Path, name: &str, entry: &Entry, scratch: &Path) -> std::io::Result<Vec<u8>> {
    let r = restore_rebuilt(dir, name, entry, scratch)?;
    match r.differs {
        None => Ok(r.bytes),
        Some(why) => Err(invalid(format!("{}: {why}", dir.join(name).display()))),
    }
}

/// [`restore`], but a rebuild that no longer matches the manifest (the model or point
/// writers changed since the scan was compacted) is given back with the reason. Its data are
/// the scan's: the grid it is rebuilt from is itself checked against the manifest, and a
/// stored form that does not match is an error as in [`restore`].
pub fn restore_rebuilt(
    dir: &Path,
    name: &str,
    entry: &Entry,
    scratch: &Path,
) -> std::io::Result<Restored> {
    if let Some(bytes) = decode(dir, name, entry)? {
        return Ok(Restored {
            bytes,
            differs: None,
        });
    }
    let grid = ScanDir::new(dir).load_grid()?;
    let mut out = rebuild(&grid, &[(name, entry.codec, entry.cell_mm)], scratch)?;
    let bytes = out.pop().map(|(_, b)| b).unwrap_or_default();
    let sha = sha256_hex(&bytes);
    let same = bytes.len() as u64 == entry.bytes && sha == entry.sha256;
    let differs = (!same).then(|| {
        format!(
            "rebuilt from the scan's grid by {MADE_BY}: {} bytes, SHA-256 {sha}, not the \
             original's {} bytes, SHA-256 {}, written by {}; the writer has changed since, \
             the data are the scan's",
            bytes.len(),
            entry.bytes,
            entry.sha256,
            entry.made_by.as_deref().unwrap_or("an earlier footscan"),
        )
    });
    Ok(Restored { bytes, differs })
}

/// Rebuild `wanted` (name, codec, model cell) from `grid`, writing scratch files into
/// `scratch` (created, then emptied of them); the bytes by name.
pub fn rebuild(
    grid: &ScanGrid,
    wanted: &[(&str, Codec, Option<f64>)],
    scratch: &Path,
) -> std::io::Result<Vec<(String, Vec<u8>)>> {
    std::fs::create_dir_all(scratch)?;
    let tag = format!("{}-{:?}", std::process::id(), std::thread::current().id())
        .replace(|c: char| !c.is_ascii_alphanumeric(), "");
    let tmp = |name: &str| scratch.join(format!(".rebuild-{tag}-{name}"));
    let mut out = Vec::new();
    let mut model: Vec<(&str, f64)> = Vec::new();
    for (name, codec, cell) in wanted {
        match codec {
            Codec::RebuildPly => {
                let (pts, q): (Vec<footscan_geom::P3>, Vec<f32>) =
                    grid.valid().map(|(_, _, p, l)| (*p, l.quality)).unzip();
                let p = tmp(name);
                crate::io::write_ply_points(&p, &pts, &q)?;
                let b = std::fs::read(&p);
                let _ = std::fs::remove_file(&p);
                out.push((name.to_string(), b?));
            }
            Codec::RebuildModel => model.push((name, cell.unwrap_or(0.5))),
            _ => {}
        }
    }
    if !model.is_empty() {
        let (net, build_ms) = crate::surface::build_scan_model(grid)
            .map_err(|e| std::io::Error::other(e.to_string()))?;
        // One model run writes the STL and the glb, each on its own cell.
        let stl = model.iter().find(|(n, _)| !n.ends_with(".glb"));
        let glb = model.iter().find(|(n, _)| n.ends_with(".glb"));
        let files = crate::cad::ModelFiles {
            stl: stl.map(|(n, _)| tmp(n)),
            ply: None,
            obj: None,
            step: None,
            iges: None,
            glb: glb.map(|(n, _)| tmp(n)),
            cell_mm: stl.map_or(0.5, |s| s.1),
            step_cell_mm: crate::cad::DEFAULT_STEP_CELL_MM,
            glb_cell_mm: glb.map_or(crate::cad::DEFAULT_GLB_CELL_MM, |g| g.1),
        };
        let r = crate::cad::write_foot_model(
            grid,
            &net,
            build_ms,
            &files,
            ["cell_mm", "step_cell_mm", "glb_cell_mm"],
        );
        let mut read = Vec::new();
        for (name, _) in stl.into_iter().chain(glb) {
            let p = tmp(name);
            read.push((name.to_string(), std::fs::read(&p)));
            let _ = std::fs::remove_file(&p);
        }
        r.map_err(|e| std::io::Error::other(format!("rebuilding the foot model: {e}")))?;
        for (name, b) in read {
            out.push((name, b?));
        }
    }
    Ok(out)
}

/// What [`compact_dir`] did to one scan directory.
#[derive(Clone, Debug, Default, Serialize)]
pub struct CompactReport {
    /// Original files now kept in compact form, by name, with how.
    pub files: BTreeMap<String, Codec>,
    /// Bytes of the directory's files before and after (lengths).
    pub bytes_before: u64,
    pub bytes_after: u64,
    /// Whether anything changed on disk.
    pub changed: bool,
    pub seconds: f64,
}

fn dir_bytes(dir: &Path) -> u64 {
    std::fs::read_dir(dir)
        .map(|rd| {
            rd.flatten()
                .filter_map(|e| e.metadata().ok())
                .filter(|m| m.is_file())
                .map(|m| m.len())
                .sum()
        })
        .unwrap_or(0)
}

/// Options of [`compact_dir`].
#[derive(Clone, Debug)]
pub struct CompactOptions {
    /// Compute and report, change nothing.
    pub dry_run: bool,
    /// Try rebuilding the rebuildable files (else they are stored as gzip).
    pub rebuild: bool,
    /// Test hook: stop (as a kill would) after writing this many stored forms in this call.
    pub stop_after_writes: Option<usize>,
}

impl Default for CompactOptions {
    fn default() -> Self {
        CompactOptions {
            dry_run: false,
            rebuild: true,
            stop_after_writes: None,
        }
    }
}

fn fsync_dir(dir: &Path) -> std::io::Result<()> {
    std::fs::File::open(dir)?.sync_all()
}

/// The cell a rebuilt model file is meshed on (None: not rebuilt from the model): what the
/// rebuild uses and the manifest records, so a later rebuild makes the same bytes.
fn rebuild_cell(name: &str, codec: Codec) -> Option<f64> {
    match (name, codec) {
        (ScanDir::MODEL_GLB, Codec::RebuildModel) => Some(crate::cad::DEFAULT_GLB_CELL_MM),
        (_, Codec::RebuildModel) => Some(0.5),
        _ => None,
    }
}

/// Put the scan directory `dir` into compact form, in place (module doc). Idempotent: a
/// directory already compact is left as it is, one half-done is finished, and an original
/// that differs from its manifest entry (rewritten since) is compacted anew. Scratch files
/// of rebuilds go into `dir`.
pub fn compact_dir(dir: &Path, opts: &CompactOptions) -> std::io::Result<CompactReport> {
    let t0 = std::time::Instant::now();
    let mut rep = CompactReport {
        bytes_before: dir_bytes(dir),
        ..Default::default()
    };
    let old = Manifest::load(dir)?.unwrap_or(Manifest {
        format: FORMAT,
        files: BTreeMap::new(),
    });
    let mut man = old.clone();
    // What an earlier compaction killed mid-write left: its own temporary files only (the
    // stored forms' and the manifest's, by write_atomic's `.NAME.tmpPID`, and rebuilds'), never
    // another writer's.
    if !opts.dry_run {
        let ours: Vec<String> = CANDIDATES
            .iter()
            .flat_map(|(n, c)| [stored_name(n, *c), stored_name(n, Codec::Gzip)])
            .chain([MANIFEST.to_string()])
            .map(|n| format!(".{n}.tmp"))
            .collect();
        for e in std::fs::read_dir(dir)?.flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with(".rebuild-") || ours.iter().any(|o| name.starts_with(o.as_str())) {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
    // The originals present, read once.
    let mut originals: Vec<(&str, Codec, Vec<u8>, String)> = Vec::new();
    for (name, codec) in CANDIDATES {
        match std::fs::read(dir.join(name)) {
            Ok(b) => {
                let sha = sha256_hex(&b);
                originals.push((name, codec, b, sha));
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
    }
    let stored_ok = |name: &str, sha: &str, len: u64| {
        old.files.get(name).is_some_and(|e| {
            e.sha256 == sha
                && e.bytes == len
                && e.stored
                    .as_ref()
                    .is_none_or(|s| dir.join(s).symlink_metadata().is_ok_and(|m| m.is_file()))
        })
    };
    let todo: Vec<&(&str, Codec, Vec<u8>, String)> = originals
        .iter()
        .filter(|(n, _, b, sha)| !stored_ok(n, sha, b.len() as u64))
        .collect();
    // Rebuilds, from the grid: the original grid.bin when it is here, else the stored one.
    let rebuildable: Vec<(&str, Codec, Option<f64>)> = todo
        .iter()
        .filter(|(_, c, _, _)| opts.rebuild && matches!(c, Codec::RebuildPly | Codec::RebuildModel))
        .map(|(n, c, _, _)| (*n, *c, rebuild_cell(n, *c)))
        .collect();
    let rebuilt: BTreeMap<String, Vec<u8>> = if rebuildable.is_empty() {
        BTreeMap::new()
    } else {
        let grid = match originals.iter().find(|o| o.0 == ScanDir::GRID) {
            Some((_, _, b, _)) => ScanGrid::parse(b, &dir.join(ScanDir::GRID)),
            None => ScanDir::new(dir).load_grid(),
        };
        match grid {
            // A scan without a readable grid keeps its files as gzip.
            Err(_) => BTreeMap::new(),
            Ok(g) => rebuild(&g, &rebuildable, dir)
                .map(|v| v.into_iter().collect())
                .unwrap_or_default(),
        }
    };
    let mut writes = 0usize;
    let (mut stored_bytes, mut moved_bytes) = (0u64, 0u64);
    for (name, codec, bytes, sha) in todo {
        moved_bytes += bytes.len() as u64;
        let rebuilt_same = rebuilt.get(*name).is_some_and(|b| b == bytes);
        let (codec, stored) = match codec {
            Codec::RebuildPly | Codec::RebuildModel if rebuilt_same => (*codec, None),
            Codec::RebuildPly | Codec::RebuildModel => {
                (Codec::Gzip, Some(stored_name(name, Codec::Gzip)))
            }
            Codec::GridShuffleGzip if grid_cells_at(bytes).is_some() => {
                (Codec::GridShuffleGzip, Some(stored_name(name, *codec)))
            }
            _ => (Codec::Gzip, Some(stored_name(name, Codec::Gzip))),
        };
        if let Some(s) = &stored {
            let data = match codec {
                Codec::GridShuffleGzip => gzip(&shuffle_grid(bytes).expect("checked"), GZIP_LEVEL),
                _ => gzip(bytes, GZIP_LEVEL),
            };
            stored_bytes += data.len() as u64;
            if !opts.dry_run {
                if opts.stop_after_writes.is_some_and(|n| writes >= n) {
                    return Err(std::io::Error::other("stopped by the test hook"));
                }
                footscan_util::write_atomic(&dir.join(s), &data)?;
                writes += 1;
            }
        }
        let cell_mm = rebuild_cell(name, codec);
        man.files.insert(
            name.to_string(),
            Entry {
                bytes: bytes.len() as u64,
                sha256: sha.clone(),
                codec,
                stored,
                cell_mm,
                made_by: Some(MADE_BY.to_string()),
                note: None,
            },
        );
    }
    for (name, e) in &man.files {
        rep.files.insert(name.clone(), e.codec);
    }
    if opts.dry_run {
        rep.bytes_after = rep.bytes_before + stored_bytes - moved_bytes;
        rep.changed = man != old;
        rep.seconds = t0.elapsed().as_secs_f64();
        return Ok(rep);
    }
    if man != old {
        man.save(dir)?;
        rep.changed = true;
    }
    // Every original the manifest now holds goes (a stored form or a rebuild gives it back).
    let mut removed = false;
    for (name, _, b, sha) in &originals {
        if man
            .files
            .get(*name)
            .is_some_and(|e| &e.sha256 == sha && e.bytes == b.len() as u64)
        {
            std::fs::remove_file(dir.join(name))?;
            removed = true;
        }
    }
    if removed {
        fsync_dir(dir)?;
        rep.changed = true;
    }
    rep.bytes_after = dir_bytes(dir);
    rep.seconds = t0.elapsed().as_secs_f64();
    Ok(rep)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compaction_keeps_every_byte_and_reruns_finish_it() {
        let d = tempfile::tempdir().unwrap();
        let dir = d.path();
        let step = b"ISO-10303-21; a step file".repeat(1000);
        std::fs::write(dir.join("model.step"), &step).unwrap();
        std::fs::write(dir.join("scan.json"), b"{}").unwrap();
        // Killed before its first write: nothing changed.
        let stop = CompactOptions {
            stop_after_writes: Some(0),
            ..Default::default()
        };
        assert!(compact_dir(dir, &stop).is_err());
        assert_eq!(std::fs::read(dir.join("model.step")).unwrap(), step);
        let r = compact_dir(dir, &CompactOptions::default()).unwrap();
        assert!(r.changed && r.bytes_after < r.bytes_before, "{r:?}");
        assert!(!dir.join("model.step").exists());
        let s = ScanDir::new(dir);
        assert_eq!(s.read_file("model.step").unwrap(), step);
        assert_eq!(s.read_file("scan.json").unwrap(), b"{}");
        let names: Vec<String> = listing(dir).unwrap().into_iter().map(|x| x.0).collect();
        assert_eq!(names, ["model.step", "scan.json"]);
        // A rerun changes nothing; an original written again is compacted anew.
        assert!(
            !compact_dir(dir, &CompactOptions::default())
                .unwrap()
                .changed
        );
        std::fs::write(dir.join("model.step"), b"new").unwrap();
        assert_eq!(s.read_file("model.step").unwrap(), b"new");
        compact_dir(dir, &CompactOptions::default()).unwrap();
        assert_eq!(s.read_file("model.step").unwrap(), b"new");
        // A damaged stored form is an error, never other bytes.
        std::fs::write(dir.join("model.step.gz"), gzip(b"old", 6)).unwrap();
        assert!(s.read_file("model.step").is_err());
    }
}
