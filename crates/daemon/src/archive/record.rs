//! The archive's records: a scan's status and metadata (record.json and an index row), what
//! starting and ending a scan say about it, and the archive's errors.

use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A scan's state: running, or the scan's verdict ([`footscan::scan::ScanStatus`], the same
/// strings, so records written before the quality gate keep loading).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Status {
    #[serde(rename = "running")]
    Running,
    #[serde(rename = "complete")]
    Complete,
    /// Usable; the reason says what to look at (docs/method.md section 3.3).
    #[serde(rename = "complete with warnings")]
    CompleteWithWarnings,
    /// The scan looks like the other foot: the operator confirms the side or rescans.
    #[serde(rename = "side mismatch")]
    SideMismatch,
    /// The scan ran but cannot be used: scan again before the patient leaves.
    #[serde(rename = "rescan")]
    Rescan,
    #[serde(rename = "failed")]
    Failed,
    #[serde(rename = "cancelled")]
    Cancelled,
}

impl Status {
    pub fn as_str(self) -> &'static str {
        match self {
            Status::Running => "running",
            Status::Complete => "complete",
            Status::CompleteWithWarnings => "complete with warnings",
            Status::SideMismatch => "side mismatch",
            Status::Rescan => "rescan",
            Status::Failed => "failed",
            Status::Cancelled => "cancelled",
        }
    }
    pub fn parse(s: &str) -> Option<Status> {
        [
            Status::Running,
            Status::Complete,
            Status::CompleteWithWarnings,
            Status::SideMismatch,
            Status::Rescan,
            Status::Failed,
            Status::Cancelled,
        ]
        .into_iter()
        .find(|x| x.as_str() == s)
    }
    /// The scan's files are usable as they are.
    pub fn is_usable(self) -> bool {
        matches!(self, Status::Complete | Status::CompleteWithWarnings)
    }
}

impl From<footscan::scan::ScanStatus> for Status {
    fn from(s: footscan::scan::ScanStatus) -> Status {
        Status::parse(s.as_str()).unwrap_or(Status::Failed)
    }
}

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
            started: footscan::util::now_rfc3339(),
            finished: None,
            frames: 0,
            points: 0,
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
pub struct Outcome {
    pub status: Status,
    pub reason: Option<String>,
    pub frames: u64,
    pub points: u64,
}

#[derive(Debug, thiserror::Error)]
pub enum ArchiveError {
    #[error("archive {path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("archive index {path}: {source}")]
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
