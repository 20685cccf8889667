//! Visits (archive/visits.rs) over HTTP, and the correction of a scan's subject or side:
//! `POST /api/visits`, `GET /api/visits?subject=&date=`, `GET /api/visits/{id}`,
//! `POST /api/visits/{id}/notes`, `POST /api/visits/{id}/scans`, `DELETE /api/visits/{id}`,
//! `POST /api/scans/{id}/record`.
//!
//! Every visit in an answer carries `started_local` and `time_zone` (the clinic's, from the
//! daemon config) beside the stored UTC `started`; `?date=` is the clinic's local date.

use super::scans::{body, known_params, paging, parse_id, query_is_paged};
use super::{blocking, ApiError, AppState};
use crate::archive::{id_bound, Page, Record, ScanId, VisitQuery};
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, Query, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Deserialize;
use std::collections::HashMap;

fn subject_ok(what: &str, s: &str) -> Result<(), ApiError> {
    let ok = (1..=64).contains(&s.len())
        && s.bytes()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, b'.' | b'_' | b'-'));
    if ok {
        Ok(())
    } else {
        Err(ApiError::invalid(format!(
            "{what} {:?}: must be 1-64 characters of A-Z a-z 0-9 . _ -",
            s.chars().take(80).collect::<String>()
        )))
    }
}

fn notes_ok(n: &str) -> Result<(), ApiError> {
    let c = n.chars().count();
    if c > 2000 {
        return Err(ApiError::invalid(format!(
            "notes: {c} characters, at most 2000"
        )));
    }
    Ok(())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NewVisit {
    patient: String,
    #[serde(default)]
    notes: String,
}

pub async fn create(
    State(st): State<AppState>,
    b: Result<Json<NewVisit>, JsonRejection>,
) -> Result<Response, ApiError> {
    let v = body(b)?;
    subject_ok("patient", &v.patient)?;
    notes_ok(&v.notes)?;
    let d = st.daemon.clone();
    let visit = blocking(move || {
        d.archive
            .new_visit(&v.patient, &v.notes)
            .map_err(ApiError::VisitNotWritten)
    })
    .await?;
    let zone = &st.daemon.config.clinic_zone;
    Ok((StatusCode::CREATED, Json(zone.visit_json(&visit))).into_response())
}

/// `?subject=` (part of the patient id, any case), `?date=YYYY-MM-DD` (the clinic's local
/// date), and the paging of `GET /api/scans` (`limit`, `before`, `since`, `until`): with
/// `limit` a page `{"items": [...], "next": id|null}`, without it every match as a bare array
/// (the answer before pages). Answered by the index.
pub async fn list(
    State(st): State<AppState>,
    Query(q): Query<HashMap<String, String>>,
) -> Result<Response, ApiError> {
    known_params(
        &q,
        &["subject", "date", "limit", "before", "since", "until"],
    )?;
    let zone = &st.daemon.config.clinic_zone;
    let p = paging(&q, zone)?;
    let mut query = VisitQuery {
        subject: q.get("subject").cloned(),
        since: p.since,
        until: p.until,
        before: p.before,
        limit: p.limit,
    };
    if let Some(date) = q.get("date") {
        let date = parse_date(date)?;
        let bad = || {
            ApiError::invalid(format!(
                "date {date}: outside the range of the clinic's calendar ({})",
                zone.name
            ))
        };
        let start = id_bound(zone.day_start(date).ok_or_else(bad)?);
        let end = id_bound(
            zone.day_start(date.tomorrow().map_err(|_| bad())?)
                .ok_or_else(bad)?,
        );
        // The tighter of each bound (a date and since/until together).
        query.since = Some(query.since.map_or(start.clone(), |s| s.max(start)));
        query.until = Some(query.until.map_or(end.clone(), |u| u.min(end)));
    }
    let d = st.daemon.clone();
    let page = blocking(move || {
        let zone = &d.config.clinic_zone;
        let page = d.archive.visit_page(&query)?;
        Ok(Page {
            items: page
                .items
                .iter()
                .map(|v| zone.visit_json(v))
                .collect::<Vec<_>>(),
            next: page.next,
        })
    })
    .await?;
    Ok(if query_is_paged(&q) {
        Json(page).into_response()
    } else {
        Json(page.items).into_response()
    })
}

/// A calendar date written YYYY-MM-DD.
fn parse_date(d: &str) -> Result<jiff::civil::Date, ApiError> {
    let b = d.as_bytes();
    let shape = b.len() == 10
        && b[4] == b'-'
        && b[7] == b'-'
        && b.iter()
            .enumerate()
            .all(|(i, c)| i == 4 || i == 7 || c.is_ascii_digit());
    let date = shape.then(|| d.parse::<jiff::civil::Date>().ok()).flatten();
    date.ok_or_else(|| {
        ApiError::invalid(format!(
            "date {:?}: must be a calendar date YYYY-MM-DD (the clinic's local date)",
            d.chars().take(80).collect::<String>()
        ))
    })
}

pub async fn show(
    State(st): State<AppState>,
    Path(vid): Path<String>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let vid = parse_id(&vid)?;
    let d = st.daemon.clone();
    blocking(move || {
        let v = d.archive.visit(&vid)?;
        let mut out = d.config.clinic_zone.visit_json(&v);
        // Each foot's record as it is now (its verdict, a corrected side).
        for side in ["left", "right"] {
            let rec = out[side]
                .as_str()
                .and_then(|s| ScanId::parse(s).ok())
                .and_then(|s| d.archive.get(&s).ok());
            out[format!("{side}_scan")] = serde_json::to_value(rec)?;
        }
        Ok(Json(out))
    })
    .await
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Notes {
    notes: String,
}

pub async fn set_notes(
    State(st): State<AppState>,
    Path(vid): Path<String>,
    b: Result<Json<Notes>, JsonRejection>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let vid = parse_id(&vid)?;
    let n = body(b)?.notes;
    notes_ok(&n)?;
    let d = st.daemon.clone();
    let v = blocking(move || Ok(d.archive.set_visit_notes(&vid, &n)?)).await?;
    Ok(Json(st.daemon.config.clinic_zone.visit_json(&v)))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AddScan {
    scan: String,
    /// Take the scan out of the visit holding it (a scan is in one visit at most).
    #[serde(default, rename = "move")]
    move_it: bool,
}

pub async fn add_scan(
    State(st): State<AppState>,
    Path(vid): Path<String>,
    b: Result<Json<AddScan>, JsonRejection>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let vid = parse_id(&vid)?;
    let a = body(b)?;
    let sid = parse_id(&a.scan)?;
    let d = st.daemon.clone();
    let v = blocking(move || Ok(d.archive.add_visit_scan(&vid, &sid, a.move_it)?)).await?;
    Ok(Json(st.daemon.config.clinic_zone.visit_json(&v)))
}

pub async fn delete(
    State(st): State<AppState>,
    Path(vid): Path<String>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let vid = parse_id(&vid)?;
    let d = st.daemon.clone();
    let key = vid.to_string();
    let scans = blocking(move || Ok(d.delete_visit(&vid)?)).await?;
    Ok(Json(
        serde_json::json!({"deleted": key, "scans_deleted": scans}),
    ))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Correction {
    #[serde(default)]
    subject: Option<String>,
    #[serde(default)]
    side: Option<String>,
    why: String,
}

/// Correct a finished scan's subject or side (a typing slip, a foot saved as the other one);
/// the change is kept in the scan's history.json with `why`.
pub async fn correct(
    State(st): State<AppState>,
    Path(sid): Path<String>,
    b: Result<Json<Correction>, JsonRejection>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let sid = parse_id(&sid)?;
    let c = body(b)?;
    if let Some(s) = &c.subject {
        subject_ok("subject", s)?;
    }
    if let Some(s) = &c.side {
        if !matches!(s.as_str(), "left" | "right") {
            return Err(ApiError::invalid(format!(
                "side {:?}: must be \"left\" or \"right\"",
                s.chars().take(80).collect::<String>()
            )));
        }
    }
    let why = c.why.trim().to_string();
    if why.is_empty() || why.chars().count() > 500 {
        return Err(ApiError::invalid(
            "why: say why the record is corrected (1-500 characters)",
        ));
    }
    if c.subject.is_none() && c.side.is_none() {
        return Err(ApiError::invalid(
            "nothing to correct: give subject or side",
        ));
    }
    let d = st.daemon.clone();
    blocking(move || {
        let edit = |r: &mut Record| {
            if let Some(s) = &c.subject {
                r.subject = s.clone();
            }
            if let Some(s) = &c.side {
                r.side = s.clone();
            }
            Ok::<(), ApiError>(())
        };
        let (rec, changes, visits) =
            d.archive
                .amend_with_visits(&sid, &format!("corrected: {why}"), edit)??;
        let mut v = serde_json::to_value(&rec)?;
        v["changes"] = serde_json::to_value(&changes)?;
        v["visits_changed"] = serde_json::to_value(&visits)?;
        Ok(Json(v))
    })
    .await
}

/// `GET /api/visits/{id}/report.pdf`: both feet side by side at 1:1 with the comparison
/// (footscan::report::render_visit); 409 until the visit holds both feet, measured.
pub async fn report_pdf(
    State(st): State<AppState>,
    Path(vid): Path<String>,
) -> Result<Response, ApiError> {
    let vid = parse_id(&vid)?;
    let d = st.daemon.clone();
    let name = format!("{vid}-visit-report.pdf");
    let bytes = blocking(move || {
        let v = d.archive.visit(&vid)?;
        let foot = |s: &Option<String>, side: &str| {
            let s = s.as_deref().ok_or_else(|| {
                ApiError::Conflict(format!(
                    "visit {vid} has no {side} foot yet: add its scan first"
                ))
            })?;
            super::report::scan_input(&d, &parse_id(s)?)
        };
        let (l, r) = (foot(&v.left, "left")?, foot(&v.right, "right")?);
        // The clinic's date of the visit.
        let date = d
            .config
            .clinic_zone
            .local_date(&v.started)
            .map_or_else(|| v.started.clone(), |d| d.to_string());
        footscan::report::render_visit(&format!("{}, {date}", v.patient), &l, &r)
            .map_err(ApiError::Report)
    })
    .await?;
    Ok(super::report::pdf(bytes, &name))
}
