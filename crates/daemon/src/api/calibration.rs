//! Calibration endpoints: the guided calibration and the daily check as jobs (start, the
//! current step, confirm / repeat / abort), the calibration history and the check trend.

use super::blocking;
use super::{scans::body, ApiError, AppState};
use crate::archive::calibrations::{valid_id, Calibrations};
use crate::daemon::guided::{parse_mistake, parse_target, Answer, AnswerFor, JobRequest};
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;
use footscan::calib::Method;
use footscan::scan::config::Backend;
use serde::Deserialize;
use serde_json::{json, Value};

/// One scripted mistake of the simulator's operator.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimMistake {
    /// The target it is asked for: `plate:<mm>`, `staircase`, `empty`.
    asked: String,
    /// What it puts there instead: `plate:<mm>`, `staircase`, `nothing`.
    placed: String,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub struct StartJob {
    #[serde(default)]
    method: Option<String>,
    /// Default: true on hardware (a person confirms), false on the simulator.
    #[serde(default)]
    guided: Option<bool>,
    #[serde(default)]
    confirmed_by: Option<String>,
    #[serde(default)]
    sim_mistakes: Vec<SimMistake>,
}

fn request(st: &AppState, req: StartJob, verify: bool) -> Result<JobRequest, ApiError> {
    let method = match req.method.as_deref() {
        None => Method::Insystem,
        Some(m) if verify => {
            return Err(ApiError::invalid(format!(
            "method {:?}: the daily check measures with the current calibration; send no method",
            m.chars().take(80).collect::<String>()
        )))
        }
        Some(m) => m.parse().map_err(|_| {
            ApiError::invalid(format!(
                "method {:?}: must be \"insystem\", \"bezier\" or \"opencv\"",
                m.chars().take(80).collect::<String>()
            ))
        })?,
    };
    let sim = st.daemon.scanner.config.scanner.backend == Backend::Sim;
    let guided = req.guided.unwrap_or(!sim);
    let confirmed_by = match req.confirmed_by {
        Some(c)
            if c.trim().is_empty() || c.chars().count() > 80 || c.chars().any(char::is_control) =>
        {
            return Err(ApiError::invalid(
                "confirmed_by: a name of 1 to 80 printable characters",
            ))
        }
        Some(c) => c.trim().to_string(),
        None if guided => "operator (dashboard)".into(),
        None if sim => "simulator operator (unattended)".into(),
        None => "nobody (unattended)".into(),
    };
    if req.sim_mistakes.len() > 16 {
        return Err(ApiError::invalid("sim_mistakes: at most 16"));
    }
    let sim_mistakes = req
        .sim_mistakes
        .iter()
        .map(|m| Ok((parse_target(&m.asked)?, parse_mistake(&m.placed)?)))
        .collect::<Result<Vec<_>, crate::daemon::guided::TargetError>>()
        .map_err(|e| ApiError::invalid(format!("sim_mistakes: {e}")))?;
    Ok(JobRequest {
        method,
        guided,
        confirmed_by,
        sim_mistakes,
    })
}

async fn start(
    st: AppState,
    b: Result<Json<StartJob>, JsonRejection>,
    kind: &'static str,
) -> Result<Response, ApiError> {
    let req = request(&st, body(b)?, kind == "verify")?;
    let d = st.daemon.clone();
    let id = tokio::task::spawn_blocking(move || d.start_calibration_job(kind, req)).await??;
    Ok((StatusCode::ACCEPTED, Json(json!({ "id": id }))).into_response())
}

/// POST /api/calibrations: start a calibration.
pub async fn start_calibration(
    State(st): State<AppState>,
    b: Result<Json<StartJob>, JsonRejection>,
) -> Result<Response, ApiError> {
    start(st, b, "calibration").await
}

/// POST /api/verify: start the daily check.
pub async fn start_verify(
    State(st): State<AppState>,
    b: Result<Json<StartJob>, JsonRejection>,
) -> Result<Response, ApiError> {
    start(st, b, "verify").await
}

/// GET /api/calibrations/job: the running or last calibration / check job.
pub async fn job(State(st): State<AppState>) -> Result<Json<Value>, ApiError> {
    match st.daemon.calibrating() {
        Some(j) => Ok(Json(serde_json::to_value(j)?)),
        None => Err(ApiError::missing(
            "no calibration or daily check has run since the daemon started",
        )),
    }
}

/// The answer's body: none, `{}`, or the step it is meant for (`phase`, `step`, `attempt`, as
/// `GET /api/calibrations/job` shows them); a body naming another step is 409.
async fn answer(
    st: AppState,
    id: String,
    a: Answer,
    b: axum::body::Bytes,
) -> Result<Json<Value>, ApiError> {
    // No body (or `{}`) asks for no check beyond the job's own.
    let expect = if b.iter().all(u8::is_ascii_whitespace) {
        None
    } else {
        Some(serde_json::from_slice::<AnswerFor>(&b).map_err(|e| {
            ApiError::invalid(format!(
                "invalid answer body ({e}): {{}} or any of \"phase\" (\"place\" or \"review\"), \
                 \"step\" (the step's index) and \"attempt\", as GET /api/calibrations/job shows them"
            ))
        })?)
    };
    let d = st.daemon.clone();
    let job = blocking(move || Ok(d.answer_job(&id, a, expect.as_ref())?)).await?;
    Ok(Json(json!({"id": job.id, "answer": a.name()})))
}

/// POST /api/calibrations/{id}/confirm
pub async fn confirm(
    State(st): State<AppState>,
    Path(id): Path<String>,
    b: axum::body::Bytes,
) -> Result<Json<Value>, ApiError> {
    answer(st, id, Answer::Confirm, b).await
}

/// POST /api/calibrations/{id}/repeat
pub async fn repeat(
    State(st): State<AppState>,
    Path(id): Path<String>,
    b: axum::body::Bytes,
) -> Result<Json<Value>, ApiError> {
    answer(st, id, Answer::Repeat, b).await
}

/// POST /api/calibrations/{id}/abort
pub async fn abort(
    State(st): State<AppState>,
    Path(id): Path<String>,
    b: axum::body::Bytes,
) -> Result<Json<Value>, ApiError> {
    answer(st, id, Answer::Abort, b).await
}

/// GET /api/calibrations: the history, newest first, and the current calibration's id.
pub async fn history(State(st): State<AppState>) -> Json<Value> {
    let h = Calibrations::new(&st.daemon.config.archive);
    let current = st.daemon.calibration().and_then(|c| c.id);
    Json(json!({ "current": current, "calibrations": h.list() }))
}

/// GET /api/calibrations/{id}: one calibration of the history.
pub async fn show(
    State(st): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<Value>, ApiError> {
    if !valid_id(&id) {
        return Err(ApiError::invalid(format!(
            "calibration id {:?}: letters, digits, '-' and '_' only",
            id.chars().take(80).collect::<String>()
        )));
    }
    Calibrations::new(&st.daemon.config.archive)
        .get(&id)
        .map(|e| Json(serde_json::to_value(e).unwrap_or_default()))
        .ok_or_else(|| ApiError::missing(format!("calibration {id} is not in the history")))
}

/// GET /api/verify: the daily-check trend (oldest first) and what the status says of it.
pub async fn trend(State(st): State<AppState>) -> Json<Value> {
    let h = Calibrations::new(&st.daemon.config.archive);
    let max_age = st.daemon.scanner.config.calibration.verify_max_age_h;
    Json(json!({ "checks": h.checks(), "status": h.check_status(max_age) }))
}
