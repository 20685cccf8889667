//! The fleet outbox: scans waiting to be pushed to the fleet database, kept in the archive's
//! SQLite index (table `fleet_outbox`) so the queue survives a restart or a kill.
//!
//! Enqueueing is one local insert made when a scan ends (nothing waits on the network). A row
//! stays after its push, as `pushed` (or `rejected`, with the database's refusal), so it is
//! never pushed twice by this daemon; the database's own keys make a repeat harmless anyway.
//! The scans table is rebuilt from the directories at every start; this table is not
//! touched by that. If the whole index is lost (damaged and moved aside), every scan is
//! queued again at the next start and the repeats cost a look-up each.

use super::{Archive, ArchiveError, Status};
use rusqlite::{params, OptionalExtension};

const SCHEMA: &str = "CREATE TABLE IF NOT EXISTS fleet_outbox (
    seq INTEGER PRIMARY KEY AUTOINCREMENT,
    scan_id TEXT NOT NULL UNIQUE,
    state TEXT NOT NULL DEFAULT 'pending',
    enqueued TEXT NOT NULL,
    attempts INTEGER NOT NULL DEFAULT 0,
    last_error TEXT,
    done TEXT
)";

/// A queued scan.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutboxEntry {
    pub seq: i64,
    pub scan_id: String,
    pub attempts: u32,
}

/// How the outbox stands.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct OutboxCounts {
    pub pending: u64,
    pub pushed: u64,
    pub rejected: u64,
}

impl Archive {
    /// Queue scan `id` for the fleet (a no-op if it was queued before).
    pub fn outbox_enqueue(&self, id: &str) -> Result<(), ArchiveError> {
        let now = footscan_util::now_rfc3339();
        self.with_index(|i| {
            i.conn().execute_batch(SCHEMA)?;
            i.conn().execute(
                "INSERT OR IGNORE INTO fleet_outbox (scan_id, enqueued) VALUES (?1, ?2)",
                params![id, now],
            )?;
            Ok(())
        })
    }

    /// Queue every ended scan of the archive not queued yet, oldest first (ids sort by
    /// time): scans recovered at start, a scan whose enqueue a kill interrupted, and the
    /// history when the fleet is first turned on. Returns how many were added.
    pub fn outbox_enqueue_all(&self) -> Result<usize, ArchiveError> {
        let mut ended: Vec<String> = self
            .list()?
            .into_iter()
            .filter(|r| r.status != Status::Running)
            .map(|r| r.id)
            .collect();
        ended.sort();
        let now = footscan_util::now_rfc3339();
        self.with_index(|i| {
            i.conn().execute_batch(SCHEMA)?;
            let tx = i.conn().unchecked_transaction()?;
            let mut n = 0;
            for id in &ended {
                n += tx.execute(
                    "INSERT OR IGNORE INTO fleet_outbox (scan_id, enqueued) VALUES (?1, ?2)",
                    params![id, now],
                )?;
            }
            tx.commit()?;
            Ok(n)
        })
    }

    /// The oldest pending scan.
    pub fn outbox_next(&self) -> Result<Option<OutboxEntry>, ArchiveError> {
        self.with_index(|i| {
            i.conn().execute_batch(SCHEMA)?;
            i.conn()
                .query_row(
                    "SELECT seq, scan_id, attempts FROM fleet_outbox WHERE state = 'pending' ORDER BY seq LIMIT 1",
                    [],
                    |r| {
                        Ok(OutboxEntry {
                            seq: r.get(0)?,
                            scan_id: r.get(1)?,
                            attempts: r.get::<_, i64>(2)? as u32,
                        })
                    },
                )
                .optional()
        })
    }

    /// A failed attempt: counted, its error kept; the entry stays first in line.
    pub fn outbox_attempt_failed(&self, seq: i64, error: &str) -> Result<(), ArchiveError> {
        self.with_index(|i| {
            i.conn().execute(
                "UPDATE fleet_outbox SET attempts = attempts + 1, last_error = ?2 WHERE seq = ?1",
                params![seq, error],
            )?;
            Ok(())
        })
    }

    /// The entry is done: `pushed`, or `rejected` with the reason (it is not retried).
    pub fn outbox_done(&self, seq: i64, rejected: Option<&str>) -> Result<(), ArchiveError> {
        let now = footscan_util::now_rfc3339();
        let state = if rejected.is_some() {
            "rejected"
        } else {
            "pushed"
        };
        self.with_index(|i| {
            i.conn().execute(
                "UPDATE fleet_outbox SET state = ?2, done = ?3, attempts = attempts + 1, last_error = ?4 WHERE seq = ?1",
                params![seq, state, now, rejected],
            )?;
            Ok(())
        })
    }

    pub fn outbox_counts(&self) -> Result<OutboxCounts, ArchiveError> {
        self.with_index(|i| {
            i.conn().execute_batch(SCHEMA)?;
            let mut st = i
                .conn()
                .prepare("SELECT state, count(*) FROM fleet_outbox GROUP BY state")?;
            let mut c = OutboxCounts::default();
            for row in st.query_map([], |r| Ok((r.get::<_, String>(0)?, r.get::<_, i64>(1)?)))? {
                let (state, n) = row?;
                match state.as_str() {
                    "pending" => c.pending = n as u64,
                    "pushed" => c.pushed = n as u64,
                    _ => c.rejected += n as u64,
                }
            }
            Ok(c)
        })
    }
}
