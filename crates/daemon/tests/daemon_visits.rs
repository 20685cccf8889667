//! Visits over real HTTP (archive/visits.rs): a visit holds a patient id, notes and both feet;
//! a scan saved under a mistyped subject is corrected (kept in its history) before it joins the
//! visit; visits are searched by subject and date; a visit deleted on request takes its scans'
//! files with it and is logged.

mod daemon_support;

use daemon_support::{Footscand, Opts, Value};
use std::time::Duration;

fn scan(d: &Footscand, subject: &str, side: &str) -> String {
    let (s, v) = d.post(
        "/api/scans",
        &format!(r#"{{"subject": "{subject}", "side": "{side}"}}"#),
    );
    assert_eq!(s, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    d.wait_scan_end(Duration::from_secs(120));
    id
}

fn delete(d: &Footscand, path: &str) -> (u16, Value) {
    let r = d
        .client
        .delete(d.url(path))
        .header("content-type", "application/json")
        .send()
        .unwrap();
    let s = r.status().as_u16();
    (s, serde_json::from_str(&r.text().unwrap()).unwrap())
}

#[test]
fn a_visit_holds_both_feet_and_is_deleted_with_them() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());

    let (s, v) = d.post("/api/visits", r#"{"patient": "p 7"}"#);
    assert_eq!(s, 400, "{v}");
    let (s, visit) = d.post(
        "/api/visits",
        r#"{"patient": "P-0007", "notes": "flat feet?"}"#,
    );
    assert_eq!(s, 201, "{visit}");
    let vid = visit["id"].as_str().unwrap().to_string();
    assert_eq!(visit["notes"], "flat feet?");

    let right = scan(&d, "P-0007", "right");
    let left = scan(&d, "P-0008", "left"); // the subject mistyped
    let add = |scan: &str| {
        d.post(
            &format!("/api/visits/{vid}/scans"),
            &format!(r#"{{"scan": "{scan}"}}"#),
        )
    };
    let (s, v) = add(&right);
    assert_eq!(s, 200, "{v}");
    assert_eq!(v["right"], right.as_str());
    let r = d.get(&format!("/api/visits/{vid}/report.pdf"));
    assert_eq!(r.status(), 409, "one foot only");
    let (s, v) = add(&left);
    assert_eq!(s, 409, "{v}");
    assert!(v["error"].as_str().unwrap().contains("P-0008"), "{v}");

    // The subject corrected, with the reason kept in the scan's history.
    let (s, v) = d.post(
        &format!("/api/scans/{left}/record"),
        r#"{"subject": "P-0007"}"#,
    );
    assert_eq!(s, 400, "no why: {v}");
    let (s, v) = d.post(
        &format!("/api/scans/{left}/record"),
        r#"{"subject": "P-0007", "why": "typed 8 for 7"}"#,
    );
    assert_eq!(s, 200, "{v}");
    let h = &d.record(&left)["history"];
    assert_eq!(h[0]["field"], "subject");
    assert_eq!(
        (&h[0]["from"], &h[0]["to"]),
        (&"P-0008".into(), &"P-0007".into())
    );
    assert!(h[0]["why"].as_str().unwrap().contains("typed 8 for 7"));
    let (s, v) = add(&left);
    assert_eq!(s, 200, "{v}");
    assert_eq!(
        (v["left"].as_str(), v["right"].as_str()),
        (Some(left.as_str()), Some(right.as_str()))
    );

    let (s, v) = d.post(
        &format!("/api/visits/{vid}/notes"),
        r#"{"notes": "pes planus, both"}"#,
    );
    assert_eq!(s, 200, "{v}");
    let shown = d.get_json(&format!("/api/visits/{vid}"));
    assert_eq!(shown["notes"], "pes planus, both");
    assert_eq!(shown["left_scan"]["subject"], "P-0007");
    assert_eq!(shown["right_scan"]["id"], right.as_str());

    // The visit's report: both feet side by side at 1:1 on A3 landscape, the comparison,
    // the 100 mm bar (283.46 pt).
    let r = d.get(&format!("/api/visits/{vid}/report.pdf"));
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], "application/pdf");
    let pdf = r.bytes().unwrap();
    std::fs::write(tmp.path().join("visit.pdf"), &pdf).unwrap();
    let text = String::from_utf8_lossy(&pdf);
    for w in [
        "footscan visit report: P-0007",
        "R - L",
        "Foot length (mm)",
        "100 mm long",
    ] {
        assert!(text.contains(w), "{w:?} not in the visit report");
    }
    let bars: Vec<Vec<f64>> = text
        .lines()
        .filter_map(|l| l.strip_suffix(" re"))
        .map(|l| l.split(' ').map(|v| v.parse::<f64>().unwrap()).collect())
        .filter(|v: &Vec<f64>| v[3] > 100.0)
        .collect();
    assert_eq!(bars.len(), 1, "{bars:?}");
    assert!((bars[0][3] - 283.4646).abs() < 0.01, "{bars:?}");
    if let Ok(keep) = std::env::var("FOOTSCAN_KEEP_VISIT_PDF") {
        std::fs::write(keep, &pdf).unwrap();
    }

    // Search by subject (any case, part of it) and by date.
    let today = &visit["started"].as_str().unwrap()[..10];
    for (q, n) in [
        ("subject=p-0007".to_string(), 1),
        ("subject=0007".to_string(), 1),
        ("subject=P-0009".to_string(), 0),
        (format!("date={today}"), 1),
        ("date=1999-01-01".to_string(), 0),
    ] {
        let l = d.get_json(&format!("/api/visits?{q}"));
        assert_eq!(l.as_array().unwrap().len(), n, "{q}: {l}");
    }
    assert_eq!(d.get("/api/visits?date=yesterday").status(), 400);

    // Deleted on request: the visit, both scans' directories and index rows; logged.
    let (s, v) = delete(&d, &format!("/api/visits/{vid}"));
    assert_eq!(s, 200, "{v}");
    assert_eq!(v["scans_deleted"].as_array().unwrap().len(), 2, "{v}");
    assert!(!d.archive.join(&left).exists() && !d.archive.join(&right).exists());
    assert_eq!(d.get_json("/api/scans").as_array().unwrap().len(), 0);
    assert_eq!(d.get(&format!("/api/visits/{vid}")).status(), 404);
    let log = std::fs::read_to_string(d.archive.join("visits/deleted.log")).unwrap();
    assert!(
        log.contains(&vid) && log.contains("P-0007") && log.contains(&left),
        "{log}"
    );
    let (s, _) = delete(&d, &format!("/api/visits/{vid}"));
    assert_eq!(s, 404);
}
