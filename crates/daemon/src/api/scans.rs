//! Scan endpoints: start, cancel, list, show, download.

use super::{ApiError, AppState};
use crate::archive::{valid_file_name, NewScan, Record, ScanId};
use axum::body::{Body, Bytes};
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use footscan::scandata::ScanDir;
use serde::Deserialize;
use tokio::io::AsyncReadExt;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartScan {
    subject: String,
    side: String,
    #[serde(default)]
    notes: Option<String>,
}

/// A JSON body, with axum's rejections turned into this API's errors: 415 without
/// `Content-Type: application/json`, 413 over the size limit, 400 for anything else.
pub fn body<T>(b: Result<Json<T>, JsonRejection>) -> Result<T, ApiError> {
    b.map(|Json(t)| t)
        .map_err(|e| super::BodyError::from(e).into())
}

pub(super) fn parse_id(id: &str) -> Result<ScanId, ApiError> {
    ScanId::parse(id).map_err(ApiError::from)
}

fn validate(s: StartScan) -> Result<NewScan, ApiError> {
    let subject_ok = (1..=64).contains(&s.subject.len())
        && s.subject
            .bytes()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, b'.' | b'_' | b'-'));
    if !subject_ok {
        return Err(ApiError::invalid(format!(
            "subject {:?}: must be 1-64 characters of A-Z a-z 0-9 . _ -",
            s.subject.chars().take(80).collect::<String>()
        )));
    }
    if !matches!(s.side.as_str(), "left" | "right") {
        return Err(ApiError::invalid(format!(
            "side {:?}: must be \"left\" or \"right\"",
            s.side.chars().take(80).collect::<String>()
        )));
    }
    let notes = s.notes.unwrap_or_default();
    if notes.chars().count() > 2000 {
        return Err(ApiError::invalid(format!(
            "notes: {} characters, at most 2000",
            notes.chars().count()
        )));
    }
    Ok(NewScan {
        subject: s.subject,
        side: s.side,
        notes,
    })
}

pub async fn start(
    State(st): State<AppState>,
    b: Result<Json<StartScan>, JsonRejection>,
) -> Result<Response, ApiError> {
    let meta = validate(body(b)?)?;
    let d = st.daemon.clone();
    let id = tokio::task::spawn_blocking(move || d.start_scan(meta)).await??;
    Ok((StatusCode::ACCEPTED, Json(serde_json::json!({ "id": id }))).into_response())
}

pub async fn cancel(
    State(st): State<AppState>,
    Path(id): Path<String>,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    let d = st.daemon.clone();
    let rid = id.clone();
    tokio::task::spawn_blocking(move || {
        d.archive.get(&rid)?;
        d.cancel_scan(rid.as_str())
    })
    .await??;
    Ok((
        StatusCode::ACCEPTED,
        Json(serde_json::json!({ "id": id.as_str(), "state": "cancelling" })),
    )
        .into_response())
}

pub async fn list(State(st): State<AppState>) -> Result<Json<Vec<Record>>, ApiError> {
    let d = st.daemon.clone();
    let v = tokio::task::spawn_blocking(move || d.archive.list()).await??;
    Ok(Json(v))
}

fn read_json(bytes: Option<Vec<u8>>) -> serde_json::Value {
    bytes
        .and_then(|b| serde_json::from_slice(&b).ok())
        .unwrap_or(serde_json::Value::Null)
}

pub async fn show(
    State(st): State<AppState>,
    Path(id): Path<String>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let id = parse_id(&id)?;
    let d = st.daemon.clone();
    tokio::task::spawn_blocking(move || {
        let a = &d.archive;
        let r = a.get(&id)?;
        let artifacts = a.artifacts(&r).unwrap_or_default();
        let mut v = serde_json::to_value(&r)?;
        v["artifacts"] = serde_json::to_value(&artifacts)?;
        v["summary"] = read_json(a.artifact_bytes(&r, ScanDir::SUMMARY));
        v["measurements"] = read_json(a.artifact_bytes(&r, ScanDir::MEASUREMENTS));
        v["history"] = serde_json::to_value(a.history(&r).unwrap_or_default())?;
        Ok(Json(v))
    })
    .await?
}

/// The artifact streamed in 64 KiB chunks (a client that goes away only stops the stream).
pub async fn download(
    State(st): State<AppState>,
    Path((id, name)): Path<(String, String)>,
    headers: axum::http::HeaderMap,
) -> Result<Response, ApiError> {
    let id = parse_id(&id)?;
    if !valid_file_name(&name) {
        return Err(ApiError::invalid(format!(
            "file name {:?}: must be {}",
            name.chars().take(80).collect::<String>(),
            footscan::io::ARTIFACT_NAME_RULE
        )));
    }
    let d = st.daemon.clone();
    let path = tokio::task::spawn_blocking(move || {
        let r = d.archive.get(&id)?;
        let p = d.archive.artifact_path(&r, &name).ok_or_else(|| {
            let names: Vec<String> = d
                .archive
                .artifacts(&r)
                .unwrap_or_default()
                .into_iter()
                .map(|a| a.name)
                .collect();
            ApiError::missing(format!(
                "scan {} has no file {name:?}; it has: {}",
                r.id,
                names.join(", ")
            ))
        })?;
        let f = d
            .archive
            .open_inside(&p)
            .map_err(|e| ApiError::missing(format!("scan {} file {name:?}: {e}", r.id)))?;
        Ok::<_, ApiError>((p, f, r))
    })
    .await??;
    let (path, file, rec) = path;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    send_file(file, &format!("{}-{name}", rec.id), &headers).await
}

/// A file as a download named `save_as`, whole or the one byte range asked for (a
/// resumed download of a large cloud).
/// The file comes opened (by [`crate::archive::Archive::open_inside`]), so what is sent is
/// what was checked.
pub(super) async fn send_file(
    file: std::fs::File,
    save_as: &str,
    headers: &axum::http::HeaderMap,
) -> Result<Response, ApiError> {
    let mut file = tokio::fs::File::from_std(file);
    let len = file.metadata().await?.len();
    let range = match headers.get(header::RANGE).and_then(|v| v.to_str().ok()) {
        None => None,
        Some(r) => match byte_range(r, len) {
            Ok(x) => x,
            Err(()) => {
                return Err(ApiError::Range {
                    range: r.to_string(),
                    len,
                });
            }
        },
    };
    let (status, start, count) = match range {
        Some((a, b)) => (StatusCode::PARTIAL_CONTENT, a, b - a + 1),
        None => (StatusCode::OK, 0, len),
    };
    if start > 0 {
        use tokio::io::AsyncSeekExt;
        file.seek(std::io::SeekFrom::Start(start)).await?;
    }
    let file = file.take(count);
    let stream = futures_util::stream::unfold(Some(file), |file| async move {
        let mut file = file?;
        let mut buf = vec![0u8; 64 * 1024];
        match file.read(&mut buf).await {
            Ok(0) => None,
            Ok(n) => {
                buf.truncate(n);
                Some((Ok::<_, std::io::Error>(Bytes::from(buf)), Some(file)))
            }
            Err(e) => Some((Err(e), None)),
        }
    });
    let mut resp = (
        status,
        [
            (
                header::CONTENT_TYPE,
                crate::archive::content_type(save_as).to_string(),
            ),
            (header::CONTENT_LENGTH, count.to_string()),
            (header::ACCEPT_RANGES, "bytes".to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{save_as}\""),
            ),
        ],
        Body::from_stream(stream),
    )
        .into_response();
    if let Some((a, b)) = range {
        resp.headers_mut().insert(
            header::CONTENT_RANGE,
            format!("bytes {a}-{b}/{len}")
                .parse()
                .expect("header value"),
        );
    }
    Ok(resp)
}

/// One byte range of `Range: bytes=a-b | a- | -n` as inclusive offsets into `len` bytes:
/// `Ok(None)` for what is served whole (several ranges, another unit, a malformed header),
/// `Err` for a range beyond the end (416).
fn byte_range(header: &str, len: u64) -> Result<Option<(u64, u64)>, ()> {
    let Some(spec) = header.trim().strip_prefix("bytes=") else {
        return Ok(None);
    };
    if spec.contains(',') {
        return Ok(None);
    }
    let Some((a, b)) = spec.trim().split_once('-') else {
        return Ok(None);
    };
    let num = |t: &str| t.trim().parse::<u64>().ok();
    let (start, end) = match (a.trim().is_empty(), b.trim().is_empty()) {
        (true, false) => {
            let Some(n) = num(b) else { return Ok(None) };
            if n == 0 || len == 0 {
                return Err(());
            }
            (len.saturating_sub(n), len - 1)
        }
        (false, _) => {
            let Some(s) = num(a) else { return Ok(None) };
            let e = if b.trim().is_empty() {
                len.saturating_sub(1)
            } else {
                match num(b) {
                    Some(e) if e >= s => e.min(len.saturating_sub(1)),
                    _ => return Ok(None),
                }
            };
            if s >= len {
                return Err(());
            }
            (s, e)
        }
        (true, true) => return Ok(None),
    };
    Ok(Some((start, end)))
}

#[cfg(test)]
mod tests {
    use super::byte_range;

    #[test]
    fn ranges() {
        assert_eq!(byte_range("bytes=0-99", 1000), Ok(Some((0, 99))));
        assert_eq!(byte_range("bytes=900-", 1000), Ok(Some((900, 999))));
        assert_eq!(byte_range("bytes=-100", 1000), Ok(Some((900, 999))));
        assert_eq!(byte_range("bytes=990-2000", 1000), Ok(Some((990, 999))));
        assert_eq!(byte_range("bytes=1000-", 1000), Err(()));
        assert_eq!(byte_range("bytes=0-1,5-6", 1000), Ok(None));
        assert_eq!(byte_range("items=0-1", 1000), Ok(None));
        assert_eq!(byte_range("bytes=5-1", 1000), Ok(None));
    }
}
