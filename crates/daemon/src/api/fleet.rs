//! The fleet database seen from one scanner, read only: `GET /api/fleet/scans` lists every
//! scanner's scans in the central database with the filters of `footscan fleet list`.

use super::{ApiError, AppState};
use axum::extract::{Query, State};
use axum::Json;
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ListQuery {
    clinic: Option<String>,
    scanner: Option<String>,
    subject: Option<String>,
    status: Option<String>,
    since: Option<String>,
    until: Option<String>,
    limit: Option<i64>,
}

pub async fn list(
    State(st): State<AppState>,
    Query(q): Query<ListQuery>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let limit = q.limit.unwrap_or(200);
    if !(1..=10_000).contains(&limit) {
        return Err(ApiError::invalid(format!("limit = {limit}: 1 to 10000")));
    }
    let filter = footscan_fleet::Filter {
        clinic: q.clinic,
        scanner: q.scanner,
        subject: q.subject,
        status: q.status,
        since: q.since,
        until: q.until,
        limit: Some(limit),
    };
    let d = st.daemon.clone();
    let res = tokio::task::spawn_blocking(move || d.fleet_list(&filter)).await?;
    match res {
        None => Err(ApiError::missing(
            "the fleet is off on this scanner: add a [fleet] section to the daemon's config",
        )),
        Some(Ok(rows)) => Ok(Json(serde_json::json!({ "scans": rows }))),
        // The database is another machine: unreachable or refusing is a gateway error.
        Some(Err(e)) => Err(e.into()),
    }
}
