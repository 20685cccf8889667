//! A scan that fails or is cancelled ends with a named reason, kept in scan.json, and writes
//! nothing that looks like a complete scan.

use footscan::scan::{run_scan, LoadedConfig, ScanOptions};
use std::path::Path;
use std::time::{Duration, Instant};

fn config_with(extra: &str) -> LoadedConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml");
    let text = std::fs::read_to_string(&path).unwrap().replace(
        "[sim.optics]",
        &format!("[sim.faults]\n{extra}\n\n[sim.optics]"),
    );
    LoadedConfig::parse(&path, text).unwrap()
}

fn scan_json(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("scan.json")).expect("scan.json kept")).unwrap()
}

fn assert_failed(dir: &Path, err: &str, stage: &str, cause: &str) {
    assert!(err.contains(&format!("stage `{stage}` failed")), "{err}");
    assert!(err.to_lowercase().contains(cause), "{err}");
    let j = scan_json(dir);
    assert_eq!(j["status"], "failed");
    assert!(j["reason"].as_str().unwrap().contains(stage), "{j}");
    assert!(
        j["frames"].as_u64().unwrap() > 0,
        "the scan had started: {j}"
    );
    assert!(
        !dir.join("points.ply").exists(),
        "a failed scan wrote a point cloud"
    );
}

#[test]
fn slider_alarm_mid_scan_fails_the_scan_with_the_alarm() {
    let cfg = config_with("slider_alarm_after_s = 3.0\nslider_alarm_code = 1");
    let dir = tempfile::tempdir().unwrap();
    let err =
        footscan_util::chain(&run_scan(&cfg, &ScanOptions::new(dir.path()), |_| {}).unwrap_err());
    assert_failed(dir.path(), &err, "acquire", "alarm");
}

#[test]
fn camera_unplug_mid_scan_fails_the_scan_as_a_disconnect() {
    let cfg = config_with("camera_unplug_after_s = 3.0");
    let dir = tempfile::tempdir().unwrap();
    let err =
        footscan_util::chain(&run_scan(&cfg, &ScanOptions::new(dir.path()), |_| {}).unwrap_err());
    assert_failed(dir.path(), &err, "acquire", "disconnected");
}

#[test]
fn silent_slider_times_out_instead_of_hanging() {
    let cfg = config_with("slider_silent_after_s = 3.0");
    let dir = tempfile::tempdir().unwrap();
    let t0 = Instant::now();
    let err =
        footscan_util::chain(&run_scan(&cfg, &ScanOptions::new(dir.path()), |_| {}).unwrap_err());
    assert_failed(dir.path(), &err, "acquire", "timed out");
    // Generous: the driver's response timeout is 2 s; the point is that it returns.
    assert!(
        t0.elapsed() < Duration::from_secs(60),
        "took {:?}",
        t0.elapsed()
    );
}

#[test]
fn cancel_mid_scan_stops_cleanly() {
    let cfg = config_with("");
    let dir = tempfile::tempdir().unwrap();
    let opts = ScanOptions::new(dir.path());
    let cancel = opts.cancel.clone();
    let t0 = Instant::now();
    let s = run_scan(&cfg, &opts, |p| {
        if p.frames >= 100 {
            cancel.cancel();
        }
    })
    .expect("a cancelled scan is not an error");
    assert_eq!(s.status, "cancelled");
    assert!(s.frames >= 100 && s.frames < 600, "{} frames", s.frames);
    assert!(t0.elapsed() < Duration::from_secs(30));
    assert_eq!(scan_json(dir.path())["status"], "cancelled");
    assert!(!dir.path().join("points.ply").exists());
}
