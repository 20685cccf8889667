//! The routes every job on a finished scan has (daemon/scanjob.rs): post a job, show its
//! record, download one of its files. `R` is the kind (the last, the insole); its own
//! routes (the stock collection, a visit's pair of insoles) are in lasts.rs and insoles.rs.

use super::scans::{body, parse_id, send_file};
use super::{blocking, ApiError, AppState};
use crate::daemon::scanjob::ScanJob;
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;

/// `POST /api/scans/{id}/{noun}`: start the scan's job (202 with the job record).
pub async fn start<R: ScanJob>(
    State(st): State<AppState>,
    Path(id): Path<String>,
    b: Result<Json<R::Request>, JsonRejection>,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let req = body(b)?;
    let d = st.daemon.clone();
    let job = blocking(move || Ok(R::start(&d, &id, req)?)).await?;
    Ok((StatusCode::ACCEPTED, Json(job)).into_response())
}

/// `GET /api/scans/{id}/{noun}`: the scan's job (running, done with its figures and files,
/// or failed with its reason).
pub async fn show<R: ScanJob>(
    State(st): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let d = st.daemon.clone();
    let rid = id.clone();
    let job = blocking(move || Ok(d.scan_job::<R>(&rid)?)).await?;
    let k = R::KIND;
    match job {
        Some(j) => Ok(Json(j).into_response()),
        None => Err(ApiError::missing(format!(
            "scan {id} has no {} yet: POST /api/scans/{id}/{} with {}",
            k.noun, k.noun, k.post_with
        ))),
    }
}

/// `GET /api/scans/{id}/{noun}/{name}`: one file the scan's job made.
pub async fn download<R: ScanJob>(
    State(st): State<AppState>,
    Path((id, name)): Path<(String, String)>,
    headers: axum::http::HeaderMap,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let d = st.daemon.clone();
    let (rid, rname) = (id.clone(), name.clone());
    let file = blocking(move || {
        let p = d.scan_job_file::<R>(&rid, &rname)?;
        d.archive.open_inside(&p).map_err(|e| {
            ApiError::missing(format!("scan {rid} {} file {rname:?}: {e}", R::KIND.noun))
        })
    })
    .await?;
    send_file(file, &format!("{id}-{name}"), &headers).await
}
