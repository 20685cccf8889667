//! Pages of the archive's scans and visits, answered by the index (SQLite) so a page costs
//! the same at 50 scans as at 50,000: newest first, keyed by id (ids begin with their UTC
//! start time, so the id is both the order and the time filter), with a cursor (`before`, the
//! last id of the previous page) rather than an offset, which would skip or repeat rows when
//! a scan is added between two pages.

use super::record::Status;
use serde::Serialize;

/// The most rows one page may ask for: a page is for a screen, a full export is the unpaged
/// list.
pub const MAX_LIMIT: usize = 500;

/// Which scans, newest first.
#[derive(Clone, Debug, Default)]
pub struct ScanQuery {
    /// Subjects beginning with this, any case (an index range, not a substring scan).
    pub subject: Option<String>,
    pub status: Option<Status>,
    pub side: Option<String>,
    /// Id bounds as compact UTC times (`YYYYMMDDTHHMMSSZ`): started at or after `since`, and
    /// before `until`.
    pub since: Option<String>,
    pub until: Option<String>,
    /// The cursor: only ids below this one.
    pub before: Option<String>,
    /// None: every match.
    pub limit: Option<usize>,
}

/// Which visits, newest first.
#[derive(Clone, Debug, Default)]
pub struct VisitQuery {
    /// Part of the patient id, any case (as `GET /api/visits?subject=` always meant).
    pub subject: Option<String>,
    /// Id bounds as compact UTC times, as for scans (a clinic date becomes both).
    pub since: Option<String>,
    pub until: Option<String>,
    pub before: Option<String>,
    pub limit: Option<usize>,
}

/// One page: its rows and, when more follow, the cursor of the next page.
#[derive(Clone, Debug, Serialize)]
pub struct Page<T> {
    pub items: Vec<T>,
    /// Pass as `before` for the next page; None on the last page.
    pub next: Option<String>,
}

/// The compact UTC form ids begin with (`20261121T221503Z`) of an instant.
pub fn id_bound(t: jiff::Timestamp) -> String {
    t.strftime("%Y%m%dT%H%M%SZ").to_string()
}

/// The SQL `WHERE` of the id bounds and cursor (shared by scans and visits), appended to
/// `sql` with its parameters.
pub(super) fn id_clauses(
    since: &Option<String>,
    until: &Option<String>,
    before: &Option<String>,
    sql: &mut Vec<String>,
    params: &mut Vec<String>,
) {
    if let Some(s) = since {
        params.push(s.clone());
        sql.push(format!("id >= ?{}", params.len()));
    }
    if let Some(u) = until {
        params.push(u.clone());
        sql.push(format!("id < ?{}", params.len()));
    }
    if let Some(b) = before {
        params.push(b.clone());
        sql.push(format!("id < ?{}", params.len()));
    }
}

/// The upper end of a case-insensitive prefix range: subjects are `A-Z a-z 0-9 . _ -`, all
/// below DEL, so `prefix || DEL` bounds every subject beginning with `prefix`.
pub(super) fn prefix_end(prefix: &str) -> String {
    format!("{prefix}\u{7f}")
}
