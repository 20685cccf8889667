//! The central view: list scans by clinic, scanner, subject, date and status; show one with
//! its files; fetch one into a scan directory that the last stages read like any other.

use crate::{sha256_hex, FleetError};
use postgres::Client;
use serde::Serialize;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Which scans to list; every field narrows the list (all empty: every scan).
#[derive(Clone, Debug, Default)]
pub struct Filter {
    pub clinic: Option<String>,
    pub scanner: Option<String>,
    pub subject: Option<String>,
    pub status: Option<String>,
    /// Started on or after (a date `YYYY-MM-DD` or an RFC 3339 time).
    pub since: Option<String>,
    /// Started before.
    pub until: Option<String>,
    pub limit: Option<i64>,
}

#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct ScanRow {
    pub scanner: String,
    pub scan_id: String,
    pub clinic: String,
    pub subject: String,
    pub side: String,
    pub status: String,
    pub reason: Option<String>,
    pub started: String,
    pub finished: Option<String>,
    pub frames: i64,
    pub points: i64,
    pub received: String,
    pub files: i64,
    pub bytes: i64,
}

#[derive(Clone, Debug, Serialize)]
pub struct StoredFile {
    pub name: String,
    pub sha256: String,
    pub bytes: i64,
    pub content_type: String,
}

#[derive(Clone, Debug, Serialize)]
pub struct ScanDetail {
    #[serde(flatten)]
    pub row: ScanRow,
    pub notes: String,
    pub calibration: Option<String>,
    pub measurements: Option<serde_json::Value>,
    pub summary: Option<serde_json::Value>,
    pub software: Option<String>,
    pub files_list: Vec<StoredFile>,
}

const ROW: &str = "s.scanner, s.scan_id, s.clinic, s.subject, s.side, s.status, s.reason,
    to_char(s.started AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS\"Z\"'),
    to_char(s.finished AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS\"Z\"'),
    s.frames, s.points,
    to_char(s.received AT TIME ZONE 'UTC', 'YYYY-MM-DD\"T\"HH24:MI:SS\"Z\"'),
    (SELECT count(*) FROM fleet_artifacts a WHERE a.scanner = s.scanner AND a.scan_id = s.scan_id),
    (SELECT coalesce(sum(a.bytes), 0)::bigint FROM fleet_artifacts a WHERE a.scanner = s.scanner AND a.scan_id = s.scan_id)";

fn row(r: &postgres::Row) -> ScanRow {
    ScanRow {
        scanner: r.get(0),
        scan_id: r.get(1),
        clinic: r.get(2),
        subject: r.get(3),
        side: r.get(4),
        status: r.get(5),
        reason: r.get(6),
        started: r.get(7),
        finished: r.get(8),
        frames: r.get(9),
        points: r.get(10),
        received: r.get(11),
        files: r.get(12),
        bytes: r.get(13),
    }
}

/// Scans matching `f`, oldest first.
pub fn list(client: &mut Client, f: &Filter) -> Result<Vec<ScanRow>, FleetError> {
    let rows = client.query(
        &format!(
            "SELECT {ROW} FROM fleet_scans s
             WHERE ($1::text IS NULL OR s.clinic = $1)
               AND ($2::text IS NULL OR s.scanner = $2)
               AND ($3::text IS NULL OR s.subject = $3)
               AND ($4::text IS NULL OR s.status = $4)
               AND ($5::text IS NULL OR s.started >= $5::text::timestamptz)
               AND ($6::text IS NULL OR s.started < $6::text::timestamptz)
             ORDER BY s.started, s.scanner, s.scan_id
             LIMIT $7"
        ),
        &[
            &f.clinic,
            &f.scanner,
            &f.subject,
            &f.status,
            &f.since,
            &f.until,
            &f.limit.unwrap_or(i64::MAX),
        ],
    )?;
    Ok(rows.iter().map(row).collect())
}

/// The scanner holding scan `scan_id` (given, or the only one that has it).
fn resolve_scanner(
    client: &mut Client,
    scanner: Option<&str>,
    scan_id: &str,
) -> Result<String, FleetError> {
    if let Some(s) = scanner {
        return Ok(s.to_string());
    }
    let rows = client.query(
        "SELECT scanner FROM fleet_scans WHERE scan_id = $1 ORDER BY scanner",
        &[&scan_id],
    )?;
    let names: Vec<String> = rows.iter().map(|r| r.get(0)).collect();
    match names.len() {
        0 => Err(FleetError::NotFound(format!(
            "scan {scan_id} is not in the fleet database"
        ))),
        1 => Ok(names.into_iter().next().unwrap()),
        _ => Err(FleetError::NotFound(format!(
            "scan {scan_id} is in the fleet database from several scanners ({}): name one with --scanner",
            names.join(", ")
        ))),
    }
}

/// One scan with its record and file list.
pub fn show(
    client: &mut Client,
    scanner: Option<&str>,
    scan_id: &str,
) -> Result<ScanDetail, FleetError> {
    let scanner = resolve_scanner(client, scanner, scan_id)?;
    let r = client
        .query_opt(
            &format!(
                "SELECT {ROW}, s.notes, s.calibration, s.measurements, s.summary, s.software
                 FROM fleet_scans s WHERE s.scanner = $1 AND s.scan_id = $2"
            ),
            &[&scanner, &scan_id],
        )?
        .ok_or_else(|| {
            FleetError::NotFound(format!(
                "scan {scan_id} of scanner {scanner} is not in the fleet database"
            ))
        })?;
    let files = client
        .query(
            "SELECT name, sha256, bytes, content_type FROM fleet_artifacts
             WHERE scanner = $1 AND scan_id = $2 ORDER BY name",
            &[&scanner, &scan_id],
        )?
        .iter()
        .map(|f| StoredFile {
            name: f.get(0),
            sha256: f.get(1),
            bytes: f.get(2),
            content_type: f.get(3),
        })
        .collect();
    let json = |i: usize| {
        r.get::<_, Option<postgres::types::Json<serde_json::Value>>>(i)
            .map(|j| j.0)
    };
    Ok(ScanDetail {
        row: row(&r),
        notes: r.get(14),
        calibration: r.get(15),
        measurements: json(16),
        summary: json(17),
        software: r.get(18),
        files_list: files,
    })
}

/// A plain file name (what the archive serves): no directory, no leading dot.
fn plain_name(n: &str) -> bool {
    !n.is_empty()
        && n.len() <= 64
        && !n.starts_with('.')
        && n.bytes()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, b'.' | b'_' | b'-'))
}

/// Write scan `scan_id`'s files into a new directory `out`, each checked against its sha256;
/// all or nothing (written in a temporary directory beside `out`, renamed into place).
/// Returns the files written.
pub fn fetch(
    client: &mut Client,
    scanner: Option<&str>,
    scan_id: &str,
    out: &Path,
) -> Result<Vec<PathBuf>, FleetError> {
    let io = |path: &Path| {
        let path = path.to_owned();
        move |source| FleetError::Io { path, source }
    };
    if out.symlink_metadata().is_ok() {
        return Err(FleetError::Io {
            path: out.to_owned(),
            source: std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                "already exists: fetch writes a new directory (remove it or choose another --out)",
            ),
        });
    }
    let scanner = resolve_scanner(client, scanner, scan_id)?;
    let rows = client.query(
        "SELECT a.name, a.sha256, b.content FROM fleet_artifacts a
         JOIN fleet_blobs b ON b.sha256 = a.sha256
         WHERE a.scanner = $1 AND a.scan_id = $2 ORDER BY a.name",
        &[&scanner, &scan_id],
    )?;
    if rows.is_empty() {
        return Err(FleetError::NotFound(format!(
            "scan {scan_id} of scanner {scanner} has no files in the fleet database (or is not there)"
        )));
    }
    let parent = out
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(io(parent))?;
    let leaf = out
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scan".into());
    let tmp = parent.join(format!(".{leaf}.fetch-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir(&tmp).map_err(io(&tmp))?;
    let result = (|| {
        let mut written = Vec::new();
        for r in &rows {
            let name: String = r.get(0);
            let sha: String = r.get(1);
            let content: Vec<u8> = r.get(2);
            if !plain_name(&name) {
                return Err(FleetError::Mismatch {
                    scan_id: scan_id.into(),
                    name: name.clone(),
                    detail: "not a plain file name: not written".into(),
                });
            }
            let got = sha256_hex(&content);
            if got != sha {
                return Err(FleetError::Mismatch {
                    scan_id: scan_id.into(),
                    name,
                    detail: format!("recorded sha256 {sha}, received bytes hash to {got}"),
                });
            }
            let p = tmp.join(&name);
            let mut f = std::fs::File::create(&p).map_err(io(&p))?;
            f.write_all(&content).map_err(io(&p))?;
            f.sync_all().map_err(io(&p))?;
            written.push(out.join(&name));
        }
        std::fs::File::open(&tmp)
            .and_then(|d| d.sync_all())
            .map_err(io(&tmp))?;
        std::fs::rename(&tmp, out).map_err(io(out))?;
        Ok(written)
    })();
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}
