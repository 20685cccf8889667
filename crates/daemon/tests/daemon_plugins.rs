//! A faulty plugin stage in footscand: a per-scan process stage that exits on every request
//! fails its scan with a reason naming the plugin, the daemon stays up, the next scan (the
//! same stage, now well-behaved) completes with the plugin's values in its record, and the
//! failed scan's record stays in the archive.

mod daemon_support;

use daemon_support::*;
use std::path::{Path, PathBuf};
use std::time::Duration;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn a_faulty_plugin_fails_its_scan_by_name_and_the_daemon_scans_on() {
    let python = std::env::var("FOOTSCAN_PLUGIN_PYTHON").unwrap_or_else(|_| {
        let p = repo().join("target/venv-plugins/bin/python");
        assert!(
            p.exists(),
            "{} is missing: run scripts/setup.sh",
            p.display()
        );
        p.display().to_string()
    });
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let flag = dir.join("fail");
    let script = dir.join("flaky.py");
    std::fs::write(
        &script,
        format!(
            "import os, sys\nsys.path.insert(0, {:?})\nfrom footscan_stage import run_scan\n\
             def stage(pts, args):\n    if os.path.exists({:?}):\n        os._exit(3)\n    \
             return {{'points': len(pts)}}\nsys.exit(run_scan(stage))\n",
            repo().join("examples/plugins/python").display().to_string(),
            flag.display().to_string()
        ),
    )
    .unwrap();
    std::fs::write(&flag, "").unwrap();

    let opts = Opts::default();
    let (cmd, archive) = command(dir, &opts);
    // The plugin stage right after accumulate, where the grid is made.
    let scanner = short_scanner_config("").replacen(
        "stage = \"accumulate\"\n",
        &format!(
            "stage = \"accumulate\"\n\n[[pipeline.stages]]\nstage = \"exec\"\nplace = \"scan\"\n\
             command = [{python:?}, {:?}]\nmax_restarts = 1\n",
            script.display().to_string()
        ),
        1,
    );
    assert!(scanner.contains("place = \"scan\""));
    std::fs::write(dir.join("scanner.toml"), scanner).unwrap();
    let d = Footscand::spawn(cmd, archive, None);

    let bad = d.start_scan("plugin-fails");
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "failed", "{end}");
    let reason = end["reason"].as_str().unwrap_or_default().to_string();
    assert!(
        reason.contains("flaky.py") && reason.contains("exited with status 3"),
        "{reason}"
    );
    assert_eq!(d.get_json("/api/health")["ok"], true);

    std::fs::remove_file(&flag).unwrap();
    let good = d.start_scan("plugin-works");
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_ne!(end["state"], "failed", "{end}");
    let rec = d.record(&good);
    let plugins = &rec["summary"]["plugins"];
    assert_eq!(plugins[0]["status"], "ok", "{rec}");
    assert!(
        plugins[0]["values"]["points"].as_f64().unwrap() > 1000.0,
        "{plugins}"
    );

    // Nothing lost: the failed scan is still listed with its reason and its files.
    let list = d.get_json("/api/scans");
    let failed = list
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["id"] == bad.as_str())
        .unwrap_or_else(|| panic!("scan {bad} lost from {list}"));
    assert_eq!(failed["status"], "failed");
    assert!(d.archive.join(&bad).join("record.json").is_file());
    assert!(d.archive.join(&bad).join("scan.json").is_file());
}
