//! The SQLite index of the archive: one row per scan, a cache of the scan directories'
//! record.json files (the directories are the truth; [`super::Archive::rebuild`] recreates it).

use super::query::{id_clauses, prefix_end, ScanQuery, VisitQuery};
use super::record::{ArchiveError, Record, Status};
use super::visits::Visit;
use rusqlite::{params, params_from_iter, Connection, OptionalExtension};
use std::path::Path;

pub struct Index {
    conn: Connection,
}

const SCHEMA: &str = "CREATE TABLE IF NOT EXISTS scans (
    id TEXT PRIMARY KEY NOT NULL,
    subject TEXT NOT NULL,
    side TEXT NOT NULL,
    notes TEXT NOT NULL,
    status TEXT NOT NULL,
    reason TEXT,
    started TEXT NOT NULL,
    finished TEXT,
    frames INTEGER NOT NULL,
    points INTEGER NOT NULL,
    calibration TEXT
)";

/// The indexes of the paged list (archive/query.rs): each filter a range of one index, ids
/// second so the newest-first order and the cursor come from the same index.
const SCAN_INDEXES: &str = "
CREATE INDEX IF NOT EXISTS scans_subject ON scans (subject COLLATE NOCASE, id);
CREATE INDEX IF NOT EXISTS scans_status ON scans (status, id);
CREATE INDEX IF NOT EXISTS scans_side ON scans (side, id);
";

/// The visits, a cache of the visit files (archive/visits.rs: the files are the truth) for
/// the paged list; `stamp` is the file's length and modification time when it was read, so
/// opening the archive rereads only the files changed behind the daemon's back.
const VISITS_SCHEMA: &str = "CREATE TABLE IF NOT EXISTS visits (
    id TEXT PRIMARY KEY NOT NULL,
    patient TEXT NOT NULL,
    json TEXT NOT NULL,
    stamp TEXT NOT NULL,
    left_scan TEXT,
    right_scan TEXT
)";

/// The visit columns, checked at open: a visits table of another shape is only a cache,
/// dropped and refilled from the files.
const VISIT_COLUMNS: &str = "id, patient, json, stamp, left_scan, right_scan";

const COLUMNS: &str =
    "id, subject, side, notes, status, reason, started, finished, frames, points, calibration";

/// Why the index could not be opened: damaged (move it aside and rebuild), or anything else
/// (a permission, a full disk: not repaired by rebuilding).
pub enum OpenError {
    Corrupt(String),
    Other(ArchiveError),
}

impl OpenError {
    pub fn into_archive(self) -> ArchiveError {
        match self {
            OpenError::Other(e) => e,
            OpenError::Corrupt(why) => ArchiveError::Io {
                path: "index".into(),
                source: std::io::Error::other(why),
            },
        }
    }
}

/// Whether SQLite says the file is damaged or is not a database at all.
pub fn is_corrupt(e: &rusqlite::Error) -> bool {
    matches!(
        e.sqlite_error_code(),
        Some(rusqlite::ErrorCode::DatabaseCorrupt | rusqlite::ErrorCode::NotADatabase)
    )
}

impl Index {
    /// Open the index, checking its integrity (a quick check: cheap for a few thousand rows).
    pub fn open(path: &Path) -> Result<Index, OpenError> {
        let classify = |e: rusqlite::Error| {
            if is_corrupt(&e) {
                OpenError::Corrupt(e.to_string())
            } else {
                OpenError::Other(ArchiveError::Index {
                    path: path.to_owned(),
                    source: e,
                })
            }
        };
        let conn = Connection::open(path).map_err(classify)?;
        // Rollback journal (no WAL): the index lives beside the scans, and a full disk must
        // not leave a growing side file; FULL sync because the index is updated rarely.
        conn.execute_batch("PRAGMA journal_mode=DELETE; PRAGMA synchronous=FULL;")
            .map_err(classify)?;
        let check: String = conn
            .query_row("PRAGMA quick_check", [], |r| r.get(0))
            .map_err(classify)?;
        if check != "ok" {
            return Err(OpenError::Corrupt(format!("integrity check: {check}")));
        }
        conn.execute(SCHEMA, []).map_err(classify)?;
        // An index made before scans recorded their calibration lacks the column.
        let has_cal = conn
            .prepare("SELECT calibration FROM scans LIMIT 0")
            .is_ok();
        if !has_cal {
            conn.execute("ALTER TABLE scans ADD COLUMN calibration TEXT", [])
                .map_err(classify)?;
        }
        // The record.json each row was read from (its length and modification time), so
        // a start rereads only the records changed since (an index before pages lacks it:
        // every record is read once more).
        if conn.prepare("SELECT stamp FROM scans LIMIT 0").is_err() {
            conn.execute("ALTER TABLE scans ADD COLUMN stamp TEXT", [])
                .map_err(classify)?;
        }
        // A table of another shape (not ours) is as good as damaged.
        conn.prepare(&format!("SELECT {COLUMNS} FROM scans LIMIT 0"))
            .map_err(|e| OpenError::Corrupt(format!("not the scan index: {e}")))?;
        conn.execute_batch(SCAN_INDEXES).map_err(classify)?;
        conn.execute(VISITS_SCHEMA, []).map_err(classify)?;
        if conn
            .prepare(&format!("SELECT {VISIT_COLUMNS} FROM visits LIMIT 0"))
            .is_err()
        {
            conn.execute_batch(&format!("DROP TABLE visits; {VISITS_SCHEMA};"))
                .map_err(classify)?;
        }
        conn.execute_batch(
            "CREATE INDEX IF NOT EXISTS visits_id_patient ON visits (id, patient);
             CREATE INDEX IF NOT EXISTS visits_left ON visits (left_scan);
             CREATE INDEX IF NOT EXISTS visits_right ON visits (right_scan);",
        )
        .map_err(classify)?;
        Ok(Index { conn })
    }

    /// The connection, for the other tables of the index file (archive/outbox.rs).
    pub(super) fn conn(&self) -> &Connection {
        &self.conn
    }

    /// The running scan's counts so far (recovery keeps them if the scan never ends).
    pub fn note_progress(&self, id: &str, frames: u64, points: u64) -> rusqlite::Result<()> {
        self.conn.execute(
            "UPDATE scans SET frames = ?1, points = ?2 WHERE id = ?3 AND status = 'running'",
            params![frames as i64, points as i64, id],
        )?;
        Ok(())
    }

    pub fn delete(&self, id: &str) -> rusqlite::Result<()> {
        self.conn.execute("DELETE FROM scans WHERE id = ?1", [id])?;
        Ok(())
    }

    /// Write `r`, read from (or just written as) a record.json stamped `stamp` (None: a
    /// running scan, or a record not on disk).
    pub fn upsert(&self, r: &Record, stamp: Option<&str>) -> rusqlite::Result<()> {
        insert(&self.conn, r, stamp)
    }

    /// Every row's (id, status, stamp): what opening the archive compares the directories
    /// to.
    pub fn scan_stamps(&self) -> rusqlite::Result<Vec<(String, String, Option<String>)>> {
        let mut st = self.conn.prepare("SELECT id, status, stamp FROM scans")?;
        let rows = st.query_map([], |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)))?;
        rows.collect()
    }

    /// Apply the scans' changes found at open in one transaction.
    pub fn sync_scans(
        &mut self,
        upserts: &[(Record, String)],
        gone: &[String],
    ) -> rusqlite::Result<()> {
        let tx = self.conn.transaction()?;
        for id in gone {
            tx.execute("DELETE FROM scans WHERE id = ?1", [id])?;
        }
        for (r, stamp) in upserts {
            insert(&tx, r, Some(stamp))?;
        }
        tx.commit()
    }

    pub fn list(&self) -> rusqlite::Result<Vec<Record>> {
        let mut st = self
            .conn
            .prepare(&format!("SELECT {COLUMNS} FROM scans ORDER BY id DESC"))?;
        let rows = st.query_map([], row)?;
        rows.collect()
    }

    /// The scans `q` asks for, newest first: at most `q.limit + 1` rows (the extra one says
    /// another page follows).
    pub fn page(&self, q: &ScanQuery) -> rusqlite::Result<Vec<Record>> {
        let mut sql = Vec::new();
        let mut p: Vec<String> = Vec::new();
        if let Some(s) = &q.subject {
            p.push(s.clone());
            p.push(prefix_end(s));
            sql.push(format!(
                "subject >= ?{} COLLATE NOCASE AND subject < ?{} COLLATE NOCASE",
                p.len() - 1,
                p.len()
            ));
        }
        if let Some(s) = q.status {
            p.push(s.as_str().to_string());
            sql.push(format!("status = ?{}", p.len()));
        }
        if let Some(s) = &q.side {
            p.push(s.clone());
            sql.push(format!("side = ?{}", p.len()));
        }
        id_clauses(&q.since, &q.until, &q.before, &mut sql, &mut p);
        let mut text = format!("SELECT {COLUMNS} FROM scans");
        if !sql.is_empty() {
            text += &format!(" WHERE {}", sql.join(" AND "));
        }
        text += " ORDER BY id DESC";
        if let Some(l) = q.limit {
            text += &format!(" LIMIT {}", l + 1);
        }
        let mut st = self.conn.prepare_cached(&text)?;
        let rows = st.query_map(params_from_iter(p.iter()), row)?;
        rows.collect()
    }

    /// The visits `q` asks for, newest first (at most `q.limit + 1`, as [`Self::page`]).
    pub fn visit_page(&self, q: &VisitQuery) -> rusqlite::Result<Vec<Visit>> {
        let mut sql = Vec::new();
        let mut p: Vec<String> = Vec::new();
        if let Some(s) = &q.subject {
            // A part of the id: no index orders by it, so the (id, patient) index is walked
            // newest first, stopping at the page's end.
            p.push(s.to_lowercase());
            sql.push(format!("instr(lower(patient), ?{}) > 0", p.len()));
        }
        id_clauses(&q.since, &q.until, &q.before, &mut sql, &mut p);
        // The ids from the (id, patient) index alone, then the rows of those only: walking
        // the table in id order fetched every row to test its patient (80 ms at p99 for a
        // search of 20,000 visits; docs/method.md).
        let searched = q.subject.is_some();
        let mut text = if searched {
            "SELECT id FROM visits INDEXED BY visits_id_patient"
        } else {
            "SELECT json FROM visits"
        }
        .to_string();
        if !sql.is_empty() {
            text += &format!(" WHERE {}", sql.join(" AND "));
        }
        text += " ORDER BY id DESC";
        if let Some(l) = q.limit {
            text += &format!(" LIMIT {}", l + 1);
        }
        if searched {
            text = format!("SELECT json FROM visits WHERE id IN ({text}) ORDER BY id DESC");
        }
        let mut st = self.conn.prepare_cached(&text)?;
        let rows = st.query_map(params_from_iter(p.iter()), |r| r.get::<_, String>(0))?;
        rows.map(|j| visit_of(&j?)).collect()
    }

    /// The visits' stamps by id (what [`super::Archive::sync_visits`] compares the files to).
    pub fn visit_stamps(&self) -> rusqlite::Result<Vec<(String, String)>> {
        let mut st = self.conn.prepare("SELECT id, stamp FROM visits")?;
        let rows = st.query_map([], |r| Ok((r.get(0)?, r.get(1)?)))?;
        rows.collect()
    }

    pub fn upsert_visit(&self, v: &Visit, stamp: &str) -> rusqlite::Result<()> {
        insert_visit(&self.conn, v, stamp)
    }

    /// The visits holding scan `scan` in either slot, newest first.
    pub fn visits_holding(&self, scan: &str) -> rusqlite::Result<Vec<Visit>> {
        let mut st = self.conn.prepare_cached(
            "SELECT json FROM visits WHERE left_scan = ?1 OR right_scan = ?1 ORDER BY id DESC",
        )?;
        let rows = st.query_map([scan], |r| r.get::<_, String>(0))?;
        rows.map(|j| visit_of(&j?)).collect()
    }

    pub fn delete_visit(&self, id: &str) -> rusqlite::Result<()> {
        self.conn
            .execute("DELETE FROM visits WHERE id = ?1", [id])?;
        Ok(())
    }

    /// Apply the visits' changes found at open in one transaction.
    pub fn sync_visits(
        &mut self,
        upserts: &[(Visit, String)],
        gone: &[String],
    ) -> rusqlite::Result<()> {
        let tx = self.conn.transaction()?;
        for id in gone {
            tx.execute("DELETE FROM visits WHERE id = ?1", [id])?;
        }
        for (v, stamp) in upserts {
            insert_visit(&tx, v, stamp)?;
        }
        tx.commit()
    }

    pub fn get(&self, id: &str) -> rusqlite::Result<Option<Record>> {
        self.conn
            .query_row(
                &format!("SELECT {COLUMNS} FROM scans WHERE id = ?1"),
                [id],
                row,
            )
            .optional()
    }

    /// Replace every row by `records` (with their record.json stamps) in one transaction.
    pub fn replace_all(&mut self, records: &[(Record, Option<String>)]) -> rusqlite::Result<()> {
        let tx = self.conn.transaction()?;
        tx.execute("DELETE FROM scans", [])?;
        for (r, stamp) in records {
            insert(&tx, r, stamp.as_deref())?;
        }
        tx.commit()
    }
}

fn insert(conn: &Connection, r: &Record, stamp: Option<&str>) -> rusqlite::Result<()> {
    conn.prepare_cached(
        &format!("INSERT OR REPLACE INTO scans ({COLUMNS}, stamp) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12)"),
    )?
    .execute(
        params![
            r.id,
            r.subject,
            r.side,
            r.notes,
            r.status.as_str(),
            r.reason,
            r.started,
            r.finished,
            r.frames as i64,
            r.points as i64,
            r.calibration,
            stamp
        ],
    )?;
    Ok(())
}

fn insert_visit(conn: &Connection, v: &Visit, stamp: &str) -> rusqlite::Result<()> {
    let json = serde_json::to_string(v).expect("visit serialises");
    conn.prepare_cached(&format!(
        "INSERT OR REPLACE INTO visits ({VISIT_COLUMNS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6)"
    ))?
    .execute(params![v.id, v.patient, json, stamp, v.left, v.right])?;
    Ok(())
}

/// A visit from its JSON column (written by [`insert_visit`]).
fn visit_of(json: &str) -> rusqlite::Result<Visit> {
    serde_json::from_str(json).map_err(|e| {
        rusqlite::Error::FromSqlConversionFailure(0, rusqlite::types::Type::Text, Box::new(e))
    })
}

fn row(r: &rusqlite::Row<'_>) -> rusqlite::Result<Record> {
    let status: String = r.get(4)?;
    Ok(Record {
        id: r.get(0)?,
        subject: r.get(1)?,
        side: r.get(2)?,
        notes: r.get(3)?,
        status: Status::parse(&status).unwrap_or(Status::Failed),
        reason: r.get(5)?,
        started: r.get(6)?,
        finished: r.get(7)?,
        frames: r.get::<_, i64>(8)? as u64,
        points: r.get::<_, i64>(9)? as u64,
        calibration: r.get(10)?,
    })
}
