//! End to end on the simulator: GRBL emulator on a pty, the serial driver, the simulated
//! camera, the threaded pipeline, the files; the 3D error checked against ground truth.

use footscan::scan::{run_scan, LoadedConfig, ScanOptions};
use std::path::Path;

fn sim_config() -> LoadedConfig {
    LoadedConfig::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml")).unwrap()
}

#[test]
fn simulated_scan_meets_accuracy_bound() {
    let cfg = sim_config();
    let dir = tempfile::tempdir().unwrap();
    let opts = ScanOptions::new(dir.path());
    let s = run_scan(&cfg, &opts, |_| {}).expect("scan runs");
    assert_eq!(s.status, "complete");
    // The nominal step gives 641 frames over 0..320 mm; allow for drops on a loaded machine.
    assert!(s.frames >= 500, "only {} frames", s.frames);
    assert!(s.points > 100_000, "only {} points", s.points);
    let t = s.truth.clone().expect("simulated scans carry truth");
    assert!(t.compared as f64 > 0.95 * s.points as f64, "{t:?}");
    // Detection by plain centre of gravity at 15 % speckle: ~0.1 px, ~0.05 mm of height.
    assert!(t.rms_mm < 0.10, "3D RMS {} mm", t.rms_mm);
    assert!(t.p99_mm < 0.40, "3D p99 {} mm", t.p99_mm);
    assert!(
        (t.spurious_points as f64) < 0.001 * s.points as f64,
        "{} spurious points",
        t.spurious_points
    );
    for f in [
        "points.ply",
        "heightmap.png",
        "scan.json",
        "calibration.toml",
        "model.stl",
        "measurements.json",
        "plantar.png",
    ] {
        let p = dir.path().join(f);
        assert!(
            p.metadata().map(|m| m.len() > 100).unwrap_or(false),
            "{f} missing or empty"
        );
    }
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("scan.json")).unwrap()).unwrap();
    for k in [
        "frames",
        "dropped_frames",
        "points",
        "seconds",
        "stages",
        "truth",
    ] {
        assert!(json.get(k).is_some(), "scan.json lacks {k}");
    }
    let stages = json["stages"].as_array().unwrap();
    assert_eq!(stages.len(), 10);
    for st in stages {
        for k in ["name", "in", "out", "dropped", "mean_latency_ms"] {
            assert!(st.get(k).is_some(), "stage entry lacks {k}: {st}");
        }
    }
    assert_eq!(stages[1]["in"], stages[0]["out"]);
    assert!(json["truth"]["rms_mm"].as_f64().unwrap() < 0.10);
}
