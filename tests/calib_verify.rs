//! The daily check (`footscan verify`) on the simulator backend through the real GRBL driver:
//! it passes with the true calibration and fails, naming the steps, with one whose D is 0.5 %
//! off.

use footscan::calib::guided::AutoGuide;
use footscan::calib::CalibrationPlan;
use footscan::scan::calibrate as procedure;
use footscan::scan::LoadedConfig;
use std::path::Path;

#[test]
fn daily_check_passes_with_the_truth_and_fails_with_d_half_a_percent_off() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut cfg = LoadedConfig::load(&root.join("config/sim.toml")).unwrap();
    // The staircase pass every 2 mm instead of 1: the same steps, half the real-time moves.
    cfg.config.calibration.verify_step_mm = 2.0;
    let plan = CalibrationPlan::default();
    let truth = footscan::scan::sim::true_calibration(&cfg.config);
    let good = procedure::verify(&cfg.config, &truth, &plan, &mut AutoGuide::new(1)).unwrap();
    for s in &good.steps {
        eprintln!(
            "true: step {} mm error {:+.4} mm ({} points)",
            s.stated_mm, s.error_mm, s.points
        );
    }
    eprintln!(
        "true: width {:.4} mm, y scale {:.5}",
        good.width_mm, good.y_scale
    );
    assert!(good.passed, "{:?}", good.failures);
    assert_eq!(good.tolerance_mm, 0.05);
    assert!(
        good.steps.iter().all(|s| s.points > 1000),
        "{:?}",
        good.steps
    );
    // The width is measured to about a row a side (see calib::verify).
    assert!((good.width_mm - 60.0).abs() < 0.4, "{}", good.width_mm);

    let mut off = truth.clone();
    off.model.d_mm *= 1.005;
    let bad = procedure::verify(&cfg.config, &off, &plan, &mut AutoGuide::new(1)).unwrap();
    for s in &bad.steps {
        eprintln!(
            "D+0.5%: step {} mm error {:+.4} mm",
            s.stated_mm, s.error_mm
        );
    }
    assert!(!bad.passed);
    let failed: Vec<f64> = bad
        .steps
        .iter()
        .filter(|s| !s.passed)
        .map(|s| s.stated_mm)
        .collect();
    assert!(failed.len() >= 3, "{failed:?}");
    for h in &failed {
        assert!(
            bad.failures
                .iter()
                .any(|f| f.contains(&format!("the step at {h} mm"))),
            "{:?}",
            bad.failures
        );
    }
    // The CLI says the same and exits with a failure.
    let dir = tempfile::tempdir().unwrap();
    let cal = dir.path().join("off.toml");
    off.save(&cal).unwrap();
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_footscan"))
        .current_dir(root)
        .args([
            "verify",
            "--yes",
            "--config",
            "config/sim.toml",
            "--calibration",
        ])
        .arg(&cal)
        .arg("--out")
        .arg(dir.path().join("check.json"))
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    eprintln!("{stdout}{stderr}");
    assert!(!o.status.success());
    assert!(
        stderr.contains("the daily check FAILED: the step at"),
        "{stderr}"
    );
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("check.json")).unwrap()).unwrap();
    assert_eq!(json["passed"], false);
}
