//! What every job on a finished scan shares (the clinic's last, lastjob.rs; the insole,
//! insolejob.rs; not the scan itself, jobs.rs): its record beside the scan's files, one job
//! of a kind at a time, a job cut off by a stop read as failed, a failure kept with its
//! reason, and the files served only from the job's own directory. One life cycle for every
//! kind, so a fix to one (the slot freed under the record's lock, the record read through
//! `read_inside`) cannot be missed in another.

use super::{Daemon, DaemonError};
use crate::archive::{ScanId, Status, VisitError};
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

/// Where a job is in its life.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JobState {
    Running,
    Done,
    Failed,
}

/// The part of a job's record the life cycle keeps: whose job it is, when it ran, how it
/// ended (flattened into the record: the JSON has these keys beside the kind's own).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct JobLife {
    /// The scan the job makes files for.
    pub scan: String,
    pub state: JobState,
    pub started: String,
    pub finished: Option<String>,
    pub seconds: Option<f64>,
    /// Why it failed: the input named and what would be valid.
    pub reason: Option<String>,
}

impl JobLife {
    /// A job on scan `id` that starts now.
    pub fn running(id: &ScanId) -> JobLife {
        JobLife {
            scan: id.to_string(),
            state: JobState::Running,
            started: footscan_util::now_rfc3339(),
            finished: None,
            seconds: None,
            reason: None,
        }
    }
}

/// The words and names that differ between kinds of job.
pub struct Kind {
    /// What is made, as in the API's path (`/api/scans/{id}/last`) and in "the last".
    pub noun: &'static str,
    /// The same with its article ("a last", "an insole").
    pub a: &'static str,
    /// The work, as a panic's reason names it ("the customization").
    pub work: &'static str,
    /// The job's record in the scan's directory.
    pub record: &'static str,
    /// The directory of the made files in the scan's directory.
    pub dir: &'static str,
    /// The files served from `dir` (`/api/scans/{id}/{noun}/{name}`); no other name is.
    pub files: &'static [&'static str],
    /// What a first job is posted with, for the 404 of a scan without one.
    pub post_with: &'static str,
}

/// A kind of job on a finished scan: its record (as written to `Kind::record` and shown by
/// the API) and how a request starts one.
pub trait ScanJob: Clone + Serialize + DeserializeOwned + Send + 'static {
    /// What `POST /api/scans/{id}/{noun}` takes.
    type Request: DeserializeOwned + Send + 'static;
    const KIND: &'static Kind;
    fn life(&mut self) -> &mut JobLife;
    /// Check a request (a 400 naming what is wrong, nothing written) and start its job; the
    /// record as it stands at the start.
    fn start(d: &Arc<Daemon>, id: &ScanId, req: Self::Request) -> Result<Self, DaemonError>;
}

/// The scans each kind's running job is making files for, by `Kind::noun` (one job of a
/// kind at a time; a visit's insole job holds both feet). One lock for every kind: a visit
/// is deleted under it, so no job of any kind starts on a scan being deleted.
#[derive(Default)]
pub(super) struct Running {
    scans: Mutex<BTreeMap<&'static str, Vec<String>>>,
}

/// A job's work on the scan's directory: fills the record's figures, or says why it failed.
pub(super) type Work<R> = Box<dyn FnOnce(&Path, &mut R) -> Result<(), String> + Send>;

/// One scan's job, checked and ready to run: the work fills the record's figures and says
/// why it failed.
pub(super) struct Planned<R> {
    pub dir: PathBuf,
    pub record: R,
    pub work: Work<R>,
}

/// `a, b and c`.
fn listed(names: &[&str]) -> String {
    match names.split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
        None => String::new(),
    }
}

fn write_record<R: ScanJob>(dir: &Path, job: &R) -> Result<(), DaemonError> {
    let p = dir.join(R::KIND.record);
    let j = serde_json::to_vec_pretty(job).expect("a job record serialises");
    footscan_util::write_atomic(&p, &j).map_err(|source| DaemonError::JobWrite {
        path: p.to_path_buf(),
        source,
    })
}

impl Daemon {
    /// A measured scan that has ended, and its directory: what a job of kind `k` is made
    /// from (409 otherwise).
    pub(super) fn finished_scan(&self, id: &ScanId, k: &Kind) -> Result<PathBuf, DaemonError> {
        let (rec, dir) = self.measured_scan(id, k.a)?;
        if rec.status == Status::Running {
            return Err(DaemonError::Conflict(format!(
                "scan {id} is still running: {} is made from a finished scan",
                k.a
            )));
        }
        Ok(dir)
    }

    /// Take the kind's slot for the planned scans, record each job as running and run them
    /// one after the other on the HTTP runtime's blocking threads (its lower priority: a job
    /// never takes the CPU from a scan). Busy (409) while another job of the kind runs.
    pub(super) fn run_jobs<R: ScanJob>(
        self: &Arc<Self>,
        mut plans: Vec<Planned<R>>,
    ) -> Result<(), DaemonError> {
        let k = R::KIND;
        let ids = plans.iter_mut().map(|p| p.record.life().scan.clone());
        let ids: Vec<String> = ids.collect();
        {
            let mut running = self.scan_jobs.scans.lock().unwrap();
            if let Some(other) = running.get(k.noun) {
                return Err(DaemonError::Busy(format!(
                    "{} is being made for scan {}: one at a time, post again when it has ended",
                    k.a,
                    other.join(" and ")
                )));
            }
            running.insert(k.noun, ids);
        }
        for p in &plans {
            if let Err(e) = write_record(&p.dir, &p.record) {
                self.scan_jobs.scans.lock().unwrap().remove(k.noun);
                return Err(e);
            }
        }
        let d = self.clone();
        let run = move || {
            let n = plans.len();
            for (i, p) in plans.into_iter().enumerate() {
                let Planned {
                    dir,
                    mut record,
                    work,
                } = p;
                let t0 = Instant::now();
                let made = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    work(&dir, &mut record)
                }))
                .unwrap_or_else(|_| {
                    Err(format!("{} panicked (a defect: please report it)", k.work))
                });
                let life = record.life();
                let scan = life.scan.clone();
                life.seconds = Some(t0.elapsed().as_secs_f64());
                life.finished = Some(footscan_util::now_rfc3339());
                match made {
                    Ok(()) => life.state = JobState::Done,
                    Err(why) => {
                        tracing::warn!("scan {scan}: {} failed: {why}", k.noun);
                        life.state = JobState::Failed;
                        life.reason = Some(why);
                    }
                }
                // The record and the slot change together: a reader that sees the job's
                // last scan ended must find the slot free (a visit deleted right after it, a
                // next job posted).
                let mut running = d.scan_jobs.scans.lock().unwrap();
                if let Err(e) = write_record(&dir, &record) {
                    tracing::error!("scan {scan}: cannot record its {} job: {e}", k.noun);
                }
                if i + 1 == n {
                    running.remove(k.noun);
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

    /// The scan's job of kind `R` (None when none was posted). A job recorded as running
    /// that this daemon is not running was cut off by a stop: it reads, and is recorded, as
    /// failed.
    pub fn scan_job<R: ScanJob>(&self, id: &ScanId) -> Result<Option<R>, DaemonError> {
        let k = R::KIND;
        let rec = self.archive.get(id)?;
        let Some(dir) = self.archive.checked_dir(&rec) else {
            return Err(DaemonError::NotFound(format!(
                "scan {id}: its directory is missing"
            )));
        };
        let p = dir.join(k.record);
        // Held while the record is read: a job that ends meanwhile writes it under this lock.
        let running = self.scan_jobs.scans.lock().unwrap();
        let bytes = match self
            .archive
            .read_inside(&p, crate::archive::MAX_JSON_ARTIFACT)
        {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(source) => return Err(DaemonError::JobRead { path: p, source }),
        };
        let mut job: R = serde_json::from_slice(&bytes).map_err(|source| DaemonError::JobJson {
            path: p.clone(),
            source,
        })?;
        let ours = running
            .get(k.noun)
            .is_some_and(|r| r.iter().any(|s| s == id.as_str()));
        let life = job.life();
        if life.state == JobState::Running && !ours {
            life.state = JobState::Failed;
            life.reason = Some(format!(
                "footscand stopped while the {} was being made; post it again",
                k.noun
            ));
            write_record(&dir, &job)?;
        }
        Ok(Some(job))
    }

    /// The path of file `name` made by the scan's job of kind `R` (a name of `Kind::files`,
    /// a regular file in the job's directory; opened by the caller through `open_inside`).
    pub fn scan_job_file<R: ScanJob>(
        &self,
        id: &ScanId,
        name: &str,
    ) -> Result<PathBuf, DaemonError> {
        let k = R::KIND;
        if !k.files.contains(&name) {
            return Err(DaemonError::BadRequest(format!(
                "file {:?}: {} has {}",
                name.chars().take(80).collect::<String>(),
                k.a,
                listed(k.files)
            )));
        }
        let rec = self.archive.get(id)?;
        self.archive
            .checked_dir(&rec)
            .map(|d| d.join(k.dir).join(name))
            .filter(|p| p.symlink_metadata().is_ok_and(|m| m.is_file()))
            .ok_or_else(|| {
                DaemonError::NotFound(format!(
                    "scan {id} has no {} file {name:?}: post {} job first (POST \
                     /api/scans/{id}/{})",
                    k.noun, k.a, k.noun
                ))
            })
    }

    /// Delete a visit with its scans, unless a job is making files for one of them: it
    /// writes them into the scan's directory when it ends and would bring the deleted scan's
    /// directory back. The running jobs' lock is held while deleting, so no job starts on a
    /// scan being deleted.
    pub fn delete_visit(&self, vid: &ScanId) -> Result<Vec<String>, VisitError> {
        use super::insolejob::InsoleJob;
        use super::lastjob::LastJob;
        let running = self.scan_jobs.scans.lock().unwrap();
        self.archive.delete_visit(vid, |v| {
            let held = |scan: &str| [&v.left, &v.right].into_iter().flatten().any(|s| s == scan);
            [LastJob::KIND, InsoleJob::KIND].into_iter().find_map(|k| {
                let scans = running.get(k.noun)?;
                scans.iter().find(|s| held(s)).map(|scan| {
                    format!(
                        "{} is being made for scan {scan} of visit {vid}: delete the visit \
                         when it has ended (GET /api/scans/{scan}/{})",
                        k.a, k.noun
                    )
                })
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::listed;

    #[test]
    fn file_lists_read_as_english() {
        assert_eq!(listed(&[]), "");
        assert_eq!(listed(&["a.stl"]), "a.stl");
        assert_eq!(
            listed(&["a.stl", "b.png", "c.json"]),
            "a.stl, b.png and c.json"
        );
    }
}
