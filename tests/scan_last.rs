//! End to end on the simulator with a shoe last on the glass: the scan of a last bottom,
//! every point checked against the mesh's exact per-row truth.

use footscan::scan::{run_scan, LoadedConfig, ScanOptions};
use std::path::Path;

fn last_config(start: f64, end: f64, extra: &str) -> LoadedConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim-last.toml");
    let text = std::fs::read_to_string(&path).unwrap() + extra;
    // A short scan over the heel, waist and ball.
    let text = text
        .replace("start_mm = 0.0 ", &format!("start_mm = {start} "))
        .replace("end_mm = 320.0 ", &format!("end_mm = {end} "))
        .replace(
            "scene = \"last\"",
            if extra.is_empty() {
                "scene = \"last\""
            } else {
                "scene = \"mesh\""
            },
        );
    LoadedConfig::parse(&path, text).unwrap()
}

/// Scans and checks the 3D error against the mesh's truth.
fn scan_and_check(cfg: &LoadedConfig) {
    assert_eq!(cfg.config.scan.start_mm, 60.0);
    let dir = tempfile::tempdir().unwrap();
    let s = run_scan(cfg, &ScanOptions::new(dir.path()), |_| {}).expect("scan runs");
    assert_eq!(s.status, "complete", "{:?}", s.reason);
    assert!(s.points > 30_000, "only {} points", s.points);
    let t = s.truth.clone().expect("simulated scans carry truth");
    assert!(t.compared as f64 > 0.95 * s.points as f64, "{t:?}");
    assert!(t.rms_mm < 0.05, "3D RMS {} mm", t.rms_mm);
    assert!(
        (t.spurious_points as f64) < 0.001 * s.points as f64,
        "{} spurious points",
        t.spurious_points
    );
    assert!(dir.path().join("points.ply").metadata().unwrap().len() > 1000);
    eprintln!(
        "{} frames, {} points, 3D RMS {:.4} mm, p99 {:.4} mm",
        s.frames, s.points, t.rms_mm, t.p99_mm
    );
}

#[test]
fn simulated_last_scan_meets_accuracy_bound() {
    scan_and_check(&last_config(60.0, 200.0, ""));
}

/// A real scanned last (in metres) from the shared data: FOOTSCAN_DATA, else ../shared/data.
#[test]
fn simulated_real_last_scan_meets_accuracy_bound() {
    let data = std::env::var_os("FOOTSCAN_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    let file = data.join("lasts/LastScan_Default.stl");
    assert!(
        file.is_file(),
        "real last not found at {} (set FOOTSCAN_DATA to the shared data directory)",
        file.display()
    );
    let extra = format!("\n[sim.mesh]\npath = {:?}\nunits = \"auto\"\n", file);
    scan_and_check(&last_config(60.0, 200.0, &extra));
}
