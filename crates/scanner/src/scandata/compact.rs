//! The compact form of a scan directory (docs/method.md section 14h.2).
//!
//! A compacted scan keeps its small files as they are (record.json, scan.json,
//! measurements.json, the calibration, the pictures) and replaces each large file by a
//! stored form listed in `compact.json`, with the original's length and SHA-256:
//!
//! - `grid.bin` as `grid.bin.shuf.gz`: the cell records' 45 bytes regrouped by byte position
//!   (every cell's first byte, then every second byte, ...; the header and frame records
//!   unchanged) and then gzip. Lossless: the grid is what a re-analysis needs.
//! - `points.ply`, `model.stl`, `model.glb`: rebuilt from the grid on request, when a rebuild
//!   made at compaction time was byte-identical to the original; else stored as `NAME.gz`.
//! - `model.step` (it carries the time it was written, so no rebuild equals it), `truth.json`
//!   and the other model files: `NAME.gz`.
//!
//! A reader asks for the original name ([`ScanDir::read_file`]): the original when it is
//! there, else its stored form decoded (or rebuilt) and checked against the manifest's
//! SHA-256, so the bytes are the original's or an error. Compaction ([`compact_dir`]) writes
//! every stored form (fsynced, renamed into place), then the manifest (atomically), and only
//! then removes the originals, so at every instant each file is readable from its original,
//! its stored form, or both: a compaction killed at any point loses nothing and a rerun
//! finishes it.

use super::{ScanDir, ScanGrid};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

/// The manifest of a compacted scan directory.
pub const MANIFEST: &str = "compact.json";
/// The manifest's format.
pub const FORMAT: u32 = 1;
/// gzip level of the stored forms (docs/method.md 14h.2 gives the figures of the levels).
pub const GZIP_LEVEL: u32 = 6;
/// The cell record of grid.bin (docs/grid-bin.md).
const CELL: usize = 45;

/// How a file of a compacted scan is kept.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Codec {
    /// gzip of the original bytes (`gunzip` gives the file back).
    Gzip,
    /// grid.bin with its cell records' bytes regrouped by position, then gzip.
    GridShuffleGzip,
    /// Rebuilt from the grid by the point-cloud sink (`write_ply_points`).
    RebuildPly,
    /// Rebuilt from the grid by the foot model (`cad::write_foot_model`) on `cell_mm` cells.
    RebuildModel,
}

/// One original file of a compacted scan.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Entry {
    /// The original's length and SHA-256 (lower-case hex).
    pub bytes: u64,
    pub sha256: String,
    pub codec: Codec,
    /// The stored file beside the manifest (none for a rebuilt one).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stored: Option<String>,
    /// The model's cell (mm) of a [`Codec::RebuildModel`] file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cell_mm: Option<f64>,
}

/// `compact.json`: original name to entry.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
pub struct Manifest {
    pub format: u32,
    pub files: BTreeMap<String, Entry>,
}

/// The large files compaction handles, in the order it handles them, and how each is kept.
/// Every other file stays as it is.
pub const CANDIDATES: [(&str, Codec); 9] = [
    (super::ScanDir::GRID, Codec::GridShuffleGzip),
    (super::ScanDir::POINTS, Codec::RebuildPly),
    ("model.stl", Codec::RebuildModel),
    ("model.glb", Codec::RebuildModel),
    ("model.step", Codec::Gzip),
    ("model.ply", Codec::Gzip),
    ("model.obj", Codec::Gzip),
    ("model.igs", Codec::Gzip),
    (super::ScanDir::TRUTH, Codec::Gzip),
];

/// Whether `name` is a file of the compact form itself (the manifest or a stored form),
/// which a scan's list of files leaves out.
pub fn is_compact_file(name: &str) -> bool {
    name == MANIFEST
        || CANDIDATES
            .iter()
            .any(|(n, c)| name == stored_name(n, *c) || name == stored_name(n, Codec::Gzip))
}

/// The stored file's name of `name` kept with `codec` (rebuilt ones have none: the gzip
/// name, used when the rebuild was refused).
pub fn stored_name(name: &str, codec: Codec) -> String {
    match codec {
        Codec::GridShuffleGzip => format!("{name}.shuf.gz"),
        _ => format!("{name}.gz"),
    }
}

pub fn sha256_hex(bytes: &[u8]) -> String {
    let d = Sha256::digest(bytes);
    let mut s = String::with_capacity(64);
    for b in d {
        s.push_str(&format!("{b:02x}"));
    }
    s
}

/// The byte offset where grid.bin's cell records begin, when `bytes` is a whole grid.bin.
fn grid_cells_at(bytes: &[u8]) -> Option<usize> {
    if bytes.len() < 16 || &bytes[..8] != b"FSGRID01" {
        return None;
    }
    let nf = u32::from_le_bytes(bytes[8..12].try_into().ok()?) as usize;
    let rows = u32::from_le_bytes(bytes[12..16].try_into().ok()?) as usize;
    let at = 16usize.checked_add(nf.checked_mul(32)?)?;
    let cells = nf.checked_mul(rows)?.checked_mul(CELL)?;
    (at.checked_add(cells)? == bytes.len()).then_some(at)
}

/// grid.bin with its cell records regrouped by byte position (None: not a whole grid.bin).
pub fn shuffle_grid(bytes: &[u8]) -> Option<Vec<u8>> {
    let at = grid_cells_at(bytes)?;
    let cells = &bytes[at..];
    let n = cells.len() / CELL;
    let mut out = Vec::with_capacity(bytes.len());
    out.extend_from_slice(&bytes[..at]);
    out.resize(bytes.len(), 0);
    let body = &mut out[at..];
    for (i, rec) in cells.chunks_exact(CELL).enumerate() {
        for (k, b) in rec.iter().enumerate() {
            body[k * n + i] = *b;
        }
    }
    Some(out)
}

/// The inverse of [`shuffle_grid`] (the header says how many cells there are).
pub fn unshuffle_grid(bytes: &[u8]) -> Option<Vec<u8>> {
    let at = grid_cells_at(bytes)?;
    let body = &bytes[at..];
    let n = body.len() / CELL;
    let mut out = Vec::with_capacity(bytes.len());
    out.extend_from_slice(&bytes[..at]);
    out.resize(bytes.len(), 0);
    let cells = &mut out[at..];
    for (k, plane) in body.chunks_exact(n.max(1)).enumerate().take(CELL) {
        for (i, b) in plane.iter().enumerate() {
            cells[i * CELL + k] = *b;
        }
    }
    Some(out)
}

pub fn gzip(bytes: &[u8], level: u32) -> Vec<u8> {
    let mut e = flate2::write::GzEncoder::new(
        Vec::with_capacity(bytes.len() / 3),
        flate2::Compression::new(level),
    );
    e.write_all(bytes).expect("writing into a Vec");
    e.finish().expect("writing into a Vec")
}

/// gunzip, refusing more than `max` bytes out (a stored form never holds more than its
/// original's length).
pub fn gunzip(bytes: &[u8], max: u64) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::with_capacity(max.min(1 << 30) as usize);
    flate2::read::GzDecoder::new(bytes)
        .take(max + 1)
        .read_to_end(&mut out)?;
    Ok(out)
}

fn invalid(msg: String) -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::InvalidData, msg)
}

impl Manifest {
    pub fn load(dir: &Path) -> std::io::Result<Option<Manifest>> {
        let p = dir.join(MANIFEST);
        let text = match std::fs::read(&p) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(e),
        };
        let m: Manifest = serde_json::from_slice(&text)
            .map_err(|e| invalid(format!("{}: not a compact-scan manifest: {e}", p.display())))?;
        if m.format != FORMAT {
            return Err(invalid(format!(
                "{}: format {} (this footscan reads {FORMAT})",
                p.display(),
                m.format
            )));
        }
        Ok(Some(m))
    }

    fn save(&self, dir: &Path) -> std::io::Result<()> {
        let json = serde_json::to_vec_pretty(self).expect("manifest serialises");
        footscan_util::write_atomic(&dir.join(MANIFEST), &json)
    }
}

/// Check `bytes` against `entry`; `what` names the file in the error.
fn verified(bytes: Vec<u8>, entry: &Entry, what: &Path) -> std::io::Result<Vec<u8>> {
    if bytes.len() as u64 != entry.bytes || sha256_hex(&bytes) != entry.sha256 {
        return Err(invalid(format!(
            "{}: the compact form gives {} bytes that do not match the manifest's {} bytes \
             and SHA-256 {}",
            what.display(),
            bytes.len(),
            entry.bytes,
            entry.sha256
        )));
    }
    Ok(bytes)
}

/// The original bytes of `name` from its entry in the compacted scan at `dir`: the stored
/// form decoded, or the file rebuilt from the grid (scratch files in `scratch`), checked
/// against the manifest.
pub fn restore(dir: &Path, name: &str, entry: &Entry, scratch: &Path) -> std::io::Result<Vec<u8>> {
    let what = dir.join(name);
    let bytes = match (entry.codec, &entry.stored) {
        (Codec::Gzip, Some(s)) => gunzip(&std::fs::read(dir.join(s))?, entry.bytes)?,
        (Codec::GridShuffleGzip, Some(s)) => {
            let sh = gunzip(&std::fs::read(dir.join(s))?, entry.bytes)?;
            unshuffle_grid(&sh).ok_or_else(|| {
                invalid(format!(
                    "{}: not a shuffled grid.bin",
                    dir.join(s).display()
                ))
            })?
        }
        (Codec::RebuildPly | Codec::RebuildModel, None) => {
            let grid = ScanDir::new(dir).load_grid()?;
            let mut out = rebuild(&grid, &[(name, entry.codec, entry.cell_mm)], scratch)?;
            out.pop().map(|(_, b)| b).unwrap_or_default()
        }
        _ => {
            return Err(invalid(format!(
                "{}: manifest entry {:?} without its stored file",
                what.display(),
                entry.codec
            )))
        }
    };
    verified(bytes, entry, &what)
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
                let (pts, q): (Vec<[f64; 3]>, Vec<f32>) =
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
        .map(|(n, c, _, _)| {
            let cell = match (*n, c) {
                ("model.glb", _) => Some(crate::cad::DEFAULT_GLB_CELL_MM),
                (_, Codec::RebuildModel) => Some(0.5),
                _ => None,
            };
            (*n, *c, cell)
        })
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
        let cell_mm = match (*name, codec) {
            ("model.glb", Codec::RebuildModel) => Some(crate::cad::DEFAULT_GLB_CELL_MM),
            (_, Codec::RebuildModel) => Some(0.5),
            _ => None,
        };
        man.files.insert(
            name.to_string(),
            Entry {
                bytes: bytes.len() as u64,
                sha256: sha.clone(),
                codec,
                stored,
                cell_mm,
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

/// The paths of a scan directory's original files and their lengths as a reader sees them:
/// the real files (less the compact form's own) and the manifest's entries not present.
pub fn listing(dir: &Path) -> std::io::Result<Vec<(String, u64, Option<PathBuf>)>> {
    let man = Manifest::load(dir)?;
    let mut out: BTreeMap<String, (u64, Option<PathBuf>)> = BTreeMap::new();
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let name = e.file_name().to_string_lossy().into_owned();
        // The compact form's own files are never listed, with a manifest or without (a
        // stored form written by a compaction killed before its manifest); nor are hidden
        // (temporary) files.
        if !e.file_type()?.is_file() || is_compact_file(&name) || name.starts_with('.') {
            continue;
        }
        out.insert(name, (e.metadata()?.len(), Some(e.path())));
    }
    if let Some(m) = man {
        for (name, e) in m.files {
            out.entry(name).or_insert((e.bytes, None));
        }
    }
    Ok(out.into_iter().map(|(n, (b, p))| (n, b, p)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shuffle_round_trips_and_refuses_other_files() {
        let mut g = b"FSGRID01".to_vec();
        g.extend_from_slice(&2u32.to_le_bytes());
        g.extend_from_slice(&3u32.to_le_bytes());
        g.extend((0..(2 * 32 + 6 * CELL)).map(|i| (i * 7 % 251) as u8));
        let s = shuffle_grid(&g).unwrap();
        assert_ne!(s, g);
        assert_eq!(unshuffle_grid(&s).unwrap(), g);
        assert!(shuffle_grid(&g[..g.len() - 1]).is_none());
        assert_eq!(gunzip(&gzip(&g, 6), g.len() as u64).unwrap(), g);
    }

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
