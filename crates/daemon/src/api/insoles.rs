//! The orthotic insole (docs/API.md, "Insoles"): the presets, a scan's insole job (posted
//! with a preset and the parameters changed from it), a visit's pair of insoles and the
//! insole's files.

use super::scans::{body, parse_id, send_file};
use super::{blocking, ApiError, AppState};
use crate::daemon::insolejob::{presets as preset_list, InsoleRequest, VisitInsoleRequest};
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;

/// `GET /api/insole/presets`: the presets and the defaults, every parameter of each.
pub async fn presets() -> Response {
    Json(preset_list()).into_response()
}

/// `POST /api/scans/{id}/insole`: start making the scan's insole (202 with the job record).
pub async fn start(
    State(st): State<AppState>,
    Path(id): Path<String>,
    b: Result<Json<InsoleRequest>, JsonRejection>,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let req = body(b)?;
    let d = st.daemon.clone();
    let job = blocking(move || Ok(d.start_insole(&id, req)?)).await?;
    Ok((StatusCode::ACCEPTED, Json(job)).into_response())
}

/// `GET /api/scans/{id}/insole`: the scan's insole job (running, done with the parameters
/// measured back and its files, or failed with its reason).
pub async fn show(
    State(st): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let d = st.daemon.clone();
    let rid = id.clone();
    let job = blocking(move || Ok(d.insole_job(&rid)?)).await?;
    match job {
        Some(j) => Ok(Json(j).into_response()),
        None => Err(ApiError::missing(format!(
            "scan {id} has no insole yet: POST /api/scans/{id}/insole with a preset and the \
             parameters to change"
        ))),
    }
}

/// `GET /api/scans/{id}/insole/{name}`: one file of the scan's insole.
pub async fn download(
    State(st): State<AppState>,
    Path((id, name)): Path<(String, String)>,
    headers: axum::http::HeaderMap,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let d = st.daemon.clone();
    let (rid, rname) = (id.clone(), name.clone());
    let file = blocking(move || {
        let p = d.insole_file(&rid, &rname)?;
        d.archive
            .open_inside(&p)
            .map_err(|e| ApiError::missing(format!("scan {rid} insole file {rname:?}: {e}")))
    })
    .await?;
    send_file(file, &format!("{id}-{name}"), &headers).await
}

/// `POST /api/visits/{id}/insole`: both feet's insoles, the shared parameters mirrored (202
/// with both job records, left first).
pub async fn start_visit(
    State(st): State<AppState>,
    Path(id): Path<String>,
    b: Result<Json<VisitInsoleRequest>, JsonRejection>,
) -> Result<Response, ApiError> {
    let vid = parse_id(&id)?;
    let req = body(b)?;
    let d = st.daemon.clone();
    let jobs = blocking(move || Ok(d.start_visit_insoles(&vid, req)?)).await?;
    Ok((
        StatusCode::ACCEPTED,
        Json(serde_json::json!({ "jobs": jobs })),
    )
        .into_response())
}
