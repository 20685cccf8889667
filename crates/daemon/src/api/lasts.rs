//! The clinic's customized last (docs/API.md, "Lasts"): the stock collection, a scan's last
//! job (posted with the fitter's girths) and the last's files.

use super::scans::{body, parse_id, send_file};
use super::{blocking, ApiError, AppState};
use crate::daemon::lastjob::{LastRequest, RankRequest};
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;

/// `GET /api/lasts`: the stock lasts a last can be made from.
pub async fn stock(State(st): State<AppState>) -> Result<Response, ApiError> {
    let d = st.daemon.clone();
    let lasts = blocking(move || Ok(d.stock_lasts()?)).await?;
    Ok(Json(serde_json::json!({ "lasts": lasts })).into_response())
}

/// `POST /api/scans/{id}/last`: start making the scan's last (202 with the job record).
pub async fn start(
    State(st): State<AppState>,
    Path(id): Path<String>,
    b: Result<Json<LastRequest>, JsonRejection>,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let req = body(b)?;
    let d = st.daemon.clone();
    let job = blocking(move || Ok(d.start_last(&id, req)?)).await?;
    Ok((StatusCode::ACCEPTED, Json(job)).into_response())
}

/// `GET /api/scans/{id}/last`: the scan's last job (running, done with its rules and files,
/// or failed with its reason).
pub async fn show(
    State(st): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let d = st.daemon.clone();
    let rid = id.clone();
    let job = blocking(move || Ok(d.last_job(&rid)?)).await?;
    match job {
        Some(j) => Ok(Json(j).into_response()),
        None => Err(ApiError::missing(format!(
            "scan {id} has no last yet: POST /api/scans/{id}/last with the girths and a stock \
             last"
        ))),
    }
}

/// `GET /api/scans/{id}/last/{name}`: one file of the scan's last.
pub async fn download(
    State(st): State<AppState>,
    Path((id, name)): Path<(String, String)>,
    headers: axum::http::HeaderMap,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let d = st.daemon.clone();
    let (rid, rname) = (id.clone(), name.clone());
    let file = blocking(move || {
        let p = d.last_file(&rid, &rname)?;
        d.archive
            .open_inside(&p)
            .map_err(|e| ApiError::missing(format!("scan {rid} last file {rname:?}: {e}")))
    })
    .await?;
    send_file(file, &format!("{id}-{name}"), &headers).await
}

/// `POST /api/scans/{id}/last/rank`: the stock collection ranked for the scan and the
/// fitter's girths (best first: the least change), answered when done.
pub async fn rank(
    State(st): State<AppState>,
    Path(id): Path<String>,
    b: Result<Json<RankRequest>, JsonRejection>,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let req = body(b)?;
    let d = st.daemon.clone();
    let ranking = blocking(move || Ok(d.rank_lasts(&id, req)?)).await?;
    Ok(Json(ranking).into_response())
}
