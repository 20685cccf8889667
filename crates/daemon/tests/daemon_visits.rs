//! Visits over real HTTP (archive/visits.rs): a visit holds a patient id, notes and both feet;
//! a scan saved under a mistyped subject is corrected (kept in its history) before it joins the
//! visit; visits are searched by subject and date; a visit deleted on request takes its scans'
//! files with it and is logged. Visits are shown and searched in the clinic's time zone
//! (`[clinic] time_zone`): across midnight and the DST changes.

mod daemon_support;

use daemon_support::{command, Footscand, Opts, Value};
use std::path::Path;
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
    let (s, v) = d.delete(&format!("/api/visits/{vid}"));
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
    let (s, _) = d.delete(&format!("/api/visits/{vid}"));
    assert_eq!(s, 404);
}

/// footscand on `dir` with `clinic` appended to its config and `TZ` set to `tz` (the machine's
/// zone, used when the config names none).
fn daemon_in_zone(dir: &Path, clinic: &str, tz: &str) -> Footscand {
    let (mut cmd, archive) = command(dir, &Opts::default());
    let cfg = dir.join("footscand.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(&cfg, format!("{text}{clinic}")).unwrap();
    cmd.env("TZ", tz);
    Footscand::spawn(cmd, archive, None)
}

/// Visits started at these UTC instants, written as the archive keeps them (the API opens
/// visits only at the present time): (id, started UTC, local in Europe/Berlin).
const PLANTED: [(&str, &str, &str); 8] = [
    // Winter (CET, +01:00): 23:30 UTC is half past midnight of the next day.
    (
        "20261124T223000Z-000a",
        "2026-11-24T22:30:00Z",
        "2026-11-24T23:30:00+01:00",
    ),
    (
        "20261124T233000Z-000b",
        "2026-11-24T23:30:00Z",
        "2026-11-25T00:30:00+01:00",
    ),
    // 29 March 2026, clocks forward at 01:00 UTC (02:00 CET -> 03:00 CEST): a 23-hour day,
    // 2026-03-28T23:00Z to 2026-03-29T22:00Z.
    (
        "20260328T223000Z-000c",
        "2026-03-28T22:30:00Z",
        "2026-03-28T23:30:00+01:00",
    ),
    (
        "20260328T233000Z-000d",
        "2026-03-28T23:30:00Z",
        "2026-03-29T00:30:00+01:00",
    ),
    (
        "20260329T013000Z-000e",
        "2026-03-29T01:30:00Z",
        "2026-03-29T03:30:00+02:00",
    ),
    (
        "20260329T215959Z-000f",
        "2026-03-29T21:59:59Z",
        "2026-03-29T23:59:59+02:00",
    ),
    (
        "20260329T223000Z-0010",
        "2026-03-29T22:30:00Z",
        "2026-03-30T00:30:00+02:00",
    ),
    // 25 October 2026, clocks back at 01:00 UTC: 02:30 local twice, told apart by the offset.
    (
        "20261025T013000Z-0011",
        "2026-10-25T01:30:00Z",
        "2026-10-25T02:30:00+01:00",
    ),
];

fn plant(archive: &Path) {
    let dir = archive.join("visits");
    std::fs::create_dir_all(&dir).unwrap();
    for (id, started, _) in PLANTED {
        let v = serde_json::json!({"id": id, "patient": "TZ-1", "notes": "", "started": started,
            "left": null, "right": null});
        std::fs::write(dir.join(format!("{id}.json")), v.to_string()).unwrap();
    }
    let early = serde_json::json!({"id": "20261025T003000Z-0012", "patient": "TZ-1",
        "notes": "", "started": "2026-10-25T00:30:00Z", "left": null, "right": null});
    std::fs::write(dir.join("20261025T003000Z-0012.json"), early.to_string()).unwrap();
}

fn ids(list: &Value) -> Vec<&str> {
    list.as_array()
        .unwrap()
        .iter()
        .map(|v| v["id"].as_str().unwrap())
        .collect()
}

#[test]
fn visits_are_dated_in_the_clinics_time_zone() {
    let tmp = tempfile::tempdir().unwrap();

    // An unknown zone name stops the daemon at start, naming the key and the value.
    let (mut cmd, _) = command(tmp.path(), &Opts::default());
    let cfg = tmp.path().join("footscand.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(
        &cfg,
        format!("{text}[clinic]\ntime_zone = \"Europe/Berln\"\n"),
    )
    .unwrap();
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "footscand started: {err}");
    assert!(
        err.contains("[clinic] time_zone = \"Europe/Berln\"") && err.contains("Europe/Berlin"),
        "{err}"
    );

    // Berlin, on a machine whose own zone is New York (the config wins).
    let mut d = daemon_in_zone(
        tmp.path(),
        "[clinic]\ntime_zone = \"Europe/Berlin\"\n",
        "America/New_York",
    );
    plant(&d.archive);
    let all = d.get_json("/api/visits?subject=TZ-1");
    assert_eq!(all.as_array().unwrap().len(), PLANTED.len() + 1, "{all}");
    for v in all.as_array().unwrap() {
        assert_eq!(v["time_zone"], "Europe/Berlin", "{v}");
        if let Some((_, _, local)) = PLANTED.iter().find(|p| p.0 == v["id"]) {
            assert_eq!(v["started_local"], *local, "{v}");
        }
    }
    let early = all
        .as_array()
        .unwrap()
        .iter()
        .find(|v| v["id"] == "20261025T003000Z-0012")
        .unwrap();
    assert_eq!(early["started_local"], "2026-10-25T02:30:00+02:00");
    for (date, want) in [
        ("2026-11-24", vec!["20261124T223000Z-000a"]),
        ("2026-11-25", vec!["20261124T233000Z-000b"]),
        ("2026-03-28", vec!["20260328T223000Z-000c"]),
        (
            "2026-03-29",
            vec![
                "20260329T215959Z-000f",
                "20260329T013000Z-000e",
                "20260328T233000Z-000d",
            ],
        ),
        ("2026-03-30", vec!["20260329T223000Z-0010"]),
        (
            "2026-10-25",
            vec!["20261025T013000Z-0011", "20261025T003000Z-0012"],
        ),
    ] {
        let l = d.get_json(&format!("/api/visits?date={date}"));
        assert_eq!(ids(&l), want, "date={date}: {l}");
    }
    for bad in ["2026-02-30", "2026-13-01", "26-11-24"] {
        let r = d.get(&format!("/api/visits?date={bad}"));
        assert_eq!(r.status(), 400, "{bad}");
        let text = r.text().unwrap();
        assert!(text.contains(bad) && text.contains("YYYY-MM-DD"), "{text}");
    }
    // Every visit answer has the local time: one opened now, shown, its notes changed.
    let (s, v) = d.post("/api/visits", r#"{"patient": "TZ-2"}"#);
    assert_eq!(s, 201, "{v}");
    let local = v["started_local"].as_str().unwrap();
    assert!(
        local.len() == 25 && (local.ends_with("+01:00") || local.ends_with("+02:00")),
        "{v}"
    );
    assert_eq!(v["time_zone"], "Europe/Berlin");
    let vid = v["id"].as_str().unwrap();
    let shown = d.get_json(&format!("/api/visits/{vid}"));
    assert_eq!(shown["started_local"], local, "{shown}");
    let (s, v) = d.post(&format!("/api/visits/{vid}/notes"), r#"{"notes": "x"}"#);
    assert_eq!(
        (s, &v["started_local"]),
        (200, &shown["started_local"]),
        "{v}"
    );
    d.terminate(Duration::from_secs(20));

    // No [clinic] zone: the machine's (TZ), here UTC; the same archive dated in UTC.
    let d = daemon_in_zone(tmp.path(), "", "UTC");
    let l = d.get_json("/api/visits?date=2026-11-24");
    assert_eq!(
        ids(&l),
        ["20261124T233000Z-000b", "20261124T223000Z-000a"],
        "{l}"
    );
    assert_eq!(l[0]["time_zone"], "UTC");
    assert_eq!(l[0]["started_local"], "2026-11-24T23:30:00+00:00");
}
