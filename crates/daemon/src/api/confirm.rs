//! `POST /api/scans/{id}/side`: the operator settles a "side mismatch" (the scan looks like
//! the other foot than they chose) by confirming the side the scan shows or keeping theirs.
//! The record's side and status are corrected, the change kept in its history.json.

use super::scans::body;
use super::{ApiError, AppState};
use crate::archive::{Record, ScanId, Status};
use axum::extract::rejection::JsonRejection;
use axum::extract::{Path, State};
use axum::Json;
use footscan::scan::quality::{Issue, Level};
use footscan::scandata::ScanDir;
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfirmSide {
    side: String,
}

/// The verdict once the side is settled: the gate's other issues (scan.json's
/// `quality.issues`) without the side's, worst first, as the gate words them.
fn settled(issues: &[Issue]) -> (Status, Option<String>) {
    let rest: Vec<&Issue> = issues
        .iter()
        .filter(|i| i.level != Level::Confirm)
        .collect();
    let status = match rest.iter().map(|i| i.level).max() {
        Some(Level::Rescan) => Status::Rescan,
        Some(Level::Warning) => Status::CompleteWithWarnings,
        _ => Status::Complete,
    };
    let said: Vec<&str> = rest
        .iter()
        .filter(|i| i.level > Level::Note)
        .map(|i| i.text.as_str())
        .collect();
    (status, (!said.is_empty()).then(|| said.join("; ")))
}

pub async fn confirm_side(
    State(st): State<AppState>,
    Path(id): Path<String>,
    b: Result<Json<ConfirmSide>, JsonRejection>,
) -> Result<Json<serde_json::Value>, ApiError> {
    let id = ScanId::parse(&id)?;
    let side = body(b)?.side;
    if !matches!(side.as_str(), "left" | "right") {
        return Err(ApiError::invalid(format!(
            "side {:?}: must be \"left\" or \"right\"",
            side.chars().take(80).collect::<String>()
        )));
    }
    let d = st.daemon.clone();
    tokio::task::spawn_blocking(move || {
        let a = &d.archive;
        let rec = a.get(&id)?;
        if rec.status == Status::Running {
            return Err(ApiError::Conflict(format!(
                "scan {} is still running: confirm its side once it has ended",
                rec.id
            )));
        }
        let summary: serde_json::Value = a
            .artifact_bytes(&rec, ScanDir::SUMMARY)
            .and_then(|b| serde_json::from_slice(&b).ok())
            .unwrap_or_default();
        let issues: Vec<Issue> =
            serde_json::from_value(summary["quality"]["issues"].clone()).unwrap_or_default();
        let detected = summary["quality"]["side"]["detected"]
            .as_str()
            .unwrap_or("?")
            .to_string();
        let why = if side == detected {
            format!("side confirmed by the operator: {side}, as the scan shows")
        } else {
            format!("side kept by the operator: {side}, though the scan looks {detected}")
        };
        let (status, reason) = settled(&issues);
        let edit = |r: &mut Record| {
            if r.status != Status::SideMismatch {
                return Err(ApiError::Conflict(format!(
                    "scan {} is {:?}, not \"side mismatch\": only a scan whose side is in \
                         question is confirmed this way",
                    r.id,
                    r.status.as_str()
                )));
            }
            r.side = side.clone();
            r.status = status;
            r.reason = reason.clone();
            Ok(())
        };
        let (rec, changes, _visits) = a.amend_with_visits(&id, &why, edit)??;
        let mut v = serde_json::to_value(&rec)?;
        v["changes"] = serde_json::to_value(&changes)?;
        Ok(Json(v))
    })
    .await?
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_side_issue_leaves_the_verdict() {
        let issue = |level, text: &str| Issue {
            level,
            text: text.into(),
        };
        let side = issue(
            Level::Confirm,
            "side mismatch: chose left, scan looks right",
        );
        assert_eq!(
            settled(std::slice::from_ref(&side)),
            (Status::Complete, None)
        );
        let drops = issue(Level::Warning, "35 frames dropped");
        assert_eq!(
            settled(&[side.clone(), drops, issue(Level::Note, "a note")]),
            (
                Status::CompleteWithWarnings,
                Some("35 frames dropped".into())
            )
        );
        let gap = issue(Level::Rescan, "20.5 mm of the foot not scanned");
        assert_eq!(settled(&[gap, side]).0, Status::Rescan);
    }
}
