//! The footscan command line: a thin shell over the library.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use footscan::scan::{self, LoadedConfig, ScanOptions};
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    name = "footscan",
    version,
    about = "Laser-line foot scanner and last-design toolkit"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scan and write points.ply, heightmap.png, scan.json and calibration.toml to --out.
    Scan {
        /// Scanner configuration (see config/sim.toml).
        #[arg(long, default_value = "config/sim.toml")]
        config: PathBuf,
        /// Scan directory to create or overwrite.
        #[arg(long)]
        out: PathBuf,
        /// Calibration TOML (default for the simulator: its true model).
        #[arg(long)]
        calibration: Option<PathBuf>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Write the simulated scanner's true calibration as a calibration TOML.
    SimCalibration {
        #[arg(long, default_value = "config/sim.toml")]
        config: PathBuf,
        #[arg(long)]
        out: PathBuf,
    },
    /// List the pipeline stages a config may name.
    Stages,
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            // Library errors often repeat their cause in their own message; print each once.
            let mut msg = String::new();
            for cause in e.chain().map(|c| c.to_string()) {
                if !msg.contains(&cause) {
                    msg = if msg.is_empty() {
                        cause
                    } else {
                        format!("{msg}: {cause}")
                    };
                }
            }
            eprintln!("error: {msg}");
            std::process::ExitCode::FAILURE
        }
    }
}

fn run() -> Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match Cli::parse().command {
        Command::Scan {
            config,
            out,
            calibration,
            quiet,
        } => run_scan(config, out, calibration, quiet),
        Command::SimCalibration { config, out } => {
            let cfg = LoadedConfig::load(&config)?;
            scan::sim::true_calibration(&cfg.config).save(&out)?;
            println!("wrote {}", out.display());
            Ok(())
        }
        Command::Stages => {
            for (name, desc) in scan::registry().entries() {
                println!("{name:16} {desc}");
            }
            Ok(())
        }
    }
}

fn run_scan(
    config: PathBuf,
    out: PathBuf,
    calibration: Option<PathBuf>,
    quiet: bool,
) -> Result<()> {
    let cfg = LoadedConfig::load(&config)?;
    let bar = if quiet {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(0)
    };
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} scanning [{bar:40}] {pos}/{len} frames {msg} ({elapsed})",
        )
        .expect("progress template")
        .progress_chars("=> "),
    );
    let mut opts = ScanOptions::new(&out);
    opts.calibration = calibration;
    let cancel = opts.cancel.clone();
    // First Ctrl-C stops the slider and ends the scan cleanly; a second one exits at once.
    ctrlc::set_handler(move || {
        if cancel.is_cancelled() {
            std::process::exit(130);
        }
        eprintln!("\ncancelling the scan (Ctrl-C again to quit at once)");
        cancel.cancel();
    })
    .context("installing the Ctrl-C handler")?;
    let summary = scan::run_scan(&cfg, &opts, |p| {
        bar.set_length(p.expected_frames);
        bar.set_position(p.frames.min(p.expected_frames));
        bar.set_message(format!("{} dropped", p.dropped));
    })
    .with_context(|| {
        format!(
            "scan failed (the reason is kept in {})",
            out.join("scan.json").display()
        )
    })?;
    bar.finish_and_clear();
    if summary.status != "complete" {
        println!(
            "scan {}: {} ({} frames; kept in {})",
            summary.status,
            summary.reason.as_deref().unwrap_or(""),
            summary.frames,
            out.join("scan.json").display()
        );
        return Ok(());
    }
    println!(
        "scan complete: {} frames ({} dropped), {} points in {:.1} s",
        summary.frames, summary.dropped_frames, summary.points, summary.seconds
    );
    if let Some(t) = &summary.truth {
        println!(
            "against ground truth: 3D RMS {:.4} mm, max {:.4} mm, p99 {:.4} mm, height RMS {:.4} mm ({} points; {} missed rows, {} spurious)",
            t.rms_mm, t.max_mm, t.p99_mm, t.height_rms_mm, t.compared, t.missed_rows, t.spurious_points
        );
    }
    for s in &summary.stages {
        println!(
            "  stage {:16} in {:6} out {:6} dropped {:4} mean {:7.3} ms max {:7.3} ms",
            s.name, s.input, s.output, s.dropped, s.mean_latency_ms, s.max_latency_ms
        );
    }
    println!(
        "wrote {}/{{points.ply, heightmap.png, scan.json, calibration.toml}}",
        out.display()
    );
    Ok(())
}
