//! The API's errors, typed, and the one place that maps them to an HTTP status and a JSON
//! message (as axum's error-handling example does): handlers return what went wrong and `?`
//! converts the daemon's, the archive's and the visits' errors, so no handler picks a status.
//! The message is the error and its causes, each printed once ([`footscan_util::Chain`]).

use crate::archive::{ArchiveError, IdError, VisitError};
use crate::daemon::DaemonError;
use axum::extract::rejection::JsonRejection;
use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;

/// What went wrong with a request.
#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    /// An input of the request is not valid: the message names it and what is valid.
    #[error("{0}")]
    Invalid(String),
    /// The request names something that is not there (a job, a file, a calibration).
    #[error("{0}")]
    Missing(String),
    /// What the request names is not in a state that allows it (a scan still running).
    #[error("{0}")]
    Conflict(String),
    #[error(transparent)]
    Id(#[from] IdError),
    #[error(transparent)]
    Body(#[from] BodyError),
    #[error(transparent)]
    Refused(#[from] Refused),
    #[error(transparent)]
    Daemon(#[from] DaemonError),
    #[error(transparent)]
    Visit(#[from] VisitError),
    #[error(transparent)]
    Archive(#[from] ArchiveError),
    /// A new visit could not be written (a full or read-only disk).
    #[error("the visit could not be written")]
    VisitNotWritten(#[source] ArchiveError),
    /// The scan's files do not make a report (a measurement the report cannot draw).
    #[error(transparent)]
    Report(anyhow::Error),
    /// The scan's files could not be read for its report.
    #[error(transparent)]
    ReportInput(anyhow::Error),
    /// The fleet database (another machine) is unreachable or refused the query.
    #[error(transparent)]
    Fleet(#[from] footscan_fleet::FleetError),
    /// A byte range beyond the end of a download.
    #[error("Range {range:?} is outside the file's {len} bytes")]
    Range { range: String, len: u64 },
    #[error("encoding the answer")]
    Encode(#[from] serde_json::Error),
    #[error("a worker thread failed")]
    Worker(#[from] tokio::task::JoinError),
    #[error("reading a file")]
    Io(#[from] std::io::Error),
    #[error("rendering the preview")]
    Preview(#[from] image::ImageError),
}

/// A JSON body axum rejected.
#[derive(Debug, thiserror::Error)]
pub enum BodyError {
    #[error("the body must be JSON with `Content-Type: application/json`")]
    NotJson,
    #[error("request body over the {limit} byte limit")]
    TooLarge { limit: usize },
    #[error("invalid JSON body: {0}")]
    Invalid(String),
}

impl From<JsonRejection> for BodyError {
    fn from(e: JsonRejection) -> Self {
        match e {
            JsonRejection::MissingJsonContentType(_) => BodyError::NotJson,
            e if e.status() == StatusCode::PAYLOAD_TOO_LARGE => BodyError::TooLarge {
                limit: super::BODY_LIMIT,
            },
            e => BodyError::Invalid(e.body_text()),
        }
    }
}

/// A request refused before any handler ran (the guard, the token, the router).
#[derive(Debug, thiserror::Error)]
pub enum Refused {
    #[error("request target of {len} bytes: at most {max}")]
    UriTooLong { len: usize, max: usize },
    #[error("request headers of {len} bytes: at most {max}")]
    HeadersTooLarge { len: usize, max: usize },
    #[error("Content-Length {len}: request bodies are at most {max} bytes")]
    DeclaredTooLarge { len: u64, max: usize },
    #[error("request body over the {limit} byte limit (or broken off)")]
    BodyTooLarge { limit: usize },
    #[error("the request body did not arrive within {0:?}")]
    BodyTimeout(std::time::Duration),
    #[error("the Host header is required")]
    NoHost,
    /// A Host or an Origin that is not this daemon: the message names it and what is allowed.
    #[error("{0}")]
    Foreign(String),
    #[error("{method} {path} needs `Content-Type: application/json` (also without a body): it changes state")]
    NotJson { method: String, path: String },
    #[error(
        "missing or wrong token: send `Authorization: Bearer <token>` or `?access_token=<token>`"
    )]
    Token,
    #[error("no such endpoint: {method} {path} (see docs/API.md)")]
    NoRoute { method: String, path: String },
    #[error("method {method} not allowed on {path} (see docs/API.md)")]
    Method { method: String, path: String },
}

impl Refused {
    fn status(&self) -> StatusCode {
        match self {
            Refused::UriTooLong { .. } => StatusCode::URI_TOO_LONG,
            Refused::HeadersTooLarge { .. } => StatusCode::REQUEST_HEADER_FIELDS_TOO_LARGE,
            Refused::DeclaredTooLarge { .. } | Refused::BodyTooLarge { .. } => {
                StatusCode::PAYLOAD_TOO_LARGE
            }
            Refused::BodyTimeout(_) => StatusCode::REQUEST_TIMEOUT,
            Refused::NoHost => StatusCode::BAD_REQUEST,
            Refused::Foreign(_) => StatusCode::FORBIDDEN,
            Refused::NotJson { .. } => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            Refused::Token => StatusCode::UNAUTHORIZED,
            Refused::NoRoute { .. } => StatusCode::NOT_FOUND,
            Refused::Method { .. } => StatusCode::METHOD_NOT_ALLOWED,
        }
    }
}

fn archive_status(e: &ArchiveError) -> StatusCode {
    match e {
        ArchiveError::NotFound(_) => StatusCode::NOT_FOUND,
        // The archive could not be read or written (a full or read-only disk).
        ArchiveError::Io { .. } | ArchiveError::Index { .. } => StatusCode::INSUFFICIENT_STORAGE,
        ArchiveError::BadRecord { .. } | ArchiveError::Locked { .. } => {
            StatusCode::INTERNAL_SERVER_ERROR
        }
    }
}

impl ApiError {
    pub fn invalid(message: impl Into<String>) -> Self {
        ApiError::Invalid(message.into())
    }
    pub fn missing(message: impl Into<String>) -> Self {
        ApiError::Missing(message.into())
    }

    /// The one mapping from what went wrong to the status answered.
    pub fn status(&self) -> StatusCode {
        use DaemonError as D;
        match self {
            ApiError::Invalid(_) | ApiError::Id(_) => StatusCode::BAD_REQUEST,
            ApiError::Missing(_) => StatusCode::NOT_FOUND,
            ApiError::Conflict(_) => StatusCode::CONFLICT,
            ApiError::Body(BodyError::NotJson) => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ApiError::Body(BodyError::TooLarge { .. }) => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::Body(BodyError::Invalid(_)) => StatusCode::BAD_REQUEST,
            ApiError::Refused(r) => r.status(),
            ApiError::Daemon(d) => match d {
                D::Busy(_) | D::NotRunning(_) | D::Conflict(_) => StatusCode::CONFLICT,
                D::NotFound(_) => StatusCode::NOT_FOUND,
                D::BadRequest(_) => StatusCode::BAD_REQUEST,
                D::Unsupported(_) => StatusCode::NOT_IMPLEMENTED,
                D::Unavailable(_) => StatusCode::SERVICE_UNAVAILABLE,
                D::Archive(a) => archive_status(a),
                D::Plantar(_) => StatusCode::CONFLICT,
                D::StockLasts { .. } => StatusCode::SERVICE_UNAVAILABLE,
                D::ScannerConfig(_)
                | D::Preflight(_)
                | D::Rules(_)
                | D::Thread { .. }
                | D::Calibration(_)
                | D::Calib(_)
                | D::JobRead { .. }
                | D::JobWrite { .. }
                | D::JobJson { .. } => StatusCode::INTERNAL_SERVER_ERROR,
            },
            ApiError::Visit(v) => match v {
                VisitError::NotFound(_) => StatusCode::NOT_FOUND,
                VisitError::Conflict(_) => StatusCode::CONFLICT,
                VisitError::Archive(a) => archive_status(a),
            },
            ApiError::Archive(a) => archive_status(a),
            ApiError::VisitNotWritten(_) => StatusCode::INSUFFICIENT_STORAGE,
            ApiError::Report(_) => StatusCode::UNPROCESSABLE_ENTITY,
            ApiError::Fleet(_) => StatusCode::BAD_GATEWAY,
            ApiError::Range { .. } => StatusCode::RANGE_NOT_SATISFIABLE,
            ApiError::ReportInput(_)
            | ApiError::Encode(_)
            | ApiError::Worker(_)
            | ApiError::Io(_)
            | ApiError::Preview(_) => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }
}

/// `{"error": message}` with `status`: every error answer of the API has this shape.
pub fn json_error(status: StatusCode, message: String) -> Response {
    (status, Json(serde_json::json!({ "error": message }))).into_response()
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let status = self.status();
        let message = footscan_util::chain(&self);
        if status.is_server_error() {
            tracing::error!("{} error: {message}", status.as_u16());
        }
        let mut resp = json_error(status, message);
        let h = resp.headers_mut();
        match &self {
            ApiError::Refused(Refused::Token) => {
                h.insert(
                    header::WWW_AUTHENTICATE,
                    HeaderValue::from_static("Bearer realm=\"footscand\""),
                );
            }
            // The unread body would otherwise be taken for the next request.
            ApiError::Refused(Refused::DeclaredTooLarge { .. } | Refused::BodyTimeout(_)) => {
                h.insert(header::CONNECTION, HeaderValue::from_static("close"));
            }
            ApiError::Range { len, .. } => {
                h.insert(
                    header::CONTENT_RANGE,
                    format!("bytes */{len}").parse().expect("header value"),
                );
            }
            _ => {}
        }
        resp
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The archive's cause is printed once, after the archive's own words.
    #[test]
    fn message_is_the_chain_once() {
        let e = ApiError::from(DaemonError::Archive(ArchiveError::Io {
            path: "/srv/archive".into(),
            source: std::io::Error::other("disk full"),
        }));
        assert_eq!(e.status(), StatusCode::INSUFFICIENT_STORAGE);
        assert_eq!(footscan_util::chain(&e), "archive /srv/archive: disk full");
        let e = ApiError::from(ArchiveError::NotFound("x".into()));
        assert_eq!(e.status(), StatusCode::NOT_FOUND);
        assert_eq!(footscan_util::chain(&e), "scan x is not in the archive");
    }
}
