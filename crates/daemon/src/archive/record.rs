//! The archive's records: a scan's status and metadata (record.json and an index row), what
//! starting and ending a scan say about it, and the archive's errors.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A scan's state: running, or the scan's verdict: the pipeline's own enum, the same strings
/// on disk, so records written before the quality gate keep loading.
pub use footscan::scan::ScanStatus as Status;

/// The metadata of one scan, as record.json and as an index row.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Record {
    pub id: String,
    pub subject: String,
    pub side: String,
    pub notes: String,
    pub status: Status,
    pub reason: Option<String>,
    /// RFC 3339 UTC.
    pub started: String,
    pub finished: Option<String>,
    pub frames: u64,
    pub points: u64,
    /// The id of the calibration the scan used (its calibration history entry); None for
    /// scans made before the history, or with a configured calibration outside it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub calibration: Option<String>,
}

impl Record {
    /// A scan that starts now.
    pub(super) fn running(id: String, meta: NewScan) -> Record {
        Record {
            id,
            subject: meta.subject,
            side: meta.side,
            notes: meta.notes,
            status: Status::Running,
            reason: None,
            started: footscan_util::now_rfc3339(),
            finished: None,
            frames: 0,
            points: 0,
            calibration: None,
        }
    }
}

/// What the operator says about a scan when starting it (validated by the caller).
#[derive(Clone, Debug)]
pub struct NewScan {
    pub subject: String,
    pub side: String,
    pub notes: String,
}

/// How a scan ended.
#[derive(Clone, Debug)]
pub struct ScanEnd {
    pub status: Status,
    pub reason: Option<String>,
    pub frames: u64,
    pub points: u64,
}

#[derive(Debug, thiserror::Error)]
pub enum ArchiveError {
    #[error("archive {path}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("archive index {path}")]
    Index {
        path: PathBuf,
        source: rusqlite::Error,
    },
    #[error("archive {path}: record.json is not valid: {message}")]
    BadRecord { path: PathBuf, message: String },
    #[error(
        "archive {root} is in use by {holder}: only one process may write into an archive \
         (a second one would recover the first one's running scan); stop it, or point \
         `archive` in [daemon] of the config elsewhere"
    )]
    Locked { root: PathBuf, holder: String },
    #[error("scan {0} is not in the archive")]
    NotFound(String),
}
