//! `footscan calibrate` refuses bad input with a message that says what is missing and writes
//! nothing; `footscan bench calibrate`'s JSON has the documented shape.

use footscan::calib::{CalibrationPlan, Method};
use footscan::scan::LoadedConfig;
use footscan_bench::calibrate::{self as bc, BenchOptions};
use std::path::Path;
use std::process::Command;

fn footscan() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footscan"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

#[test]
fn bad_plans_write_no_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("calib.toml");
    let cases = [
        ("plate_heights_mm = [0.0, 10.0]\n", "at least 3"),
        ("frames_per_height = 1\n", "frames_per_height"),
        ("bogus = 1\n", "bogus"),
        (
            "[staircase]\nheights_mm = [5.0]\nlengths_mm = []\nwidth_mm = 40.0\n",
            "staircase.heights_mm",
        ),
    ];
    for (plan, expect) in cases {
        let p = dir.path().join("plan.toml");
        std::fs::write(&p, plan).unwrap();
        let o = footscan()
            .args(["calibrate", "--method", "insystem", "--quiet", "--plan"])
            .arg(&p)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{plan}: succeeded");
        assert!(err.contains(expect), "{plan}: {err}");
        assert!(!out.exists(), "{plan}: a calibration was written");
    }
    // The same plan named by the scanner config: refused when the config is read, with the
    // key and its line.
    let text =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml"))
            .unwrap();
    let cfg = dir.path().join("scanner.toml");
    std::fs::write(
        &cfg,
        format!("{text}\n[calibration]\nplan = \"plan.toml\"\n"),
    )
    .unwrap();
    std::fs::write(dir.path().join("plan.toml"), "frames_per_height = 1\n").unwrap();
    let o = footscan()
        .args(["calibrate", "--method", "insystem", "--quiet", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "{err}");
    assert!(
        err.contains("calibration.plan (line") && err.contains("frames_per_height = 1"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn bench_json_has_the_documented_keys() {
    let cfg =
        LoadedConfig::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml")).unwrap();
    let plan = CalibrationPlan {
        plate_heights_mm: vec![0.0, 14.0, 28.0, 42.0],
        frames_per_height: 4,
        stair_step_mm: 1.0,
        ..CalibrationPlan::default()
    };
    let opts = BenchOptions {
        methods: vec![Method::Insystem, Method::Bezier],
        direct: true,
    };
    let rows = bc::run(&cfg.config, &plan, &opts, &mut |_, _, _| {}).unwrap();
    let json = serde_json::to_value(&rows).unwrap();
    let arr = json.as_array().unwrap();
    assert_eq!(arr.len(), 2);
    for (row, method) in arr.iter().zip(["insystem", "bezier"]) {
        assert_eq!(row["method"], method);
        let f = &row["params"]["f_px"];
        assert_eq!(f["truth"], 2000.0);
        assert!(f["value"].as_f64().is_some() && f["rel_error"].as_f64().unwrap() < 1e-3);
        let rms = row["val_rms_mm"].as_f64().unwrap();
        assert!(rms > 0.0 && rms < 0.03, "{method}: {rms}");
        assert!(row["val_max_mm"].as_f64().unwrap() >= rms);
        assert!(row.get("error").is_none());
    }
    let table = bc::table(&rows);
    assert!(table.contains("validation height RMS") && table.contains("f_px"));
}
