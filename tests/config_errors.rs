//! Bad configuration is reported with the file, the key, its line and column.

use footscan::scan::{run_scan, LoadedConfig, ScanOptions};
use std::path::Path;

fn sim_text() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml")).unwrap()
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn unknown_top_level_key_names_key_line_and_column() {
    let text = sim_text().replace("step_mm = 0.5", "step_mm = 0.5\nstep_mn = 0.25");
    let line = line_of(&text, "step_mn");
    let e = LoadedConfig::parse(Path::new("my.toml"), text)
        .unwrap_err()
        .to_string();
    assert!(e.contains("my.toml"), "{e}");
    assert!(e.contains("step_mn"), "{e}");
    assert!(e.contains(&format!("line {line}, column 1")), "{e}");
}

#[test]
fn unknown_sim_key_is_located() {
    let text = sim_text().replace("k2 = 0.01", "k2 = 0.01\n  k3 = 0.001");
    let line = line_of(&text, "k3 =");
    let e = LoadedConfig::parse(Path::new("sim.toml"), text)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("k3") && e.contains(&format!("line {line}, column 3")),
        "{e}"
    );
}

#[test]
fn unknown_stage_parameter_names_key_line_and_column() {
    let text = sim_text().replacen("threshold = 30 ", "treshold = 30 ", 1);
    let line = line_of(&text, "treshold");
    let cfg =
        LoadedConfig::parse(Path::new("sim.toml"), text).expect("parses: params are per stage");
    let dir = tempfile::tempdir().unwrap();
    let opts = ScanOptions::new(dir.path());
    let e = run_scan(&cfg, &opts, |_| {}).unwrap_err().to_string();
    assert!(e.contains("treshold") && e.contains("detect."), "{e}");
    assert!(e.contains(&format!("line {line}, column 1")), "{e}");
    // The failed scan is kept with its reason.
    let json = std::fs::read_to_string(dir.path().join("scan.json")).unwrap();
    assert!(
        json.contains("\"failed\"") && json.contains("treshold"),
        "{json}"
    );
}

#[test]
fn unknown_stage_name_lists_valid_ones() {
    let text = sim_text().replace("stage = \"detect.bezier-plus\"", "stage = \"detect.magic\"");
    let line = line_of(&text, "detect.magic");
    let cfg = LoadedConfig::parse(Path::new("sim.toml"), text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let opts = ScanOptions::new(dir.path());
    let e = run_scan(&cfg, &opts, |_| {}).unwrap_err().to_string();
    assert!(
        e.contains("detect.magic") && e.contains("detect.cog"),
        "{e}"
    );
    assert!(e.contains(&format!("line {line}")), "{e}");
}

#[test]
fn invalid_value_is_explained() {
    let text = sim_text().replace("step_mm = 0.5", "step_mm = -1");
    let e = LoadedConfig::parse(Path::new("sim.toml"), text)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("scan.step_mm") && e.contains("must be > 0") && e.contains("line"),
        "{e}"
    );
}
