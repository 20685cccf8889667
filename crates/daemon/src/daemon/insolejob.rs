//! The orthotic insole as a job of the daemon (docs/API.md, "Insoles"), built as the last
//! job is (lastjob.rs): a measured, finished scan and the clinician's parameters (a preset
//! and the keys changed from it) become the insole's files in the scan's directory
//! (`insole/`, replaced as a whole once every file is written, by crates/insole), with the
//! job's record beside them (`insole-job.json`: the request, the parameters as applied, the
//! state, each parameter measured back on the mesh, and the reason when it failed; a failed
//! job leaves an earlier insole as it was). A visit's two feet are one job: the parameters
//! posted for both are given to each foot in its own medial and lateral sense (mirrored: a
//! medial post is medial on both), with a foot's own changes over them. Its life cycle (one
//! job at a time, a visit's two feet one after the other, recovery after a stop, the files
//! served) is every scan job's: scanjob.rs.

use super::scanjob::{JobLife, Kind, Planned, ScanJob};
use super::{Daemon, DaemonError};
use crate::archive::ScanId;
use footscan_insole::{write, write_insole_in, Params, Plantar, ShoeBottom};
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};
use std::path::Path;
use std::sync::Arc;

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
    /// The visit whose two feet were posted together, if so.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub visit: Option<String>,
    #[serde(flatten)]
    pub life: JobLife,
    /// This foot's request (for a visit: the shared changes with the foot's own over them).
    pub request: InsoleRequest,
    /// Every parameter as applied.
    pub params: Params,
    pub figures: Option<InsoleFigures>,
    /// The files of `insole/`, downloadable at `/api/scans/{id}/insole/{name}`.
    pub files: Vec<String>,
}

impl ScanJob for InsoleJob {
    type Request = InsoleRequest;
    const KIND: &'static Kind = &Kind {
        noun: "insole",
        a: "an insole",
        work: "the insole design",
        record: "insole-job.json",
        dir: INSOLE_DIR,
        files: &FILES,
        post_with: "a preset and the parameters to change",
    };
    fn life(&mut self) -> &mut JobLife {
        &mut self.life
    }
    /// The parameters are checked before the job starts; what depends on the foot (a pad
    /// higher than its arch, a 3/4 insole without metatarsal heads) fails the job with the
    /// reason, nothing written.
    fn start(d: &Arc<Daemon>, id: &ScanId, req: InsoleRequest) -> Result<InsoleJob, DaemonError> {
        let plan = d.plan_insole(id, req, None, "")?;
        let first = plan.record.clone();
        d.run_jobs(vec![plan])?;
        Ok(first)
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
    ) -> Result<Planned<InsoleJob>, DaemonError> {
        let dir = self.finished_scan(id, InsoleJob::KIND)?;
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
        let record = InsoleJob {
            visit: visit.map(str::to_string),
            life: JobLife::running(id),
            request: req,
            params: params.clone(),
            figures: None,
            files: Vec::new(),
        };
        Ok(Planned {
            dir,
            record,
            work: Box::new(move |dir: &Path, job: &mut InsoleJob| {
                make_insole(dir, &params, shoe.as_ref(), job)
            }),
        })
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
        let jobs = plans.iter().map(|p| p.record.clone()).collect();
        self.run_jobs(plans)?;
        Ok(jobs)
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
