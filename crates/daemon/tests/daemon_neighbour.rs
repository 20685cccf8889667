//! footscand under a careless or hostile neighbour: a second daemon on the same archive, a
//! damaged index, symlinked and deleted scan directories, an archive that fails mid-scan,
//! slow and idle connections, foreign Host and Origin headers.

mod daemon_support;

use daemon_support::*;
use std::io::Read;
use std::process::ExitStatus;
use std::time::{Duration, Instant};

/// Wait for `child` to exit (killing it after `limit`): its status, stdout and stderr.
fn exit_of(mut child: std::process::Child, limit: Duration) -> (Option<ExitStatus>, String) {
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break Some(s);
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let mut out = String::new();
    if let Some(mut e) = child.stderr.take() {
        let _ = e.read_to_string(&mut out);
    }
    if let Some(mut o) = child.stdout.take() {
        let _ = o.read_to_string(&mut out);
    }
    (status, out)
}

/// Item 1: a second footscand on the archive of a running one refuses to start, naming the
/// first, and touches nothing: the first one's scan completes with all its files.
#[test]
fn second_daemon_on_one_archive_refuses_to_start() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    let id = d.start_scan("first");
    let t0 = Instant::now();
    while d.get_json("/api/status")["scan"]["frames"]
        .as_u64()
        .unwrap()
        < 5
    {
        assert!(t0.elapsed() < Duration::from_secs(60), "no frames");
        std::thread::sleep(Duration::from_millis(20));
    }
    let dir2 = tmp.path().join("second");
    std::fs::create_dir(&dir2).unwrap();
    let (cmd, _) = command(
        &dir2,
        &Opts {
            archive: Some(d.archive.clone()),
            ..Opts::default()
        },
    );
    let mut cmd = cmd;
    let (status, out) = exit_of(cmd.spawn().unwrap(), Duration::from_secs(20));
    let status = status.unwrap_or_else(|| panic!("the second daemon kept running: {out}"));
    assert!(!status.success(), "second daemon started: {out}");
    let pid = format!("pid {}", d.child.id());
    assert!(
        out.contains(&pid) && out.contains("footscand") && out.contains("in use"),
        "the refusal names the first daemon ({pid}): {out}"
    );
    assert!(
        d.archive.join(format!(".tmp-{id}")).is_dir(),
        "the running scan's directory was left alone"
    );
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "complete", "{end}");
    let rec = d.record(&id);
    let names: Vec<&str> = rec["artifacts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["name"].as_str().unwrap())
        .collect();
    for want in [
        "points.ply",
        "model.stl",
        "grid.bin",
        "heightmap.png",
        "scan.json",
    ] {
        assert!(names.contains(&want), "{want} missing: {names:?}");
    }
    println!(
        "second daemon refused: {}",
        out.lines().last().unwrap_or("")
    );
}

use footscan_daemon::archive::{Archive, NewScan, ScanEnd, Status};

/// An archive with `n` complete scans made through the library (each with a scan.json and
/// a points.ply); their ids.
fn archive_with_scans(root: &std::path::Path, n: usize) -> Vec<String> {
    let a = Archive::open(root).unwrap();
    let ids = (0..n)
        .map(|i| {
            let s = a
                .begin(NewScan {
                    subject: format!("s{i}"),
                    side: "left".into(),
                    notes: String::new(),
                })
                .unwrap();
            std::fs::write(
                s.dir.join("scan.json"),
                br#"{"status": "complete", "frames": 7, "points": 70}"#,
            )
            .unwrap();
            std::fs::write(s.dir.join("points.ply"), b"ply\n").unwrap();
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
        .collect();
    ids
}

fn ids_listed(d: &Footscand) -> Vec<String> {
    d.get_json("/api/scans")
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["id"].as_str().unwrap().to_string())
        .collect()
}

/// Item 6: a damaged index is a cache: moved aside, rebuilt from the directories, said in
/// the status; the daemon starts.
#[test]
fn corrupt_index_is_moved_aside_and_rebuilt() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    let ids = archive_with_scans(&root, 2);
    let garbage: Vec<u8> = (0..64 * 1024u32).map(|i| (i * 7919 % 251) as u8).collect();
    std::fs::write(root.join("index.sqlite"), &garbage).unwrap();
    let d = Footscand::start(
        tmp.path(),
        Opts {
            archive: Some(root.clone()),
            ..Opts::default()
        },
    );
    let mut listed = ids_listed(&d);
    listed.sort();
    assert_eq!(listed, ids, "rebuilt from the scan directories");
    let notices = d.get_json("/api/status")["archive"]["notices"].clone();
    let text = notices.to_string();
    assert!(
        text.contains("damaged") && text.contains("index.sqlite.corrupt-"),
        "status says so: {notices}"
    );
    let aside: Vec<_> = std::fs::read_dir(&root)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| {
            e.file_name()
                .to_string_lossy()
                .starts_with("index.sqlite.corrupt-")
        })
        .collect();
    assert_eq!(aside.len(), 1, "the damaged index is kept aside");
    assert_eq!(std::fs::read(aside[0].path()).unwrap(), garbage);
    assert!(d.stderr().contains("damaged"), "logged");
    // And a new scan goes into the new index.
    let id = d.start_scan("after");
    assert_eq!(
        d.wait_scan_end(Duration::from_secs(120))["state"],
        "complete"
    );
    assert!(ids_listed(&d).contains(&id));
}

/// Item 7: a scan directory that is a symlink (to a directory outside the archive holding
/// a plausible record) is neither listed nor served, at start or when swapped in later; a
/// scan directory deleted behind the daemon's back is no longer listed.
#[test]
fn symlinked_and_deleted_scan_directories() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    let ids = archive_with_scans(&root, 3);
    // A directory outside the archive dressed up as a scan, linked in under a fresh id.
    let outside = tmp.path().join("outside");
    std::fs::create_dir(&outside).unwrap();
    std::fs::write(outside.join("secret.txt"), b"root:x:0:0").unwrap();
    let fake = "20250101T000000Z-0bad";
    let mut rec: Value =
        serde_json::from_slice(&std::fs::read(root.join(&ids[0]).join("record.json")).unwrap())
            .unwrap();
    rec["id"] = fake.into();
    std::fs::write(outside.join("record.json"), rec.to_string()).unwrap();
    std::os::unix::fs::symlink(&outside, root.join(fake)).unwrap();
    let d = Footscand::start(
        tmp.path(),
        Opts {
            archive: Some(root.clone()),
            ..Opts::default()
        },
    );
    assert!(
        !ids_listed(&d).contains(&fake.to_string()),
        "symlink listed"
    );
    assert_eq!(
        d.get(&format!("/api/scans/{fake}/files/secret.txt"))
            .status(),
        404
    );
    // Swapped in while the daemon runs: a listed scan's directory replaced by a symlink.
    let swapped = &ids[1];
    std::fs::remove_dir_all(root.join(swapped)).unwrap();
    std::fs::write(outside.join("points.ply"), b"not yours").unwrap();
    std::os::unix::fs::symlink(&outside, root.join(swapped)).unwrap();
    let r = d.get(&format!("/api/scans/{swapped}/files/secret.txt"));
    assert_eq!(r.status(), 404, "served through a symlink");
    let r = d.get(&format!("/api/scans/{swapped}/files/points.ply"));
    assert_eq!(r.status(), 404, "served through a symlink");
    // Deleted behind the daemon's back.
    let deleted = &ids[2];
    std::fs::remove_dir_all(root.join(deleted)).unwrap();
    let listed = ids_listed(&d);
    assert_eq!(
        listed,
        vec![ids[0].clone()],
        "only the intact scan is listed"
    );
    assert_eq!(d.get(&format!("/api/scans/{deleted}")).status(), 404);
    assert_eq!(d.get(&format!("/api/scans/{swapped}")).status(), 404);
    assert_eq!(d.get(&format!("/api/scans/{}", ids[0])).status(), 200);
}

/// Item 4: a scan whose archiving fails (its directory cannot take its final name and the
/// index cannot be written) is shown failed with the reason, not running, and keeps that
/// reason across a restart instead of becoming "interrupted".
#[test]
fn failed_archiving_keeps_its_reason_across_restarts() {
    let tmp = tempfile::tempdir().unwrap();
    let mut d = Footscand::start(tmp.path(), Opts::default());
    let root = d.archive.clone();
    let id = d.start_scan("rofs");
    let t0 = Instant::now();
    while d.get_json("/api/status")["scan"]["frames"]
        .as_u64()
        .unwrap()
        < 5
    {
        assert!(t0.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(20));
    }
    // The final name taken by a non-empty directory, and the index held by another writer
    // (as a read-only or failing archive would refuse both; this works as root too).
    std::fs::create_dir_all(root.join(&id).join("blocker")).unwrap();
    let holder = rusqlite::Connection::open(root.join("index.sqlite")).unwrap();
    holder.execute_batch("BEGIN IMMEDIATE").unwrap();
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "failed", "{end}");
    let listed = d.get_json("/api/scans");
    let row = listed
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["id"] == id.as_str())
        .unwrap_or_else(|| panic!("{id} not listed: {listed}"))
        .clone();
    assert_eq!(row["status"], "failed", "still listed as running: {row}");
    let reason = row["reason"].as_str().unwrap().to_string();
    assert!(reason.contains("archiving failed"), "{reason}");
    assert!(
        d.stderr().contains("could not record scan"),
        "the index refused"
    );
    assert_eq!(d.terminate(Duration::from_secs(30)).code(), Some(0));
    drop(d);
    std::fs::remove_dir_all(root.join(&id)).unwrap();
    holder.execute_batch("ROLLBACK").unwrap();
    drop(holder);
    let d = Footscand::start(
        tmp.path(),
        Opts {
            archive: Some(root.clone()),
            ..Opts::default()
        },
    );
    let rec = d.record(&id);
    assert_eq!(rec["status"], "failed");
    assert_eq!(rec["reason"], reason.as_str(), "the real reason survives");
    assert_ne!(rec["reason"], footscan_daemon::archive::INTERRUPTED);
    assert!(rec["frames"].as_u64().unwrap() > 100, "{rec}");
}

/// Item 4: a scan killed before its summary keeps the frame count the daemon knew.
#[test]
fn killed_scan_keeps_its_frame_count() {
    let tmp = tempfile::tempdir().unwrap();
    let mut d = Footscand::start(tmp.path(), Opts::default());
    let root = d.archive.clone();
    let id = d.start_scan("killed");
    let t0 = Instant::now();
    let mut frames = 0;
    while frames < 20 {
        let s = d.get_json("/api/status");
        assert_eq!(s["scan"]["state"], "running", "ended too soon: {s}");
        frames = s["scan"]["frames"].as_u64().unwrap();
        assert!(t0.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(20));
    }
    // The count is noted once a second: give it one note after `frames`.
    std::thread::sleep(Duration::from_millis(1300));
    let s = d.get_json("/api/status");
    assert_eq!(s["scan"]["state"], "running", "ended too soon: {s}");
    let last = s["scan"]["frames"].as_u64().unwrap();
    d.child.kill().unwrap();
    d.child.wait().unwrap();
    drop(d);
    let d = Footscand::start(
        tmp.path(),
        Opts {
            archive: Some(root),
            ..Opts::default()
        },
    );
    let rec = d.record(&id);
    assert_eq!(rec["reason"], footscan_daemon::archive::INTERRUPTED);
    let kept = rec["frames"].as_u64().unwrap();
    assert!(
        kept >= frames && kept <= last + 20,
        "frames kept {kept}; {frames} seen 1.3 s before the kill, {last} just before"
    );
    println!("killed at >= {last} frames; the record keeps {kept}");
}

/// A raw request on a fresh connection: (status, lower-cased head, body); status 0 when the
/// daemon closed or did not answer within `limit`.
fn raw(base: &str, request: &str, limit: Duration) -> (u16, String, String) {
    use std::io::Write;
    let addr = base.strip_prefix("http://").unwrap();
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(limit)).unwrap();
    s.write_all(request.as_bytes()).unwrap();
    let mut buf = Vec::new();
    let _ = s.read_to_end(&mut buf);
    let text = String::from_utf8_lossy(&buf).into_owned();
    let (head, body) = text.split_once("\r\n\r\n").unwrap_or((&text, ""));
    let status = head
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    (status, head.to_ascii_lowercase(), body.to_string())
}

/// Start footscand with `extra` lines in [daemon] and, if given, a file-descriptor limit.
fn start_with(dir: &std::path::Path, extra: &str, nofile: Option<u64>) -> Footscand {
    use std::os::unix::process::CommandExt;
    let (mut cmd, archive) = command(dir, &Opts::default());
    let cfg = dir.join("footscand.toml");
    let mut text = std::fs::read_to_string(&cfg).unwrap();
    text.push_str(extra);
    std::fs::write(&cfg, text).unwrap();
    if let Some(n) = nofile {
        // SAFETY: setrlimit only, between fork and exec.
        unsafe {
            cmd.pre_exec(move || {
                let rl = libc::rlimit {
                    rlim_cur: n,
                    rlim_max: n,
                };
                if libc::setrlimit(libc::RLIMIT_NOFILE, &rl) != 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
    }
    Footscand::spawn(cmd, archive, None)
}

/// Item 2: with a descriptor limit of 128, a thousand idle and half-sent connections neither
/// stop /api/health nor fail the running scan; idle connections are closed after the header
/// timeout; a body that never arrives gets 408; SIGTERM does not wait for idle connections.
#[test]
fn idle_and_half_sent_connections_cannot_starve_the_daemon() {
    use std::io::Write;
    let tmp = tempfile::tempdir().unwrap();
    let mut d = start_with(
        tmp.path(),
        "header_timeout_s = 2.0\nbody_timeout_s = 2.0\n",
        Some(128),
    );
    let addr = d.base.strip_prefix("http://").unwrap().to_string();
    let id = d.start_scan("flood");
    let mut held = Vec::new();
    for i in 0..1000 {
        let Ok(mut s) = std::net::TcpStream::connect(&addr) else {
            break;
        };
        if i % 2 == 1 {
            let _ = s.write_all(b"GET /api/status HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: ");
        }
        held.push(s);
    }
    println!("{} connections held", held.len());
    assert!(held.len() >= 500, "only {} connections opened", held.len());
    // Health answers while they are held.
    let quick = reqwest::blocking::Client::builder()
        .timeout(Duration::from_secs(10))
        .build()
        .unwrap();
    let mut worst = 0f64;
    for _ in 0..10 {
        let t = Instant::now();
        let r = quick
            .get(d.url("/api/health"))
            .send()
            .unwrap_or_else(|e| panic!("health with {} connections held: {e}", held.len()));
        assert_eq!(r.status(), 200);
        worst = worst.max(t.elapsed().as_secs_f64());
        std::thread::sleep(Duration::from_millis(100));
    }
    let end = d.wait_scan_end(Duration::from_secs(180));
    assert_eq!(end["state"], "complete", "the scan under the flood: {end}");
    let rec = d.record(&id);
    let names = rec["artifacts"].to_string();
    for want in ["points.ply", "model.stl", "grid.bin", "heightmap.png"] {
        assert!(names.contains(want), "{want} missing: {names}");
    }
    drop(held);
    // An idle connection is closed by the daemon after the header timeout (2 s).
    let mut idle = std::net::TcpStream::connect(&addr).unwrap();
    idle.set_read_timeout(Some(Duration::from_secs(15)))
        .unwrap();
    let t = Instant::now();
    let mut b = [0u8; 64];
    let n = idle.read(&mut b).unwrap_or(usize::MAX);
    let closed_after = t.elapsed().as_secs_f64();
    assert!(
        n == 0 && closed_after < 8.0,
        "idle connection: read {n} after {closed_after:.1} s"
    );
    // A body that never arrives.
    let (status, _, body) = raw(
        &d.base,
        "POST /api/scans HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\nContent-Length: 100\r\n\r\n{\"subj",
        Duration::from_secs(15),
    );
    assert_eq!(status, 408, "{body}");
    assert!(body.contains("\"error\""), "{body}");
    // SIGTERM with idle connections open.
    let idle: Vec<_> = (0..20)
        .map(|_| std::net::TcpStream::connect(&addr).unwrap())
        .collect();
    std::thread::sleep(Duration::from_millis(200));
    let t = Instant::now();
    let status = d.terminate(Duration::from_secs(30));
    let stop_s = t.elapsed().as_secs_f64();
    assert_eq!(status.code(), Some(0));
    assert!(
        stop_s < 5.0,
        "SIGTERM took {stop_s:.1} s with idle connections open"
    );
    drop(idle);
    println!(
        "flood: health worst {worst:.2} s; idle connection closed after {closed_after:.1} s; SIGTERM {stop_s:.2} s"
    );
}

/// Item 3: a foreign Host (DNS rebinding) is refused before anything runs; a cross-site
/// form POST cannot cancel a scan (wrong Origin, and not JSON); the dashboard cannot be
/// framed.
#[test]
fn foreign_host_and_cross_site_posts_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    let port = d.base.rsplit(':').next().unwrap().to_string();
    let start = format!(
        "POST /api/scans HTTP/1.1\r\nHost: attacker.example:{port}\r\nContent-Type: application/json\r\nContent-Length: 32\r\nConnection: close\r\n\r\n{{\"subject\":\"x\",\"side\":\"left\"}}  "
    );
    let (status, _, body) = raw(&d.base, &start, Duration::from_secs(10));
    assert_eq!(status, 403, "{body}");
    assert!(body.contains("attacker.example"), "{body}");
    assert!(
        d.get_json("/api/status")["scan"].is_null(),
        "a scan started"
    );
    let (status, _, _) = raw(
        &d.base,
        &format!("GET /api/status HTTP/1.1\r\nHost: attacker.example:{port}\r\nConnection: close\r\n\r\n"),
        Duration::from_secs(10),
    );
    assert_eq!(status, 403);
    let id = d.start_scan("victim");
    let host = d.base.strip_prefix("http://").unwrap();
    // The form a hostile page would submit.
    let form = |origin: &str| {
        let o = if origin.is_empty() {
            String::new()
        } else {
            format!("Origin: {origin}\r\n")
        };
        format!(
            "POST /api/scans/{id}/cancel HTTP/1.1\r\nHost: {host}\r\n{o}Content-Type: application/x-www-form-urlencoded\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
        )
    };
    let (status, _, body) = raw(
        &d.base,
        &form("http://attacker.example"),
        Duration::from_secs(10),
    );
    assert_eq!(status, 403, "{body}");
    let (status, _, body) = raw(&d.base, &form(""), Duration::from_secs(10));
    assert_eq!(status, 415, "{body}");
    let json_cross = format!(
        "POST /api/scans/{id}/cancel HTTP/1.1\r\nHost: {host}\r\nOrigin: null\r\nContent-Type: application/json\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
    );
    assert_eq!(raw(&d.base, &json_cross, Duration::from_secs(10)).0, 403);
    assert_eq!(
        d.get_json("/api/status")["scan"]["state"],
        "running",
        "cancelled"
    );
    // The daemon's own page may cancel.
    let own = format!(
        "POST /api/scans/{id}/cancel HTTP/1.1\r\nHost: {host}\r\nOrigin: http://{host}\r\nContent-Type: application/json\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
    );
    let (status, _, body) = raw(&d.base, &own, Duration::from_secs(10));
    assert_eq!(status, 202, "{body}");
    assert_eq!(
        d.wait_scan_end(Duration::from_secs(60))["state"],
        "cancelled"
    );
    let (status, head, _) = raw(
        &d.base,
        &format!("GET / HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"),
        Duration::from_secs(10),
    );
    assert_eq!(status, 200);
    assert!(head.contains("x-frame-options: deny"), "{head}");
    assert!(head.contains("frame-ancestors 'none'"), "{head}");
    assert!(head.contains("x-content-type-options: nosniff"), "{head}");
    // localhost by name is this daemon.
    let (status, _, _) = raw(
        &d.base,
        &format!("GET /api/health HTTP/1.1\r\nHost: localhost:{port}\r\nConnection: close\r\n\r\n"),
        Duration::from_secs(10),
    );
    assert_eq!(status, 200);
}

/// Item 9: a lowercase `bearer` scheme is accepted; Range requests resume a download; an
/// event stream open when SIGTERM cancels a scan sees the scan's final state.
#[test]
fn range_lowercase_bearer_and_final_state_on_sigterm() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    let ids = archive_with_scans(&root, 1);
    let big: Vec<u8> = (0..300_000u32).map(|i| (i % 253) as u8).collect();
    std::fs::write(root.join(&ids[0]).join("grid.bin"), &big).unwrap();
    let token = "0123456789abcdef-token";
    let mut d = Footscand::start(
        tmp.path(),
        Opts {
            archive: Some(root),
            token: Some(token),
            ..Opts::default()
        },
    );
    let r = d
        .client
        .get(d.url("/api/status"))
        .header("authorization", format!("bearer {token}"))
        .send()
        .unwrap();
    assert_eq!(r.status(), 200, "lowercase bearer");
    let url = d.url(&format!("/api/scans/{}/files/grid.bin", ids[0]));
    let part = |range: &str| {
        d.client
            .get(&url)
            .bearer_auth(token)
            .header("range", range)
            .send()
            .unwrap()
    };
    let r = part("bytes=100000-");
    assert_eq!(r.status(), 206);
    assert_eq!(
        r.headers()["content-range"],
        format!("bytes 100000-299999/{}", big.len()).as_str()
    );
    assert_eq!(r.bytes().unwrap().as_ref(), &big[100_000..]);
    let r = part("bytes=10-19");
    assert_eq!(r.status(), 206);
    assert_eq!(r.bytes().unwrap().as_ref(), &big[10..20]);
    let r = part("bytes=-5");
    assert_eq!(r.bytes().unwrap().as_ref(), &big[big.len() - 5..]);
    let r = part("bytes=400000-");
    assert_eq!(r.status(), 416);
    let whole = d.get(&format!("/api/scans/{}/files/grid.bin", ids[0]));
    assert_eq!(whole.headers()["accept-ranges"], "bytes");
    assert_eq!(whole.bytes().unwrap().len(), big.len());

    // An impossible date is not a scan id (400, not 404).
    let r = d.get("/api/scans/20260231T221503Z-3f2a");
    assert_eq!(r.status(), 400, "31 February accepted as an id");

    // SIGTERM during a scan, with an event stream open.
    let id = d.start_scan("term");
    let t0 = Instant::now();
    while d.get_json("/api/status")["scan"]["frames"]
        .as_u64()
        .unwrap()
        < 5
    {
        assert!(t0.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(20));
    }
    let follower = {
        let (base, id) = (d.base.clone(), id.clone());
        std::thread::spawn(move || {
            use std::io::BufRead;
            let r = reqwest::blocking::Client::new()
                .get(format!("{base}/api/events"))
                .bearer_auth("0123456789abcdef-token")
                .send()
                .unwrap();
            let mut last_state = None;
            let mut name = String::new();
            for line in std::io::BufReader::new(r).lines().map_while(Result::ok) {
                if let Some(n) = line.strip_prefix("event: ") {
                    name = n.to_string();
                } else if let Some(data) = line.strip_prefix("data: ") {
                    let v: Value = serde_json::from_str(data).unwrap();
                    if name == "state" && v["id"] == id.as_str() {
                        last_state = Some(v);
                    }
                }
            }
            last_state
        })
    };
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(d.terminate(Duration::from_secs(60)).code(), Some(0));
    let last = follower.join().unwrap().expect("a state event");
    assert_eq!(last["state"], "cancelled", "{last}");
    assert_eq!(last["reason"], "daemon shutting down");
}

/// Item 5: config errors stop the daemon at start (an unknown stage, a scan range beyond
/// the slider's travel); missing hardware devices are reported absent and scans refused
/// with 503 naming the device.
#[test]
fn what_can_be_checked_at_start_is_checked() {
    let tmp = tempfile::tempdir().unwrap();
    // Start on the short scanner config edited by `edit` (and the daemon config by `daemon`):
    // footscand must exit non-zero, saying each of `want`.
    let refused = |edit: &dyn Fn(String) -> String, daemon: &str, want: &[&str]| {
        let dir = tempfile::tempdir_in(tmp.path()).unwrap();
        let (mut cmd, archive) = command(dir.path(), &Opts::default());
        let sc = dir.path().join("scanner.toml");
        let text = edit(std::fs::read_to_string(&sc).unwrap());
        assert_ne!(text, std::fs::read_to_string(&sc).unwrap(), "edit applied");
        std::fs::write(&sc, text).unwrap();
        let dc = dir.path().join("footscand.toml");
        let text = std::fs::read_to_string(&dc).unwrap() + daemon;
        std::fs::write(&dc, text).unwrap();
        let (status, out) = exit_of(cmd.spawn().unwrap(), Duration::from_secs(30));
        let status = status.unwrap_or_else(|| panic!("started: {out}"));
        assert!(!status.success(), "started: {out}");
        for w in want {
            assert!(out.contains(w), "{w:?} not in: {out}");
        }
        assert!(!archive.exists(), "the archive was touched: {out}");
    };
    refused(
        &|t| t.replacen("stage = \"triangulate\"", "stage = \"triangulat\"", 1),
        "",
        &[
            "scanner.toml",
            "\"triangulat\"",
            "not a stage",
            "triangulate",
        ],
    );
    // Stage parameters: an unknown key (with the valid ones) and a value out of range, each
    // with its line.
    refused(
        &|t| t.replace("file = \"points.ply\"", "fille = \"points.ply\""),
        "",
        &["scanner.toml", "sink.ply", "`fille`", "`file`", "line "],
    );
    refused(
        &|t| t.replace("cell_mm = 0.1 ", "cell_mm = 5.0 "),
        "",
        &["measure.foot", "cell_mm = 5", "[0.05, 1]", "line "],
    );
    refused(
        &|t| t.replace("end_mm = 200.0", "end_mm = 400.0"),
        "",
        &["400", "travel", "sim.slider.travel_mm"],
    );
    // Impossible optics: a parameter out of its range, and a laser line the camera cannot see.
    refused(
        &|t| t.replacen("f_px = 2000.0", "f_px = 0.0", 1),
        "",
        &["scanner.toml", "[sim.optics]", "f_px", "expected"],
    );
    refused(
        &|t| t.replacen("l_mm = 70.0", "l_mm = 400.0", 1),
        "",
        &["[sim.optics]", "laser line", "outside", "l_mm = 400"],
    );
    // Missing calibration files, from the scanner config and from the daemon config.
    refused(
        &|t| {
            t.replacen(
                "[scanner]\n",
                "[scanner]\ncalibration = \"absent.toml\"\n",
                1,
            )
        },
        "",
        &["absent.toml", "scanner.calibration", "scanner.toml"],
    );
    refused(
        &|t| t + "\n",
        "calibration = \"gone.toml\"\n",
        &["gone.toml", "calibration in [daemon]", "footscand.toml"],
    );
    // The hardware backend: without its calibration file it does not start; with it, devices
    // that are not there are reported absent and scans are refused with 503 naming them.
    let dir = tmp.path().join("hw");
    std::fs::create_dir(&dir).unwrap();
    let (cmd, archive) = command(&dir, &Opts::default());
    let sim = std::fs::read_to_string(dir.join("scanner.toml")).unwrap();
    let hw = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/footscan.toml");
    let text = std::fs::read_to_string(hw)
        .unwrap()
        .replace("/dev/video0", dir.join("video-absent").to_str().unwrap())
        .replace("/dev/ttyUSB0", "/dev/ttyFOOTSCAN-test-absent");
    std::fs::write(dir.join("scanner.toml"), text).unwrap();
    let mut cmd = cmd;
    let (status, out) = exit_of(cmd.spawn().unwrap(), Duration::from_secs(30));
    assert!(status.is_some_and(|s| !s.success()), "started: {out}");
    assert!(
        out.contains("calibration.toml") && out.contains("scanner.calibration"),
        "{out}"
    );
    let sim = footscan::scan::LoadedConfig::parse(std::path::Path::new("sim.toml"), sim).unwrap();
    footscan::scan::sim::true_calibration(&sim.config)
        .save(&dir.join("calibration.toml"))
        .unwrap();
    let d = Footscand::spawn(cmd, archive, None);
    let st = d.get_json("/api/status");
    assert_eq!(st["devices"]["camera"]["connected"], false, "{st}");
    assert_eq!(st["devices"]["slider"]["connected"], false, "{st}");
    let (s, v) = d.post("/api/scans", r#"{"subject": "a", "side": "left"}"#);
    assert_eq!(s, 503, "{v}");
    let msg = v["error"].as_str().unwrap();
    assert!(
        msg.contains("video-absent") && msg.contains("/dev/ttyFOOTSCAN-test-absent"),
        "{msg}"
    );
    // A device plugged in later is seen without a restart (here a file stands for the node).
    std::fs::write(dir.join("video-absent"), "").unwrap();
    let st = d.get_json("/api/status");
    assert_eq!(st["devices"]["camera"]["connected"], true, "{st}");
    assert_eq!(st["devices"]["slider"]["connected"], false, "{st}");
    let (s, v) = d.post("/api/scans", r#"{"subject": "a", "side": "left"}"#);
    assert_eq!(s, 503, "{v}");
    let msg = v["error"].as_str().unwrap();
    assert!(
        !msg.contains("video-absent") && msg.contains("ttyFOOTSCAN"),
        "{msg}"
    );
    assert!(
        d.get_json("/api/scans").as_array().unwrap().is_empty(),
        "nothing archived"
    );
}

/// Item 9: an over-long request target (414) and over-large headers (431) are answered with
/// the API's JSON error, not an empty body.
#[test]
fn long_uri_and_large_headers_get_json_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    let host = d.base.strip_prefix("http://").unwrap().to_string();
    let long = format!(
        "GET /api/status?x={} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n",
        "a".repeat(20_000)
    );
    let (status, head, body) = raw(&d.base, &long, Duration::from_secs(10));
    assert_eq!(status, 414, "{head}");
    assert!(body.contains("\"error\""), "{body:?}");
    let big = format!(
        "GET /api/status HTTP/1.1\r\nHost: {host}\r\nX-Big: {}\r\nConnection: close\r\n\r\n",
        "b".repeat(40_000)
    );
    let (status, head, body) = raw(&d.base, &big, Duration::from_secs(10));
    assert_eq!(status, 431, "{head}");
    assert!(body.contains("\"error\""), "{body:?}");
}
