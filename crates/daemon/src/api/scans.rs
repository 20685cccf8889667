//! Scan endpoints: start, cancel, list, show, download.

use super::{blocking, ApiError, AppState};
use crate::archive::{id_bound, valid_file_name, NewScan, ScanId, ScanQuery, Status, MAX_LIMIT};
use axum::body::{Body, Bytes};
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, Query, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use footscan::scandata::ScanDir;
use serde::Deserialize;
use std::collections::HashMap;
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

/// The query of a paged list (scans and visits): the cursor, the page size and the time
/// bounds, checked, each error naming the parameter and what it takes.
pub(super) struct Paging {
    pub before: Option<String>,
    pub limit: Option<usize>,
    pub since: Option<String>,
    pub until: Option<String>,
}

/// The paging parameters of `q` (the clinic's zone reads dates); the rest of `q` is the
/// caller's.
pub(super) fn paging(
    q: &HashMap<String, String>,
    zone: &crate::archive::ClinicZone,
) -> Result<Paging, ApiError> {
    let limit = q
        .get("limit")
        .map(|l| match l.parse::<usize>() {
            Ok(n) if (1..=MAX_LIMIT).contains(&n) => Ok(n),
            _ => Err(ApiError::invalid(format!(
                "limit {:?}: must be a whole number from 1 to {MAX_LIMIT}",
                l.chars().take(80).collect::<String>()
            ))),
        })
        .transpose()?;
    let before = q
        .get("before")
        .map(|b| {
            ScanId::parse(b).map(|id| id.to_string()).map_err(|e| {
                ApiError::invalid(format!("before: {e}; pass the `next` of the previous page"))
            })
        })
        .transpose()?;
    let since = q
        .get("since")
        .map(|s| time_bound("since", s, zone, false))
        .transpose()?;
    let until = q
        .get("until")
        .map(|s| time_bound("until", s, zone, true))
        .transpose()?;
    Ok(Paging {
        before,
        limit,
        since,
        until,
    })
}

/// `since`/`until` as an id bound: an RFC 3339 instant, or a date YYYY-MM-DD in the clinic's
/// time zone (since: from its start; until: through its end).
fn time_bound(
    what: &str,
    s: &str,
    zone: &crate::archive::ClinicZone,
    end_of_day: bool,
) -> Result<String, ApiError> {
    let err = || {
        ApiError::invalid(format!(
            "{what} {:?}: must be an RFC 3339 time (2026-11-25T10:00:00Z, \
             2026-11-25T11:00:00+01:00) or a date YYYY-MM-DD (the clinic's local date, {})",
            s.chars().take(80).collect::<String>(),
            zone.name
        ))
    };
    let t = if s.len() == 10 {
        let d: jiff::civil::Date = s.parse().map_err(|_| err())?;
        let d = if end_of_day {
            d.tomorrow().map_err(|_| err())?
        } else {
            d
        };
        zone.day_start(d).ok_or_else(err)?
    } else {
        s.parse::<jiff::Timestamp>().map_err(|_| err())?
    };
    Ok(id_bound(t))
}

/// Refuse a parameter not in `known`, naming the valid ones; `access_token` (the token as a
/// query parameter, checked by the guard) is always allowed.
pub(super) fn known_params(q: &HashMap<String, String>, known: &[&str]) -> Result<(), ApiError> {
    match q
        .keys()
        .find(|k| k.as_str() != "access_token" && !known.contains(&k.as_str()))
    {
        Some(k) => Err(ApiError::invalid(format!(
            "unknown query parameter {:?}: use {}",
            k.chars().take(80).collect::<String>(),
            known.join(", ")
        ))),
        None => Ok(()),
    }
}

/// `GET /api/scans`: newest first. With `limit` a page (`{"items": [...], "next": id|null}`,
/// `before=<next>` for the following one); without it the old answer, every matching scan as
/// a bare array, kept for the clients written before pages (docs/API.md).
pub async fn list(
    State(st): State<AppState>,
    Query(q): Query<HashMap<String, String>>,
) -> Result<Response, ApiError> {
    known_params(
        &q,
        &[
            "limit", "before", "subject", "status", "side", "since", "until",
        ],
    )?;
    let p = paging(&q, &st.daemon.config.clinic_zone)?;
    let subject = q
        .get("subject")
        .map(|s| {
            let ok = (1..=64).contains(&s.len())
                && s.bytes()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, b'.' | b'_' | b'-'));
            if ok {
                Ok(s.clone())
            } else {
                Err(ApiError::invalid(format!(
                    "subject {:?}: must be 1-64 characters of A-Z a-z 0-9 . _ - (the start of \
                     the subject, any case)",
                    s.chars().take(80).collect::<String>()
                )))
            }
        })
        .transpose()?;
    let status = q
        .get("status")
        .map(|s| {
            Status::parse(s).ok_or_else(|| {
                let all: Vec<&str> = Status::ALL.iter().map(|s| s.as_str()).collect();
                ApiError::invalid(format!(
                    "status {:?}: must be one of {}",
                    s.chars().take(80).collect::<String>(),
                    all.join(", ")
                ))
            })
        })
        .transpose()?;
    let side = q
        .get("side")
        .map(|s| match s.as_str() {
            "left" | "right" => Ok(s.clone()),
            _ => Err(ApiError::invalid(format!(
                "side {:?}: must be \"left\" or \"right\"",
                s.chars().take(80).collect::<String>()
            ))),
        })
        .transpose()?;
    let query = ScanQuery {
        subject,
        status,
        side,
        since: p.since,
        until: p.until,
        before: p.before,
        limit: p.limit,
    };
    let d = st.daemon.clone();
    let page = blocking(move || Ok(d.archive.list_page(&query)?)).await?;
    Ok(if query_is_paged(&q) {
        Json(page).into_response()
    } else {
        Json(page.items).into_response()
    })
}

/// Whether the client asked for a page (`limit` given): the answer is then the page object.
pub(super) fn query_is_paged(q: &HashMap<String, String>) -> bool {
    q.contains_key("limit")
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
        let rebuilt = d.archive.rebuilt_note(&p);
        Ok::<_, ApiError>((p, f, r, rebuilt))
    })
    .await??;
    let (path, file, rec, rebuilt) = path;
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let mut resp = send_file(file, &format!("{}-{name}", rec.id), &headers).await?;
    // A compacted scan's file rebuilt by a later footscan: served, and said so.
    if let Some(why) = rebuilt {
        let text: String = why
            .chars()
            .map(|c| {
                if c.is_ascii_graphic() || c == ' ' {
                    c
                } else {
                    '?'
                }
            })
            .collect();
        if let Ok(v) = header::HeaderValue::from_str(&text) {
            resp.headers_mut().insert(REBUILT_HEADER, v);
        }
    }
    Ok(resp)
}

/// The header on a download that is not byte for byte the scan's original file: a compacted
/// scan's model or cloud rebuilt from its grid by a footscan whose writers have changed
/// since; its value says so with both lengths and the original's SHA-256.
pub const REBUILT_HEADER: &str = "x-footscan-rebuilt";

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
