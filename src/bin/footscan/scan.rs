//! `footscan scan`: a scan with a progress bar, a printed summary and the quality gate's
//! verdict; a scan that must be redone (or whose side disagrees with `--side`) ends the
//! command with an error, its files kept with the reason in scan.json. The scan is written
//! beside `--out` and moved there when it ends (`scan_dir`): an earlier scan in `--out` is kept
//! whole as `--out.previous-<UTC time>`, never mixed with the new one.

use crate::scan_dir::Staged;
use anyhow::{bail, Context, Result};
use footscan::measure::Side;
use footscan::scan::{self, ScanOptions, ScanStatus};
use footscan::scandata::ScanDir;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::PathBuf;

pub fn run(
    config: PathBuf,
    out: PathBuf,
    calibration: Option<PathBuf>,
    quiet: bool,
    side: Option<crate::SideArg>,
) -> Result<()> {
    let cfg = crate::load_config(&config)?;
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
    let staged = Staged::begin(&out)?;
    let out = staged.dest.clone();
    let mut opts = ScanOptions::new(&staged.partial);
    opts.calibration = calibration;
    opts.side = side.map(Side::from);
    let cancel = opts.cancel.clone();
    let partial = staged.partial.clone();
    // First Ctrl-C stops the slider and ends the scan cleanly; a second one exits at once.
    ctrlc::set_handler(move || {
        if cancel.is_cancelled() {
            eprintln!("\nthe unfinished scan is left in {}", partial.display());
            std::process::exit(130);
        }
        eprintln!("\ncancelling the scan (Ctrl-C again to quit at once)");
        cancel.cancel();
    })
    .context("installing the Ctrl-C handler")?;
    let result = scan::run_scan(&cfg, &opts, |p| {
        bar.set_length(p.expected_frames);
        bar.set_position(p.frames.min(p.expected_frames));
        bar.set_message(format!("{} dropped", p.dropped));
    });
    bar.finish_and_clear();
    // Ended, whichever way: the new scan (even a failed one, with its reason) goes to --out.
    let json_written = ScanDir::new(&staged.partial).summary_path().is_file();
    let placed = staged.finish()?;
    if let Some(prev) = &placed.previous {
        eprintln!(
            "the earlier scan in {} is kept as {}",
            out.display(),
            prev.display()
        );
    }
    let summary = result.with_context(|| {
        let json = ScanDir::new(&out).summary_path();
        if json_written {
            format!("scan failed (the reason is kept in {})", json.display())
        } else {
            format!(
                "scan failed (and {} could not be written, so the reason is only here)",
                json.display()
            )
        }
    })?;
    match summary.status {
        // A failed scan is an error for scripts and the shell (exit 1); a cancelled one
        // exits 130 like any command stopped by Ctrl-C. Both keep their files and reason.
        ScanStatus::Failed => bail!(
            "scan failed: {} ({} frames; the files and the reason are kept in {})",
            summary.reason.as_deref().unwrap_or("no reason given"),
            summary.frames,
            out.display()
        ),
        ScanStatus::Cancelled => {
            println!(
                "scan cancelled: {} ({} frames; kept in {})",
                summary.reason.as_deref().unwrap_or(""),
                summary.frames,
                ScanDir::new(&out).summary_path().display()
            );
            std::process::exit(130);
        }
        ScanStatus::Rescan | ScanStatus::SideMismatch => bail!(
            "scan {} ({} frames; the files and the reason are kept in {})",
            summary.verdict(),
            summary.frames,
            out.display()
        ),
        ScanStatus::Complete | ScanStatus::CompleteWithWarnings => {}
        ScanStatus::Running => bail!(
            "the scan returned without a verdict (status \"running\"): a bug; the files are in {}",
            out.display()
        ),
    }
    println!(
        "scan {}: {} frames ({} dropped), {} points in {:.1} s",
        summary.verdict(),
        summary.frames,
        summary.dropped_frames,
        summary.points,
        summary.seconds
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
    if let Some(t) = &summary.timeline {
        let model = match (&summary.model, t.model_after_last_frame_s) {
            (Some(m), Some(s)) => format!(", CAD files {} {s:.2} s after it", m.state.as_str()),
            _ => String::new(),
        };
        println!(
            "results {:.2} s after the last frame (at {:.1} s){model}",
            t.results_after_last_frame_s, t.last_frame_s
        );
    }
    // What this scan's stages wrote: --out holds this scan alone.
    let mut files: Vec<String> = std::fs::read_dir(&out)
        .map(|d| {
            d.filter_map(|e| e.ok())
                .filter(|e| e.path().is_file())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    println!("wrote {}/{{{}}}", out.display(), files.join(", "));
    Ok(())
}
