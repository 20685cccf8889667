//! The clinic's customized last (docs/API.md, "Lasts"): the stock collection and its ranking
//! for a scan; the last's job (posted with the fitter's girths) and its files are every scan
//! job's routes (scanjobs.rs).

use super::scans::{body, parse_id};
use super::{blocking, ApiError, AppState};
use crate::daemon::lastjob::RankRequest;
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::response::{IntoResponse, Response};
use axum::Json;

/// `GET /api/lasts`: the stock lasts a last can be made from.
pub async fn stock(State(st): State<AppState>) -> Result<Response, ApiError> {
    let d = st.daemon.clone();
    let lasts = blocking(move || Ok(d.stock_lasts()?)).await?;
    Ok(Json(serde_json::json!({ "lasts": lasts })).into_response())
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
