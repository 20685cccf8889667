//! The calibration history and the daily-check trend, beside the scans in the archive.
//!
//! `<archive>/calibrations/<id>.toml` is each calibration as a scan loads it and
//! `<id>.json` its record (date, method, plan, parameters with their standard deviations,
//! residuals, what each step saw, who confirmed it). Neither is ever overwritten (an id
//! that exists is refused), so every calibration stays. `current` holds the id of the one
//! later scans use: a pointer, replaced atomically. An archive written before the history
//! has only `current.toml`; it stays the current calibration until a new one is made.
//!
//! `<archive>/calibrations/checks/<time>-<id>.json` is one daily check each (the
//! `footscan verify` report plus the calibration it checked): the trend, oldest first by name.

use footscan::calib::verify::CheckReport;
use footscan::calib::{Calibration, CalibrationPlan};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// The pointer file naming the current calibration's id.
const POINTER: &str = "current";
/// What an archive kept before the history existed.
const LEGACY: &str = "current.toml";

/// One calibration's record, `<id>.json`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CalibrationEntry {
    pub id: String,
    /// RFC 3339 UTC, the calibration's own date.
    pub date: String,
    pub method: String,
    /// Who confirmed the steps ("simulator operator", a name given to the job, ...).
    pub confirmed_by: String,
    /// The plan the steps followed (targets, heights, positions, checks).
    pub plan: Option<CalibrationPlan>,
    /// The fitted model's parameters, their standard deviations, the fit's residuals.
    pub parameters: serde_json::Value,
    pub stddev: serde_json::Value,
    pub residuals: serde_json::Value,
    /// What each kept step saw, with its attempts.
    pub steps: serde_json::Value,
}

/// One daily check of the trend.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct CheckEntry {
    pub id: String,
    /// The id of the calibration checked (None: a configured calibration outside the history).
    pub calibration_id: Option<String>,
    /// RFC 3339 UTC.
    pub date: String,
    pub passed: bool,
    pub failures: Vec<String>,
    /// The whole report (`footscan verify --out`); a step not seen has a null error.
    pub report: serde_json::Value,
}

impl CheckEntry {
    pub fn new(id: String, calibration_id: Option<String>, r: &CheckReport) -> CheckEntry {
        CheckEntry {
            id,
            calibration_id,
            date: r.date.clone(),
            passed: r.passed,
            failures: r.failures.clone(),
            report: serde_json::to_value(r).expect("report serialises"),
        }
    }
}

/// The history directory of one archive.
pub struct Calibrations {
    dir: PathBuf,
}

/// Why a calibration or a daily check could not be kept.
#[derive(Debug, thiserror::Error)]
pub enum HistoryError {
    #[error("{}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "calibration {id} is already in the history ({}): a calibration is never overwritten",
        path.display()
    )]
    Taken { id: String, path: PathBuf },
    #[error("check {0} is already in the trend")]
    CheckTaken(String),
    #[error(transparent)]
    Save(#[from] footscan::calib::CalibrationError),
}

fn err(path: &Path, source: std::io::Error) -> HistoryError {
    HistoryError::Io {
        path: path.to_path_buf(),
        source,
    }
}

impl Calibrations {
    pub fn new(archive_root: &Path) -> Calibrations {
        Calibrations {
            dir: archive_root.join("calibrations"),
        }
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    fn checks_dir(&self) -> PathBuf {
        self.dir.join("checks")
    }

    /// The calibration file of `id`.
    pub fn path(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.toml"))
    }

    /// Keep `entry` and its calibration `c` under `entry.id` and make it current. Refuses an
    /// id already in the history (nothing is overwritten).
    pub fn add(&self, entry: &CalibrationEntry, c: &Calibration) -> Result<PathBuf, HistoryError> {
        std::fs::create_dir_all(&self.dir).map_err(|e| err(&self.dir, e))?;
        let toml_path = self.path(&entry.id);
        let json_path = self.dir.join(format!("{}.json", entry.id));
        if toml_path.exists() || json_path.exists() {
            return Err(HistoryError::Taken {
                id: entry.id.clone(),
                path: toml_path,
            });
        }
        c.save(&toml_path)?;
        let json = serde_json::to_vec_pretty(entry).expect("entry serialises");
        if let Err(e) = footscan_util::write_atomic(&json_path, &json) {
            // Half an entry is none: the id stays free and the current one unchanged.
            let _ = std::fs::remove_file(&toml_path);
            return Err(err(&json_path, e));
        }
        let pointer = self.dir.join(POINTER);
        footscan_util::write_atomic(&pointer, format!("{}\n", entry.id).as_bytes())
            .map_err(|e| err(&pointer, e))?;
        Ok(toml_path)
    }

    /// The current calibration: its id (None for a pre-history `current.toml`) and file.
    pub fn current(&self) -> Option<(Option<String>, PathBuf)> {
        if let Ok(id) = std::fs::read_to_string(self.dir.join(POINTER)) {
            let id = id.trim().to_string();
            let p = self.path(&id);
            if valid_id(&id) && p.is_file() {
                return Some((Some(id), p));
            }
            tracing::warn!(
                "calibration history: {} names {id:?}, which has no calibration file; ignored",
                self.dir.join(POINTER).display()
            );
        }
        let legacy = self.dir.join(LEGACY);
        legacy.is_file().then_some((None, legacy))
    }

    /// Every calibration of the history, newest first (unreadable records skipped, logged).
    pub fn list(&self) -> Vec<CalibrationEntry> {
        let mut out: Vec<CalibrationEntry> = json_files(&self.dir)
            .into_iter()
            .filter_map(|p| read_json(&p))
            .collect();
        out.sort_by(|a, b| b.date.cmp(&a.date).then(b.id.cmp(&a.id)));
        out
    }

    /// The record of calibration `id`.
    pub fn get(&self, id: &str) -> Option<CalibrationEntry> {
        if !valid_id(id) {
            return None;
        }
        read_json(&self.dir.join(format!("{id}.json")))
    }

    /// Add a daily check to the trend.
    pub fn add_check(&self, entry: &CheckEntry) -> Result<PathBuf, HistoryError> {
        let dir = self.checks_dir();
        std::fs::create_dir_all(&dir).map_err(|e| err(&dir, e))?;
        let p = dir.join(format!("{}.json", entry.id));
        if p.exists() {
            return Err(HistoryError::CheckTaken(entry.id.clone()));
        }
        let json = serde_json::to_vec_pretty(entry).expect("check serialises");
        footscan_util::write_atomic(&p, &json).map_err(|e| err(&p, e))?;
        Ok(p)
    }

    /// The daily checks, oldest first.
    pub fn checks(&self) -> Vec<CheckEntry> {
        let mut out: Vec<CheckEntry> = json_files(&self.checks_dir())
            .into_iter()
            .filter_map(|p| read_json(&p))
            .collect();
        out.sort_by(|a, b| a.date.cmp(&b.date).then(a.id.cmp(&b.id)));
        out
    }

    /// What the status says about the daily checks: the last one, the last passing one, and
    /// a warning when the last check failed or the last pass is older than `max_age_h`.
    pub fn check_status(&self, max_age_h: f64) -> serde_json::Value {
        let checks = self.checks();
        let last = checks.last();
        let last_pass = checks.iter().rev().find(|c| c.passed);
        let pass_age = last_pass.and_then(|c| age_h(&c.date));
        let warning = match (last, pass_age) {
            (Some(l), _) if !l.passed => Some(format!(
                "the last daily check ({}) failed: {}",
                l.date,
                l.failures.join("; ")
            )),
            (_, None) => Some(
                "no daily check has passed yet: run the daily check (POST /api/verify or \
                 footscan verify)"
                    .to_string(),
            ),
            (_, Some(a)) if a > max_age_h => Some(format!(
                "the last passing daily check is {a:.1} h old, older than \
                 calibration.verify_max_age_h = {max_age_h} h: run the daily check"
            )),
            _ => None,
        };
        serde_json::json!({
            "checks": checks.len(),
            "last": last.map(|c| serde_json::json!({
                "id": c.id,
                "date": c.date,
                "passed": c.passed,
                "calibration_id": c.calibration_id,
                "failures": c.failures,
            })),
            "last_pass": last_pass.map(|c| c.date.clone()),
            "last_pass_age_h": pass_age,
            "max_age_h": max_age_h,
            "warning": warning,
        })
    }
}

/// An id as the history names files: letters, digits, `-` and `_` only (no path).
pub fn valid_id(id: &str) -> bool {
    !id.is_empty()
        && id.len() <= 64
        && id
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

/// Hours since the RFC 3339 time `date` (None if it does not parse).
pub fn age_h(date: &str) -> Option<f64> {
    let t = humantime::parse_rfc3339_weak(date).ok()?;
    let age = SystemTime::now().duration_since(t).unwrap_or_default();
    Some((age.as_secs_f64() / 3600.0 * 1000.0).round() / 1000.0)
}

fn json_files(dir: &Path) -> Vec<PathBuf> {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    rd.filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e == "json") && p.is_file())
        .collect()
}

fn read_json<T: serde::de::DeserializeOwned>(p: &Path) -> Option<T> {
    let bytes = std::fs::read(p).ok()?;
    match serde_json::from_slice(&bytes) {
        Ok(v) => Some(v),
        Err(e) => {
            tracing::warn!("calibration history: {} skipped: {e}", p.display());
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn calibration(d_mm: f64) -> Calibration {
        let mut model = CalibrationPlan::default().nominal.model(1280, 1024);
        model.d_mm = d_mm;
        Calibration {
            method: "insystem".into(),
            date: footscan_util::now_rfc3339(),
            model,
            stddev: [("d_mm".to_string(), 0.02)].into(),
            residuals: [("u_h_mm".to_string(), f64::NAN)].into(),
            bezier: None,
        }
    }

    fn entry(id: &str, c: &Calibration) -> CalibrationEntry {
        CalibrationEntry {
            id: id.into(),
            date: c.date.clone(),
            method: c.method.clone(),
            confirmed_by: "test".into(),
            plan: Some(CalibrationPlan::default()),
            parameters: serde_json::to_value(&c.model).unwrap(),
            stddev: serde_json::to_value(&c.stddev).unwrap(),
            residuals: serde_json::to_value(&c.residuals).unwrap(),
            steps: serde_json::json!([]),
        }
    }

    #[test]
    fn history_keeps_every_calibration_and_points_at_the_current_one() {
        let tmp = tempfile::tempdir().unwrap();
        let h = Calibrations::new(tmp.path());
        assert!(h.current().is_none());
        // An archive from before the history: its current.toml is current.
        std::fs::create_dir_all(h.dir()).unwrap();
        let (a, b) = (calibration(250.0), calibration(251.0));
        a.save(&h.dir().join(LEGACY)).unwrap();
        assert_eq!(h.current().unwrap().0, None);
        let pa = h.add(&entry("cal-a", &a), &a).unwrap();
        assert_eq!(h.current().unwrap(), (Some("cal-a".into()), pa.clone()));
        let pb = h.add(&entry("cal-b", &b), &b).unwrap();
        assert_eq!(h.current().unwrap().1, pb);
        // The same id again is refused and changes nothing.
        let e = footscan_util::chain(&h.add(&entry("cal-a", &b), &b).unwrap_err());
        assert!(e.contains("never overwritten"), "{e}");
        assert_eq!(Calibration::load(&pa).unwrap().model.d_mm, 250.0);
        assert_eq!(h.current().unwrap().0.as_deref(), Some("cal-b"));
        assert_eq!(h.list().len(), 2);
        // A NaN residual is kept as null and the record still loads.
        assert!(h.get("cal-b").unwrap().residuals["u_h_mm"].is_null());
        assert!(h.get("../cal-b").is_none());
    }

    #[test]
    fn check_status_warns_on_a_failed_or_stale_check() {
        let tmp = tempfile::tempdir().unwrap();
        let h = Calibrations::new(tmp.path());
        let w = |h: &Calibrations, age: f64| h.check_status(age)["warning"].clone();
        assert!(w(&h, 26.0).as_str().unwrap().contains("no daily check"));
        let report = |date: &str, passed: bool| CheckReport {
            date: date.into(),
            calibration: "insystem".into(),
            tolerance_mm: 0.05,
            width_tolerance_mm: 0.5,
            steps: Vec::new(),
            width_stated_mm: 60.0,
            width_mm: 59.7,
            y_scale: 0.995,
            width_passed: true,
            passed,
            failures: if passed {
                vec![]
            } else {
                vec!["step 7 mm: -1.27 mm".into()]
            },
        };
        let two_days = humantime::format_rfc3339_seconds(
            SystemTime::now() - std::time::Duration::from_secs(48 * 3600),
        )
        .to_string();
        h.add_check(&CheckEntry::new(
            "c1".into(),
            None,
            &report(&two_days, true),
        ))
        .unwrap();
        assert!(w(&h, 26.0).as_str().unwrap().contains("older than"));
        assert!(w(&h, 72.0).is_null());
        let now = footscan_util::now_rfc3339();
        h.add_check(&CheckEntry::new("c2".into(), None, &report(&now, false)))
            .unwrap();
        let st = h.check_status(72.0);
        assert!(st["warning"].as_str().unwrap().contains("-1.27 mm"), "{st}");
        assert_eq!(st["last_pass"], two_days.as_str());
        assert_eq!(st["checks"], 2);
    }

    #[test]
    fn an_index_from_before_the_calibration_column_is_migrated() {
        let tmp = tempfile::tempdir().unwrap();
        let db = tmp.path().join("index.sqlite");
        let old = rusqlite::Connection::open(&db).unwrap();
        old.execute_batch(
            "CREATE TABLE scans (id TEXT PRIMARY KEY NOT NULL, subject TEXT NOT NULL, \
             side TEXT NOT NULL, notes TEXT NOT NULL, status TEXT NOT NULL, reason TEXT, \
             started TEXT NOT NULL, finished TEXT, frames INTEGER NOT NULL, \
             points INTEGER NOT NULL); \
             INSERT INTO scans VALUES ('20261121T222947Z-c20b', 's', 'left', '', 'complete', \
             NULL, '2026-11-21T22:29:47Z', NULL, 1, 2);",
        )
        .unwrap();
        drop(old);
        let Ok(index) = super::super::index::Index::open(&db) else {
            panic!("the old index opens")
        };
        let mut r = index.get("20261121T222947Z-c20b").unwrap().unwrap();
        assert_eq!(r.calibration, None);
        r.calibration = Some("cal-a".into());
        index.upsert(&r, None).unwrap();
        let back = index.get(&r.id).unwrap().unwrap();
        assert_eq!(back.calibration.as_deref(), Some("cal-a"));
        // An old record.json (no calibration field) still loads.
        let json = serde_json::to_value(&back).unwrap();
        let mut obj = json.as_object().unwrap().clone();
        obj.remove("calibration");
        let old: super::super::Record = serde_json::from_value(obj.into()).unwrap();
        assert_eq!(old.calibration, None);
    }

    #[test]
    fn ids_and_ages() {
        assert!(valid_id("20261124T223000Z-abc"));
        assert!(!valid_id("../x") && !valid_id("") && !valid_id("a/b"));
        let a = age_h(&footscan_util::now_rfc3339()).unwrap();
        assert!(a < 0.01, "{a}");
        assert!(age_h("2020-01-01T00:00:00Z").unwrap() > 24.0 * 365.0);
        assert!(age_h("yesterday").is_none());
    }
}
