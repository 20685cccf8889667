//! `GET /api/scans/{id}/report.pdf`: the printable report of a measured scan (the library's
//! crates/scanner/src/report.rs: the foot at 1:1 with a 100 mm calibration bar), made from the scan's files
//! when asked for, so a record corrected later (its side, its subject) prints as corrected.

use super::{ApiError, AppState};
use crate::archive::ScanId;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};

pub async fn report_pdf(
    State(st): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id = ScanId::parse(&id)?;
    let d = st.daemon.clone();
    let (bytes, id) = tokio::task::spawn_blocking(move || {
        let input = scan_input(&d, &id)?;
        let (bytes, _) = footscan::report::render(&input).map_err(ApiError::Report)?;
        Ok::<_, ApiError>((bytes, input.title))
    })
    .await??;
    Ok(pdf(bytes, &format!("{id}-report.pdf")))
}

/// What the report of scan `id` shows: its files and its record as it is now (a corrected
/// side or subject). 409 without measurements.json.
pub(super) fn scan_input(
    d: &crate::daemon::Daemon,
    id: &ScanId,
) -> Result<footscan::report::ReportInput, ApiError> {
    let (rec, dir) = d.measured_scan(id, "a report")?;
    let mut input =
        footscan::report::ReportInput::from_scan_dir(&dir).map_err(ApiError::ReportInput)?;
    input.title = rec.id.clone();
    input.record = serde_json::to_value(&rec)?;
    Ok(input)
}

/// A PDF response shown in the browser, saved as `name`.
pub(super) fn pdf(bytes: Vec<u8>, name: &str) -> Response {
    (
        [
            (header::CONTENT_TYPE, "application/pdf".to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("inline; filename=\"{name}\""),
            ),
        ],
        bytes,
    )
        .into_response()
}
