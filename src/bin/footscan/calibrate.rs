//! `footscan calibrate`: calibrate the scanner with a progress bar and write the calibration
//! TOML (only if the calibration succeeded).

use anyhow::{Context, Result};
use footscan::calib::{CalibrationPlan, Method};
use footscan::scan::LoadedConfig;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Scanner configuration (see config/sim.toml).
    #[arg(long, default_value = "config/sim.toml")]
    config: PathBuf,
    /// insystem: the scanner's own fit of the general model; bezier: heights from the Bezier
    /// depth network; opencv: the checkerboard reference.
    #[arg(long, default_value = "insystem", value_parser = ["insystem", "bezier", "opencv"])]
    method: String,
    /// Calibration file to write.
    #[arg(long)]
    out: PathBuf,
    /// The calibration procedure as TOML (targets, heights, poses); default: the built-in
    /// procedure for the simulated scanner.
    #[arg(long)]
    plan: Option<PathBuf>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

pub fn run(args: Args) -> Result<()> {
    let cfg = LoadedConfig::load(&args.config)?;
    let plan = match &args.plan {
        Some(p) => CalibrationPlan::load(p)?,
        None => CalibrationPlan::default(),
    };
    let method: Method = args.method.parse().map_err(anyhow::Error::msg)?;
    let bar = if args.quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} calibrating [{bar:40}] {pos}/{len} {msg} ({elapsed})",
        )
        .expect("progress template")
        .progress_chars("=> "),
    );
    let outcome =
        footscan::scan::calibrate_sim(&cfg.config, method, &plan, &mut |what, done, total| {
            bar.set_length(total as u64);
            bar.set_position(done as u64);
            bar.set_message(what.to_string());
        })
        .with_context(|| format!("{} calibration failed; nothing written", method.name()))?;
    bar.finish_and_clear();
    let c = &outcome.calibration;
    c.save(&args.out)?;
    let m = &c.model;
    let sd = |k: &str| {
        c.stddev
            .get(k)
            .map_or(String::new(), |s| format!(" +/- {s:.3}"))
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
        "k1 {:.5}, k2 {:.5}, camera tilt {:?} deg, laser tilt [{:.4}, {:.4}] deg, slider scale {:.6}",
        m.k1, m.k2, m.camera_tilt_deg, m.laser_tilt_deg[0], m.laser_tilt_deg[1], m.slider_scale
    );
    for (k, v) in &c.residuals {
        println!("  {k:28} {v:.5}");
    }
    if let Some(fit) = &outcome.insystem {
        println!(
            "in-system fit: {} evaluations, condition {:.3e}; staircase found at x {:.3} y {:.3} mm, yaw {:.4} deg",
            fit.evaluations, fit.condition, fit.block.x_mm, fit.block.y_mm, fit.block.yaw_deg
        );
    }
    println!("wrote {}", args.out.display());
    Ok(())
}
