//! Corrections of a finished scan's record (the side the operator confirms, a subject typed
//! wrong): record.json and the index row are changed, and every change is kept in the scan's
//! `history.json` (what changed, from what to what, when and why), so a corrected record
//! never hides what the scan was first saved as.
//!
//! The history is written before the record: a crash between the two leaves a history entry
//! for a change the record does not show yet (said, not lost), never the reverse.

use super::record::{ArchiveError, Record, Status};
use super::{io_at, Archive, ScanId, RECORD};
use serde::{Deserialize, Serialize};
use std::sync::Mutex;

/// The file in a scan's directory listing the changes made to its record after it ended.
pub const HISTORY: &str = "history.json";

/// One field of a record changed after the scan ended.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Change {
    /// RFC 3339 UTC.
    pub at: String,
    /// "subject", "side", "status" or "reason".
    pub field: String,
    pub from: Option<String>,
    pub to: Option<String>,
    /// Why, in the words of whoever changed it ("side confirmed by the operator: ...").
    pub why: String,
}

/// Serialises corrections: two at once would each append to the history they read.
static AMENDING: Mutex<()> = Mutex::new(());

impl Archive {
    /// The changes made to a scan's record after it ended, oldest first (none: empty).
    pub fn history(&self, record: &Record) -> Result<Vec<Change>, ArchiveError> {
        let Some(path) = self.artifact_path(record, HISTORY) else {
            return Ok(Vec::new());
        };
        let bytes = self
            .read_inside(&path, super::MAX_JSON_ARTIFACT)
            .map_err(io_at(&path))?;
        serde_json::from_slice(&bytes).map_err(|e| ArchiveError::BadRecord {
            path,
            message: format!("{HISTORY}: {e}"),
        })
    }

    /// Change a finished scan's record with `edit` (which may refuse, with a message), keep
    /// each changed field in history.json with `why`, rewrite record.json atomically and
    /// update the index. Returns the new record and the changes made (none when `edit`
    /// changed nothing: nothing is written then).
    pub fn amend<E>(
        &self,
        id: &ScanId,
        why: &str,
        edit: impl FnOnce(&mut Record) -> Result<(), E>,
    ) -> Result<Result<(Record, Vec<Change>), E>, ArchiveError> {
        let _one = AMENDING.lock().unwrap_or_else(|p| p.into_inner());
        let before = self.get(id)?;
        if before.status == Status::Running {
            return Err(ArchiveError::Io {
                path: self.dir(&before),
                source: std::io::Error::other(format!(
                    "scan {id} is still running: its record can be changed once it has ended"
                )),
            });
        }
        let mut after = before.clone();
        if let Err(e) = edit(&mut after) {
            return Ok(Err(e));
        }
        after.id = before.id.clone();
        let at = footscan_util::now_rfc3339();
        let change = |field: &str, from: Option<&str>, to: Option<&str>| {
            (from != to).then(|| Change {
                at: at.clone(),
                field: field.into(),
                from: from.map(str::to_string),
                to: to.map(str::to_string),
                why: why.to_string(),
            })
        };
        let changes: Vec<Change> = [
            change("subject", Some(&before.subject), Some(&after.subject)),
            change("side", Some(&before.side), Some(&after.side)),
            change(
                "status",
                Some(before.status.as_str()),
                Some(after.status.as_str()),
            ),
            change("reason", before.reason.as_deref(), after.reason.as_deref()),
        ]
        .into_iter()
        .flatten()
        .collect();
        if changes.is_empty() {
            return Ok(Ok((before, changes)));
        }
        let dir = self.checked_dir(&before).ok_or_else(|| ArchiveError::Io {
            path: self.dir(&before),
            source: std::io::Error::other(
                "missing, or not a directory inside the archive (symlinks are refused)",
            ),
        })?;
        let mut history = self.history(&before)?;
        history.extend(changes.iter().cloned());
        let hist_path = dir.join(HISTORY);
        let json = serde_json::to_vec_pretty(&history).expect("history serialises");
        footscan_util::write_atomic(&hist_path, &json).map_err(io_at(&hist_path))?;
        let rec_path = dir.join(RECORD);
        let json = serde_json::to_vec_pretty(&after).expect("record serialises");
        footscan_util::write_atomic(&rec_path, &json).map_err(io_at(&rec_path))?;
        self.index_upsert(&after);
        for c in &changes {
            tracing::info!(
                "scan {}: {} changed from {:?} to {:?}: {}",
                after.id,
                c.field,
                c.from,
                c.to,
                c.why
            );
        }
        Ok(Ok((after, changes)))
    }
}
