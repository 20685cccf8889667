//! The orthotic insole as a job of the daemon (docs/API.md, "Insoles"), built as the last
//! job is (lastjob.rs): a measured, finished scan and the clinician's parameters (a preset
//! and the keys changed from it) become the insole's files in the scan's directory
//! (`insole/`, replaced as a whole once every file is written, by crates/insole), with the
//! job's record beside them (`insole-job.json`: the request, the parameters as applied, the
//! state, each parameter measured back on the mesh, and the reason when it failed; a failed
//! job leaves an earlier insole as it was). A visit's two feet are one job: the parameters
//! posted for both are given to each foot in its own medial and lateral sense (mirrored: a
//! medial post is medial on both), with a foot's own changes over them. One job at a time,
//! on the HTTP runtime's blocking threads, at its lower priority: an insole never takes the
//! CPU from a scan.

use super::{Daemon, DaemonError};
use crate::archive::{ScanId, Status};
use footscan_insole::{write, write_insole_in, Params, Plantar, ShoeBottom};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

/// The job's record in the scan's directory.
pub const JOB_FILE: &str = "insole-job.json";
/// The directory of the insole's files in the scan's directory.
pub const INSOLE_DIR: &str = "insole";
/// The files of `insole/`, downloadable at `/api/scans/{id}/insole/{name}`.
pub const FILES: [&str; 7] = [
    write::STL,
    write::THREEMF,
    write::STEP,
    write::JSON,
    write::THICKNESS_PNG,
    write::TOP_PNG,
    write::SIDE_PNG,
];
/// Reason a job gets when the daemon stopped during it (found at the next look).
pub const INTERRUPTED: &str = "footscand stopped while the insole was being made; post it again";

/// What a clinic posts for a scan's insole (`POST /api/scans/{id}/insole`).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InsoleRequest {
    /// A preset of `GET /api/insole/presets` to start from (absent: the defaults).
    #[serde(default)]
    pub preset: Option<String>,
    /// The parameters changed from the preset, by name (docs/method.md 14f).
    #[serde(default)]
    pub params: Map<String, Value>,
    /// The outline from the scan's own adjusted last (`last_adjusted.stl` of a `last.adjust`
    /// stage) instead of the footprint plus `margin_mm`.
    #[serde(default)]
    pub shoe_bottom: bool,
}

/// `POST /api/visits/{id}/insole`: both feet of a visit.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VisitInsoleRequest {
    #[serde(default)]
    pub preset: Option<String>,
    /// The parameters changed for both feet, mirrored: each foot takes them in its own
    /// medial and lateral sense.
    #[serde(default)]
    pub params: Map<String, Value>,
    /// A foot's own changes, over `params`.
    #[serde(default)]
    pub left: Map<String, Value>,
    #[serde(default)]
    pub right: Map<String, Value>,
    #[serde(default)]
    pub shoe_bottom: bool,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InsoleState {
    Running,
    Done,
    Failed,
}

/// One parameter as asked and as measured back on the mesh (the whole report is
/// insole/insole.json).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CheckLine {
    pub name: String,
    pub unit: String,
    pub asked: f64,
    pub measured: f64,
    pub error: f64,
    pub bound: f64,
    pub ok: bool,
}

/// The figures of a made insole that the card shows.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct InsoleFigures {
    /// The foot measured on the scan ("left" or "right").
    pub side: String,
    pub foot_length_mm: f64,
    pub checks: Vec<CheckLine>,
    /// The thinnest shell (mm) and its lower bound.
    pub min_thickness_mm: f64,
    pub min_thickness_bound_mm: f64,
    /// The top against the scanned sole over the weight-bearing area (mm).
    pub contact_rms_mm: f64,
    pub contact_max_mm: f64,
    /// Every check within its bound.
    pub ok: bool,
    pub triangles: usize,
    pub volume_mm3: f64,
    pub outline_from: String,
    pub warnings: Vec<String>,
}

/// A scan's insole job as recorded in `insole-job.json` and shown by the API.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct InsoleJob {
    pub scan: String,
    /// The visit whose two feet were posted together, if so.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub visit: Option<String>,
    pub state: InsoleState,
    /// This foot's request (for a visit: the shared changes with the foot's own over them).
    pub request: InsoleRequest,
    /// Every parameter as applied.
    pub params: Params,
    pub started: String,
    pub finished: Option<String>,
    pub seconds: Option<f64>,
    /// Why it failed: the input named and what would be valid.
    pub reason: Option<String>,
    pub figures: Option<InsoleFigures>,
    /// The files of `insole/`, downloadable at `/api/scans/{id}/insole/{name}`.
    pub files: Vec<String>,
}

/// The scans whose insoles are being made (one job at a time; a visit's job holds both).
#[derive(Default)]
pub(super) struct InsoleJobs {
    running: Mutex<Option<Vec<String>>>,
}

impl InsoleJobs {
    /// The running job's scans while `f` runs (so none starts meanwhile).
    pub(super) fn with_running<T>(&self, f: impl FnOnce(&[String]) -> T) -> T {
        let r = self.running.lock().unwrap();
        f(r.as_deref().unwrap_or(&[]))
    }
}

/// `GET /api/insole/presets`: every preset with all its parameters, and the defaults.
pub fn presets() -> Value {
    let mut m = Map::new();
    for n in footscan_insole::PRESETS {
        m.insert(
            n.into(),
            serde_json::to_value(Params::preset(n).expect("a listed preset")).unwrap(),
        );
    }
    serde_json::json!({
        "presets": m,
        "defaults": Params::default(),
    })
}

/// One foot's job, checked and ready to run.
struct Planned {
    id: ScanId,
    dir: PathBuf,
    params: Params,
    shoe: Option<ShoeBottom>,
    job: InsoleJob,
}

impl Daemon {
    /// A scan an insole can be made from, and its parameters checked: 400 naming the
    /// parameter (or the preset) and its valid range, 409 for a scan still running or not
    /// measured. `what` names the foot in the messages of a visit.
    fn plan_insole(
        &self,
        id: &ScanId,
        req: InsoleRequest,
        visit: Option<&str>,
        what: &str,
    ) -> Result<Planned, DaemonError> {
        let (rec, dir) = self.measured_scan(id, "an insole")?;
        if rec.status == Status::Running {
            return Err(DaemonError::Conflict(format!(
                "scan {id} is still running: an insole is made from a finished scan"
            )));
        }
        let params = Params::from_preset_json(req.preset.as_deref(), &req.params)
            .map_err(|e| DaemonError::BadRequest(format!("{what}{e} (nothing written)")))?;
        let shoe = if req.shoe_bottom {
            let p = dir.join(footscan_last::adjust::output::LAST_STL);
            if !p.symlink_metadata().is_ok_and(|m| m.is_file()) {
                return Err(DaemonError::BadRequest(format!(
                    "{what}shoe_bottom = true: scan {id} has no {} (a scanner pipeline with \
                     a last.adjust stage writes it); post shoe_bottom = false for the \
                     footprint plus margin_mm",
                    footscan_last::adjust::output::LAST_STL
                )));
            }
            Some(ShoeBottom::from_adjust_dir(&dir).map_err(|e| {
                DaemonError::BadRequest(format!("{what}shoe_bottom: {}", footscan_util::chain(&e)))
            })?)
        } else {
            None
        };
        let job = InsoleJob {
            scan: id.to_string(),
            visit: visit.map(str::to_string),
            state: InsoleState::Running,
            request: req,
            params: params.clone(),
            started: footscan_util::now_rfc3339(),
            finished: None,
            seconds: None,
            reason: None,
            figures: None,
            files: Vec::new(),
        };
        Ok(Planned {
            id: id.clone(),
            dir,
            params,
            shoe,
            job,
        })
    }

    /// Check a request and start its job; the job's record says `running` until it ends.
    /// The parameters are checked here, so a bad one is a 400, not a job that fails; what
    /// depends on the foot (a pad higher than its arch, a 3/4 insole without metatarsal
    /// heads) fails the job with the reason, nothing written.
    pub fn start_insole(
        self: &std::sync::Arc<Self>,
        id: &ScanId,
        req: InsoleRequest,
    ) -> Result<InsoleJob, DaemonError> {
        let plan = self.plan_insole(id, req, None, "")?;
        let first = plan.job.clone();
        self.run_insoles(vec![plan])?;
        Ok(first)
    }

    /// Both feet of visit `vid`: the shared parameters given to each foot (mirrored: posts and
    /// cut-outs are by the foot's own medial side), each foot's own changes over them. Both
    /// are checked before either starts.
    pub fn start_visit_insoles(
        self: &std::sync::Arc<Self>,
        vid: &ScanId,
        req: VisitInsoleRequest,
    ) -> Result<Vec<InsoleJob>, DaemonError> {
        use crate::archive::VisitError as V;
        let v = self.archive.visit(vid).map_err(|e| match e {
            V::NotFound(_) => DaemonError::NotFound(e.to_string()),
            V::Conflict(m) => DaemonError::Conflict(m),
            V::Archive(a) => DaemonError::Archive(a),
        })?;
        let (Some(left), Some(right)) = (&v.left, &v.right) else {
            return Err(DaemonError::Conflict(format!(
                "visit {vid} holds {}: insoles for a visit are made for both feet (add the \
                 other foot's scan, or post each scan's insole on its own)",
                match (&v.left, &v.right) {
                    (Some(_), None) => "the left foot only",
                    (None, Some(_)) => "the right foot only",
                    _ => "no scan",
                }
            )));
        };
        let mut plans = Vec::new();
        for (side, scan, own) in [("left", left, &req.left), ("right", right, &req.right)] {
            let mut params = req.params.clone();
            for (k, x) in own {
                params.insert(k.clone(), x.clone());
            }
            let one = InsoleRequest {
                preset: req.preset.clone(),
                params,
                shoe_bottom: req.shoe_bottom,
            };
            let id = ScanId::parse(scan).map_err(|e| {
                DaemonError::NotFound(format!("visit {vid}'s {side} scan {scan:?}: {e}"))
            })?;
            plans.push(self.plan_insole(
                &id,
                one,
                Some(vid.as_str()),
                &format!("{side} foot: "),
            )?);
        }
        let jobs = plans.iter().map(|p| p.job.clone()).collect();
        self.run_insoles(plans)?;
        Ok(jobs)
    }

    /// Take the slot, record each job as running and run them one after the other on a
    /// blocking thread.
    fn run_insoles(self: &std::sync::Arc<Self>, plans: Vec<Planned>) -> Result<(), DaemonError> {
        let ids: Vec<String> = plans.iter().map(|p| p.id.to_string()).collect();
        {
            let mut running = self.insole_jobs.running.lock().unwrap();
            if let Some(other) = running.as_ref() {
                return Err(DaemonError::Busy(format!(
                    "an insole is being made for scan {}: one at a time, post again when it \
                     has ended",
                    other.join(" and ")
                )));
            }
            *running = Some(ids);
        }
        for p in &plans {
            if let Err(e) = write_job(&p.dir, &p.job) {
                *self.insole_jobs.running.lock().unwrap() = None;
                return Err(e);
            }
        }
        let d = self.clone();
        let run = move || {
            let n = plans.len();
            for (i, plan) in plans.into_iter().enumerate() {
                let Planned {
                    dir,
                    params,
                    shoe,
                    mut job,
                    ..
                } = plan;
                let t0 = Instant::now();
                let made = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    make_insole(&dir, &params, shoe.as_ref(), &mut job)
                }))
                .unwrap_or_else(|_| {
                    Err("the insole design panicked (a defect: please report it)".into())
                });
                job.seconds = Some(t0.elapsed().as_secs_f64());
                job.finished = Some(footscan_util::now_rfc3339());
                match made {
                    Ok(()) => job.state = InsoleState::Done,
                    Err(why) => {
                        tracing::warn!("scan {}: insole failed: {why}", job.scan);
                        job.state = InsoleState::Failed;
                        job.reason = Some(why);
                    }
                }
                // The record and the slot change together (the last job's rule): a reader
                // that sees the job's last foot ended must find the slot free.
                let mut running = d.insole_jobs.running.lock().unwrap();
                if let Err(e) = write_job(&dir, &job) {
                    tracing::error!("scan {}: cannot record its insole job: {e}", job.scan);
                }
                if i + 1 == n {
                    *running = None;
                }
            }
        };
        match tokio::runtime::Handle::try_current() {
            // The runtime's blocking threads run at its lower priority (main.rs).
            Ok(h) => drop(h.spawn_blocking(run)),
            Err(_) => drop(std::thread::spawn(run)),
        }
        Ok(())
    }

    /// The scan's insole job (None when none was posted). A job recorded as running that this
    /// daemon is not running was cut off by a stop: it reads, and is recorded, as failed.
    pub fn insole_job(&self, id: &ScanId) -> Result<Option<InsoleJob>, DaemonError> {
        let rec = self.archive.get(id)?;
        let Some(dir) = self.archive.checked_dir(&rec) else {
            return Err(DaemonError::NotFound(format!(
                "scan {id}: its directory is missing"
            )));
        };
        let p = dir.join(JOB_FILE);
        // Held while the record is read: a job that ends meanwhile writes it under this lock.
        let running = self.insole_jobs.running.lock().unwrap();
        let bytes = match self
            .archive
            .read_inside(&p, crate::archive::MAX_JSON_ARTIFACT)
        {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(DaemonError::JobRead { path: p, source }),
        };
        let mut job: InsoleJob =
            serde_json::from_slice(&bytes).map_err(|source| DaemonError::JobJson {
                path: p.clone(),
                source,
            })?;
        let ours = running
            .as_ref()
            .is_some_and(|r| r.iter().any(|s| s == id.as_str()));
        if job.state == InsoleState::Running && !ours {
            job.state = InsoleState::Failed;
            job.reason = Some(INTERRUPTED.into());
            write_job(&dir, &job)?;
        }
        Ok(Some(job))
    }

    /// The path of file `name` of the scan's insole.
    pub fn insole_file(&self, id: &ScanId, name: &str) -> Result<PathBuf, DaemonError> {
        if !FILES.contains(&name) {
            return Err(DaemonError::BadRequest(format!(
                "file {:?}: an insole has {}",
                name.chars().take(80).collect::<String>(),
                FILES.join(", ")
            )));
        }
        let rec = self.archive.get(id)?;
        self.archive
            .checked_dir(&rec)
            .map(|d| d.join(INSOLE_DIR).join(name))
            .filter(|p| p.symlink_metadata().is_ok_and(|m| m.is_file()))
            .ok_or_else(|| {
                DaemonError::NotFound(format!(
                    "scan {id} has no insole file {name:?}: post an insole job first \
                     (POST /api/scans/{id}/insole)"
                ))
            })
    }
}

/// The job's work: design, measure back and write `insole/` all or nothing (crates/insole),
/// fill the record's figures.
fn make_insole(
    dir: &Path,
    params: &Params,
    shoe: Option<&ShoeBottom>,
    job: &mut InsoleJob,
) -> Result<(), String> {
    let plantar = Plantar::from_scan_dir(dir).map_err(|e| footscan_util::chain(&e))?;
    let w = write_insole_in(&plantar, params, shoe, &dir.join(INSOLE_DIR))
        .map_err(|e| format!("{} (nothing written)", footscan_util::chain(&e)))?;
    let r = &w.report;
    let m = &r.measured;
    job.figures = Some(InsoleFigures {
        side: r.side.clone(),
        foot_length_mm: r.foot_length_mm,
        checks: m
            .checks
            .iter()
            .map(|c| CheckLine {
                name: c.name.clone(),
                unit: c.unit.into(),
                asked: c.asked,
                measured: c.measured,
                error: c.error,
                bound: c.bound,
                ok: c.ok,
            })
            .collect(),
        min_thickness_mm: m.min_thickness_mm,
        min_thickness_bound_mm: m.min_thickness_bound_mm,
        contact_rms_mm: m.contact_rms_mm,
        contact_max_mm: m.contact_max_mm,
        ok: m.ok,
        triangles: r.mesh.triangles,
        volume_mm3: r.mesh.volume_mm3,
        // The scan's own directory is no business of the client's.
        outline_from: r
            .outline_from
            .replace(&dir.display().to_string(), "the scan"),
        warnings: r.warnings.clone(),
    });
    job.files = FILES.iter().map(|s| s.to_string()).collect();
    if !m.ok {
        return Err(format!(
            "the insole does not meet what was asked within the bounds: {}; its files are \
             written for inspection",
            r.warnings.join("; ")
        ));
    }
    Ok(())
}

fn write_job(dir: &Path, job: &InsoleJob) -> Result<(), DaemonError> {
    let p = dir.join(JOB_FILE);
    let j = serde_json::to_vec_pretty(job).expect("a job record serialises");
    footscan_util::write_atomic(&p, &j).map_err(|source| DaemonError::JobWrite {
        path: p.to_path_buf(),
        source,
    })
}
