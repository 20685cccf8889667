//! The clinic's customized last as a job of the daemon (docs/API.md, "Lasts"): a measured
//! scan, the girths a fitter posts with it and a stock last from the configured collection
//! become the last's files in the scan's directory (`last/`, replaced as a whole once every
//! file is written), with the job's record beside them (`last-job.json`: the request, the
//! state, the figures, and the reason when it failed; a failed job leaves an earlier last as
//! it was). Its life cycle (one job at a time, at the HTTP runtime's lower priority, recovery
//! after a stop, the files served) is every scan job's: scanjob.rs.

use super::fitview::{write_fit_view, FitView, FIT_FILE};
use super::scanjob::{JobLife, Kind, Planned, ScanJob};
use super::{Daemon, DaemonError};
use crate::archive::ScanId;
use footscan::lastcustom::{customize_scan, STOCK_EXTENSIONS};
use footscan_last::customize::clinic::TapeGirths;
use footscan_last::customize::rules::{RuleSet, Shoe, Wearer};
use footscan_last::customize::{
    write_misfit_atomic, write_outputs_atomic, Inputs, HEEL_RANGE_MM, OUTPUT_FILES,
};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

/// The directory of the last's files in the scan's directory.
pub const LAST_DIR: &str = "last";

/// The files of `last/`: the customization's and the 3D view's.
const FILES: [&str; 7] = {
    let o = OUTPUT_FILES;
    [o[0], o[1], o[2], o[3], o[4], o[5], FIT_FILE]
};
const _: () = assert!(OUTPUT_FILES.len() + 1 == FILES.len());

fn default_shoe() -> Shoe {
    Inputs::default().shoe
}
fn default_wearer() -> Wearer {
    Inputs::default().wearer
}
fn default_heel_mm() -> Option<f64> {
    Inputs::default().heel_mm
}

/// What a clinic posts for a scan's last (`POST /api/scans/{id}/last`).
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LastRequest {
    /// The girths a fitter measured with a tape (mm).
    pub girths: TapeGirths,
    /// A file of the stock collection (`GET /api/lasts`), for the scanned foot's side.
    pub stock: String,
    #[serde(default = "default_shoe")]
    pub shoe: Shoe,
    #[serde(default = "default_wearer")]
    pub wearer: Wearer,
    /// Heel height of the shoe (mm); absent or null: the stock last's own.
    #[serde(default = "default_heel_mm")]
    pub heel_mm: Option<f64>,
}

/// `POST /api/scans/{id}/last/rank`: the girths and what the last is for, no stock.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RankRequest {
    pub girths: TapeGirths,
    #[serde(default = "default_shoe")]
    pub shoe: Shoe,
    #[serde(default = "default_wearer")]
    pub wearer: Wearer,
    /// Heel height of the shoe (mm); absent or null: the stock last's own.
    #[serde(default = "default_heel_mm")]
    pub heel_mm: Option<f64>,
}

/// The stock collection ranked for a scan, best first.
#[derive(Clone, Debug, Serialize)]
pub struct Ranking {
    pub scan: String,
    pub seconds: f64,
    pub lasts: Vec<footscan_last::choose::Candidate>,
}

/// One rule's line as the dashboard shows it (the whole table is in last/report.json).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RuleLine {
    pub rule: String,
    pub quantity: String,
    pub foot_mm: f64,
    pub target_mm: f64,
    pub last_mm: f64,
    pub error_mm: f64,
    pub met: bool,
    /// Why the rule has no counterpart on the stock last (not solved for; `met` true,
    /// `error_mm` 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub not_applicable: Option<String>,
    /// How much the build-up for the footprint grew the measure after the solve met it.
    #[serde(default)]
    pub built_up_mm: f64,
}

/// A scan's last job as recorded in `last-job.json` and shown by the API.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct LastJob {
    #[serde(flatten)]
    pub life: JobLife,
    pub request: LastRequest,
    pub rules: Vec<RuleLine>,
    /// The clearance line (region by region: the scan's footprint inside the last's bottom
    /// outline) and whether it lies inside where the rules say the foot must fit.
    pub clearance: Option<String>,
    pub fits: Option<bool>,
    /// The files of `last/`, downloadable at `/api/scans/{id}/last/{name}`.
    pub files: Vec<String>,
    /// The foot inside the last for the 3D view (`last/fit.glb`) and the placement it used;
    /// absent before the last is written, or when it could not be made (`fit_error` says
    /// why: the last itself is made all the same).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit: Option<FitView>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fit_error: Option<String>,
}

impl ScanJob for LastJob {
    type Request = LastRequest;
    const KIND: &'static Kind = &Kind {
        noun: "last",
        a: "a last",
        work: "the customization",
        record: "last-job.json",
        dir: LAST_DIR,
        files: &FILES,
        post_with: "the girths and a stock last",
    };
    fn life(&mut self) -> &mut JobLife {
        &mut self.life
    }
    fn start(d: &Arc<Daemon>, id: &ScanId, req: LastRequest) -> Result<LastJob, DaemonError> {
        d.start_last(id, req)
    }
}

/// A stock last of the collection.
#[derive(Clone, Debug, Serialize)]
pub struct StockLast {
    pub name: String,
    pub bytes: u64,
}

/// Whether `name` can be a stock last's file: an artifact name with a mesh extension.
fn stock_name_ok(name: &str) -> bool {
    footscan::io::is_artifact_name(name)
        && name
            .rsplit_once('.')
            .is_some_and(|(_, e)| STOCK_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

impl Daemon {
    fn stock_dir(&self) -> Result<&Path, DaemonError> {
        self.config.stock_lasts.as_deref().ok_or_else(|| {
            DaemonError::Unsupported(format!(
                "no stock lasts: set `stock_dir` in [lasts] of {} to the directory of the \
                 shop's lasts (STL, OBJ or PLY)",
                self.config.path.display()
            ))
        })
    }

    /// The stock collection: every mesh file in `[lasts] stock_dir`, by name.
    pub fn stock_lasts(&self) -> Result<Vec<StockLast>, DaemonError> {
        let dir = self.stock_dir()?;
        let rd = std::fs::read_dir(dir).map_err(|source| DaemonError::StockLasts {
            dir: dir.to_path_buf(),
            source,
        })?;
        let mut out: Vec<StockLast> = rd
            .flatten()
            .filter(|e| e.file_type().is_ok_and(|t| t.is_file()))
            .filter_map(|e| {
                let name = e.file_name().to_string_lossy().into_owned();
                let bytes = e.metadata().ok()?.len();
                stock_name_ok(&name).then_some(StockLast { name, bytes })
            })
            .collect();
        out.sort_by(|a, b| a.name.cmp(&b.name));
        Ok(out)
    }

    /// The path of stock last `name`: a regular file directly in the collection.
    fn stock_path(&self, name: &str) -> Result<PathBuf, DaemonError> {
        let dir = self.stock_dir()?;
        let listed = || {
            self.stock_lasts()
                .map(|v| v.into_iter().map(|s| s.name).collect::<Vec<_>>().join(", "))
                .unwrap_or_default()
        };
        if !stock_name_ok(name) {
            return Err(DaemonError::BadRequest(format!(
                "stock {:?}: must be a file of the stock collection ({}), one of: {}",
                name.chars().take(80).collect::<String>(),
                STOCK_EXTENSIONS.join(", "),
                listed()
            )));
        }
        let p = dir.join(name);
        if !p.symlink_metadata().is_ok_and(|m| m.is_file()) {
            return Err(DaemonError::BadRequest(format!(
                "stock {name:?} is not in the stock collection {}; it has: {}",
                dir.display(),
                listed()
            )));
        }
        Ok(p)
    }

    /// A last request's girths and heel checked (400 naming the value and what is valid), and
    /// the rule set in force.
    fn checked_request(
        &self,
        g: &TapeGirths,
        heel_mm: Option<f64>,
    ) -> Result<(TapeGirths, RuleSet), DaemonError> {
        let girths = TapeGirths::checked(g.ball, g.instep, g.long_heel, g.ankle)
            .map_err(|e| DaemonError::BadRequest(format!("girths: {e}")))?;
        if let Some(heel_mm) = heel_mm.filter(|h| !(HEEL_RANGE_MM.0..=HEEL_RANGE_MM.1).contains(h))
        {
            return Err(DaemonError::BadRequest(format!(
                "heel_mm = {}: a heel is {:.0}-{:.0} mm high",
                heel_mm, HEEL_RANGE_MM.0, HEEL_RANGE_MM.1
            )));
        }
        let rules = match &self.config.last_rules {
            Some(p) => RuleSet::load(p)?,
            None => RuleSet::default_rules(),
        };
        Ok((girths, rules))
    }

    /// Rank the stock collection for a measured scan and the fitter's girths, as `footscan
    /// last choose` does: by how little each last must change (its largest rule station and
    /// its bottom outline), with what each cannot meet and why. Runs on the caller's thread
    /// (the API's blocking pool): reading and measuring the lasts is the work, in parallel.
    pub fn rank_lasts(&self, id: &ScanId, req: RankRequest) -> Result<Ranking, DaemonError> {
        let (_, dir) = self.measured_scan(id, "a ranking of the stock lasts")?;
        let (girths, rules) = self.checked_request(&req.girths, req.heel_mm)?;
        let plantar = footscan::lastcustom::plantar_of_scan(&dir).map_err(DaemonError::Plantar)?;
        girths
            .check_against(&plantar)
            .map_err(|e| DaemonError::BadRequest(format!("girths: {e}")))?;
        let inp = Inputs {
            shoe: req.shoe,
            wearer: req.wearer,
            heel_mm: req.heel_mm,
        };
        let t0 = Instant::now();
        let stock = self.stock_dir()?.to_path_buf();
        let names: Vec<String> = self.stock_lasts()?.into_iter().map(|s| s.name).collect();
        let files: Vec<PathBuf> = names.iter().map(|n| stock.join(n)).collect();
        let want = footscan_last::choose::Wanted {
            girths: &girths,
            rules: &rules,
            inp: &inp,
        };
        let judged = footscan_last::choose::judge_files(
            &files,
            footscan_geom::mesh::Units::Auto,
            None,
            &plantar,
            &want,
        );
        let mut lasts: Vec<footscan_last::choose::Candidate> = judged
            .into_iter()
            .zip(&names)
            .map(|((mut c, _), n)| {
                // The collection's file name, not the daemon's path to it.
                let path = c.name.clone();
                for t in c.cannot.iter_mut().chain(c.notes.iter_mut()) {
                    *t = t.replace(&path, n);
                }
                c.name = n.clone();
                c
            })
            .collect();
        footscan_last::choose::rank(&mut lasts);
        Ok(Ranking {
            scan: id.to_string(),
            seconds: t0.elapsed().as_secs_f64(),
            lasts,
        })
    }

    /// Check a request and start its job; the job's record says `running` until it ends.
    /// Everything the request names is checked here, so a bad one is a 400, not a job that
    /// fails.
    fn start_last(self: &Arc<Self>, id: &ScanId, req: LastRequest) -> Result<LastJob, DaemonError> {
        let dir = self.finished_scan(id, LastJob::KIND)?;
        let (girths, rules) = self.checked_request(&req.girths, req.heel_mm)?;
        let stock = self.stock_path(&req.stock)?;
        let inp = Inputs {
            shoe: req.shoe,
            wearer: req.wearer,
            heel_mm: req.heel_mm,
        };
        let record = LastJob {
            life: JobLife::running(id),
            request: req,
            rules: Vec::new(),
            clearance: None,
            fits: None,
            files: Vec::new(),
            fit: None,
            fit_error: None,
        };
        let first = record.clone();
        self.run_jobs(vec![Planned {
            dir,
            record,
            work: Box::new(move |dir: &Path, job: &mut LastJob| {
                make_last(dir, &girths, &stock, &rules, &inp, job)
            }),
        }])?;
        Ok(first)
    }
}

/// The job's work: customize, write `last/` all or nothing, fill the record's figures.
fn make_last(
    dir: &Path,
    girths: &TapeGirths,
    stock: &Path,
    rules: &RuleSet,
    inp: &Inputs,
    job: &mut LastJob,
) -> Result<(), String> {
    let c = customize_scan(dir, girths, stock, rules, inp).map_err(|e| footscan_util::chain(&e))?;
    job.rules = c
        .rules
        .iter()
        .map(|r| RuleLine {
            rule: r.rule.into(),
            quantity: r.quantity.into(),
            foot_mm: r.foot_mm,
            target_mm: r.target_mm,
            last_mm: r.last_mm,
            // NaN would be written as null and not read back.
            error_mm: if r.applies { r.error_mm } else { 0.0 },
            met: r.met,
            not_applicable: r.not_applicable.clone(),
            built_up_mm: r.built_up_mm,
        })
        .collect();
    job.clearance = Some(format!(
        "{} inside the last: {}",
        c.clearance.of,
        c.clearance.summary()
    ));
    job.fits = Some(c.clearance.regions.iter().all(|r| r.met()));
    // As the CLI: a last that misses its rules is not a made last. Its files are kept,
    // marked (report.json "misfit", MISFIT.txt), so nothing is lost, and the job fails with
    // the reasons.
    let misfits = c.misfits();
    let write = if misfits.is_empty() {
        write_outputs_atomic
    } else {
        write_misfit_atomic
    };
    let files = write(&c, inp, &dir.join(LAST_DIR)).map_err(|e| footscan_util::chain(&e))?;
    job.files = files
        .iter()
        .filter_map(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .collect();
    // The 3D view's foot inside the last, written into the directory just replaced (so no
    // earlier last's view is left beside this last). The last is made without it.
    let fit = match footscan::scandata::ScanDir::new(dir).load_measurements() {
        Ok(Some(m)) => write_fit_view(dir, &dir.join(LAST_DIR), &m, &c),
        Ok(None) => Err("the scan has no measurements.json".into()),
        Err(e) => Err(footscan_util::chain(&e)),
    };
    match fit {
        Ok(f) => job.fit = Some(f),
        Err(why) => {
            tracing::warn!(
                "scan {}: no 3D view of the foot in the last: {why}",
                job.life.scan
            );
            job.fit_error = Some(why);
        }
    }
    if !misfits.is_empty() {
        return Err(format!(
            "the last does not do what its rules ask: {}; its files are kept marked as a \
             misfit ({})",
            misfits.join("; "),
            footscan_last::customize::MISFIT_FILE
        ));
    }
    Ok(())
}
