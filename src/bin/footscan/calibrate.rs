//! `footscan calibrate`: the guided in-system calibration on the configured backend (the
//! operator is walked through the steps on the console, or nobody with `--yes`), then the fit,
//! its parameters, residuals and height uncertainty; the calibration TOML is written only if
//! it succeeded and is within the configured limits.

use anyhow::{Context, Result};
use footscan::calib::guided::{Decision, Guide, Ready, Step, StepResult};
use footscan::calib::{CalibError, CalibrationPlan, Method};
use footscan::scan::calibrate as procedure;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::{BufRead, Write};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    #[arg(long, default_value = crate::DEFAULT_CONFIG, help = crate::CONFIG_HELP)]
    config: PathBuf,
    /// insystem: the scanner's own fit of the general model; bezier: heights from the Bezier
    /// depth network; opencv: the checkerboard reference (simulator only).
    #[arg(long, default_value = "insystem", value_parser = ["insystem", "bezier", "opencv"])]
    method: String,
    /// Calibration file to write.
    #[arg(long)]
    out: PathBuf,
    /// The shop's calibration plan as TOML: spacer heights and staircase dimensions as
    /// measured, their tolerance, the slider positions, the step checks; default: the
    /// config's `calibration.plan`, else the built-in plan of the default scanner.
    #[arg(long)]
    plan: Option<PathBuf>,
    /// Confirm every step without asking (scripts; the simulator places its own targets). A
    /// step whose check fails then aborts the calibration with its message.
    #[arg(long)]
    yes: bool,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// Walks a person through the steps on the terminal: what to place, progress, what was seen,
/// then keep / repeat / abort.
struct ConsoleGuide {
    bar: ProgressBar,
    /// Confirm without asking.
    yes: bool,
    input: Box<dyn BufRead>,
}

impl ConsoleGuide {
    fn ask(&mut self, prompt: &str) -> Result<String, CalibError> {
        eprint!("{prompt}");
        let _ = std::io::stderr().flush();
        let mut line = String::new();
        let n = self
            .input
            .read_line(&mut line)
            .map_err(|e| CalibError::Plan(format!("reading the operator's answer: {e}")))?;
        if n == 0 {
            // End of input: nobody is there to answer.
            return Ok("a".into());
        }
        Ok(line.trim().to_lowercase())
    }
}

impl Guide for ConsoleGuide {
    fn ready(&mut self, step: &Step, attempt: usize) -> Result<Ready, CalibError> {
        let again = if attempt > 1 {
            format!(" (attempt {attempt})")
        } else {
            String::new()
        };
        eprintln!(
            "\nStep {}/{}: {}{again}\n  {}",
            step.index + 1,
            step.of,
            step.title,
            step.instruction
        );
        if self.yes {
            eprintln!("  (--yes: confirmed)");
        } else {
            loop {
                match self
                    .ask("  Press Enter when it is in place (a = abort): ")?
                    .as_str()
                {
                    "" | "y" | "yes" => break,
                    "a" | "abort" => return Ok(Ready::Abort),
                    other => eprintln!("  `{other}`: Enter to go on, a to abort"),
                }
            }
        }
        self.bar.reset();
        self.bar.set_length(step.frames() as u64);
        self.bar.set_message(step.title.clone());
        Ok(Ready::Go)
    }

    fn progress(&mut self, _step: &Step, done: usize, total: usize) {
        self.bar.set_length(total as u64);
        self.bar.set_position(done as u64);
    }

    fn review(&mut self, _step: &Step, result: &StepResult) -> Result<Decision, CalibError> {
        self.bar.finish_and_clear();
        match result {
            StepResult::Checked(s) if s.passed => eprintln!("  ok: saw {}", s.seen),
            StepResult::Checked(s) => {
                eprintln!("  FAILED: expected {}", s.expected);
                eprintln!("          saw {}", s.seen);
                if let Some(p) = &s.problem {
                    eprintln!("          {p}");
                }
            }
            StepResult::Fault { reason } => eprintln!("  FAULT: {reason}"),
        }
        let passed = result.passed();
        if self.yes {
            return Ok(if passed {
                Decision::Accept
            } else {
                Decision::Abort
            });
        }
        let prompt = if passed {
            "  Enter = keep and go on, r = repeat, a = abort: "
        } else {
            "  r = repeat the step (fix the target first), a = abort: "
        };
        loop {
            match self.ask(prompt)?.as_str() {
                "" | "y" | "k" if passed => return Ok(Decision::Accept),
                "r" | "repeat" => return Ok(Decision::Repeat),
                "a" | "abort" => return Ok(Decision::Abort),
                other => eprintln!("  `{other}`: not one of the choices"),
            }
        }
    }
}

pub fn run(args: Args) -> Result<()> {
    let cfg = crate::load_config(&args.config)?;
    let plan = match &args.plan {
        Some(p) => CalibrationPlan::load(p)?,
        None => cfg.calibration_plan()?,
    };
    let method: Method = args.method.parse()?;
    let prior = procedure::prior_calibration(&cfg)?;
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    bar.set_style(
        ProgressStyle::with_template("  [{bar:40}] {pos}/{len} frames {msg} ({elapsed})")
            .expect("progress template")
            .progress_chars("=> "),
    );
    let mut guide = ConsoleGuide {
        bar,
        yes: args.yes,
        input: Box::new(std::io::stdin().lock()),
    };
    eprintln!(
        "Calibrating ({}) the {:?} scanner of {}; the steps are checked with {}.",
        method.name(),
        cfg.config.scanner.backend,
        args.config.display(),
        match &prior {
            Some(c) => format!("the current calibration ({} of {})", c.method, c.date),
            None => "the plan's nominal design values (no calibration yet)".into(),
        }
    );
    let outcome = procedure::calibrate(
        &cfg.config,
        method,
        &plan,
        prior.as_ref().map(|c| &c.model),
        &mut guide,
    )
    .with_context(|| format!("{} calibration failed; nothing written", method.name()))?;
    let c = &outcome.calibration;
    let m = &c.model;
    let sd = |k: &str| {
        c.stddev
            .get(k)
            .map_or(String::new(), |s| format!(" +/- {s:.4}"))
    };
    println!("method {} ({})", c.method, c.date);
    println!(
        "F {:.3}{} px, c_x {:.3}{} px, c_y {:.3}{} px, D {:.4}{} mm, L {:.4}{} mm",
        m.f_px,
        sd("f_px"),
        m.cx,
        sd("cx"),
        m.cy,
        sd("cy"),
        m.d_mm,
        sd("d_mm"),
        m.l_mm,
        sd("l_mm")
    );
    println!(
        "k1 {:.5}{}, k2 {:.5}{}, laser tilt [{:.4}{}, {:.4}{}] deg, slider scale {:.6}{}",
        m.k1,
        sd("k1"),
        m.k2,
        sd("k2"),
        m.laser_tilt_deg[0],
        sd("laser_tilt_deg[0]"),
        m.laser_tilt_deg[1],
        sd("laser_tilt_deg[1]"),
        m.slider_scale,
        sd("slider_scale")
    );
    println!("residuals:");
    for (k, v) in &c.residuals {
        println!("  {k:28} {v:.5}");
    }
    if let Some(u) = c.residuals.get("u_h_mm") {
        println!("height uncertainty u_h {u:.4} mm (eq. 30)");
    }
    if let Some(fit) = &outcome.insystem {
        println!(
            "in-system fit: {} evaluations, condition {:.3e}; staircase found at x {:.3} y {:.3} mm, yaw {:.4} deg",
            fit.evaluations, fit.condition, fit.block.x_mm, fit.block.y_mm, fit.block.yaw_deg
        );
    }
    let limits = &cfg.config.calibration;
    procedure::check_limits(c, limits.max_residual_px, limits.max_u_h_mm)
        .context("nothing written")?;
    c.save(&args.out)?;
    println!("wrote {}", args.out.display());
    Ok(())
}
