//! The SQLite index of the archive: one row per scan, a cache of the scan directories'
//! record.json files (the directories are the truth; [`super::Archive::rebuild`] recreates it).

use super::record::{ArchiveError, Record, Status};
use rusqlite::{params, Connection, OptionalExtension};
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
        // A table of another shape (not ours) is as good as damaged.
        conn.prepare(&format!("SELECT {COLUMNS} FROM scans LIMIT 0"))
            .map_err(|e| OpenError::Corrupt(format!("not the scan index: {e}")))?;
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

    pub fn upsert(&self, r: &Record) -> rusqlite::Result<()> {
        insert(&self.conn, r)
    }

    pub fn list(&self) -> rusqlite::Result<Vec<Record>> {
        let mut st = self
            .conn
            .prepare(&format!("SELECT {COLUMNS} FROM scans ORDER BY id DESC"))?;
        let rows = st.query_map([], row)?;
        rows.collect()
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

    /// Replace every row by `records` in one transaction.
    pub fn replace_all(&mut self, records: &[Record]) -> rusqlite::Result<()> {
        let tx = self.conn.transaction()?;
        tx.execute("DELETE FROM scans", [])?;
        for r in records {
            insert(&tx, r)?;
        }
        tx.commit()
    }
}

fn insert(conn: &Connection, r: &Record) -> rusqlite::Result<()> {
    conn.execute(
        &format!("INSERT OR REPLACE INTO scans ({COLUMNS}) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11)"),
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
            r.calibration
        ],
    )?;
    Ok(())
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
