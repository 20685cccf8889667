//! Pushing one scan: its record and its files, in one transaction, idempotent.
//!
//! The files are read once into memory and hashed there, so the bytes hashed are the bytes
//! sent. Blobs the database lacks are inserted (`ON CONFLICT DO NOTHING`, in hash order so
//! that two pushers sharing a blob cannot deadlock), the database checking each hash itself;
//! the scan row and its artifact rows likewise. Before committing, the stored list of
//! (name, sha256, bytes) is read back and compared with what was sent: equal means the scan
//! is there exactly as in the archive, whether this push or an earlier one put it there.

use crate::{migrate::SOFTWARE, sha256_hex, FleetError};
use footscan_util::scan_files;
use postgres::Client;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// A file of the scan directory to push.
#[derive(Clone, Debug)]
pub struct LocalFile {
    pub name: String,
    pub path: PathBuf,
    pub content_type: String,
}

/// One scan as the archive holds it.
#[derive(Clone, Debug)]
pub struct ScanUpload {
    pub scanner: String,
    pub clinic: String,
    pub scan_id: String,
    pub subject: String,
    pub side: String,
    pub notes: String,
    pub status: String,
    pub reason: Option<String>,
    /// RFC 3339.
    pub started: String,
    pub finished: Option<String>,
    pub frames: u64,
    pub points: u64,
    /// The archive's record.json as JSON.
    pub record: serde_json::Value,
    pub files: Vec<LocalFile>,
}

/// What a push did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PushOutcome {
    /// The scan row was new (false: it was there already, identical).
    pub inserted: bool,
    /// Blobs sent (the others were in the database already).
    pub blobs_sent: usize,
    pub bytes_sent: u64,
    pub files: usize,
}

/// Push `scan`, once: a second push of the same scan changes nothing and succeeds.
pub fn push(client: &mut Client, scan: &ScanUpload) -> Result<PushOutcome, FleetError> {
    // Read and hash every file first: nothing is sent for a scan whose files are unreadable.
    let mut files: BTreeMap<String, (String, Vec<u8>, String)> = BTreeMap::new();
    for f in &scan.files {
        let bytes = std::fs::read(&f.path).map_err(|source| FleetError::Io {
            path: f.path.clone(),
            source,
        })?;
        files.insert(
            f.name.clone(),
            (sha256_hex(&bytes), bytes, f.content_type.clone()),
        );
    }
    let text_of = |name: &str| {
        files
            .get(name)
            .and_then(|(_, b, _)| std::str::from_utf8(b).ok().map(str::to_string))
    };
    let json_of = |name: &str| {
        files
            .get(name)
            .and_then(|(_, b, _)| serde_json::from_slice::<serde_json::Value>(b).ok())
    };
    let calibration = text_of(scan_files::CALIBRATION);
    let measurements = json_of(scan_files::MEASUREMENTS);
    let summary = json_of(scan_files::SUMMARY);

    let mut out = PushOutcome {
        files: files.len(),
        ..PushOutcome::default()
    };
    let mut tx = client.transaction()?;
    // Blobs, by hash (sorted, unique).
    let mut by_hash: BTreeMap<&str, &[u8]> = BTreeMap::new();
    for (h, b, _) in files.values() {
        by_hash.insert(h.as_str(), b.as_slice());
    }
    let hashes: Vec<&str> = by_hash.keys().copied().collect();
    let present: std::collections::HashSet<String> = tx
        .query(
            "SELECT sha256 FROM fleet_blobs WHERE sha256 = ANY($1)",
            &[&hashes],
        )?
        .iter()
        .map(|r| r.get(0))
        .collect();
    let insert_blob = tx.prepare(
        "INSERT INTO fleet_blobs (sha256, bytes, content) VALUES ($1, $2, $3) ON CONFLICT (sha256) DO NOTHING",
    )?;
    for (h, b) in &by_hash {
        if present.contains(*h) {
            continue;
        }
        tx.execute(&insert_blob, &[h, &(b.len() as i64), b])?;
        out.blobs_sent += 1;
        out.bytes_sent += b.len() as u64;
    }
    let n = tx.execute(
        "INSERT INTO fleet_scans (scanner, scan_id, clinic, subject, side, notes, status, reason,
             started, finished, frames, points, calibration, measurements, summary, record, software)
         VALUES ($1, $2, $3, $4, $5, $6, $7, $8, $9::text::timestamptz, $10::text::timestamptz,
             $11, $12, $13, $14, $15, $16, $17)
         ON CONFLICT (scanner, scan_id) DO NOTHING",
        &[
            &scan.scanner,
            &scan.scan_id,
            &scan.clinic,
            &scan.subject,
            &scan.side,
            &scan.notes,
            &scan.status,
            &scan.reason,
            &scan.started,
            &scan.finished,
            &(scan.frames as i64),
            &(scan.points as i64),
            &calibration,
            &measurements.map(postgres::types::Json),
            &summary.map(postgres::types::Json),
            &postgres::types::Json(&scan.record),
            &SOFTWARE,
        ],
    )?;
    out.inserted = n == 1;
    if out.inserted {
        let insert_art = tx.prepare(
            "INSERT INTO fleet_artifacts (scanner, scan_id, name, sha256, bytes, content_type)
             VALUES ($1, $2, $3, $4, $5, $6) ON CONFLICT DO NOTHING",
        )?;
        for (name, (h, b, ct)) in &files {
            tx.execute(
                &insert_art,
                &[&scan.scanner, &scan.scan_id, name, h, &(b.len() as i64), ct],
            )?;
        }
    }
    // What the database holds for this scan now, against what was sent.
    let stored: BTreeMap<String, (String, i64, i64)> = tx
        .query(
            "SELECT a.name, a.sha256, a.bytes, b.bytes FROM fleet_artifacts a
             JOIN fleet_blobs b ON b.sha256 = a.sha256
             WHERE a.scanner = $1 AND a.scan_id = $2",
            &[&scan.scanner, &scan.scan_id],
        )?
        .iter()
        .map(|r| (r.get(0), (r.get(1), r.get(2), r.get(3))))
        .collect();
    let sent: BTreeMap<String, (String, i64, i64)> = files
        .iter()
        .map(|(n, (h, b, _))| (n.clone(), (h.clone(), b.len() as i64, b.len() as i64)))
        .collect();
    if stored != sent {
        let detail = describe_difference(&sent, &stored);
        if out.inserted {
            // Cannot happen short of a bug or a tampering trigger: never commit it.
            return Err(FleetError::Mismatch {
                scan_id: scan.scan_id.clone(),
                name: detail.0,
                detail: detail.1,
            });
        }
        return Err(FleetError::Conflict {
            scanner: scan.scanner.clone(),
            scan_id: scan.scan_id.clone(),
            detail: format!("{}: {}", detail.0, detail.1),
        });
    }
    tx.commit()?;
    Ok(out)
}

type Listing = BTreeMap<String, (String, i64, i64)>;

/// The first file that differs between the two listings, and how.
fn describe_difference(sent: &Listing, stored: &Listing) -> (String, String) {
    for (n, s) in sent {
        match stored.get(n) {
            None => return (n.clone(), "sent but not stored".into()),
            Some(d) if d != s => {
                return (
                    n.clone(),
                    format!(
                        "sent sha256 {} ({} bytes), stored {} ({} bytes)",
                        s.0, s.1, d.0, d.2
                    ),
                )
            }
            _ => {}
        }
    }
    for n in stored.keys() {
        if !sent.contains_key(n) {
            return (n.clone(), "stored but not in the archive".into());
        }
    }
    ("?".into(), "listings differ".into())
}
