//! footscand pushing scans to a real PostgreSQL (started by this test: initdb + pg_ctl on a
//! free loopback port, as the postgres user under root), through the faults of issue 20:
//! three scanners scanning and pushing at once with the server bounced twice, a wrong
//! password, the network cut (the daemon pointed at a closed port), the server stopped
//! mid-upload, the daemon SIGKILLed mid-push, a duplicate push of everything, a database at
//! an older schema version and one at a newer incompatible one. After each: every scan of
//! the archive in the database exactly once, its files byte-identical (sha256), and the
//! local archive's scan directories untouched.
//!
//! The fault runs use archive records made directly (the push is what is under test); the
//! three-scanner run uses real short simulated scans. The full target (3 x 20 scans)
//! and the 100-scan drain are `#[ignore]`d studies: `cargo test -p footscand --test
//! daemon_fleet -- --ignored --nocapture`.

mod daemon_support;

use daemon_support::*;
use footscan_daemon::archive::{Archive, NewScan, ScanEnd, Status};
use footscan_fleet::testing::{PgServer, PASSWORD};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Start footscand in `dir` with a [fleet] section for `scanner` pointing at `url`.
fn start_fleet_daemon(dir: &Path, url: &str, scanner: &str, password: &str) -> Footscand {
    let (mut cmd, archive) = command(dir, &Opts::default());
    let cfg = dir.join("footscand.toml");
    let mut text = std::fs::read_to_string(&cfg).unwrap();
    // Drop a [fleet] section written by an earlier start in the same directory.
    if let Some(i) = text.find("\n[fleet]") {
        text.truncate(i + 1);
    }
    text.push_str(&format!(
        "\n[fleet]\nurl = {url:?}\nscanner = {scanner:?}\nclinic = \"clinic-{}\"\nretry_max_s = 1.0\nconnect_timeout_s = 2.0\n",
        &scanner[scanner.len() - 1..]
    ));
    std::fs::write(&cfg, text).unwrap();
    cmd.env(footscan_fleet::settings::PASSWORD_ENV, password);
    Footscand::spawn(cmd, archive, None)
}

/// Scans made directly in the archive at `root` (closed, as a daemon would), each with
/// files of distinct content (~`kib` KiB) and one file every scan shares.
fn make_scans(root: &Path, n: usize, kib: usize, tag: &str) -> Vec<String> {
    let a = Archive::open(root).unwrap();
    let mut ids = Vec::new();
    for i in 0..n {
        let s = a
            .begin(NewScan {
                subject: format!("{tag}{i}"),
                side: if i % 2 == 0 { "left" } else { "right" }.into(),
                notes: String::new(),
            })
            .unwrap();
        let seed = (i as u64 + 1).wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ tag.bytes().map(u64::from).sum::<u64>();
        let mut x = seed;
        let grid: Vec<u8> = (0..kib * 1024)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x as u8
            })
            .collect();
        std::fs::write(s.dir.join("grid.bin"), grid).unwrap();
        std::fs::write(
            s.dir.join("measurements.json"),
            format!("{{\"length_mm\": {}}}", 240 + i),
        )
        .unwrap();
        std::fs::write(s.dir.join("calibration.toml"), "method = \"sim\"\n").unwrap();
        let status = [Status::Complete, Status::Failed, Status::Cancelled][i % 3];
        let r = a
            .finish(
                s,
                ScanEnd {
                    status,
                    reason: (status != Status::Complete).then(|| "made by the test".into()),
                    frames: 100 + i as u64,
                    points: 1000,
                },
            )
            .unwrap();
        ids.push(r.id);
    }
    ids
}

/// Every file of the archive's scan directories with its sha256 (the index and lock
/// excluded: they are the daemon's to change).
fn manifest(root: &Path) -> BTreeMap<String, String> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(root).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !e.path().is_dir() || name.starts_with('.') || name == "calibrations" {
            continue;
        }
        // The scan's files as served: a scan the daemon compacted when it ended lists and
        // reads its original files (docs/method.md 14h.2).
        let dir = footscan::scandata::ScanDir::new(e.path());
        for (f, _, _) in footscan::compact::listing(&e.path()).unwrap() {
            let b = dir.read_file(&f).unwrap();
            m.insert(format!("{name}/{f}"), footscan_fleet::sha256_hex(&b));
        }
    }
    m
}

/// The archive's scans against the database: each exactly once, every file byte-identical.
/// Returns the number of scans checked.
fn check_exactly_once(pg: &PgServer, scanner: &str, root: &Path) -> usize {
    let local = manifest(root);
    let mut c = pg.fleet_client();
    let mut ids: Vec<String> = local
        .keys()
        .map(|k| k.split('/').next().unwrap().to_string())
        .collect();
    ids.dedup();
    let rows = c
        .query(
            "SELECT scan_id, count(*) FROM fleet_scans WHERE scanner = $1 GROUP BY scan_id",
            &[&scanner],
        )
        .unwrap();
    let counts: BTreeMap<String, i64> = rows.iter().map(|r| (r.get(0), r.get(1))).collect();
    for id in &ids {
        assert_eq!(
            counts.get(id),
            Some(&1),
            "scan {id} of {scanner} in the database"
        );
    }
    assert_eq!(
        counts.len(),
        ids.len(),
        "{scanner}: the database holds scans the archive does not"
    );
    // Files: name and sha256 as stored, and the stored bytes hashed again here.
    let stored = c
        .query(
            "SELECT a.scan_id, a.name, a.sha256, encode(sha256(b.content), 'hex')
             FROM fleet_artifacts a JOIN fleet_blobs b ON b.sha256 = a.sha256 WHERE a.scanner = $1",
            &[&scanner],
        )
        .unwrap();
    let mut db = BTreeMap::new();
    for r in &stored {
        let (id, name, sha, real): (String, String, String, String) =
            (r.get(0), r.get(1), r.get(2), r.get(3));
        assert_eq!(
            sha, real,
            "{id}/{name}: stored bytes do not hash to their key"
        );
        assert!(db.insert(format!("{id}/{name}"), sha).is_none());
    }
    assert_eq!(db, local, "{scanner}: files in the database vs the archive");
    ids.len()
}

fn fleet_status(d: &Footscand) -> Value {
    d.get_json("/api/status")["fleet"].clone()
}

/// Wait until the daemon's backlog is empty and `n` scans are in the database for `scanner`.
fn wait_drained(d: &Footscand, pg: &PgServer, scanner: &str, n: i64, limit: Duration) -> f64 {
    let t0 = Instant::now();
    loop {
        let st = fleet_status(d);
        let in_db: i64 = pg
            .fleet_client()
            .query_one(
                "SELECT count(*) FROM fleet_scans WHERE scanner = $1",
                &[&scanner],
            )
            .unwrap()
            .get(0);
        if st["backlog"] == 0 && in_db == n {
            return t0.elapsed().as_secs_f64();
        }
        assert!(
            t0.elapsed() < limit,
            "not drained after {limit:?}: {in_db}/{n} in the database, status {st}\n{}",
            d.stderr()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn db_count(pg: &PgServer, scanner: &str) -> i64 {
    pg.fleet_client()
        .query_one(
            "SELECT count(*) FROM fleet_scans WHERE scanner = $1",
            &[&scanner],
        )
        .unwrap()
        .get(0)
}

/// Wait until the database holds at least `n` scans of `scanner` (a push under way).
fn wait_in_db(pg: &PgServer, scanner: &str, n: i64) {
    let t0 = Instant::now();
    while db_count(pg, scanner) < n {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "no push reached the database"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn assert_no_password(d: &Footscand, password: &str) {
    let status = d.get_json("/api/status").to_string();
    assert!(
        !status.contains(password),
        "status shows the password: {status}"
    );
    assert!(!d.stderr().contains(password), "the log shows the password");
}

#[test]
fn faults_leave_every_scan_exactly_once() {
    let pg = PgServer::start();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let root = dir.join("archive");
    let scanner = "scanner-1";
    let mut total = 0usize;

    // An older schema: the daemon brings it up to date when it connects.
    footscan_fleet::migrate(&mut pg.fleet_client(), Some(1)).unwrap();

    // 1. A wrong password: refused, retried, nothing stored, the password shown nowhere.
    let wrong = "wrong-password-5731";
    total += make_scans(&root, 12, 256, "a").len();
    let before = manifest(&root);
    let mut d = start_fleet_daemon(dir, &pg.url(), scanner, wrong);
    let t0 = Instant::now();
    let st = loop {
        let st = fleet_status(&d);
        if st["failures"].as_u64().unwrap_or(0) >= 2 {
            break st;
        }
        assert!(t0.elapsed() < Duration::from_secs(30), "{st}");
        std::thread::sleep(Duration::from_millis(100));
    };
    println!("wrong password: {st}");
    assert_eq!(st["state"], "retrying");
    assert_eq!(st["backlog"], 12);
    assert!(
        st["last_error"]
            .as_str()
            .unwrap()
            .contains("password authentication failed"),
        "{st}"
    );
    assert_eq!(db_count(&pg, scanner), 0);
    assert_no_password(&d, wrong);
    d.terminate(Duration::from_secs(20));

    // 2. The network cut: a closed port for a while, then the server's port again.
    let closed = format!(
        "postgres://footscan@127.0.0.1:{}/fleet",
        footscan_fleet::testing::free_port()
    );
    let mut d = start_fleet_daemon(dir, &closed, scanner, PASSWORD);
    std::thread::sleep(Duration::from_secs(2));
    let st = fleet_status(&d);
    println!("closed port: {st}");
    assert_eq!(st["state"], "retrying", "{st}");
    assert!(
        st["last_error"]
            .as_str()
            .unwrap()
            .contains("onnection refused"),
        "{st}"
    );
    d.terminate(Duration::from_secs(20));
    let d = start_fleet_daemon(dir, &pg.url(), scanner, PASSWORD);
    let s = wait_drained(&d, &pg, scanner, total as i64, Duration::from_secs(60));
    println!("after the cut: {total} scans drained in {s:.2} s");
    assert_eq!(check_exactly_once(&pg, scanner, &root), total);
    let v: i32 = pg
        .fleet_client()
        .query_one("SELECT max(version) FROM fleet_migrations", &[])
        .unwrap()
        .get(0);
    assert_eq!(
        v,
        footscan_fleet::SCHEMA_VERSION,
        "the older schema was brought up to date"
    );
    assert_no_password(&d, PASSWORD);
    drop(d);

    // 3. The server stopped (as if it crashed) mid-upload, restarted a moment later.
    total += make_scans(&root, 30, 1024, "b").len();
    let d = start_fleet_daemon(dir, &pg.url(), scanner, PASSWORD);
    wait_in_db(&pg, scanner, 14);
    pg.stop("immediate");
    let mid = fleet_status(&d);
    std::thread::sleep(Duration::from_secs(2));
    let st = fleet_status(&d);
    println!(
        "server stopped mid-upload: backlog {} then {}, {}",
        mid["backlog"], st["backlog"], st["last_error"]
    );
    assert_eq!(st["state"], "retrying", "{st}");
    pg.start_server();
    wait_drained(&d, &pg, scanner, total as i64, Duration::from_secs(60));
    assert_eq!(check_exactly_once(&pg, scanner, &root), total);

    // 4. The daemon SIGKILLed mid-push, then started again.
    drop(d);
    total += make_scans(&root, 30, 1024, "c").len();
    let mut d = start_fleet_daemon(dir, &pg.url(), scanner, PASSWORD);
    wait_in_db(&pg, scanner, total as i64 - 25);
    d.child.kill().unwrap(); // SIGKILL
    d.child.wait().unwrap();
    let at_kill = db_count(&pg, scanner);
    println!("SIGKILL with {at_kill}/{total} in the database");
    assert!(
        at_kill < total as i64,
        "the kill came after the drain: make the backlog larger"
    );
    let d = start_fleet_daemon(dir, &pg.url(), scanner, PASSWORD);
    wait_drained(&d, &pg, scanner, total as i64, Duration::from_secs(60));
    assert_eq!(check_exactly_once(&pg, scanner, &root), total);
    drop(d);

    // 5. A duplicate push of everything (the outbox forgotten): nothing added.
    let blobs = |pg: &PgServer| -> i64 {
        pg.fleet_client()
            .query_one("SELECT count(*) FROM fleet_blobs", &[])
            .unwrap()
            .get(0)
    };
    let blobs_before = blobs(&pg);
    let db = rusqlite::Connection::open(root.join("index.sqlite")).unwrap();
    let n = db.execute("DELETE FROM fleet_outbox", []).unwrap();
    assert_eq!(n, total);
    drop(db);
    let d = start_fleet_daemon(dir, &pg.url(), scanner, PASSWORD);
    let t0 = Instant::now();
    while fleet_status(&d)["pushed"] != total as u64 {
        assert!(
            t0.elapsed() < Duration::from_secs(60),
            "{}",
            fleet_status(&d)
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    assert_eq!(check_exactly_once(&pg, scanner, &root), total);
    assert_eq!(
        blobs(&pg),
        blobs_before,
        "a repeated push stored blobs again"
    );
    assert!(d.stderr().contains("was already in the database"));
    drop(d);

    // 6. A database at a newer, incompatible schema: refused, naming both versions; the scans
    // wait in the outbox and go once the database is compatible again.
    pg.fleet_client()
        .execute(
            "INSERT INTO fleet_migrations (version, name, compatible_from, software) VALUES (99, 'test: breaking', 99, '99.0.0')",
            &[],
        )
        .unwrap();
    make_scans(&root, 2, 64, "d");
    total += 2;
    let d = start_fleet_daemon(dir, &pg.url(), scanner, PASSWORD);
    let t0 = Instant::now();
    let st = loop {
        let st = fleet_status(&d);
        if st["last_error"]
            .as_str()
            .is_some_and(|e| e.contains("schema version 99"))
        {
            break st;
        }
        assert!(t0.elapsed() < Duration::from_secs(30), "{st}");
        std::thread::sleep(Duration::from_millis(100));
    };
    println!("newer schema: {}", st["last_error"]);
    assert!(st["last_error"]
        .as_str()
        .unwrap()
        .contains(&format!("up to {}", footscan_fleet::SCHEMA_VERSION)));
    assert_eq!(st["backlog"], 2);
    pg.fleet_client()
        .execute("DELETE FROM fleet_migrations WHERE version = 99", &[])
        .unwrap();
    wait_drained(&d, &pg, scanner, total as i64, Duration::from_secs(60));
    assert_eq!(check_exactly_once(&pg, scanner, &root), total);

    // The scan directories of the first batch are as they were.
    let after = manifest(&root);
    for (k, v) in &before {
        assert_eq!(after.get(k), Some(v), "{k} changed in the local archive");
    }
    assert_no_password(&d, PASSWORD);
}

/// Scans on `n` daemons at once, the server bounced `bounces` times while they run; the
/// scan stage timings of every scan. With `fleet` false the daemons have no [fleet].
fn scanners_run(
    pg: &PgServer,
    n_daemons: usize,
    scans: usize,
    bounces: usize,
    fleet: bool,
) -> Vec<f64> {
    // The schema first, so the test's own queries do not race the daemons' migration.
    footscan_fleet::migrate(&mut pg.fleet_client(), None).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let daemons: Vec<(String, PathBuf, Footscand)> = (0..n_daemons)
        .map(|i| {
            let dir = tmp.path().join(format!("d{i}"));
            std::fs::create_dir_all(&dir).unwrap();
            let name = format!("scanner-{}", i + 1);
            let d = if fleet {
                start_fleet_daemon(&dir, &pg.url(), &name, PASSWORD)
            } else {
                Footscand::start(&dir, Opts::default())
            };
            (name, dir.join("archive"), d)
        })
        .collect();
    let timings = std::sync::Mutex::new(Vec::new());
    let bounce_at: Vec<usize> = (1..=bounces).map(|b| b * scans / (bounces + 1)).collect();
    std::thread::scope(|s| {
        for (k, (_, _, d)) in daemons.iter().enumerate() {
            let timings = &timings;
            let bounce_at = &bounce_at;
            s.spawn(move || {
                for i in 0..scans {
                    if k == 0 && fleet && bounce_at.contains(&i) {
                        pg.stop("fast");
                        std::thread::sleep(Duration::from_millis(500));
                        pg.start_server();
                    }
                    let id = d.start_scan(&format!("p{k}x{i}"));
                    let end = d.wait_scan_end(Duration::from_secs(120));
                    assert!(end["state"] != "failed", "{end}");
                    let summary: Value =
                        serde_json::from_slice(&d.download(&id, "scan.json")).unwrap();
                    timings
                        .lock()
                        .unwrap()
                        .push(summary["seconds"].as_f64().unwrap());
                }
            });
        }
    });
    if fleet {
        let t0 = Instant::now();
        for (name, root, d) in &daemons {
            wait_drained(d, pg, name, scans as i64, Duration::from_secs(120));
            assert_eq!(check_exactly_once(pg, name, root), scans);
            assert_no_password(d, PASSWORD);
        }
        println!(
            "backlog drained {:.2} s after the last scan",
            t0.elapsed().as_secs_f64()
        );
        let dups: i64 = pg
            .fleet_client()
            .query_one(
                "SELECT count(*) - count(DISTINCT (scanner, scan_id)) FROM fleet_scans",
                &[],
            )
            .unwrap()
            .get(0);
        assert_eq!(dups, 0);
        // The read-only view: one scanner sees every scanner's scans in the database.
        let (_, _, d0) = &daemons[0];
        let all = d0.get_json("/api/fleet/scans");
        assert_eq!(
            all["scans"].as_array().unwrap().len(),
            n_daemons * scans,
            "{all}"
        );
        let other = format!("scanner-{n_daemons}");
        let one = d0.get_json(&format!("/api/fleet/scans?scanner={other}"));
        let rows = one["scans"].as_array().unwrap();
        assert_eq!(rows.len(), scans, "{one}");
        assert!(rows.iter().all(|r| r["scanner"] == other.as_str()), "{one}");
        assert_eq!(d0.get("/api/fleet/scans?limit=0").status(), 400);
    }
    timings.into_inner().unwrap()
}

fn summary_line(label: &str, mut t: Vec<f64>) {
    let n = t.len();
    let mean = t.iter().sum::<f64>() / n as f64;
    println!(
        "{label}: {n} scans, scan seconds mean {mean:.3}, median {:.3}, p90 {:.3}, max {:.3}",
        percentile(&mut t, 50.0),
        percentile(&mut t, 90.0),
        percentile(&mut t, 100.0)
    );
}

#[test]
fn three_scanners_push_while_the_server_is_bounced() {
    let pg = PgServer::start();
    let t = scanners_run(&pg, 3, 3, 2, true);
    summary_line("3 scanners x 3 scans, 2 bounces", t);
}

/// The target: 3 scanners x 20 short scans, the server bounced twice; then the same
/// scans without [fleet] for the stage timings.
#[test]
#[ignore = "study: several minutes; run with --ignored --nocapture"]
fn study_three_scanners_twenty_scans_each() {
    let pg = PgServer::start();
    let on = scanners_run(&pg, 3, 20, 2, true);
    let n: i64 = pg
        .fleet_client()
        .query_one("SELECT count(*) FROM fleet_scans", &[])
        .unwrap()
        .get(0);
    println!("database: {n} scans");
    let off = scanners_run(&pg, 3, 20, 0, false);
    summary_line("fleet on ", on);
    summary_line("fleet off", off);
}

/// A backlog of 100 scans the size of a real short simulated scan, drained from start.
#[test]
#[ignore = "study: run with --ignored --nocapture"]
fn study_drain_a_backlog_of_100_scans() {
    let pg = PgServer::start();
    // The schema first, so the test's own queries do not race the daemon's migration.
    footscan_fleet::migrate(&mut pg.fleet_client(), None).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    // One real short scan for the sizes of its files.
    let probe = tmp.path().join("probe");
    std::fs::create_dir_all(&probe).unwrap();
    let d = Footscand::start(&probe, Opts::default());
    let id = d.start_scan("probe");
    d.wait_scan_end(Duration::from_secs(120));
    let arts = d.record(&id)["artifacts"].clone();
    drop(d);
    let bytes: u64 = arts
        .as_array()
        .unwrap()
        .iter()
        .map(|a| a["bytes"].as_u64().unwrap())
        .sum();
    println!(
        "a short scan: {} files, {bytes} bytes",
        arts.as_array().unwrap().len()
    );
    let dir = tmp.path().join("d");
    let root = dir.join("archive");
    std::fs::create_dir_all(&dir).unwrap();
    // 100 scans of that size, every file distinct.
    make_scans(&root, 100, (bytes / 1024) as usize, "z");
    let t0 = Instant::now();
    let d = start_fleet_daemon(&dir, &pg.url(), "scanner-1", PASSWORD);
    let s = wait_drained(&d, &pg, "scanner-1", 100, Duration::from_secs(600));
    println!(
        "backlog of 100 scans ({:.1} MB) drained in {s:.2} s ({:.2} s from the daemon's start)",
        100.0 * bytes as f64 / 1e6,
        t0.elapsed().as_secs_f64()
    );
    assert_eq!(check_exactly_once(&pg, "scanner-1", &root), 100);
}
