//! `footscan verify`: the daily check. A short pass over the staircase gauge measured with the
//! current calibration: each step's height error against the gauge's stated heights and the
//! block's width (the y scale), pass or fail against `calibration.verify_tolerance_mm`. Exits
//! with status 1 when the check fails.

use anyhow::{bail, Context, Result};
use footscan::calib::guided::{AutoGuide, Decision, Guide, Ready, Step, StepResult};
use footscan::calib::{CalibError, Calibration, CalibrationPlan};
use footscan::scan::calibrate as procedure;
use footscan::scan::config::Backend;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    #[arg(long, default_value = crate::DEFAULT_CONFIG, help = crate::CONFIG_HELP)]
    config: PathBuf,
    /// The calibration to check (default: scanner.calibration; the simulator's true model
    /// when the simulator has none).
    #[arg(long)]
    calibration: Option<PathBuf>,
    /// The plan whose staircase gauge is used (stated heights and width, the pass); default:
    /// the config's `calibration.plan`, else the built-in plan.
    #[arg(long)]
    plan: Option<PathBuf>,
    /// Do not wait for the operator to confirm that the gauge is in place.
    #[arg(long)]
    yes: bool,
    /// Write the report as JSON here.
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Asks on the terminal that the gauge be put in place, then reports what the pass saw.
struct Console {
    yes: bool,
}

impl Guide for Console {
    fn ready(&mut self, step: &Step, _attempt: usize) -> Result<Ready, CalibError> {
        eprintln!("{}: {}", step.title, step.instruction);
        if !self.yes {
            eprint!("Press Enter when it is in place (a = abort): ");
            let mut line = String::new();
            std::io::stdin()
                .read_line(&mut line)
                .map_err(|e| CalibError::Plan(format!("reading the operator's answer: {e}")))?;
            if line.trim() == "a" {
                return Ok(Ready::Abort);
            }
        }
        Ok(Ready::Go)
    }
    fn review(&mut self, step: &Step, result: &StepResult) -> Result<Decision, CalibError> {
        eprintln!("{}: {}", step.title, result.message());
        AutoGuide::new(1).review(step, result)
    }
}

pub fn run(args: Args) -> Result<()> {
    let cfg = crate::load_config(&args.config)?;
    let plan = match &args.plan {
        Some(p) => CalibrationPlan::load(p)?,
        None => cfg.calibration_plan()?,
    };
    let cal = match args.calibration.clone().or_else(|| cfg.calibration_path()) {
        Some(p) => Calibration::load(&p)?,
        None if cfg.config.scanner.backend == Backend::Sim => {
            footscan::scan::sim::true_calibration(&cfg.config)
        }
        None => bail!(
            "no calibration to check: pass --calibration FILE or set scanner.calibration in {}",
            args.config.display()
        ),
    };
    let report = procedure::verify(&cfg.config, &cal, &plan, &mut Console { yes: args.yes })
        .context("daily check failed to run")?;
    println!(
        "daily check of the calibration {} (tolerance {} mm)",
        report.calibration, report.tolerance_mm
    );
    for s in &report.steps {
        println!(
            "  step {:6.2} mm: error {:+.4} mm (spread {:.4} mm, {} points) {}",
            s.stated_mm,
            s.error_mm,
            s.rms_mm,
            s.points,
            if s.passed { "ok" } else { "FAIL" }
        );
    }
    println!(
        "  width {:.3} mm of {} mm: {:+.4} mm, y scale {:.5} {}",
        report.width_mm,
        report.width_stated_mm,
        report.width_mm - report.width_stated_mm,
        report.y_scale,
        if report.width_passed { "ok" } else { "FAIL" }
    );
    if let Some(out) = &args.out {
        let json = serde_json::to_vec_pretty(&report)?;
        footscan::io::write_atomic(out, &json)
            .with_context(|| format!("writing {}", out.display()))?;
    }
    if report.passed {
        println!("PASS");
        Ok(())
    } else {
        bail!("the daily check FAILED: {}", report.failures.join("; "))
    }
}
