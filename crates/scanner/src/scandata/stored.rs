//! The stored forms of a compacted scan directory (docs/method.md section 14h.2): the
//! manifest, the codecs and the decoding that needs nothing above the scan's data. Compaction
//! and the files rebuilt from the grid are [`crate::compact`]'s, a module above the models.
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

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::io::{Read, Write};

use super::ScanDir;
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
    /// The footscan that compacted the file: a rebuild is byte for byte the original only
    /// while the writers are that version's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub made_by: Option<String>,
    /// Why the bytes kept are not the original's as first written (a rebuild by a later
    /// footscan, stored when the grid it came from went).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
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
    (ScanDir::GRID, Codec::GridShuffleGzip),
    (ScanDir::POINTS, Codec::RebuildPly),
    (ScanDir::MODEL_STL, Codec::RebuildModel),
    (ScanDir::MODEL_GLB, Codec::RebuildModel),
    (ScanDir::MODEL_STEP, Codec::Gzip),
    (ScanDir::MODEL_PLY, Codec::Gzip),
    (ScanDir::MODEL_OBJ, Codec::Gzip),
    (ScanDir::MODEL_IGES, Codec::Gzip),
    (ScanDir::TRUTH, Codec::Gzip),
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
pub fn grid_cells_at(bytes: &[u8]) -> Option<usize> {
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

pub fn invalid(msg: String) -> std::io::Error {
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

    pub fn save(&self, dir: &Path) -> std::io::Result<()> {
        let json = serde_json::to_vec_pretty(self).expect("manifest serialises");
        footscan_util::write_atomic(&dir.join(MANIFEST), &json)
    }
}

/// Check `bytes` against `entry`; `what` names the file in the error.
pub fn verified(bytes: Vec<u8>, entry: &Entry, what: &Path) -> std::io::Result<Vec<u8>> {
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

/// The original bytes of `name` from its entry in the compacted scan at `dir` when its
/// stored form is decoded here: Some(bytes), checked against the manifest; None for a file
/// rebuilt from the grid ([`crate::compact::restore`] rebuilds it).
pub fn decode(dir: &Path, name: &str, entry: &Entry) -> std::io::Result<Option<Vec<u8>>> {
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
        (Codec::RebuildPly | Codec::RebuildModel, None) => return Ok(None),
        _ => {
            return Err(invalid(format!(
                "{}: manifest entry {:?} without its stored file",
                what.display(),
                entry.codec
            )))
        }
    };
    verified(bytes, entry, &what).map(Some)
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
}
