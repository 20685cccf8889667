//! Soak benchmark (not a test): footscand's resident memory over many long scans in a row.
//!
//! `cargo bench -p footscand --bench soak` runs SOAK_SCANS (default 20) full simulated
//! scans at SOAK_STEP_MM (default 0.25 mm: 1,280 frames over the default 320 mm travel)
//! through one daemon, printing after each its resident memory (VmRSS) and its peak during
//! the scan (VmHWM, reset before each), and exits 1 if any is over SOAK_LIMIT_MB (default
//! 250). `--profile dev` runs it on the debug build.

#[path = "../tests/daemon_support/mod.rs"]
mod daemon_support;

use daemon_support::*;
use std::time::{Duration, Instant};

fn env<T: std::str::FromStr>(key: &str, default: T) -> T {
    std::env::var(key)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// `key` (VmRSS, VmHWM) of `pid` in MB.
fn status_mb(pid: u32, key: &str) -> f64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix(key)?.strip_prefix(':'))
        .and_then(|v| v.split_whitespace().next()?.parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn rss_mb(pid: u32) -> f64 {
    status_mb(pid, "VmRSS")
}

/// Restart the kernel's peak-RSS count (VmHWM) of `pid`, so the next reading is the peak of
/// one scan, exactly, not the largest of a few samples.
fn reset_peak(pid: u32) {
    std::fs::write(format!("/proc/{pid}/clear_refs"), "5").expect("reset VmHWM (clear_refs)");
}

fn main() {
    // `cargo bench` passes --bench; `cargo test --all-targets` runs this binary without it
    // (or with --list), and a 10-minute soak does not belong in the test suite.
    if !std::env::args().any(|a| a == "--bench") {
        println!("soak: a benchmark; run it with `cargo bench -p footscand --bench soak`");
        return;
    }
    let scans: usize = env("SOAK_SCANS", 20);
    let step: f64 = env("SOAK_STEP_MM", 0.25);
    let limit: f64 = env("SOAK_LIMIT_MB", 250.0);
    let tmp = tempfile::tempdir().unwrap();
    let (cmd, archive) = command(tmp.path(), &Opts::default());
    // The default simulated scanner, full travel, at the soak step.
    let sim = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/sim.toml");
    let text: String = std::fs::read_to_string(sim)
        .unwrap()
        .lines()
        .map(|l| {
            if l.trim_start().starts_with("step_mm") && l.contains("advance") {
                format!("step_mm = {step}\n")
            } else {
                format!("{l}\n")
            }
        })
        .collect();
    std::fs::write(tmp.path().join("scanner.toml"), text).unwrap();
    let d = Footscand::spawn(cmd, archive, None);
    let pid = d.child.id();
    println!(
        "soak: {scans} scans at {step} mm, footscand pid {pid}, RSS at start {:.0} MB",
        rss_mb(pid)
    );
    let mut worst: f64 = 0.0;
    let mut during_worst: f64 = 0.0;
    for i in 0..scans {
        let t = Instant::now();
        reset_peak(pid);
        let id = d.start_scan(&format!("soak{i}"));
        loop {
            let s = d.get_json("/api/status");
            if s["scan"]["state"] != "running" {
                assert_eq!(s["scan"]["state"], "complete", "scan {id}: {s}");
                break;
            }
            std::thread::sleep(Duration::from_millis(250));
        }
        let rec = d.record(&id);
        let frames = rec["frames"].as_u64().unwrap_or(0);
        let dropped = rec["summary"]["dropped_frames"].as_u64().unwrap_or(0);
        let peak = status_mb(pid, "VmHWM");
        during_worst = during_worst.max(peak);
        let after = rss_mb(pid);
        worst = worst.max(after);
        println!(
            "scan {:2}: {frames} frames ({dropped} dropped) in {:.1} s; RSS after {after:.0} MB, peak {peak:.0} MB",
            i + 1,
            t.elapsed().as_secs_f64()
        );
    }
    let verdict = worst.max(during_worst) <= limit;
    println!(
        "soak: largest RSS after a scan {worst:.0} MB, during scans {during_worst:.0} MB; limit {limit:.0} MB: {}",
        if verdict { "ok" } else { "OVER" }
    );
    if !verdict {
        std::process::exit(1);
    }
}
