//! In-system calibration through the scanner's own devices, end to end: the GRBL emulator on a
//! pty behind the real serial driver, the simulated camera in real time, the simulated operator
//! swapping the targets; then a scan that loads the calibration file.

use footscan::calib::{Calibration, CalibrationPlan};
use footscan::scan::calibrate::{self as run, Method};
use footscan::scan::{run_scan, LoadedConfig, ScanOptions};
use std::path::Path;

const CONFIG: &str = r#"
[scanner]
backend = "sim"
[scan]
start_mm = 0.0
end_mm = 30.0
step_mm = 0.5
[sim]
scene = "plate"
plate_height_mm = 17.5
[pipeline]
[[pipeline.stages]]
stage = "acquire"
[[pipeline.stages]]
stage = "detect.bezier-plus"
[[pipeline.stages]]
stage = "triangulate"
[[pipeline.stages]]
stage = "accumulate"
[[pipeline.stages]]
stage = "sink.summary"
"#;

#[test]
fn calibrate_through_the_devices_then_scan_with_the_file() {
    let cfg = LoadedConfig::parse(Path::new("e2e.toml"), CONFIG.to_string()).unwrap();
    // A shorter procedure than the default: fewer heights and frames, a coarser pass.
    let plan = CalibrationPlan {
        plate_heights_mm: vec![0.0, 14.0, 28.0, 42.0],
        frames_per_height: 6,
        stair_step_mm: 1.0,
        ..CalibrationPlan::default()
    };
    let mut steps = Vec::new();
    let out = run::calibrate_unattended(
        &cfg.config,
        Method::Insystem,
        &plan,
        &mut |what, done, _| steps.push((what.to_string(), done)),
    )
    .unwrap();
    assert!(
        steps.iter().any(|s| s.0 == "staircase gauge"),
        "progress reported"
    );
    let truth = footscan::scan::sim::true_calibration(&cfg.config).model;
    let m = &out.calibration.model;
    let rel = |a: f64, b: f64| (a - b).abs() / b;
    assert!(rel(m.f_px, truth.f_px) < 1e-3, "F {}", m.f_px);
    assert!(rel(m.l_mm, truth.l_mm) < 2e-3, "L {}", m.l_mm);
    assert!((m.slider_scale - 1.0).abs() < 3e-4, "{}", m.slider_scale);
    let fit = out.insystem.as_ref().unwrap();
    assert!((fit.block.yaw_deg - plan.sim.staircase.yaw_deg).abs() < 0.02);
    // Save, and scan a plate at a height between the calibration heights with the file.
    let dir = tempfile::tempdir().unwrap();
    let cal_path = dir.path().join("calib.toml");
    out.calibration.save(&cal_path).unwrap();
    assert_eq!(Calibration::load(&cal_path).unwrap().method, "insystem");
    let mut opts = ScanOptions::new(dir.path().join("scan"));
    opts.calibration = Some(cal_path);
    let s = run_scan(&cfg, &opts, |_| {}).expect("scan runs");
    assert_eq!(s.status, "complete");
    let t = s.truth.expect("truth");
    assert!(t.compared > 20_000, "{t:?}");
    // Detection noise (~0.02 mm) dominates; a wrong calibration would show as an offset.
    assert!(t.height_rms_mm < 0.04, "height RMS {} mm", t.height_rms_mm);
    let kept = std::fs::read_to_string(dir.path().join("scan/calibration.toml")).unwrap();
    assert!(kept.contains("method = \"insystem\""));
}
