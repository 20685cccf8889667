//! The guided calibration and the daily check as daemon jobs: the library's one procedure
//! (`footscan::calib::guided`) on the scanner's own backend, confirmed over HTTP.
//!
//! The job thread runs the procedure with an [`HttpGuide`]: at each step it publishes the step
//! (what to place) in the job's view, sends it on the event stream, and blocks until the
//! operator answers through the API (confirm, repeat, abort); after the step it publishes what
//! was seen and waits again. On the simulator backend the rig's operator swaps the scene
//! (scripted mistakes included); on hardware a person does, and the job is the same. A job
//! with `guided: false` is confirmed by nobody (every step accepted when its check passes).
//! The result goes into the archive's calibration history ([`Calibrations`]) or the daily
//! check trend.

use super::{CalibrationInfo, CalibrationJob, Daemon, DaemonError, Event, Job};
use crate::archive::calibrations::{CalibrationEntry, Calibrations, CheckEntry};
use crate::archive::{ScanId, Status};
use footscan::calib::acquire::{Mistake, Target};
use footscan::calib::guided::{AutoGuide, Decision, Guide, Ready, Step, StepResult};
use footscan::calib::{self, CalibError, CalibrationPlan, Method};
use footscan::scan::calibrate as procedure;
use std::panic::AssertUnwindSafe;
use std::sync::mpsc::{Receiver, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The operator's answer to the waiting step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Answer {
    /// The target is in place (when placing); keep the step (when reviewing).
    Confirm,
    /// Take the step again (when reviewing).
    Repeat,
    Abort,
}

impl Answer {
    pub fn name(self) -> &'static str {
        match self {
            Answer::Confirm => "confirm",
            Answer::Repeat => "repeat",
            Answer::Abort => "abort",
        }
    }
}

/// The step an answer is meant for, as the operator saw it (`GET /api/calibrations/job`);
/// each field left out is not checked.
#[derive(Clone, Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnswerFor {
    /// "place" or "review".
    pub phase: Option<String>,
    /// The step's 0-based index (`step.index`).
    pub step: Option<usize>,
    pub attempt: Option<usize>,
}

/// What a calibration or check job is asked to do.
#[derive(Clone, Debug)]
pub struct JobRequest {
    pub method: Method,
    /// Wait for the operator at each step (else every passing step is kept).
    pub guided: bool,
    /// Who confirms, kept with the calibration.
    pub confirmed_by: String,
    /// Simulator only: what its operator places instead of the asked target (once each).
    pub sim_mistakes: Vec<(Target, Mistake)>,
}

/// A target or a simulated mistake the API does not know.
#[derive(Debug, thiserror::Error)]
pub enum TargetError {
    #[error("target {0:?}: must be \"plate:<mm>\" (e.g. plate:15), \"staircase\" or \"empty\"")]
    Target(String),
    #[error(
        "placed {0:?}: must be \"plate:<mm>\" (the plate on other spacers), \"staircase\" or \
         \"nothing\""
    )]
    Mistake(String),
}

/// Parse a target as the API names it: `plate:<mm>`, `staircase`, `empty`.
pub fn parse_target(s: &str) -> Result<Target, TargetError> {
    match s {
        "staircase" => Ok(Target::Staircase),
        "empty" => Ok(Target::Empty),
        _ => plate_mm(s)
            .map(|height_mm| Target::Plate { height_mm })
            .ok_or_else(|| TargetError::Target(s.to_string())),
    }
}

/// Parse a simulated mistake: `plate:<mm>`, `staircase`, `nothing`.
pub fn parse_mistake(s: &str) -> Result<Mistake, TargetError> {
    match s {
        "staircase" => Ok(Mistake::Staircase),
        "nothing" => Ok(Mistake::Nothing),
        _ => plate_mm(s)
            .map(|height_mm| Mistake::Plate { height_mm })
            .ok_or_else(|| TargetError::Mistake(s.to_string())),
    }
}

fn plate_mm(s: &str) -> Option<f64> {
    let v: f64 = s.strip_prefix("plate:")?.trim().parse().ok()?;
    (v.is_finite() && (0.0..=200.0).contains(&v)).then_some(v)
}

/// Minimum spacing of frame-progress events.
const PROGRESS_PERIOD: Duration = Duration::from_millis(100);

/// Confirms the steps through the daemon: publishes each step and waits for an [`Answer`].
struct HttpGuide {
    daemon: Arc<Daemon>,
    answers: Receiver<Answer>,
    last_progress: Option<Instant>,
}

impl HttpGuide {
    fn wait(&mut self, step: &Step) -> Result<Answer, CalibError> {
        self.answers.recv().map_err(|_| CalibError::Aborted {
            step: step.index + 1,
            title: step.title.clone(),
            reason: "the daemon is shutting down".into(),
        })
    }
}

impl Guide for HttpGuide {
    fn ready(&mut self, step: &Step, attempt: usize) -> Result<Ready, CalibError> {
        self.daemon.update_job(|j| {
            j.phase = "place".into();
            j.step = Some(step.clone());
            j.attempt = attempt;
            j.frames = 0;
            j.total_frames = step.frames();
            j.result = None;
            j.message = Some(format!(
                "step {} of {}: {} (attempt {attempt}). Place it and confirm.",
                step.index + 1,
                step.of,
                step.instruction
            ));
        });
        loop {
            match self.wait(step)? {
                Answer::Confirm => break,
                Answer::Abort => return Ok(Ready::Abort),
                Answer::Repeat => {} // refused by the API while placing
            }
        }
        self.daemon.update_job(|j| {
            j.phase = "acquiring".into();
            j.message = Some(format!("acquiring {}", step.title));
        });
        Ok(Ready::Go)
    }

    fn progress(&mut self, step: &Step, done: usize, total: usize) {
        let emit = done == total
            || self
                .last_progress
                .is_none_or(|t| t.elapsed() >= PROGRESS_PERIOD);
        self.daemon.update_job_quiet(|j| {
            j.frames = done;
            j.total_frames = total;
            j.step.get_or_insert_with(|| step.clone());
        });
        if emit {
            self.last_progress = Some(Instant::now());
            self.daemon.emit_job();
        }
    }

    fn review(&mut self, step: &Step, result: &StepResult) -> Result<Decision, CalibError> {
        let passed = result.passed();
        self.daemon.update_job(|j| {
            j.phase = "review".into();
            j.result = Some(result.clone());
            j.message = Some(if passed {
                format!(
                    "{}: {}. Keep it (confirm), repeat or abort.",
                    step.title,
                    result.message()
                )
            } else {
                format!(
                    "{}: {}. Repeat the step or abort.",
                    step.title,
                    result.message()
                )
            });
        });
        Ok(match self.wait(step)? {
            Answer::Confirm => {
                self.daemon.update_job(|j| {
                    j.kept.push(step.title.clone());
                    // After the last step the fit (or the check's measurement) runs.
                    j.phase = if step.index + 1 == step.of {
                        "fitting"
                    } else {
                        "acquiring"
                    }
                    .into();
                    j.message = None;
                });
                Decision::Accept
            }
            Answer::Repeat => Decision::Repeat,
            Answer::Abort => Decision::Abort,
        })
    }
}

/// A guide that answers itself but shows the steps in the job's view (`guided: false`).
struct ShownAutoGuide {
    daemon: Arc<Daemon>,
    auto: AutoGuide<'static>,
    last_progress: Option<Instant>,
}

impl Guide for ShownAutoGuide {
    fn ready(&mut self, step: &Step, attempt: usize) -> Result<Ready, CalibError> {
        self.daemon.update_job(|j| {
            j.phase = "acquiring".into();
            j.step = Some(step.clone());
            j.attempt = attempt;
            j.result = None;
            j.message = Some(format!("acquiring {}", step.title));
        });
        self.auto.ready(step, attempt)
    }

    fn progress(&mut self, _step: &Step, done: usize, total: usize) {
        self.daemon.update_job_quiet(|j| {
            j.frames = done;
            j.total_frames = total;
        });
        if done == total
            || self
                .last_progress
                .is_none_or(|t| t.elapsed() >= PROGRESS_PERIOD)
        {
            self.last_progress = Some(Instant::now());
            self.daemon.emit_job();
        }
    }

    fn review(&mut self, step: &Step, result: &StepResult) -> Result<Decision, CalibError> {
        let d = self.auto.review(step, result)?;
        self.daemon.update_job(|j| {
            j.result = Some(result.clone());
            if d == Decision::Accept {
                j.kept.push(step.title.clone());
            }
        });
        Ok(d)
    }
}

impl Daemon {
    fn busy_job(&self) -> Option<String> {
        let st = self.state.lock().unwrap();
        if st.shutting_down {
            return Some("the daemon is shutting down".into());
        }
        match &st.job {
            Some(Job::Scan { id, .. }) => Some(format!(
                "scan {id} is running: wait for it to end or cancel it (POST /api/scans/{id}/cancel)"
            )),
            Some(Job::Calibration { .. }) => {
                let c = st.calibrating.as_ref();
                Some(format!(
                    "{} {} is running: finish or abort it (POST /api/calibrations/{}/abort)",
                    c.map_or("calibration", |c| c.kind.as_str()),
                    c.map_or("", |c| c.id.as_str()),
                    c.map_or("<id>", |c| c.id.as_str()),
                ))
            }
            None => None,
        }
    }

    /// Change the job's view and send it on the event stream.
    fn update_job(&self, f: impl FnOnce(&mut CalibrationJob)) {
        self.update_job_quiet(f);
        self.emit_job();
    }

    fn update_job_quiet(&self, f: impl FnOnce(&mut CalibrationJob)) {
        if let Some(j) = self.state.lock().unwrap().calibrating.as_mut() {
            f(j);
        }
    }

    fn emit_job(&self) {
        let j = self.state.lock().unwrap().calibrating.clone();
        if let Some(j) = j {
            self.emit(Event::Calibration(Box::new(j)));
        }
    }

    /// Start a calibration (`kind` "calibration") or a daily check ("verify"); returns its id.
    /// Busy while another job runs.
    pub fn start_calibration_job(
        self: &Arc<Self>,
        kind: &str,
        req: JobRequest,
    ) -> Result<String, DaemonError> {
        let sim = self.scanner.config.scanner.backend == footscan::scan::config::Backend::Sim;
        if !sim && !req.sim_mistakes.is_empty() {
            return Err(DaemonError::BadRequest(
                "sim_mistakes: only the simulator backend has an operator to script".into(),
            ));
        }
        if !sim && req.method == Method::Opencv {
            return Err(DaemonError::BadRequest(
                "method opencv is the simulator's checkerboard reference; calibrate a hardware \
                 scanner with insystem or bezier"
                    .into(),
            ));
        }
        let check_cal = if kind == "verify" {
            Some(self.calibration_to_check()?)
        } else {
            None
        };
        if let Some(why) = self.busy_job() {
            return Err(DaemonError::Busy(why));
        }
        let mut st = self.state.lock().unwrap();
        if st.job.is_some() || st.shutting_down {
            return Err(DaemonError::Busy("another job started just now".into()));
        }
        let id = format!("{}", ScanId::generate(7));
        let job = CalibrationJob {
            id: id.clone(),
            kind: kind.into(),
            method: req.method.name().into(),
            state: Status::Running,
            reason: None,
            guided: req.guided,
            confirmed_by: req.confirmed_by.clone(),
            phase: "starting".into(),
            step: None,
            attempt: 0,
            frames: 0,
            total_frames: 0,
            result: None,
            message: None,
            kept: Vec::new(),
            calibration_id: None,
            report: None,
        };
        st.calibrating = Some(job.clone());
        let (tx, rx) = std::sync::mpsc::channel();
        st.guide = req.guided.then_some(tx);
        let me = self.clone();
        let thread = self
            .launcher
            .spawn(format!("{kind}-{id}"), move || {
                me.run_job(req, rx, check_cal)
            })
            .map_err(|source| DaemonError::Thread {
                what: format!("the {kind} thread"),
                source,
            })?;
        st.job = Some(Job::Calibration { _thread: thread });
        drop(st);
        tracing::info!("{kind} {id} started");
        self.emit(Event::Calibration(Box::new(job)));
        Ok(id)
    }

    /// The operator's answer to job `id`'s waiting step. Refused when the job is not
    /// waiting for that answer (confirming a step that failed its check, repeating before
    /// the step was taken).
    ///
    /// The check and the hand-over are one step under the state lock: the answer moves the
    /// job out of its waiting phase before the lock is let go, so of several simultaneous
    /// answers one is taken and the others are refused (409); none waits in the channel for
    /// a later step. `expect`, when given, is the step the operator saw: an answer meant for
    /// another phase, step or attempt is refused too.
    pub fn answer_job(
        &self,
        id: &str,
        a: Answer,
        expect: Option<&AnswerFor>,
    ) -> Result<CalibrationJob, DaemonError> {
        let mut st = self.state.lock().unwrap();
        let job = match &st.calibrating {
            Some(j) if j.id == id => j.clone(),
            _ => {
                return Err(DaemonError::NotFound(format!(
                    "calibration job {id} is not the current job (GET /api/calibrations/job)"
                )))
            }
        };
        if job.state != Status::Running {
            return Err(DaemonError::NotRunning(format!(
                "{} {id} has ended ({}): nothing to {}",
                job.kind,
                job.state.as_str(),
                a.name()
            )));
        }
        let Some(tx) = st.guide.as_ref() else {
            return Err(DaemonError::NotRunning(format!(
                "{} {id} was started with guided: false; it confirms its own steps",
                job.kind
            )));
        };
        if let Some(e) = expect {
            let step = job.step.as_ref().map(|s| s.index);
            let mismatch = [
                e.phase
                    .as_deref()
                    .filter(|p| *p != job.phase)
                    .map(|p| format!("the answer is for phase {p:?}, the job is {:?}", job.phase)),
                e.step.filter(|s| Some(*s) != step).map(|s| {
                    format!(
                        "the answer is for step index {s}, the job is at {}",
                        step.map_or("no step".into(), |x| format!("step index {x}"))
                    )
                }),
                e.attempt.filter(|t| *t != job.attempt).map(|t| {
                    format!(
                        "the answer is for attempt {t}, the job is at attempt {}",
                        job.attempt
                    )
                }),
            ]
            .into_iter()
            .flatten()
            .collect::<Vec<_>>();
            if !mismatch.is_empty() {
                return Err(DaemonError::Conflict(format!(
                    "cannot {} {} {id}: {}; GET /api/calibrations/job for the current step",
                    a.name(),
                    job.kind,
                    mismatch.join("; ")
                )));
            }
        }
        let passed = job.result.as_ref().is_some_and(StepResult::passed);
        let ok = match (a, job.phase.as_str()) {
            (Answer::Abort, "aborting") => false,
            (Answer::Abort, _) => true,
            (Answer::Confirm, "place") => true,
            (Answer::Confirm, "review") => passed,
            (Answer::Repeat, "review") => true,
            _ => false,
        };
        if !ok {
            let step = job
                .step
                .as_ref()
                .map_or(String::new(), |s| format!(" at {}", s.title));
            let why = match (a, job.phase.as_str()) {
                (Answer::Confirm, "review") => format!(
                    "the step failed its check ({}): repeat it or abort",
                    job.result
                        .as_ref()
                        .map(StepResult::message)
                        .unwrap_or_default()
                ),
                (_, "place") => {
                    "the step has not been taken yet: confirm that the target is in place, or abort"
                        .into()
                }
                (_, phase) => {
                    format!("the job is {phase}: wait for the step to be shown, or abort")
                }
            };
            return Err(DaemonError::Conflict(format!(
                "cannot {} {} {id}{step}: {why}",
                a.name(),
                job.kind
            )));
        }
        if tx.send(a).is_err() {
            return Err(DaemonError::NotRunning(format!(
                "{} {id} is ending: nothing to {}",
                job.kind,
                a.name()
            )));
        }
        // Handed over: the job leaves its waiting phase now, under the same lock, so the
        // next answer finds nothing waiting. The job thread sets the phase it really enters.
        let handed = match (a, job.phase.as_str()) {
            (Answer::Abort, _) => "aborting",
            (Answer::Confirm, "place") => "acquiring",
            (Answer::Confirm, _) => "keeping",
            (Answer::Repeat, _) => "repeating",
        };
        if let Some(j) = st.calibrating.as_mut() {
            j.phase = handed.into();
        }
        Ok(job)
    }

    /// The calibration the daily check measures with: the daemon's current one, else the
    /// scanner config's.
    fn calibration_to_check(&self) -> Result<(Option<String>, calib::Calibration), DaemonError> {
        let info = self.calibration();
        let (id, cal) = match info {
            Some(i) => (i.id.clone(), calib::Calibration::load(&i.path)?),
            None => match procedure::prior_calibration(&self.scanner)? {
                Some(c) => (None, c),
                None => {
                    return Err(DaemonError::NotRunning(
                        "no calibration to check: calibrate first (POST /api/calibrations)".into(),
                    ))
                }
            },
        };
        Ok((id, cal))
    }

    fn run_job(
        self: Arc<Self>,
        req: JobRequest,
        answers: Receiver<Answer>,
        check_cal: Option<(Option<String>, calib::Calibration)>,
    ) {
        let result = std::panic::catch_unwind(AssertUnwindSafe(|| match &check_cal {
            None => self
                .calibrate_now(&req, answers)
                .map(|(info, id)| Done::Calibration(info, id)),
            Some((cid, cal)) => self
                .verify_now(&req, answers, cid.clone(), cal)
                .map(Done::Check),
        }))
        .unwrap_or_else(|_| {
            Err(JobError::Failed(
                "internal error: the job thread panicked".into(),
            ))
        });
        let mut st = self.state.lock().unwrap();
        st.guide = None;
        let mut job = st
            .calibrating
            .clone()
            .expect("the job's view exists while it runs");
        job.phase = "done".into();
        match result {
            Ok(Done::Calibration(info, entry_id)) => {
                job.state = Status::Complete;
                job.calibration_id = Some(entry_id.clone());
                job.message = Some(format!("calibration {entry_id} kept and made current"));
                st.calibration = Some(info);
            }
            Ok(Done::Check(entry)) => {
                job.state = Status::Complete;
                job.calibration_id = entry.calibration_id.clone();
                job.message = Some(if entry.passed {
                    "the daily check passed".into()
                } else {
                    format!("the daily check FAILED: {}", entry.failures.join("; "))
                });
                job.report = Some(entry.report);
            }
            Err(JobError::Aborted(reason)) => {
                job.state = Status::Cancelled;
                job.reason = Some(reason);
            }
            Err(JobError::Failed(reason)) => {
                job.state = Status::Failed;
                job.reason = Some(reason);
            }
        }
        tracing::info!(
            "{} {} {}{}",
            job.kind,
            job.id,
            job.state.as_str(),
            job.reason
                .as_deref()
                .map_or(String::new(), |r| format!(": {r}"))
        );
        st.calibrating = Some(job.clone());
        if matches!(st.job, Some(Job::Calibration { .. })) {
            st.job = None;
        }
        drop(st);
        self.emit(Event::Calibration(Box::new(job)));
    }

    fn guide(self: &Arc<Self>, req: &JobRequest, answers: Receiver<Answer>) -> Box<dyn Guide> {
        if req.guided {
            Box::new(HttpGuide {
                daemon: self.clone(),
                answers,
                last_progress: None,
            })
        } else {
            Box::new(ShownAutoGuide {
                daemon: self.clone(),
                auto: AutoGuide::new(1),
                last_progress: None,
            })
        }
    }

    fn open_rig(
        &self,
        req: &JobRequest,
        plan: &CalibrationPlan,
    ) -> Result<procedure::OpenRig, CalibError> {
        let open = procedure::open_rig(&self.scanner.config, plan)?;
        if let Some(sim) = &open.sim {
            for (asked, placed) in &req.sim_mistakes {
                sim.mistakes.push(asked.clone(), placed.clone());
            }
        }
        Ok(open)
    }

    fn calibrate_now(
        self: &Arc<Self>,
        req: &JobRequest,
        answers: Receiver<Answer>,
    ) -> Result<(CalibrationInfo, String), JobError> {
        let method = req.method;
        let plan = self
            .scanner
            .calibration_plan()
            .map_err(|e| JobError::from_calib(method.name(), req.guided, e))?;
        let mut guide = self.guide(req, answers);
        let outcome = if method == Method::Opencv {
            procedure::calibrate_unattended(&self.scanner.config, method, &plan, &mut |_, _, _| {})
        } else {
            let prior = self
                .calibration()
                .and_then(|i| calib::Calibration::load(&i.path).ok());
            plan.validate()
                .and_then(|_| plan.check_insystem())
                .and_then(|_| self.open_rig(req, &plan))
                .and_then(|mut open| {
                    procedure::calibrate_with(
                        &mut open.rig,
                        method,
                        &plan,
                        prior.as_ref().map(|c| &c.model),
                        guide.as_mut(),
                    )
                })
        }
        .map_err(|e| JobError::from_calib(method.name(), req.guided, e))?;
        self.update_job(|j| {
            j.phase = "fitting".into();
            j.message = Some("checking the fit against the limits and keeping it".into());
        });
        let c = &outcome.calibration;
        let limits = &self.scanner.config.calibration;
        procedure::check_limits(c, limits.max_residual_px, limits.max_u_h_mm).map_err(|e| {
            JobError::Failed(format!(
                "{} calibration refused, nothing kept: {e}",
                method.name()
            ))
        })?;
        let id = format!("{}", ScanId::generate(11));
        let entry = CalibrationEntry {
            id: id.clone(),
            date: c.date.clone(),
            method: c.method.clone(),
            confirmed_by: req.confirmed_by.clone(),
            plan: (method != Method::Opencv).then_some(plan),
            parameters: serde_json::to_value(&c.model).unwrap_or_default(),
            stddev: serde_json::to_value(&c.stddev).unwrap_or_default(),
            residuals: serde_json::to_value(&c.residuals).unwrap_or_default(),
            steps: serde_json::to_value(&outcome.steps).unwrap_or_default(),
        };
        let path = Calibrations::new(&self.config.archive)
            .add(&entry, c)
            .map_err(|e| {
                JobError::Failed(format!(
                    "keeping the calibration: {}",
                    footscan_util::Chain(&e)
                ))
            })?;
        Ok((
            CalibrationInfo {
                id: Some(id.clone()),
                method: c.method.clone(),
                date: c.date.clone(),
                path,
            },
            id,
        ))
    }

    fn verify_now(
        self: &Arc<Self>,
        req: &JobRequest,
        answers: Receiver<Answer>,
        calibration_id: Option<String>,
        cal: &calib::Calibration,
    ) -> Result<CheckEntry, JobError> {
        let plan = self
            .scanner
            .calibration_plan()
            .map_err(|e| JobError::from_calib("the daily check", req.guided, e))?;
        let mut guide = self.guide(req, answers);
        let report = self
            .open_rig(req, &plan)
            .and_then(|mut open| {
                procedure::verify_with(
                    &mut open.rig,
                    cal,
                    &plan,
                    &self.scanner.config.calibration,
                    guide.as_mut(),
                )
            })
            .map_err(|e| JobError::from_calib("the daily check", req.guided, e))?;
        let entry = CheckEntry::new(format!("{}", ScanId::generate(13)), calibration_id, &report);
        Calibrations::new(&self.config.archive)
            .add_check(&entry)
            .map_err(|e| {
                JobError::Failed(format!(
                    "keeping the daily check: {}",
                    footscan_util::Chain(&e)
                ))
            })?;
        Ok(entry)
    }

    /// The operator's answers go nowhere once the daemon stops: the waiting job ends.
    pub(super) fn end_guides(&self) {
        self.state.lock().unwrap().guide = None;
    }
}

enum Done {
    Calibration(CalibrationInfo, String),
    Check(CheckEntry),
}

enum JobError {
    Aborted(String),
    Failed(String),
}

impl JobError {
    /// An abort is the operator's (guided) or a step that failed its check with nobody to
    /// repeat it (unguided: a failure).
    fn from_calib(what: &str, guided: bool, e: CalibError) -> JobError {
        match e {
            CalibError::Aborted { .. } if guided => JobError::Aborted(e.to_string()),
            e => JobError::Failed(format!("{what} failed: {}", footscan_util::Chain(&e))),
        }
    }
}

/// Where the operator's answers go, held by the daemon's state while a guided job runs.
pub(super) type AnswerTx = Sender<Answer>;
