//! The calibration job: POST /api/calibrations runs the in-system calibration through the
//! simulated scanner, stores it as the current calibration, and later scans (also after a
//! restart) use it.

mod daemon_support;

use daemon_support::*;
use std::io::BufRead;
use std::time::{Duration, Instant};

#[test]
fn calibration_job_becomes_the_calibration_of_later_scans() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    assert!(d.get_json("/api/status")["calibration"].is_null());
    let events = d.client.get(d.url("/api/events")).send().unwrap();
    let t0 = Instant::now();
    let (s, v) = d.post("/api/calibrations", r#"{"method": "insystem"}"#);
    assert_eq!(s, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    let (s, v) = d.post("/api/scans", r#"{"subject": "a", "side": "left"}"#);
    assert_eq!(s, 409, "no scan while calibrating: {v}");
    let (s, _) = d.post("/api/calibrations", r#"{"method": "bezier"}"#);
    assert_eq!(s, 409, "one calibration at a time");
    assert_eq!(d.get_json("/api/status")["calibrating"]["state"], "running");

    let mut name = String::new();
    let mut last = Value::Null;
    for line in std::io::BufReader::new(events).lines() {
        let line = line.unwrap();
        if let Some(n) = line.strip_prefix("event: ") {
            name = n.to_string();
        } else if let Some(data) = line.strip_prefix("data: ") {
            let v: Value = serde_json::from_str(data).unwrap();
            if name == "calibration" && v["id"] == id.as_str() && v["state"] != "running" {
                last = v;
                break;
            }
        }
    }
    let took = t0.elapsed().as_secs_f64();
    assert_eq!(last["state"], "complete", "{last}");
    assert_eq!(last["method"], "insystem");
    let st = d.get_json("/api/status");
    assert_eq!(st["calibration"]["method"], "insystem", "{st}");
    let current = std::path::PathBuf::from(st["calibration"]["path"].as_str().unwrap());
    assert_eq!(current, d.archive.join("calibrations/current.toml"));
    assert!(d.archive.join(format!("calibrations/{id}.toml")).is_file());
    let cal: toml::Table = toml::from_str(&std::fs::read_to_string(&current).unwrap()).unwrap();

    let scan = d.start_scan("calibrated");
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "complete", "{end}");
    let used: toml::Table =
        toml::from_str(&String::from_utf8(d.download(&scan, "calibration.toml")).unwrap()).unwrap();
    assert_eq!(used, cal, "the scan used the daemon's calibration");
    let rec = d.record(&scan);
    println!(
        "calibration insystem: {took:.1} s; scan with it: truth RMS {} mm, points {}",
        rec["summary"]["truth"]["rms_mm"], rec["points"]
    );
    let archive = d.archive.clone();
    drop(d);

    // After a restart the daemon still uses it.
    let d = Footscand::start(
        tmp.path(),
        Opts {
            archive: Some(archive),
            ..Opts::default()
        },
    );
    assert_eq!(
        d.get_json("/api/status")["calibration"]["method"],
        "insystem"
    );
}
