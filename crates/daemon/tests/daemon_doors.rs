//! The four doors a hostile neighbour found (issue 37): a slow-header flood, a symlinked
//! `last/` directory, simultaneous answers to one calibration step, and a scan in two visits;
//! and the small ones: 507 for a visit the archive cannot take, an immediate 413 for a huge
//! Content-Length, the API's JSON error for a head hyper refuses itself.

mod daemon_support;

use daemon_support::*;
use footscan_daemon::archive::{Archive, NewScan, ScanEnd, Status};
use std::io::{Read, Write};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// A raw request on a fresh connection: (status, lower-cased head, body, seconds taken);
/// status 0 when the daemon closed or did not answer within `limit`.
fn raw(base: &str, request: &str, limit: Duration) -> (u16, String, String, f64) {
    let addr = base.strip_prefix("http://").unwrap();
    let t = Instant::now();
    let Ok(mut s) = std::net::TcpStream::connect_timeout(&addr.parse().unwrap(), limit) else {
        return (0, String::new(), String::new(), t.elapsed().as_secs_f64());
    };
    s.set_read_timeout(Some(limit)).unwrap();
    let _ = s.write_all(request.as_bytes());
    let mut buf = Vec::new();
    let _ = s.read_to_end(&mut buf);
    let took = t.elapsed().as_secs_f64();
    let text = String::from_utf8_lossy(&buf).into_owned();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (status, head.to_ascii_lowercase(), body.to_string(), took)
}

/// `n` connections that each send half a request head and are reopened when the daemon
/// closes them, until `stop`. Returns how many were reopened.
fn slow_header_flood(
    addr: std::net::SocketAddr,
    n: usize,
    stop: Arc<AtomicBool>,
    open: Arc<AtomicUsize>,
) -> std::thread::JoinHandle<usize> {
    std::thread::spawn(move || {
        let half = b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ";
        let connect = || {
            let s = std::net::TcpStream::connect_timeout(&addr, Duration::from_millis(50)).ok()?;
            s.set_nonblocking(true).ok()?;
            let mut s = s;
            let _ = s.write(half);
            Some(s)
        };
        let mut socks: Vec<Option<std::net::TcpStream>> = (0..n).map(|_| None).collect();
        let mut reopened = 0;
        let mut b = [0u8; 512];
        while !stop.load(Ordering::Relaxed) {
            // Wait (poll, not a busy loop: the flood must not take the daemon's CPU) until
            // the daemon closes or answers some of them.
            use std::os::fd::AsRawFd;
            let mut fds: Vec<libc::pollfd> = socks
                .iter()
                .map(|s| libc::pollfd {
                    fd: s.as_ref().map_or(-1, |s| s.as_raw_fd()),
                    events: libc::POLLIN,
                    revents: 0,
                })
                .collect();
            // SAFETY: `fds` is a valid array of pollfd for the length given.
            unsafe { libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, 20) };
            let mut live = 0;
            for (slot, p) in socks.iter_mut().zip(&fds) {
                let closed = match slot {
                    None => true,
                    Some(s) if p.revents != 0 => match s.read(&mut b) {
                        Ok(_) => true, // closed, or answered (503): either way, reopen
                        Err(e) => e.kind() != std::io::ErrorKind::WouldBlock,
                    },
                    Some(_) => false,
                };
                if closed {
                    if slot.is_some() {
                        reopened += 1;
                    }
                    *slot = connect();
                }
                live += slot.is_some() as usize;
            }
            open.store(live, Ordering::Relaxed);
        }
        reopened
    })
}

/// Door 1: under 2,000 connections that send half a head and are reopened when closed,
/// /api/health on a fresh connection answers every time (p99 printed: the target is 100 ms),
/// and a scan running meanwhile ends with its files.
#[test]
fn a_slow_header_flood_cannot_hold_the_door() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    let addr: std::net::SocketAddr = d.base.strip_prefix("http://").unwrap().parse().unwrap();
    let stop = Arc::new(AtomicBool::new(false));
    let open = Arc::new(AtomicUsize::new(0));
    let flood = slow_header_flood(addr, 2000, stop.clone(), open.clone());
    let t0 = Instant::now();
    while open.load(Ordering::Relaxed) < 1500 && t0.elapsed() < Duration::from_secs(20) {
        std::thread::sleep(Duration::from_millis(50));
    }
    println!(
        "{} slow connections open after {:.1} s",
        open.load(Ordering::Relaxed),
        t0.elapsed().as_secs_f64()
    );
    let id = d.start_scan("flood");
    let health = format!("GET /api/health HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    let mut times = Vec::new();
    let mut failed = 0;
    for _ in 0..200 {
        let (status, _, _, took) = raw(&d.base, &health, Duration::from_secs(5));
        if status != 200 {
            failed += 1;
        }
        times.push(took);
        std::thread::sleep(Duration::from_millis(10));
    }
    let end = d.wait_scan_end(Duration::from_secs(180));
    stop.store(true, Ordering::Relaxed);
    let reopened = flood.join().unwrap();
    let p50 = percentile(&mut times, 50.0) * 1e3;
    let p99 = percentile(&mut times, 99.0) * 1e3;
    println!(
        "slow-header flood: {reopened} connections evicted and reopened; health p50 {p50:.1} ms, \
         p99 {p99:.1} ms, {failed} of 200 failed; scan {} with {} frames, {} dropped",
        end["state"], end["frames"], end["dropped"]
    );
    // Before the fix the cap (256) filled with half-sent connections that were never
    // evicted, accepting stopped and health timed out. Now the default cap holds the flood
    // (no churn through eviction, which only queues the reopened connections ahead of real
    // ones: p99 was 1.0-1.7 s that way, docs/method.md 14.2). The p99 (target: under
    // 100 ms) and the frames dropped are printed, not asserted: speed belongs to benches, and
    // on a loaded machine the simulated scan drops frames without any flood. What is
    // asserted is liveness: every health request answered within its 5 s limit.
    assert_eq!(failed, 0, "health requests failed under the flood");
    assert_ne!(end["state"], "failed", "{end}");
    assert!(d.record(&id)["artifacts"].to_string().contains("grid.bin"));
}

/// Door 1, as the probe found it: 300 half-sent connections against a cap of 256. Those over
/// the cap are closed at once to make room (before, none was closed before the 10 s header
/// timeout), and health answers meanwhile.
#[test]
fn half_sent_connections_over_the_cap_are_evicted_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let (cmd, archive) = command(tmp.path(), &Opts::default());
    let cfg = tmp.path().join("footscand.toml");
    let text = std::fs::read_to_string(&cfg).unwrap()
        + "max_connections = 256\nmax_connections_per_client = 256\n";
    std::fs::write(&cfg, text).unwrap();
    let d = Footscand::spawn(cmd, archive, None);
    let addr = d.base.strip_prefix("http://").unwrap().to_string();
    let t0 = Instant::now();
    let mut held: Vec<std::net::TcpStream> = (0..300)
        .map(|_| {
            let mut s = std::net::TcpStream::connect(&addr).unwrap();
            s.write_all(b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ")
                .unwrap();
            s
        })
        .collect();
    std::thread::sleep(Duration::from_millis(1500));
    let mut closed = 0;
    for s in &mut held {
        s.set_nonblocking(true).unwrap();
        let mut b = [0u8; 64];
        match s.read(&mut b) {
            Ok(_) => closed += 1,
            Err(e) if e.kind() != std::io::ErrorKind::WouldBlock => closed += 1,
            Err(_) => {}
        }
    }
    let took = t0.elapsed().as_secs_f64();
    let health = format!("GET /api/health HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n");
    let (status, _, _, h) = raw(&d.base, &health, Duration::from_secs(5));
    println!("300 half-sent against a cap of 256: {closed} closed within {took:.1} s; health {status} in {:.1} ms", h * 1e3);
    assert!(
        closed >= 300 - 256,
        "only {closed} of 300 half-sent connections closed"
    );
    assert_eq!(status, 200);
}

/// Small doors: a Content-Length far over the limit with no body is 413 at once; a
/// duplicate Content-Length (refused by hyper itself) gets the API's JSON error.
#[test]
fn huge_and_duplicate_content_length_get_json_errors_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    let host = d.base.strip_prefix("http://").unwrap().to_string();
    let huge = format!(
        "POST /api/visits HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n\
         Content-Length: 1000000000000000\r\n\r\n"
    );
    let (status, head, body, took) = raw(&d.base, &huge, Duration::from_secs(15));
    println!("Content-Length 10^15: {status} after {took:.3} s: {body}");
    assert_eq!(status, 413, "{head}");
    assert!(took < 2.0, "413 took {took:.1} s");
    assert!(body.contains("1000000000000000"), "{body}");
    let dup = format!(
        "POST /api/visits HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n\
         Content-Length: 5\r\nContent-Length: 20\r\n\r\n{{\"patient\": \"P-1\"}}"
    );
    let (status, head, body, _) = raw(&d.base, &dup, Duration::from_secs(15));
    println!("duplicate Content-Length: {status}: {body}");
    assert_eq!(status, 400, "{head}");
    assert!(head.contains("content-type: application/json"), "{head}");
    let v: Value = serde_json::from_str(&body).unwrap_or_else(|e| panic!("{e}: {body:?}"));
    assert!(
        v["error"].as_str().unwrap().contains("Content-Length"),
        "{v}"
    );
    // And the daemon still answers.
    assert_eq!(d.get_json("/api/health")["ok"], true);
}

/// An archive with finished scans made through the library, one per (subject, side).
fn archive_with(root: &std::path::Path, scans: &[(&str, &str)]) -> Vec<String> {
    let a = Archive::open(root).unwrap();
    scans
        .iter()
        .map(|(subject, side)| {
            let s = a
                .begin(NewScan {
                    subject: subject.to_string(),
                    side: side.to_string(),
                    notes: String::new(),
                })
                .unwrap();
            std::fs::write(s.dir.join("scan.json"), br#"{"status": "complete"}"#).unwrap();
            let r = a
                .finish(
                    s,
                    ScanEnd {
                        status: Status::Complete,
                        reason: None,
                        frames: 7,
                        points: 70,
                    },
                )
                .unwrap();
            std::thread::sleep(Duration::from_millis(1100)); // ids sort by second
            r.id
        })
        .collect()
}

fn start_on(tmp: &std::path::Path, root: &std::path::Path) -> Footscand {
    Footscand::start(
        tmp,
        Opts {
            archive: Some(root.to_path_buf()),
            ..Opts::default()
        },
    )
}

/// Door 2: a scan's `last/` replaced by a symlink to a directory outside the archive is not
/// served through; a real `last/` is.
#[test]
fn a_symlinked_last_directory_is_not_served() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    let ids = archive_with(&root, &[("P-1", "left"), ("P-2", "left"), ("P-3", "left")]);
    let outside = tmp.path().join("outside");
    std::fs::create_dir(&outside).unwrap();
    std::fs::write(outside.join("report.json"), br#"{"secret": true}"#).unwrap();
    std::fs::write(outside.join("last.stl"), b"solid secret\nendsolid\n").unwrap();
    std::os::unix::fs::symlink(&outside, root.join(&ids[0]).join("last")).unwrap();
    let real = root.join(&ids[1]).join("last");
    std::fs::create_dir(&real).unwrap();
    std::fs::write(real.join("report.json"), br#"{"own": true}"#).unwrap();
    // A file inside a real last/ that is itself a symlink out.
    std::os::unix::fs::symlink(outside.join("last.stl"), real.join("last.stl")).unwrap();
    let job = serde_json::json!({
        "scan": ids[2], "state": "done", "started": "2026-11-27T12:00:00Z",
        "finished": null, "seconds": null, "reason": "secret", "rules": [],
        "clearance": null, "fits": null, "files": [],
        "request": {
            "girths": {"ball": 260.0, "instep": 248.0, "long_heel": 367.0, "ankle": 200.5},
            "stock": "secret.stl"
        }
    });
    std::fs::write(outside.join("job.json"), job.to_string()).unwrap();
    std::os::unix::fs::symlink(
        outside.join("job.json"),
        root.join(&ids[2]).join("last-job.json"),
    )
    .unwrap();
    let d = start_on(tmp.path(), &root);
    for name in ["report.json", "last.stl"] {
        let r = d.get(&format!("/api/scans/{}/last/{name}", ids[0]));
        let status = r.status();
        let body = r.text().unwrap();
        assert_eq!(
            status, 404,
            "{name} served through a symlinked last/: {body}"
        );
        assert!(!body.contains("secret"), "{body}");
    }
    let r = d.get(&format!("/api/scans/{}/last/last.stl", ids[1]));
    assert_eq!(r.status(), 404, "a symlinked file in last/ was served");
    let r = d.get(&format!("/api/scans/{}/last/report.json", ids[1]));
    assert_eq!(r.status(), 200);
    assert_eq!(r.text().unwrap(), r#"{"own": true}"#);
    // The scan's last job record, a symlink out: its JSON was read through the link and
    // served as the scan's last (final components were checked only for downloads).
    let r = d.get(&format!("/api/scans/{}/last", ids[2]));
    let (status, body) = (r.status(), r.text().unwrap());
    assert!(
        !body.contains("secret"),
        "a symlinked last-job.json was served ({status}): {body}"
    );
    assert_ne!(status, 200, "{body}");
}

fn wait_job(d: &Footscand, phases: &[&str], limit: Duration) -> Value {
    let t0 = Instant::now();
    loop {
        let j = d.get_json("/api/calibrations/job");
        if phases.contains(&j["phase"].as_str().unwrap_or("")) || j["state"] != "running" {
            return j;
        }
        assert!(t0.elapsed() < limit, "job stuck: {j}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Door 3: eight simultaneous confirms of one placement: one is taken, seven are 409, and
/// the step then waits for its own review; an answer meant for another phase or attempt is
/// 409, and nothing queued is applied later.
#[test]
fn simultaneous_confirms_hand_over_one_answer() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    let limit = Duration::from_secs(120);
    let (s, v) = d.post(
        "/api/calibrations",
        r#"{"guided": true, "confirmed_by": "test operator"}"#,
    );
    assert_eq!(s, 202, "{v}");
    let id = v["id"].as_str().unwrap().to_string();
    let j = wait_job(&d, &["place"], limit);
    assert_eq!(j["step"]["index"], 0, "{j}");
    let barrier = Arc::new(std::sync::Barrier::new(8));
    let answers: Vec<_> = (0..8)
        .map(|_| {
            let (base, id, barrier) = (d.base.clone(), id.clone(), barrier.clone());
            std::thread::spawn(move || {
                let c = reqwest::blocking::Client::new();
                barrier.wait();
                c.post(format!("{base}/api/calibrations/{id}/confirm"))
                    .header("content-type", "application/json")
                    .body("{}")
                    .send()
                    .unwrap()
                    .status()
                    .as_u16()
            })
        })
        .collect();
    let mut codes: Vec<u16> = answers.into_iter().map(|t| t.join().unwrap()).collect();
    codes.sort();
    println!("eight simultaneous confirms: {codes:?}");
    assert_eq!(codes, vec![200, 409, 409, 409, 409, 409, 409, 409]);
    let j = wait_job(&d, &["review"], limit);
    assert_eq!(j["step"]["index"], 0, "{j}");
    assert_eq!(j["attempt"], 1, "{j}");
    // Nothing queued: the step stays in review, unkept, with no operator.
    std::thread::sleep(Duration::from_secs(2));
    let j = d.get_json("/api/calibrations/job");
    assert_eq!(j["phase"], "review", "{j}");
    assert_eq!(j["step"]["index"], 0, "{j}");
    assert_eq!(
        j["kept"],
        serde_json::json!([]),
        "kept with no operator: {j}"
    );
    // A confirm meant for the placement, arriving during the review, is refused.
    let (s, v) = d.post(
        &format!("/api/calibrations/{id}/confirm"),
        r#"{"phase": "place", "step": 0, "attempt": 1}"#,
    );
    assert_eq!(s, 409, "{v}");
    assert!(v["error"].as_str().unwrap().contains("place"), "{v}");
    let (s, v) = d.post(
        &format!("/api/calibrations/{id}/confirm"),
        r#"{"phase": "review", "step": 0, "attempt": 2}"#,
    );
    assert_eq!(s, 409, "{v}");
    let (s, v) = d.post(&format!("/api/calibrations/{id}/confirm"), r#"{"phas": 1}"#);
    assert_eq!(s, 400, "{v}");
    assert_eq!(
        d.get_json("/api/calibrations/job")["kept"],
        serde_json::json!([])
    );
    // The answer for this very step is taken.
    if j["result"]["passed"] == true {
        let (s, v) = d.post(
            &format!("/api/calibrations/{id}/confirm"),
            r#"{"phase": "review", "step": 0, "attempt": 1}"#,
        );
        assert_eq!(s, 200, "{v}");
        let j = wait_job(&d, &["place"], limit);
        assert_eq!(j["step"]["index"], 1, "{j}");
        assert_eq!(j["kept"].as_array().unwrap().len(), 1, "{j}");
    }
    let (s, v) = d.post(&format!("/api/calibrations/{id}/abort"), "{}");
    assert_eq!(s, 200, "{v}");
}

fn visit(d: &Footscand, patient: &str) -> String {
    let (s, v) = d.post("/api/visits", &format!(r#"{{"patient": "{patient}"}}"#));
    assert_eq!(s, 201, "{v}");
    v["id"].as_str().unwrap().to_string()
}

fn add(d: &Footscand, vid: &str, body: &str) -> (u16, Value) {
    d.post(&format!("/api/visits/{vid}/scans"), body)
}

/// Door 4: a scan belongs to one visit at most; moving it is explicit; a visit deletes only
/// the scans it owns; a side correction moves the scan's slot; a subject correction takes
/// it out of another patient's visit.
#[test]
fn a_visit_deletes_only_the_scans_it_owns() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    let ids = archive_with(&root, &[("P-1", "left"), ("P-1", "right"), ("P-5", "left")]);
    let (s_left, s_right, s_old) = (&ids[0], &ids[1], &ids[2]);
    // An archive written before the rule: two visits of P-5 listing the same scan.
    let visits = root.join("visits");
    std::fs::create_dir_all(&visits).unwrap();
    for vid in ["20250101T000000Z-0a0a", "20250101T000001Z-0b0b"] {
        let v = serde_json::json!({"id": vid, "patient": "P-5", "notes": "",
            "started": "2025-01-01T00:00:00Z", "left": s_old, "right": null});
        std::fs::write(visits.join(format!("{vid}.json")), v.to_string()).unwrap();
    }
    let d = start_on(tmp.path(), &root);

    // The issue's case: in P-1's visit, corrected to P-9, then put into P-9's visit.
    let v1 = visit(&d, "P-1");
    assert_eq!(add(&d, &v1, &format!(r#"{{"scan": "{s_left}"}}"#)).0, 200);
    let (s, v) = d.post(
        &format!("/api/scans/{s_left}/record"),
        r#"{"subject": "P-9", "why": "typed the wrong patient"}"#,
    );
    assert_eq!(s, 200, "{v}");
    assert_eq!(v["visits_changed"][0]["left"], Value::Null, "{v}");
    let v9 = visit(&d, "P-9");
    assert_eq!(add(&d, &v9, &format!(r#"{{"scan": "{s_left}"}}"#)).0, 200);
    assert_eq!(
        d.get_json(&format!("/api/visits/{v1}"))["left"],
        Value::Null
    );

    // Into a second visit of the same patient: refused unless moved explicitly.
    assert_eq!(add(&d, &v1, &format!(r#"{{"scan": "{s_right}"}}"#)).0, 200);
    let v1b = visit(&d, "P-1");
    let (s, v) = add(&d, &v1b, &format!(r#"{{"scan": "{s_right}"}}"#));
    assert_eq!(s, 409, "{v}");
    assert!(v["error"].as_str().unwrap().contains(&v1), "{v}");
    let (s, v) = add(
        &d,
        &v1b,
        &format!(r#"{{"scan": "{s_right}", "move": true}}"#),
    );
    assert_eq!(s, 200, "{v}");
    assert_eq!(v["right"], s_right.as_str());
    assert_eq!(
        d.get_json(&format!("/api/visits/{v1}"))["right"],
        Value::Null
    );

    // A side correction moves the slot.
    let (s, v) = d.post(
        &format!("/api/scans/{s_right}/record"),
        r#"{"side": "left", "why": "saved as the other foot"}"#,
    );
    assert_eq!(s, 200, "{v}");
    let vb = d.get_json(&format!("/api/visits/{v1b}"));
    assert_eq!(vb["left"], s_right.as_str(), "{vb}");
    assert_eq!(vb["right"], Value::Null, "{vb}");

    // Deleting P-1's first visit deletes nothing it no longer holds.
    let (s, v) = d.delete(&format!("/api/visits/{v1}"));
    assert_eq!(s, 200, "{v}");
    assert_eq!(v["scans_deleted"], serde_json::json!([]), "{v}");
    for sid in [s_left, s_right] {
        assert_eq!(
            d.get(&format!("/api/scans/{sid}")).status(),
            200,
            "{sid} gone"
        );
    }
    // The old double listing: the scan is kept while another visit lists it.
    let (s, v) = d.delete("/api/visits/20250101T000000Z-0a0a");
    assert_eq!(s, 200, "{v}");
    assert_eq!(v["scans_deleted"], serde_json::json!([]), "{v}");
    assert_eq!(d.get(&format!("/api/scans/{s_old}")).status(), 200);
    let (s, v) = d.delete("/api/visits/20250101T000001Z-0b0b");
    assert_eq!(s, 200, "{v}");
    assert_eq!(v["scans_deleted"], serde_json::json!([s_old]), "{v}");
    // P-9's visit still lists its scan, and it is there.
    assert_eq!(
        d.get_json(&format!("/api/visits/{v9}"))["left"],
        s_left.as_str()
    );
    assert_eq!(d.get(&format!("/api/scans/{s_left}")).status(), 200);
}

/// POST /api/visits answers 507 (as docs/API.md says) when the archive cannot take it.
#[test]
fn a_visit_the_archive_cannot_write_is_507() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    archive_with(&root, &[]);
    // `visits` taken by a file: no visit can be written (this holds as root too).
    std::fs::write(root.join("visits"), b"not a directory").unwrap();
    let d = start_on(tmp.path(), &root);
    let (s, v) = d.post("/api/visits", r#"{"patient": "P-1"}"#);
    assert_eq!(s, 507, "{v}");
    assert!(v["error"].as_str().unwrap().contains("visits"), "{v}");
}

/// HTTP JSON bodies, fuzzed: mutations of each POST endpoint's valid body (and arbitrary
/// bytes) get an answer below 500 with the API's JSON error, and the daemon stays up. The
/// body limit (16 KiB) bounds what any of them can make the daemon allocate. A longer run:
/// `FOOTSCAN_FUZZ_CASES=20000 cargo test -p footscand --test daemon_doors http_json`.
#[test]
fn http_json_bodies_fuzzed_get_json_answers() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    let ids = archive_with(&root, &[("P-1", "left")]);
    let d = start_on(tmp.path(), &root);
    let vid = visit(&d, "P-1");
    let sid = &ids[0];
    let seeds: Vec<(String, String)> = vec![
        (
            "/api/visits".into(),
            r#"{"patient": "P-2", "notes": "x"}"#.into(),
        ),
        (
            format!("/api/visits/{vid}/notes"),
            r#"{"notes": "n"}"#.into(),
        ),
        (
            format!("/api/visits/{vid}/scans"),
            format!(r#"{{"scan": "{sid}", "move": true}}"#),
        ),
        (
            format!("/api/scans/{sid}/record"),
            r#"{"subject": "P-1", "side": "left", "why": "w"}"#.into(),
        ),
        (
            format!("/api/scans/{sid}/side"),
            r#"{"side": "left", "confirmed_by": "op"}"#.into(),
        ),
        (
            format!("/api/scans/{sid}/last"),
            r#"{"girths": {"ball_mm": 230}, "stock": "x"}"#.into(),
        ),
        (
            "/api/scans".into(),
            r#"{"subject": "", "side": "up"}"#.into(),
        ),
        (
            "/api/calibrations/x/confirm".into(),
            r#"{"phase": "place", "step": 0, "attempt": 1}"#.into(),
        ),
        (
            "/api/verify".into(),
            r#"{"guided": true, "confirmed_by": "op", "sim_mistakes": []}"#.into(),
        ),
    ];
    let n: usize = std::env::var("FOOTSCAN_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(400);
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        x ^= x >> 12;
        x ^= x << 25;
        x ^= x >> 27;
        x.wrapping_mul(0x2545_F491_4F6C_DD1D)
    };
    let mut by_status = std::collections::BTreeMap::new();
    for i in 0..n {
        let (path, seed) = &seeds[next() as usize % seeds.len()];
        let mut b = seed.clone().into_bytes();
        if i % 5 == 0 {
            b = (0..next() % 300).map(|_| next() as u8).collect();
        } else {
            for _ in 0..1 + next() % 4 {
                let at = next() as usize % (b.len() + 1);
                let tokens: [&[u8]; 8] = [
                    b"{", b"}", b"\"", b",", b"null", b"1e999", b"-1", b"\\u0000",
                ];
                match next() % 3 {
                    0 if at < b.len() => b[at] = next() as u8,
                    1 => {
                        let t = tokens[next() as usize % tokens.len()];
                        b.splice(at..at, t.iter().copied());
                    }
                    _ => b.truncate(at),
                }
            }
        }
        let r = d
            .client
            .post(d.url(path))
            .header("content-type", "application/json")
            .body(b.clone())
            .send()
            .unwrap_or_else(|e| panic!("case {i}: POST {path}: {e}"));
        let status = r.status().as_u16();
        let text = r.text().unwrap();
        *by_status.entry(status).or_insert(0) += 1;
        assert!(
            status < 500 || status == 503,
            "case {i}: POST {path} {:?}: {status} {text}",
            String::from_utf8_lossy(&b)
        );
        if status >= 400 {
            let v: Value = serde_json::from_str(&text)
                .unwrap_or_else(|e| panic!("case {i}: {status} not JSON ({e}): {text}"));
            assert!(v["error"].is_string(), "case {i}: {text}");
        }
    }
    println!("{n} fuzzed JSON bodies: answers by status {by_status:?}");
    assert_eq!(d.get_json("/api/health")["ok"], true);
}

/// A scan whose directory could not take its record (the archive turned read-only) while
/// the index took its end keeps that first reason across a restart instead of becoming
/// "interrupted".
#[test]
fn the_first_reason_survives_a_directory_that_refused_its_record() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    let a = Archive::open(&root).unwrap();
    let s = a
        .begin(NewScan {
            subject: "P-1".into(),
            side: "left".into(),
            notes: String::new(),
        })
        .unwrap();
    let dir = s.dir.clone();
    // record.json taken by a non-empty directory: no record can be written there (as with
    // a read-only directory; this holds as root too). No scan.json either.
    std::fs::create_dir_all(dir.join("record.json").join("blocker")).unwrap();
    let id = s.record.id.clone();
    let end = a.finish(
        s,
        ScanEnd {
            status: Status::Complete,
            reason: None,
            frames: 141,
            points: 75_000,
        },
    );
    assert!(end.is_err(), "archiving should have failed");
    drop(a);
    // Writable again; the daemon restarts.
    std::fs::remove_dir_all(dir.join("record.json")).unwrap();
    let a = Archive::open(&root).unwrap();
    let r = a
        .get(&footscan_daemon::archive::ScanId::parse(&id).unwrap())
        .unwrap();
    println!("after the restart: {} {:?}", r.status.as_str(), r.reason);
    assert_eq!(r.status, Status::Failed);
    let reason = r.reason.unwrap_or_default();
    assert_ne!(reason, footscan_daemon::archive::INTERRUPTED);
    assert!(reason.contains("archiving failed"), "{reason}");
    assert_eq!(r.frames, 141);
}

/// The issue's case: the whole archive refuses the end (record.json and the index alike)
/// and the daemon then stops; the scan's first reason and frame count survive the restart,
/// read from the reserve the scan held open from its start, instead of "interrupted".
#[test]
fn the_first_reason_survives_an_archive_that_refused_everything() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    let a = Archive::open(&root).unwrap();
    let s = a
        .begin(NewScan {
            subject: "P-1".into(),
            side: "left".into(),
            notes: String::new(),
        })
        .unwrap();
    let dir = s.dir.clone();
    let id = s.record.id.clone();
    // record.json taken by a non-empty directory (as a directory that turned read-only
    // refuses new names; this holds as root too) and the index held by another writer.
    std::fs::create_dir_all(dir.join("record.json").join("blocker")).unwrap();
    let holder = rusqlite::Connection::open(root.join("index.sqlite")).unwrap();
    holder.execute_batch("BEGIN IMMEDIATE").unwrap();
    let end = a.finish(
        s,
        ScanEnd {
            status: Status::Complete,
            reason: None,
            frames: 141,
            points: 75_000,
        },
    );
    assert!(end.is_err(), "archiving should have failed");
    drop(a);
    holder.execute_batch("ROLLBACK").unwrap();
    drop(holder);
    std::fs::remove_dir_all(dir.join("record.json")).unwrap();
    let a = Archive::open(&root).unwrap();
    let r = a
        .get(&footscan_daemon::archive::ScanId::parse(&id).unwrap())
        .unwrap();
    println!("after the restart: {} {:?}", r.status.as_str(), r.reason);
    assert_eq!(r.status, Status::Failed);
    let reason = r.reason.unwrap_or_default();
    assert_ne!(reason, footscan_daemon::archive::INTERRUPTED);
    assert!(reason.contains("archiving failed"), "{reason}");
    assert_eq!(r.frames, 141);
    // Sealed at the restart: the directory has its id, and record.json the end.
    let rec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(root.join(&id).join("record.json")).unwrap())
            .unwrap();
    assert_eq!(rec["frames"], 141);
}

/// Unmounts the test's tmpfs however the test ends.
struct Mounted(std::path::PathBuf);

impl Drop for Mounted {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount")
            .arg("-l")
            .arg(&self.0)
            .status();
    }
}

fn mount(args: &[&str], at: &std::path::Path) -> Result<(), String> {
    let out = std::process::Command::new("mount")
        .args(args)
        .arg(at)
        .output()
        .map_err(|e| format!("mount: {e}"))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(String::from_utf8_lossy(&out.stderr).trim().to_string())
    }
}

/// The issue's read-only remount, on a real filesystem (a tmpfs; needs root, skipped
/// otherwise): the scan holds its `.reserve` open for writing from its start, so the kernel
/// refuses to remount the archive read-only under it ("mount point is busy") and the scan
/// ends complete with its frames, instead of losing its end and becoming "interrupted". Only
/// a remount the kernel forces after an I/O error bypasses this (docs/method.md 14.2.2).
#[test]
fn a_read_only_remount_is_refused_while_a_scan_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let mnt = tmp.path().join("mnt");
    std::fs::create_dir(&mnt).unwrap();
    if let Err(e) = mount(&["-t", "tmpfs", "-o", "size=16m", "tmpfs"], &mnt) {
        eprintln!("skipped: a tmpfs cannot be mounted here ({e}); needs root");
        return;
    }
    let _guard = Mounted(mnt.clone());
    let root = mnt.join("archive");
    let a = Archive::open(&root).unwrap();
    let s = a
        .begin(NewScan {
            subject: "P-1".into(),
            side: "left".into(),
            notes: String::new(),
        })
        .unwrap();
    std::fs::write(s.dir.join("frames.bin"), vec![7u8; 4096]).unwrap();
    let refused = mount(&["-o", "remount,ro"], &mnt);
    println!("remount read-only during the scan: {refused:?}");
    assert!(refused.is_err(), "the archive was remounted under a scan");
    let id = s.record.id.clone();
    let r = a
        .finish(
            s,
            ScanEnd {
                status: Status::Complete,
                reason: None,
                frames: 141,
                points: 75_000,
            },
        )
        .expect("the scan is archived");
    assert_eq!((r.status, r.frames), (Status::Complete, 141));
    drop(a);
    // With the daemon gone the remount goes through, and the scan reads back whole.
    mount(&["-o", "remount,ro"], &mnt).expect("remount once nothing is open");
    let rec: serde_json::Value =
        serde_json::from_slice(&std::fs::read(root.join(&id).join("record.json")).unwrap())
            .unwrap();
    assert_eq!(
        (rec["status"].as_str(), rec["frames"].as_u64()),
        (Some("complete"), Some(141))
    );
}
