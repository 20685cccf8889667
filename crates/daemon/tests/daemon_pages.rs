//! `GET /api/scans` and `GET /api/visits` by page and search (issue 39): an archive of
//! planted scan directories and visit files (a few hundred, so the test takes seconds; the
//! 50,000-scan figures are the archive bench's), walked page by page and searched, each
//! answer checked against the planted records filtered here.

mod daemon_support;

use daemon_support::{command, Footscand, Opts};
use serde_json::Value;
use std::path::Path;

const SUBJECTS: [&str; 5] = ["P-0042", "p-0043", "Q-17", "alice", "P-0042b"];
const STATUSES: [&str; 4] = ["complete", "complete with warnings", "failed", "rescan"];

/// A planted scan: (id, subject, side, status).
type Planted = (String, &'static str, &'static str, &'static str);

/// `n` scans, one every 37 minutes from 2026-01-01T00:00Z, written as the archive keeps them.
fn plant_scans(archive: &Path, n: usize) -> Vec<Planted> {
    let t0 = jiff::Timestamp::from_second(1_767_225_600).unwrap(); // 2026-01-01T00:00:00Z
    let mut out = Vec::new();
    for i in 0..n {
        let t = t0 + jiff::SignedDuration::from_secs(i as i64 * 37 * 60);
        let id = format!("{}-{:04x}", t.strftime("%Y%m%dT%H%M%SZ"), i);
        let (subject, side, status) = (
            SUBJECTS[i % SUBJECTS.len()],
            if i % 3 == 0 { "left" } else { "right" },
            STATUSES[(i / 2) % STATUSES.len()],
        );
        let dir = archive.join(&id);
        std::fs::create_dir_all(&dir).unwrap();
        let rec = serde_json::json!({
            "id": id, "subject": subject, "side": side, "notes": "", "status": status,
            "reason": null, "started": t.strftime("%Y-%m-%dT%H:%M:%SZ").to_string(),
            "finished": null, "frames": 10, "points": 100,
        });
        std::fs::write(dir.join("record.json"), rec.to_string()).unwrap();
        out.push((id, subject, side, status));
    }
    out.sort_by(|a, b| b.0.cmp(&a.0));
    out
}

/// The daemon on `archive`, in UTC whatever the machine's zone (dates are the clinic's).
fn start(dir: &Path, archive: &Path) -> Footscand {
    let (mut cmd, archive) = command(
        dir,
        &Opts {
            archive: Some(archive.to_owned()),
            ..Opts::default()
        },
    );
    cmd.env("TZ", "UTC");
    Footscand::spawn(cmd, archive, None)
}

fn ids(v: &Value) -> Vec<String> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|r| r["id"].as_str().unwrap().to_string())
        .collect()
}

/// Every page of `path` (which has `limit=`), following `next`; the ids in order and the
/// number of pages.
fn walk(d: &Footscand, path: &str) -> (Vec<String>, usize) {
    let mut all = Vec::new();
    let mut before: Option<String> = None;
    let mut pages = 0;
    loop {
        let url = match &before {
            Some(b) => format!("{path}&before={b}"),
            None => path.to_string(),
        };
        let page = d.get_json(&url);
        pages += 1;
        let items = ids(&page["items"]);
        all.extend(items);
        match page["next"].as_str() {
            Some(n) => {
                assert_eq!(
                    all.last().map(String::as_str),
                    Some(n),
                    "{url}: next is the last id"
                );
                before = Some(n.to_string());
            }
            None => return (all, pages),
        }
        assert!(pages < 1000, "{path}: no end");
    }
}

#[test]
fn scans_page_and_search_by_index() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    let planted = plant_scans(&archive, 230);
    let d = start(tmp.path(), &archive);

    // The unpaged call answers as before: a bare array of every scan, newest first.
    let all = d.get_json("/api/scans");
    let want: Vec<String> = planted.iter().map(|p| p.0.clone()).collect();
    assert_eq!(ids(&all), want);
    // The token as a query parameter (the guard's) is not an unknown parameter.
    assert_eq!(ids(&d.get_json("/api/scans?access_token=t")), want);
    assert_eq!(ids(&d.get_json("/api/visits?access_token=t")).len(), 0);

    // Pages of 50: every scan once, in order, the last page short and without a cursor.
    let (walked, pages) = walk(&d, "/api/scans?limit=50");
    assert_eq!(walked, want);
    assert_eq!(pages, 5);
    let last = d.get_json(&format!("/api/scans?limit=50&before={}", want[199]));
    assert_eq!(ids(&last["items"]).len(), 30);
    assert!(last["next"].is_null(), "{}", last["next"]);

    // Searches, each against the planted records filtered here.
    let check = |query: &str, keep: &dyn Fn(&Planted) -> bool| {
        let want: Vec<String> = planted
            .iter()
            .filter(|p| keep(p))
            .map(|p| p.0.clone())
            .collect();
        assert!(!want.is_empty(), "{query}: the test plants matches");
        let (got, _) = walk(&d, &format!("/api/scans?limit=7&{query}"));
        assert_eq!(got, want, "{query}");
        let unpaged = d.get_json(&format!("/api/scans?{query}"));
        assert_eq!(ids(&unpaged), want, "{query} unpaged");
    };
    // Subject: the start of the id, any case.
    check("subject=p-0042", &|p| {
        p.1.to_lowercase().starts_with("p-0042")
    });
    check("subject=P-0042b", &|p| p.1 == "P-0042b");
    check("subject=P", &|p| p.1.to_lowercase().starts_with('p'));
    check("status=rescan", &|p| p.3 == "rescan");
    check("status=complete%20with%20warnings&side=left", &|p| {
        p.3 == "complete with warnings" && p.2 == "left"
    });
    check("side=right&subject=alice", &|p| {
        p.2 == "right" && p.1 == "alice"
    });
    // Time bounds: since inclusive, until exclusive, by the start time (the id's).
    check(
        "since=2026-01-02T00:00:00Z&until=2026-01-03T12:00:00Z",
        &|p| p.0.as_str() >= "20260102T000000Z" && p.0.as_str() < "20260103T120000Z",
    );
    // A date is the clinic's (UTC here): since from its start, until through its end.
    check("since=2026-01-03&until=2026-01-03", &|p| {
        p.0.starts_with("20260103T")
    });
    assert!(d
        .get_json("/api/scans?subject=nobody")
        .as_array()
        .unwrap()
        .is_empty());

    // A scan whose directory went away between two pages: the next page is still full and
    // does not list it.
    let page1 = d.get_json("/api/scans?limit=50");
    let cursor = page1["next"].as_str().unwrap().to_string();
    std::fs::remove_dir_all(archive.join(&want[52])).unwrap();
    let page2 = d.get_json(&format!("/api/scans?limit=50&before={cursor}"));
    let got = ids(&page2["items"]);
    let mut expect: Vec<String> = want[50..101].to_vec();
    expect.remove(2);
    assert_eq!(got, expect);

    // Bad queries: 400 naming the parameter and what it takes.
    for (q, says) in [
        ("limit=0", "1 to 500"),
        ("limit=501", "1 to 500"),
        ("limit=ten", "whole number"),
        ("before=yesterday", "YYYYMMDDTHHMMSSZ-xxxx"),
        ("status=done", "complete with warnings"),
        ("side=both", "\\\"left\\\" or \\\"right\\\""),
        ("subject=a%20b", "A-Z a-z 0-9"),
        ("since=2026-13-01", "RFC 3339"),
        ("until=noon", "YYYY-MM-DD"),
        ("page=2", "limit, before, subject"),
    ] {
        let r = d.get(&format!("/api/scans?{q}"));
        assert_eq!(r.status(), 400, "{q}");
        let text = r.text().unwrap();
        assert!(text.contains(says), "{q}: {text}");
    }
}

#[test]
fn visits_page_and_search_by_index() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    let dir = archive.join("visits");
    std::fs::create_dir_all(&dir).unwrap();
    let t0 = jiff::Timestamp::from_second(1_767_225_600).unwrap();
    let mut planted = Vec::new();
    let write = |dir: &Path, i: usize| {
        let t = t0 + jiff::SignedDuration::from_secs(i as i64 * 53 * 60);
        let id = format!("{}-{:04x}", t.strftime("%Y%m%dT%H%M%SZ"), i);
        let patient = SUBJECTS[i % SUBJECTS.len()];
        let v = serde_json::json!({"id": id, "patient": patient, "notes": "",
            "started": t.strftime("%Y-%m-%dT%H:%M:%SZ").to_string(), "left": null, "right": null});
        std::fs::write(dir.join(format!("{id}.json")), v.to_string()).unwrap();
        (id, patient)
    };
    for i in 0..120 {
        planted.push(write(&dir, i));
    }
    let d = start(tmp.path(), &archive);
    planted.sort_by(|a, b| b.0.cmp(&a.0));
    let want: Vec<String> = planted.iter().map(|p| p.0.clone()).collect();
    assert_eq!(ids(&d.get_json("/api/visits")), want, "unpaged: as before");
    let (walked, pages) = walk(&d, "/api/visits?limit=25");
    assert_eq!(walked, want);
    assert_eq!(pages, 5);
    // Subject: any part of the patient id, any case (as before pages).
    let part: Vec<String> = planted
        .iter()
        .filter(|p| p.1.to_lowercase().contains("004"))
        .map(|p| p.0.clone())
        .collect();
    assert_eq!(walk(&d, "/api/visits?limit=10&subject=004").0, part);
    let day: Vec<String> = planted
        .iter()
        .filter(|p| p.0.starts_with("20260102T"))
        .map(|p| p.0.clone())
        .collect();
    assert!(!day.is_empty());
    assert_eq!(walk(&d, "/api/visits?limit=4&date=2026-01-02").0, day);

    // A visit file added and one removed behind the daemon's back are seen by the next list
    // (the directory's time says the index is behind).
    let added = write(&dir, 500);
    std::fs::remove_file(dir.join(format!("{}.json", want[0]))).unwrap();
    let now = ids(&d.get_json("/api/visits?limit=500")["items"]);
    assert_eq!(now[0], added.0);
    assert!(!now.contains(&want[0]), "{now:?}");
    assert_eq!(now.len(), want.len());

    let r = d.get("/api/visits?limit=20&cursor=x");
    assert_eq!(r.status(), 400);
    assert!(r.text().unwrap().contains("subject, date, limit, before"));
}

/// `footscand archive du`: where the space goes, by kind and by year, against files of known
/// lengths; a missing archive is an error naming it.
#[test]
fn archive_du_says_where_the_space_goes() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    let planted = plant_scans(&archive, 12);
    for (i, p) in planted.iter().enumerate() {
        std::fs::write(archive.join(&p.0).join("grid.bin"), vec![7u8; 10_000 + i]).unwrap();
        if i % 2 == 0 {
            std::fs::write(archive.join(&p.0).join("model.stl"), vec![1u8; 3000]).unwrap();
        }
    }
    std::fs::create_dir_all(archive.join("visits")).unwrap();
    std::fs::write(archive.join("visits/x.json"), b"{}").unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_footscand"))
        .args(["archive", "du", "--json"])
        .arg(&archive)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let u: Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(u["scans"], 12, "{u}");
    let grid = &u["by_kind"]["grid.bin"];
    assert_eq!(grid["files"], 12);
    assert_eq!(grid["bytes"], (0..12).map(|i| 10_000 + i).sum::<u64>());
    assert!(grid["disk"].as_u64().unwrap() >= grid["bytes"].as_u64().unwrap());
    assert_eq!(u["by_kind"]["model.stl"]["bytes"], 6 * 3000);
    assert_eq!(u["by_kind"]["record.json"]["files"], 12);
    // 12 scans 37 minutes apart from 2026-01-01: all of 2026.
    assert_eq!(u["by_year"]["2026"][0], 12);
    assert_eq!(u["other"]["visits"]["files"], 1);

    let table = std::process::Command::new(env!("CARGO_BIN_EXE_footscand"))
        .args(["archive", "du"])
        .arg(&archive)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(
        text.contains("12 scans") && text.contains("grid.bin"),
        "{text}"
    );

    let missing = std::process::Command::new(env!("CARGO_BIN_EXE_footscand"))
        .args(["archive", "du"])
        .arg(tmp.path().join("nowhere"))
        .output()
        .unwrap();
    assert!(!missing.status.success());
    let err = String::from_utf8_lossy(&missing.stderr);
    assert!(
        err.contains("nowhere") && err.contains("not a directory"),
        "{err}"
    );
}

/// The dashboard's archive table in headless Chromium: the first view shows one page of 50,
/// "Older scans" appends the next by its cursor, and the search shows only matching scans.
#[test]
fn dashboard_archive_table_pages_and_searches() {
    use daemon_support::chromium::Browser;
    use std::time::Duration;
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    let planted = plant_scans(&archive, 120);
    let d = start(tmp.path(), &archive);
    let mut b = Browser::launch(&tmp.path().join("profile"), 1400, 2600);
    let rows = "[...document.querySelectorAll('#scans tbody tr[data-scan-id]')].map((r) => r.dataset.scanId)";
    b.open(
        &d.base,
        "performance.getEntriesByName('scans-shown').length > 0",
        Duration::from_secs(30),
    );
    let want: Vec<String> = planted.iter().map(|p| p.0.clone()).collect();
    let shown = |b: &mut Browser| -> Vec<String> { serde_json::from_value(b.eval(rows)).unwrap() };
    assert_eq!(shown(&mut b), want[..50]);
    assert_eq!(
        b.eval("document.getElementById('scans-more').hidden"),
        false
    );
    b.click("scans-more");
    b.wait_for(
        "document.querySelectorAll('#scans tbody tr[data-scan-id]').length === 100",
        Duration::from_secs(10),
    );
    assert_eq!(shown(&mut b), want[..100]);
    b.click("scans-more");
    b.wait_for(
        "document.querySelectorAll('#scans tbody tr[data-scan-id]').length === 120",
        Duration::from_secs(10),
    );
    assert_eq!(shown(&mut b), want);
    assert_eq!(b.eval("document.getElementById('scans-more').hidden"), true);

    // Search: subject "q-1" (any case, the start of the id) and the left foot.
    b.eval(
        "document.getElementById('scan-subject').value = 'q-1'; \
         document.getElementById('scan-side').value = 'left'; \
         document.getElementById('scan-search-go').click(); true",
    );
    let matching: Vec<String> = planted
        .iter()
        .filter(|p| p.1 == "Q-17" && p.2 == "left")
        .map(|p| p.0.clone())
        .collect();
    assert!(!matching.is_empty());
    b.wait_for(
        &format!(
            "document.querySelectorAll('#scans tbody tr[data-scan-id]').length === {}",
            matching.len()
        ),
        Duration::from_secs(10),
    );
    assert_eq!(shown(&mut b), matching);
    let caption = b.eval("document.getElementById('scans-caption').textContent");
    assert!(
        caption
            .as_str()
            .unwrap()
            .starts_with(&format!("{} scan", matching.len())),
        "{caption}"
    );
}

/// Which visit holds a scan comes from the index (one query, not every visit file read), and
/// a visit file written behind the daemon's back counts: a scan it holds is refused to
/// another visit (409 naming it) until moved, and deleting the other visit keeps the scan.
#[test]
fn the_visit_holding_a_scan_is_found_by_index() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    let planted = plant_scans(&archive, 30);
    // A planted scan of "alice" (left) held by a visit written as a file.
    let (scan, _, side, _) = planted
        .iter()
        .find(|p| p.1 == "alice" && p.2 == "left")
        .unwrap()
        .clone();
    assert_eq!(side, "left");
    let d = start(tmp.path(), &archive);
    let held_by = "20260101T000000Z-0abc";
    // The daemon makes the visits directory with its first visit; this one comes first.
    std::fs::create_dir_all(archive.join("visits")).unwrap();
    let v = serde_json::json!({"id": held_by, "patient": "alice", "notes": "",
        "started": "2026-01-01T00:00:00Z", "left": scan, "right": null});
    std::fs::write(
        archive.join(format!("visits/{held_by}.json")),
        v.to_string(),
    )
    .unwrap();
    let (s, visit) = d.post("/api/visits", r#"{"patient": "alice"}"#);
    assert_eq!(s, 201, "{visit}");
    let vid = visit["id"].as_str().unwrap().to_string();
    let body = format!(r#"{{"scan": "{scan}"}}"#);
    let (s, err) = d.post(&format!("/api/visits/{vid}/scans"), &body);
    assert_eq!(s, 409, "{err}");
    assert!(err.to_string().contains(held_by), "{err}");
    // Moved on request: the planted visit no longer holds it (its file says so).
    let body = format!(r#"{{"scan": "{scan}", "move": true}}"#);
    let (s, now) = d.post(&format!("/api/visits/{vid}/scans"), &body);
    assert_eq!(s, 200, "{now}");
    assert_eq!(now["left"], scan.as_str());
    let old: Value = serde_json::from_slice(
        &std::fs::read(archive.join(format!("visits/{held_by}.json"))).unwrap(),
    )
    .unwrap();
    assert!(old["left"].is_null(), "{old}");
    // Put back into the planted visit by hand (behind the daemon's back): deleting the new
    // visit must keep the scan, which another visit holds.
    std::fs::write(
        archive.join(format!("visits/{held_by}.json")),
        v.to_string(),
    )
    .unwrap();
    let (s, gone) = d.delete(&format!("/api/visits/{vid}"));
    assert_eq!(s, 200, "{gone}");
    assert_eq!(d.get(&format!("/api/scans/{scan}")).status(), 200);
}
