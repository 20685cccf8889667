//! The calibration job: POST /api/calibrations runs the in-system calibration through the
//! simulated scanner, keeps it in the archive's calibration history as the current
//! calibration, and later scans (also after a restart) use it and record its id. The guided
//! job over HTTP: each step shown, confirmed, checked; a wrong plate caught at its step and
//! repeated; an abort; a second calibration never overwrites the first; the daily check over
//! HTTP into the trend.

mod daemon_support;

use daemon_support::*;
use std::io::BufRead;
use std::time::{Duration, Instant};

#[test]
fn calibration_job_becomes_the_calibration_of_later_scans() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), light_calibration(tmp.path()));
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
    let cal_id = st["calibration"]["id"].as_str().unwrap().to_string();
    assert!(st["calibration"]["age_h"].as_f64().unwrap() < 0.1, "{st}");
    let current = std::path::PathBuf::from(st["calibration"]["path"].as_str().unwrap());
    assert_eq!(
        current,
        d.archive.join(format!("calibrations/{cal_id}.toml"))
    );
    assert_eq!(
        std::fs::read_to_string(d.archive.join("calibrations/current"))
            .unwrap()
            .trim(),
        cal_id
    );
    let hist = d.get_json("/api/calibrations");
    assert_eq!(hist["current"], cal_id.as_str());
    assert_eq!(hist["calibrations"].as_array().unwrap().len(), 1, "{hist}");
    let entry = d.get_json(&format!("/api/calibrations/{cal_id}"));
    assert_eq!(entry["method"], "insystem");
    assert!(entry["residuals"]["u_h_mm"].as_f64().is_some(), "{entry}");
    assert!(entry["stddev"]["d_mm"].as_f64().is_some(), "{entry}");
    assert_eq!(
        entry["plan"]["plate_heights_mm"].as_array().unwrap().len(),
        8
    );
    assert_eq!(entry["steps"].as_array().unwrap().len(), 10, "{entry}");
    assert_eq!(
        entry["plan"]["frames_per_height"], 4,
        "the scanner config's calibration.plan: {entry}"
    );
    // No daily check yet: the status warns.
    assert!(
        st["daily_check"]["warning"]
            .as_str()
            .unwrap()
            .contains("no daily check"),
        "{st}"
    );
    let cal: toml::Table = toml::from_str(&std::fs::read_to_string(&current).unwrap()).unwrap();

    let scan = d.start_scan("calibrated");
    let end = d.wait_scan_end(Duration::from_secs(120));
    // A frame dropped under the load of the other test is a usable scan too.
    assert!(
        end["state"].as_str().unwrap().starts_with("complete"),
        "{end}"
    );
    let used: toml::Table =
        toml::from_str(&String::from_utf8(d.download(&scan, "calibration.toml")).unwrap()).unwrap();
    assert_eq!(used, cal, "the scan used the daemon's calibration");
    let rec = d.record(&scan);
    assert_eq!(
        rec["calibration"],
        cal_id.as_str(),
        "the scan records its calibration: {rec}"
    );
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
            ..light_calibration(tmp.path())
        },
    );
    let st = d.get_json("/api/status");
    assert_eq!(st["calibration"]["method"], "insystem");
    assert_eq!(st["calibration"]["id"], cal_id.as_str());
}

/// The job's view, polled until its phase is one of `phases` (or the job ended).
fn wait_phase(d: &Footscand, phases: &[&str], limit: Duration) -> Value {
    let t0 = Instant::now();
    loop {
        let j = d.get_json("/api/calibrations/job");
        if phases.contains(&j["phase"].as_str().unwrap_or("")) || j["state"] != "running" {
            return j;
        }
        assert!(t0.elapsed() < limit, "waited {limit:?} for {phases:?}: {j}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn guided_calibration_over_http_repeats_a_wrong_plate_aborts_and_checks_daily() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), light_calibration(tmp.path()));
    let limit = Duration::from_secs(120);

    // An abort while the first step waits: nothing kept, the daemon free again.
    let (s, v) = d.post("/api/calibrations", r#"{"guided": true}"#);
    assert_eq!(s, 202, "{v}");
    let aborted = v["id"].as_str().unwrap().to_string();
    let j = wait_phase(&d, &["place"], limit);
    assert_eq!(j["step"]["title"], "plate at 0 mm", "{j}");
    assert!(
        j["step"]["instruction"]
            .as_str()
            .unwrap()
            .contains("matte sheet"),
        "{j}"
    );
    let (s, v) = d.post(&format!("/api/calibrations/{aborted}/repeat"), "{}");
    assert_eq!(s, 409, "nothing to repeat before the step is taken: {v}");
    let (s, v) = d.post(&format!("/api/calibrations/{aborted}/abort"), "{}");
    assert_eq!(s, 200, "{v}");
    let j = wait_phase(&d, &["done"], limit);
    assert_eq!(j["state"], "cancelled", "{j}");
    assert!(j["reason"].as_str().unwrap().contains("abort"), "{j}");
    assert!(d.get_json("/api/status")["calibration"].is_null());
    assert_eq!(
        d.get_json("/api/calibrations")["calibrations"],
        serde_json::json!([])
    );

    // The guided job: the simulator's operator puts the plate on the 21 mm spacers when asked
    // for 14 mm; the step's check catches it, confirming it is refused, it is repeated.
    let (s, v) = d.post(
        "/api/calibrations",
        r#"{"guided": true, "confirmed_by": "test operator",
            "sim_mistakes": [{"asked": "plate:14", "placed": "plate:21"}]}"#,
    );
    assert_eq!(s, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    let events = d.client.get(d.url("/api/events")).send().unwrap();
    let t0 = Instant::now();
    let mut failed_once = false;
    let mut confirms = 0;
    loop {
        let j = wait_phase(&d, &["place", "review"], limit);
        if j["state"] != "running" {
            break;
        }
        let title = j["step"]["title"].as_str().unwrap().to_string();
        if j["phase"] == "place" {
            confirms += 1;
            let (s, v) = d.post(&format!("/api/calibrations/{id}/confirm"), "{}");
            assert_eq!(s, 200, "{v}");
        } else if j["result"]["passed"] == true {
            let (s, v) = d.post(&format!("/api/calibrations/{id}/confirm"), "{}");
            assert_eq!(s, 200, "{v}");
        } else {
            assert_eq!(title, "plate at 14 mm", "only the wrong plate fails: {j}");
            assert_eq!(j["attempt"], 1, "{j}");
            let expected = j["result"]["expected"].as_str().unwrap();
            let seen = j["result"]["seen"].as_str().unwrap();
            assert!(expected.contains("14 mm"), "{expected}");
            let at: f64 = seen
                .strip_prefix("a line at ")
                .and_then(|r| r.split(' ').next())
                .and_then(|x| x.parse().ok())
                .unwrap_or_else(|| panic!("seen: {seen}"));
            assert!(
                (at - 21.0).abs() < 1.0,
                "the 21 mm plate seen at {at} mm: {seen}"
            );
            println!("wrong plate caught: expected {expected}; saw {seen}");
            let (s, v) = d.post(&format!("/api/calibrations/{id}/confirm"), "{}");
            assert_eq!(s, 409, "a failed step cannot be kept: {v}");
            assert!(
                v["error"].as_str().unwrap().contains("repeat it or abort"),
                "{v}"
            );
            let (s, v) = d.post(&format!("/api/calibrations/{id}/repeat"), "{}");
            assert_eq!(s, 200, "{v}");
            failed_once = true;
        }
        // Wait for the answer to be taken before polling again.
        let t = Instant::now();
        while d.get_json("/api/calibrations/job")["phase"] == j["phase"]
            && d.get_json("/api/calibrations/job")["step"] == j["step"]
            && d.get_json("/api/calibrations/job")["attempt"] == j["attempt"]
        {
            assert!(t.elapsed() < limit);
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    let took = t0.elapsed().as_secs_f64();
    let j = d.get_json("/api/calibrations/job");
    assert_eq!(j["state"], "complete", "{j}");
    assert!(failed_once, "the wrong plate was caught");
    assert_eq!(confirms, 11, "10 steps and one repeat placed");
    assert_eq!(j["kept"].as_array().unwrap().len(), 10, "{j}");
    let first = j["calibration_id"].as_str().unwrap().to_string();

    // The events carried the steps.
    let mut phases = std::collections::BTreeSet::new();
    for line in std::io::BufReader::new(events).lines() {
        let line = line.unwrap();
        if let Some(data) = line.strip_prefix("data: ") {
            let v: Value = serde_json::from_str(data).unwrap();
            if v["id"] == id.as_str() {
                phases.insert(v["phase"].as_str().unwrap_or("").to_string());
                if v["state"] != "running" {
                    break;
                }
            }
        }
    }
    for p in ["place", "acquiring", "review", "done"] {
        assert!(phases.contains(p), "event phases {phases:?}");
    }
    let entry = d.get_json(&format!("/api/calibrations/{first}"));
    assert_eq!(entry["confirmed_by"], "test operator");
    let plate14 = entry["steps"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["title"] == "plate at 14 mm")
        .unwrap();
    assert_eq!(plate14["attempts"], 2, "{entry}");
    println!(
        "guided calibration over HTTP: {took:.1} s; D {} +/- {} mm, u_h {} mm",
        entry["parameters"]["d_mm"], entry["stddev"]["d_mm"], entry["residuals"]["u_h_mm"]
    );

    // The daily check with it passes and goes into the trend; the warning is gone.
    let (s, v) = d.post("/api/verify", "{}");
    assert_eq!(s, 202, "{v}");
    let j = wait_phase(&d, &["done"], limit);
    assert_eq!(j["state"], "complete", "{j}");
    assert_eq!(j["kind"], "verify");
    assert_eq!(j["report"]["passed"], true, "{j}");
    assert_eq!(j["calibration_id"], first.as_str());
    let worst = j["report"]["steps"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["error_mm"].as_f64().unwrap().abs())
        .fold(0.0, f64::max);
    println!("daily check over HTTP: worst step error {worst:.4} mm");
    let trend = d.get_json("/api/verify");
    assert_eq!(trend["checks"].as_array().unwrap().len(), 1, "{trend}");
    let st = d.get_json("/api/status");
    assert_eq!(st["daily_check"]["last"]["passed"], true, "{st}");
    assert!(st["daily_check"]["warning"].is_null(), "{st}");

    // A second (unattended) calibration is kept beside the first, which stays whole.
    let first_toml = std::fs::read(d.archive.join(format!("calibrations/{first}.toml"))).unwrap();
    let (s, v) = d.post("/api/calibrations", r#"{"guided": false}"#);
    assert_eq!(s, 202, "{v}");
    let j = wait_phase(&d, &["done"], Duration::from_secs(180));
    assert_eq!(j["state"], "complete", "{j}");
    let second = j["calibration_id"].as_str().unwrap();
    assert_ne!(second, first);
    let hist = d.get_json("/api/calibrations");
    assert_eq!(hist["current"], second);
    assert_eq!(hist["calibrations"].as_array().unwrap().len(), 2, "{hist}");
    assert_eq!(
        std::fs::read(d.archive.join(format!("calibrations/{first}.toml"))).unwrap(),
        first_toml
    );
}
