//! The visits card of the dashboard in Debian's headless Chromium, worked over the DevTools
//! protocol: footscand (clinic time zone Europe/Berlin, a token) scans a right and a left foot
//! of one patient (the simulator's foot turned to each side) and a visit holding both is made
//! over HTTP, beside another patient's empty visit. The page must list both visits newest
//! first, find the patient's by part of the id and by the clinic's date, open it with the
//! patient, the local time, both feet with the verdicts the archive gives and working links
//! (the scan into Result, each foot's report, the visit's report), save notes typed into the
//! page (read back over HTTP), and delete the visit with its scans only after the
//! confirmation. The open visit shows both feet side by side: each in 3D (WebGL on
//! SwiftShader, the canvas showing the foot) and the visit report's table of both feet's
//! figures with right minus left, checked against the archive's measurements. Screenshots at
//! target/dashboard-visits.png (the open visit), target/dashboard-visits-3d-{left,right}.png
//! and target/dashboard-visits-delete.png (the confirmation), for people to look at.

mod daemon_support;

use chromium::Browser;
use daemon_support::{chromium, command, short_scanner_config, Footscand, Opts, Value};
use std::path::Path;
use std::time::Duration;

const TOKEN: &str = "dashboard-visits-token-0123456789";
const WAIT: Duration = Duration::from_secs(30);
/// style.css: --ok (green) and --warn (amber) badges.
const GREEN: [u8; 3] = [0x17, 0x66, 0x3a];
const AMBER: [u8; 3] = [0xe0, 0xa8, 0x00];

/// footscand on `archive` in Berlin, the short simulated travel over a `side` foot.
fn daemon(dir: &Path, archive: &Path, side: &str) -> Footscand {
    let o = Opts {
        archive: Some(archive.to_owned()),
        token: Some(TOKEN),
        ..Opts::default()
    };
    let (cmd, archive) = command(dir, &o);
    let cfg = dir.join("footscand.toml");
    let text = std::fs::read_to_string(&cfg).unwrap();
    std::fs::write(
        &cfg,
        format!("{text}[clinic]\ntime_zone = \"Europe/Berlin\"\n"),
    )
    .unwrap();
    let scanner = short_scanner_config("");
    assert_eq!(scanner.matches("side = \"right\"").count(), 1);
    std::fs::write(
        dir.join("scanner.toml"),
        scanner.replace("side = \"right\"", &format!("side = \"{side}\"")),
    )
    .unwrap();
    Footscand::spawn(cmd, archive, Some(TOKEN))
}

fn scan(d: &Footscand, subject: &str, side: &str) -> String {
    let (s, v) = d.post(
        "/api/scans",
        &format!(r#"{{"subject": "{subject}", "side": "{side}"}}"#),
    );
    assert_eq!(s, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    d.wait_scan_end(Duration::from_secs(240));
    id
}

/// app.js's VERDICT: how the page words a status.
fn worded(status: &str) -> String {
    match status {
        "side mismatch" => "side mismatch: confirm the side".into(),
        "rescan" => "failed: rescan before the patient leaves".into(),
        s => s.into(),
    }
}

/// What the visits card shows (read from the DOM, as the operator sees it).
const CARD: &str = r#"(() => {
  const t = (id) => (document.getElementById(id) || {}).textContent || '';
  const foot = (side) => {
    const b = document.getElementById('visit-foot-' + side);
    const a = (sel) => { const e = b.querySelector(sel); return e ? e.getAttribute('href') : null; };
    return { scan: b.dataset.scanId || null, text: b.textContent,
      verdict: (b.querySelector('.badge') || {}).textContent || null,
      verdictClass: (b.querySelector('.badge') || {}).className || null,
      scanLink: a('a.scan-link'), report: a('a.report-link'),
      plantar: !!b.querySelector('img.visit-plantar') };
  };
  return {
    rows: [...document.querySelectorAll('#visit-list tbody tr[data-visit-id]')].map((r) =>
      ({ id: r.dataset.visitId, cells: [...r.cells].map((c) => c.textContent) })),
    caption: t('visit-list-caption'), zone: t('visits-zone'),
    open: document.getElementById('visit-detail').hidden ? null : document.getElementById('visit-detail').dataset.visitId,
    title: t('visit-title'), when: t('visit-when'), notes: document.getElementById('visit-notes').value,
    notesState: t('visit-notes-state'), left: foot('left'), right: foot('right'),
    visitReport: (document.getElementById('visit-report-link') || { getAttribute: () => null }).getAttribute('href'),
    confirm: document.getElementById('visit-delete-confirm').hidden ? null : t('visit-delete-question'),
    error: document.getElementById('error').hidden ? '' : t('error-text'),
    result: document.getElementById('result').dataset.scanId || null,
  };
})()"#;

fn card(b: &mut Browser) -> Value {
    let c = b.eval(CARD);
    assert_eq!(c["error"], "", "the page shows an error: {c}");
    c
}

/// Search the list: type `subject` and `date` into the form and submit it; the ids listed.
fn search(b: &mut Browser, subject: &str, date: &str, want: usize) -> Value {
    b.eval(&format!(
        "document.getElementById('visit-subject').value = {subject:?}; \
         document.getElementById('visit-date').value = {date:?}; \
         document.getElementById('visit-search-go').click()"
    ));
    let what = if subject.is_empty() && date.is_empty() {
        String::new()
    } else {
        "(".into()
    };
    b.wait_for(
        &format!(
            "document.querySelectorAll('#visit-list tbody tr[data-visit-id]').length === {want} \
             && document.getElementById('visit-list-caption').textContent.includes({what:?})"
        ),
        WAIT,
    );
    card(b)
}

fn near(p: [u8; 3], c: [u8; 3]) -> bool {
    (0..3).all(|k| (p[k] as i32 - c[k] as i32).abs() <= 12)
}

#[test]
fn visits_in_the_dashboard() {
    chromium::require();
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");

    // A right foot and a left foot of P-0042 (the simulator's foot on each side), a visit
    // holding both, and a later visit of another patient.
    let mut d = daemon(tmp.path(), &archive, "right");
    let right = scan(&d, "P-0042", "right");
    d.terminate(Duration::from_secs(20));
    let d = daemon(tmp.path(), &archive, "left");
    let left = scan(&d, "P-0042", "left");
    let (s, visit) = d.post(
        "/api/visits",
        r#"{"patient": "P-0042", "notes": "first visit"}"#,
    );
    assert_eq!(s, 201, "{visit}");
    let vid = visit["id"].as_str().unwrap().to_string();
    for scan in [&right, &left] {
        let (s, v) = d.post(
            &format!("/api/visits/{vid}/scans"),
            &format!(r#"{{"scan": "{scan}"}}"#),
        );
        assert_eq!(s, 200, "{v}");
    }
    std::thread::sleep(Duration::from_millis(1100)); // a later id for the second visit
    let (s, other) = d.post("/api/visits", r#"{"patient": "Q-7"}"#);
    assert_eq!(s, 201, "{other}");
    let status = |id: &str| d.record(id)["status"].as_str().unwrap().to_string();
    let (left_status, right_status) = (status(&left), status(&right));
    println!("visit {vid}: left {left} {left_status}, right {right} {right_status}");
    let local = visit["started_local"].as_str().unwrap().to_string();
    let shown_time = format!("{} {} ({})", &local[..10], &local[11..16], &local[19..]);

    // The list: both visits, newest first, in the clinic's time.
    let mut b = Browser::launch_with(&tmp.path().join("profile"), 1280, 2400, &chromium::WEBGL);
    b.open(
        &format!("{}/#token={TOKEN}", d.base),
        "document.querySelectorAll('#visit-list tbody tr[data-visit-id]').length === 2",
        WAIT,
    );
    let c = card(&mut b);
    let ids: Vec<&str> = c["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["id"].as_str().unwrap())
        .collect();
    assert_eq!(ids, [other["id"].as_str().unwrap(), vid.as_str()], "{c}");
    let row = &c["rows"][1]["cells"];
    assert_eq!(row[0], shown_time.as_str(), "{c}");
    assert_eq!(
        (&row[1], &row[2], &row[3], &row[4]),
        (
            &"P-0042".into(),
            &"scanned".into(),
            &"scanned".into(),
            &"first visit".into()
        ),
        "{c}"
    );
    assert_eq!(c["zone"], "times in Europe/Berlin", "{c}");

    // Search by part of the patient id (any case) and by the clinic's date.
    let c = search(&mut b, "p-00", "", 1);
    assert_eq!(c["rows"][0]["id"], vid.as_str(), "{c}");
    let c = search(&mut b, "", &local[..10], 2);
    assert!(c["caption"].as_str().unwrap().contains(&local[..10]), "{c}");
    let c = search(&mut b, "0042", "1999-01-01", 0);
    assert!(
        c["caption"].as_str().unwrap().starts_with("0 visits"),
        "{c}"
    );
    search(&mut b, "", "", 2);

    // Open the visit: patient, local time, both feet with their verdicts and links.
    b.eval(&format!(
        "document.querySelector('#visit-list tr[data-visit-id=\"{vid}\"] button').click()"
    ));
    b.wait_for(
        "document.getElementById('visit-foot-left').dataset.scanId \
         && document.getElementById('visit-foot-right').dataset.scanId \
         && document.querySelectorAll('img.visit-plantar').length === 2 \
         && [...document.querySelectorAll('img.visit-plantar')].every((i) => i.complete && i.naturalWidth > 0)",
        WAIT,
    );
    let c = card(&mut b);
    println!("open visit: {c}");
    assert_eq!(c["open"], vid.as_str());
    assert!(
        c["title"].as_str().unwrap().contains("Visit of P-0042"),
        "{c}"
    );
    assert_eq!(
        c["when"],
        format!("Started {shown_time}, Europe/Berlin").as_str()
    );
    assert_eq!(c["notes"], "first visit");
    for (side, id, st) in [
        ("left", &left, &left_status),
        ("right", &right, &right_status),
    ] {
        let f = &c[side];
        assert_eq!(f["scan"], id.as_str(), "{side}: {f}");
        assert_eq!(f["verdict"], worded(st).as_str(), "{side}: {f}");
        let class = format!("st-{}", st.replace(' ', "-"));
        assert!(
            f["verdictClass"].as_str().unwrap().contains(&class),
            "{side}: {f}"
        );
        assert!(
            f["text"].as_str().unwrap().contains("length "),
            "{side}: {f}"
        );
        assert!(
            f["scanLink"] == "#result"
                && f["text"].as_str().unwrap().contains(&format!("Scan {id}")),
            "{side}: {f}"
        );
        let report = f["report"].as_str().unwrap();
        assert!(
            report.starts_with(&format!("/api/scans/{id}/report.pdf?access_token=")),
            "{report}"
        );
    }
    both_feet_side_by_side(&mut b, &d, &left, &right);
    // The links answer (with the token the page put in them): a foot's report and the visit's.
    let visit_report = c["visitReport"].as_str().unwrap().to_string();
    assert!(
        visit_report.starts_with(&format!("/api/visits/{vid}/report.pdf?access_token=")),
        "{visit_report}"
    );
    for href in [c["left"]["report"].as_str().unwrap(), &visit_report] {
        let got = b.eval(&format!(
            "fetch({href:?}).then(async (r) => [r.status, r.headers.get('content-type'), \
             (await r.arrayBuffer()).byteLength])"
        ));
        println!("{href}: {got}");
        assert_eq!(got[0], 200, "{href}: {got}");
        assert_eq!(got[1], "application/pdf", "{href}: {got}");
        assert!(got[2].as_u64().unwrap() > 1000, "{href}: {got}");
    }
    // The scan link shows that scan in Result.
    b.eval("document.querySelector('#visit-foot-left a.scan-link').click()");
    b.wait_for(
        &format!("document.getElementById('result').dataset.scanId === {left:?}"),
        WAIT,
    );

    // Notes typed into the page and saved through the API.
    let notes = "pes planus, both feet; insoles ordered";
    b.eval(&format!(
        "document.getElementById('visit-notes').value = {notes:?}"
    ));
    b.click("visit-notes-save");
    b.wait_for(
        "document.getElementById('visit-notes-state').textContent === 'Saved.'",
        WAIT,
    );
    assert_eq!(d.get_json(&format!("/api/visits/{vid}"))["notes"], notes);
    b.wait_for(
        &format!(
            "document.querySelector('#visit-list tr[data-visit-id=\"{vid}\"] td.visit-notes-cell')\
             .textContent === {notes:?}"
        ),
        WAIT,
    );
    b.eval("document.getElementById('visits').scrollIntoView()");
    let png = chromium::target_png("dashboard-visits.png");
    let img = b.screenshot(&png, Some("visits"));
    let count = |c: [u8; 3]| img.pixels().filter(|p| near(p.0, c)).count();
    let want = |st: &str| match st {
        "complete" => Some(GREEN),
        "complete with warnings" | "side mismatch" => Some(AMBER),
        _ => None,
    };
    // Each verdict badge is about 750 pixels of its colour (nothing else on the card has it).
    for colour in [GREEN, AMBER] {
        let badges = [&left_status, &right_status]
            .iter()
            .filter(|st| want(st) == Some(colour))
            .count();
        let n = count(colour);
        println!("screenshot: {badges} badges of {colour:?}: {n} pixels");
        assert!(
            if badges == 0 {
                n < 100
            } else {
                n > 400 * badges
            },
            "{n} pixels of {colour:?} for {badges} verdict badges ({left_status}, {right_status})"
        );
    }

    // Delete: nothing happens before the confirmation; "Keep" keeps the visit.
    b.click("visit-delete");
    let c = card(&mut b);
    let q = c["confirm"].as_str().unwrap_or_default();
    assert!(
        q.contains("P-0042") && q.contains("2 scans") && q.contains("cannot be undone"),
        "{c}"
    );
    b.screenshot(
        &chromium::target_png("dashboard-visits-delete.png"),
        Some("visits"),
    );
    b.click("visit-delete-no");
    assert_eq!(card(&mut b)["confirm"], Value::Null);
    assert_eq!(d.get(&format!("/api/visits/{vid}")).status(), 200);
    b.click("visit-delete");
    b.click("visit-delete-yes");
    b.wait_for(
        &format!(
            "!document.querySelector('#visit-list tr[data-visit-id=\"{vid}\"]') \
             && document.getElementById('visit-detail').hidden"
        ),
        WAIT,
    );
    card(&mut b);
    assert_eq!(d.get(&format!("/api/visits/{vid}")).status(), 404);
    for id in [&left, &right] {
        assert_eq!(d.get(&format!("/api/scans/{id}")).status(), 404, "{id}");
    }
    let log = std::fs::read_to_string(archive.join("visits/deleted.log")).unwrap();
    assert!(log.contains(&vid) && log.contains(&right), "{log}");
}

/// The open visit's two feet: a 3D view each that shows its foot (a tenth of the canvas at
/// least, away from the background), and the table of both feet's figures whose right minus
/// left is the archive's (to the table's decimals).
fn both_feet_side_by_side(b: &mut Browser, d: &Footscand, left: &str, right: &str) {
    b.wait_for(
        "(() => { const c = [...document.querySelectorAll('canvas.visit-viewer')]; \
         return c.length === 2 && c.every((x) => x.dataset.ready === '1' || x.dataset.error); })()",
        WAIT,
    );
    let v = b.eval(
        "(() => ({ views: [...document.querySelectorAll('canvas.visit-viewer')].map((c) => \
           ({ id: c.id, scan: c.dataset.scanId, ms: c.dataset.loadMs, tri: c.dataset.triangles, \
              err: c.dataset.error || null })), \
           rows: [...document.querySelectorAll('#visit-compare-table tbody tr')].map((r) => \
              [...r.cells].map((c) => c.textContent)) }))()",
    );
    println!("visit 3D views and figures: {v}");
    for (view, side, id) in [(0, "left", left), (1, "right", right)] {
        let w = &v["views"][view];
        assert_eq!(w["err"], Value::Null, "{w}");
        assert_eq!(w["id"], format!("visit-viewer-{side}").as_str(), "{w}");
        assert_eq!(w["scan"], id, "{w}");
        let png = chromium::target_png(&format!("dashboard-visits-3d-{side}.png"));
        let img = b.screenshot(&png, Some(&format!("visit-viewer-{side}")));
        let bg = [0xf7u8, 0xf7, 0xf5];
        let foot = img
            .pixels()
            .filter(|p| (0..3).any(|k| (p[k] as i32 - bg[k] as i32).abs() > 24))
            .count();
        let share = foot as f64 / (img.width() * img.height()) as f64;
        println!("{side} foot in 3D: {:.1} % of its canvas", 100.0 * share);
        assert!(share > 0.1, "{side}: the 3D view shows {share:.3} of foot");
    }
    let rows = v["rows"].as_array().unwrap();
    assert_eq!(rows.len(), 8, "{v}");
    let m = |id: &str| d.get_json(&format!("/api/scans/{id}"))["measurements"].clone();
    let (ml, mr) = (m(left), m(right));
    for (row, key, dec) in [
        (0, "foot_length_mm", 1),
        (2, "ball_width_mm", 1),
        (4, "heel_width_mm", 1),
        (6, "arch_index", 3),
    ] {
        let (l, r) = (ml[key].as_f64().unwrap(), mr[key].as_f64().unwrap());
        let cells = rows[row].as_array().unwrap();
        let num = |k: usize| cells[k].as_str().unwrap().parse::<f64>().unwrap();
        let tol = 0.51 * 10f64.powi(-dec);
        assert!((num(1) - l).abs() <= tol, "{key} left {l}: {cells:?}");
        assert!((num(2) - r).abs() <= tol, "{key} right {r}: {cells:?}");
        assert!(
            (num(3) - (r - l)).abs() <= 2.0 * tol,
            "{key} R - L {}: {cells:?}",
            r - l
        );
    }
}
