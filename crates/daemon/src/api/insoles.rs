//! The orthotic insole (docs/API.md, "Insoles"): the presets and a visit's pair of insoles;
//! a scan's insole job (posted with a preset and the parameters changed from it) and its
//! files are every scan job's routes (scanjobs.rs).

use super::scans::{body, parse_id};
use super::{blocking, ApiError, AppState};
use crate::daemon::insolejob::{presets as preset_list, VisitInsoleRequest};
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;

/// `GET /api/insole/presets`: the presets and the defaults, every parameter of each.
pub async fn presets() -> Response {
    Json(preset_list()).into_response()
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
