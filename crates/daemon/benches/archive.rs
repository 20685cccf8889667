//! Archive benchmark (not a test): the archive at a clinic's years (issue 39).
//!
//! `cargo bench -p footscand --no-default-features --profile dev --bench archive` fills an
//! archive with ARCHIVE_SCANS (default 50,000) scan records of ARCHIVE_PATIENTS (default
//! 2,000) patients over five years, and ARCHIVE_VISITS (default 20,000) visits, then prints:
//! the index rebuild from the directories (the first open, no index.sqlite), footscand's
//! start-up on that archive (spawn to the first page answered), a page of 50 scans over HTTP
//! (p50, p99 of random cursors), a subject search (p50, p99), and the same for visits. Each
//! target of the issue is said ok or OVER, and the run exits 1 if any is over.
//!
//! The records are generated: the index, the pages and the start-up read records.json and
//! directory entries, never the scan files, so the directories hold only their record (a
//! real scan's files would only cost disk). ARCHIVE_DIR puts the archive elsewhere than the
//! system's temporary directory (the disk the numbers are for: tmpfs flatters them); it is
//! deleted at the end.
//!
//! `ARCHIVE_PART=compact ARCHIVE_SCAN_DIR=DIR` measures the compact form on one scan instead
//! ([`compact_part`]).

#[path = "../tests/daemon_support/mod.rs"]
mod daemon_support;

use daemon_support::*;
use std::path::Path;
use std::time::Instant;

fn env<T: std::str::FromStr>(key: &str, default: T) -> T {
    std::env::var(key)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// splitmix64: reproducible picks without a dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

const STATUSES: [&str; 6] = [
    "complete",
    "complete",
    "complete",
    "complete with warnings",
    "rescan",
    "failed",
];

/// The ids of the scans written, oldest first.
fn fill(root: &Path, scans: usize, patients: usize, visits: usize) -> Vec<String> {
    let mut rng = Rng(39);
    let t0: i64 = 1_640_995_200; // 2022-01-01T00:00:00Z
    let span: i64 = 5 * 365 * 86_400;
    let mut ids = Vec::with_capacity(scans);
    for i in 0..scans {
        let secs = t0 + span * i as i64 / scans as i64;
        let t = jiff::Timestamp::from_second(secs).unwrap();
        let id = format!(
            "{}-{:04x}",
            t.strftime("%Y%m%dT%H%M%SZ"),
            rng.below(0x10000)
        );
        let rec = serde_json::json!({
            "id": id,
            "subject": format!("P-{:05}", rng.below(patients)),
            "side": if i % 2 == 0 { "left" } else { "right" },
            "notes": "",
            "status": STATUSES[rng.below(STATUSES.len())],
            "reason": null,
            "started": t.strftime("%Y-%m-%dT%H:%M:%SZ").to_string(),
            "finished": (t + jiff::SignedDuration::from_secs(40)).strftime("%Y-%m-%dT%H:%M:%SZ").to_string(),
            "frames": 1280,
            "points": 77_000 + rng.below(5000),
        });
        let dir = root.join(&id);
        std::fs::create_dir(&dir).unwrap();
        std::fs::write(dir.join("record.json"), rec.to_string()).unwrap();
        ids.push(id);
    }
    let vdir = root.join("visits");
    std::fs::create_dir_all(&vdir).unwrap();
    for i in 0..visits {
        let secs = t0 + span * i as i64 / visits as i64 + 7;
        let t = jiff::Timestamp::from_second(secs).unwrap();
        let id = format!(
            "{}-{:04x}",
            t.strftime("%Y%m%dT%H%M%SZ"),
            rng.below(0x10000)
        );
        let v = serde_json::json!({"id": id, "patient": format!("P-{:05}", rng.below(patients)),
            "notes": "", "started": t.strftime("%Y-%m-%dT%H:%M:%SZ").to_string(),
            "left": null, "right": null});
        std::fs::write(vdir.join(format!("{id}.json")), v.to_string()).unwrap();
    }
    ids
}

/// `n` timed GETs of the paths `path(i)` (each must answer 200); their p50 and p99 in ms.
fn timed(d: &Footscand, n: usize, path: impl Fn(usize) -> String) -> (f64, f64) {
    let mut ms = Vec::with_capacity(n);
    for i in 0..n {
        let p = path(i);
        let t = Instant::now();
        let r = d.get(&p);
        let status = r.status();
        let body = r.bytes().unwrap();
        ms.push(t.elapsed().as_secs_f64() * 1e3);
        assert_eq!(status, 200, "{p}: {}", String::from_utf8_lossy(&body));
    }
    (percentile(&mut ms.clone(), 50.0), percentile(&mut ms, 99.0))
}

/// `ARCHIVE_PART=compact`: one scan directory (ARCHIVE_SCAN_DIR, a default simulated scan)
/// before and after compaction (docs/method.md 14h.2): sizes, the codecs' figures on its
/// grid.bin, the compaction's time, and the time to serve each compacted file (decoded or
/// rebuilt into the cache, then from the cache).
fn compact_part() {
    use footscan::compact;
    let src = std::path::PathBuf::from(
        std::env::var_os("ARCHIVE_SCAN_DIR")
            .expect("ARCHIVE_SCAN_DIR: a scan directory (e.g. target/tmp/shared-sim-scan)"),
    );
    let runs: usize = env("ARCHIVE_RUNS", 3);
    let tmp = match std::env::var_os("ARCHIVE_DIR") {
        Some(d) => tempfile::tempdir_in(d).unwrap(),
        None => tempfile::tempdir().unwrap(),
    };
    let sizes = |dir: &Path| -> (u64, u64) {
        use std::os::unix::fs::MetadataExt;
        std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.metadata().unwrap())
            .filter(|m| m.is_file())
            .fold((0, 0), |(b, d), m| (b + m.len(), d + m.blocks() * 512))
    };
    let mb = |b: u64| b as f64 / 1e6;
    println!("compact: scan {}", src.display());
    for e in std::fs::read_dir(&src).unwrap().flatten() {
        println!(
            "  {:<20} {:>10} bytes",
            e.file_name().to_string_lossy(),
            e.metadata().unwrap().len()
        );
    }
    // The codecs on grid.bin: plain and shuffled, gzip levels 1, 6, 9.
    let grid = std::fs::read(src.join("grid.bin")).unwrap();
    let shuffled = compact::shuffle_grid(&grid).expect("a whole grid.bin");
    for (what, bytes) in [("plain", &grid), ("shuffled", &shuffled)] {
        for level in [1, 6, 9] {
            let t = Instant::now();
            let z = compact::gzip(bytes, level);
            let ct = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let back = compact::gunzip(&z, bytes.len() as u64).unwrap();
            let dt = t.elapsed().as_secs_f64();
            assert!(back == *bytes);
            println!(
                "  grid.bin {what:<8} gzip -{level}: {:.2} MB ({:.1} %), compress {:.0} ms, decompress {:.0} ms",
                mb(z.len() as u64),
                100.0 * z.len() as f64 / grid.len() as f64,
                ct * 1e3,
                dt * 1e3
            );
        }
    }
    let root = tmp.path().join("archive");
    let mut times = Vec::new();
    let mut last_id = String::new();
    for k in 0..runs {
        let id = format!("20261128T1200{k:02}Z-00{k:02}");
        let dir = root.join(&id);
        std::fs::create_dir_all(&dir).unwrap();
        for e in std::fs::read_dir(&src).unwrap().flatten() {
            std::fs::copy(e.path(), dir.join(e.file_name())).unwrap();
        }
        let rec = serde_json::json!({
            "id": id, "subject": "P-bench", "side": "right", "notes": "",
            "status": "complete", "reason": null, "frames": 642, "points": 253220,
            "started": "2026-11-28T12:00:00Z", "finished": "2026-11-28T12:00:20Z",
        });
        std::fs::write(
            dir.join("record.json"),
            serde_json::to_vec_pretty(&rec).unwrap(),
        )
        .unwrap();
        let (b0, d0) = sizes(&dir);
        let t = Instant::now();
        let r = compact::compact_dir(&dir, &Default::default()).unwrap();
        let s = t.elapsed().as_secs_f64();
        times.push(s);
        let (b1, d1) = sizes(&dir);
        if k == 0 {
            println!(
                "  scan: {:.1} MB in files ({:.1} MB on disk) -> {:.1} MB ({:.1} MB on disk)",
                mb(b0),
                mb(d0),
                mb(b1),
                mb(d1)
            );
            for (name, codec) in &r.files {
                println!("    {name:<14} {codec:?}");
            }
        }
        last_id = id;
    }
    println!(
        "  compaction: {} runs, {:.2} s median ({})",
        runs,
        percentile(&mut times.clone(), 50.0),
        times
            .iter()
            .map(|t| format!("{t:.2}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    // Serving: the daemon's cache path, cold (decode or rebuild) then warm.
    let a = footscan_daemon::archive::Archive::open(&root).unwrap();
    let rec = a
        .get(&footscan_daemon::archive::ScanId::parse(&last_id).unwrap())
        .unwrap();
    let man = compact::Manifest::load(&root.join(&last_id))
        .unwrap()
        .unwrap();
    for (name, e) in &man.files {
        let t = Instant::now();
        let p = a.artifact_path(&rec, name).unwrap();
        let cold = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let p2 = a.artifact_path(&rec, name).unwrap();
        let warm = t.elapsed().as_secs_f64();
        assert_eq!(p, p2);
        let b = std::fs::read(&p).unwrap();
        assert_eq!(compact::sha256_hex(&b), e.sha256, "{name}");
        println!(
            "  serve {name:<14} ({:?}): first request {:.0} ms, then {:.1} ms",
            e.codec,
            cold * 1e3,
            warm * 1e3
        );
    }
}

fn main() {
    if !std::env::args().any(|a| a == "--bench") {
        println!("archive: a benchmark; run it with `cargo bench -p footscand --bench archive`");
        return;
    }
    if std::env::var("ARCHIVE_PART").as_deref() == Ok("compact") {
        compact_part();
        return;
    }
    let scans: usize = env("ARCHIVE_SCANS", 50_000);
    let patients: usize = env("ARCHIVE_PATIENTS", 2_000);
    let visits: usize = env("ARCHIVE_VISITS", 20_000);
    let n: usize = env("ARCHIVE_REQUESTS", 1000);
    let tmp = match std::env::var_os("ARCHIVE_DIR") {
        Some(d) => tempfile::tempdir_in(d).unwrap(),
        None => tempfile::tempdir().unwrap(),
    };
    let root = tmp.path().join("archive");
    std::fs::create_dir_all(&root).unwrap();
    let t = Instant::now();
    let ids = fill(&root, scans, patients, visits);
    println!(
        "archive: {scans} scan records of {patients} patients, {visits} visits written in {:.1} s under {}",
        t.elapsed().as_secs_f64(),
        root.display()
    );

    let mut verdicts = Vec::new();
    let mut say = |what: &str, value: f64, limit: Option<f64>| {
        let v = match limit {
            Some(l) if value <= l => format!(" (target {l} : ok)"),
            Some(l) => {
                verdicts.push(what.to_string());
                format!(" (target {l} : OVER)")
            }
            None => String::new(),
        };
        println!("archive: {what}: {value:.1}{v}");
    };

    // The index rebuilt from the directories: the first open, with no index.sqlite.
    let t = Instant::now();
    let a = footscan_daemon::archive::Archive::open(&root).unwrap();
    say(
        "index rebuild from the directories, s",
        t.elapsed().as_secs_f64(),
        None,
    );
    let page = a
        .list_page(&footscan_daemon::archive::ScanQuery {
            limit: Some(50),
            ..Default::default()
        })
        .unwrap();
    assert_eq!(page.items.len(), 50);
    drop(a);

    // footscand's start-up on the archive with its index: spawn to the first page answered.
    let (cmd, archive) = command(
        tmp.path(),
        &Opts {
            archive: Some(root.clone()),
            ..Opts::default()
        },
    );
    let t = Instant::now();
    let d = Footscand::spawn(cmd, archive, None);
    let first = d.get_json("/api/scans?limit=50");
    say(
        "footscand start-up to the first page, s",
        t.elapsed().as_secs_f64(),
        Some(2.0),
    );
    assert_eq!(first["items"].as_array().unwrap().len(), 50);

    let mut rng = Rng(7);
    let cursors: Vec<String> = (0..n).map(|_| ids[rng.below(ids.len())].clone()).collect();
    let subjects: Vec<String> = (0..n)
        .map(|_| format!("P-{:05}", rng.below(patients)))
        .collect();
    // (what, the path of request i, the p99 target in ms)
    type PathOf<'a> = Box<dyn Fn(usize) -> String + 'a>;
    let runs: Vec<(&str, PathOf, Option<f64>)> = vec![
        (
            "page of 50 scans, random cursor",
            Box::new(|i| format!("/api/scans?limit=50&before={}", cursors[i])),
            Some(20.0),
        ),
        (
            "subject search (one patient's scans)",
            Box::new(|i| format!("/api/scans?limit=50&subject={}", subjects[i])),
            Some(50.0),
        ),
        (
            "subject prefix search (P-0x: 100 patients' scans)",
            Box::new(|i| format!("/api/scans?limit=50&subject={}", &subjects[i][..5])),
            Some(50.0),
        ),
        (
            "status and side search, random cursor",
            Box::new(|i| {
                format!(
                    "/api/scans?limit=50&status=rescan&side=left&before={}",
                    cursors[i]
                )
            }),
            Some(50.0),
        ),
        (
            "page of 50 visits, random cursor",
            Box::new(|i| format!("/api/visits?limit=50&before={}", cursors[i])),
            Some(20.0),
        ),
        (
            "visit subject search (any part of the id)",
            Box::new(|i| format!("/api/visits?limit=50&subject={}", subjects[i])),
            Some(50.0),
        ),
    ];
    for (what, path, limit) in runs {
        let (p50, p99) = timed(&d, n, path);
        say(&format!("{what}, p50 ms"), p50, None);
        say(&format!("{what}, p99 ms"), p99, limit);
    }
    if std::path::Path::new(chromium::CHROMIUM).is_file() {
        // The dashboard's first view: navigation start to both tables drawn (the marks
        // app.js and visits.js set), in headless Chromium, the worst of three loads.
        let profile = tmp.path().join("chromium");
        let mut b = chromium::Browser::launch(&profile, 1400, 2600);
        let mut worst: f64 = 0.0;
        for _ in 0..3 {
            b.open(
                &d.base,
                "performance.getEntriesByName('scans-shown').length > 0 \
                 && performance.getEntriesByName('visits-shown').length > 0",
                std::time::Duration::from_secs(30),
            );
            let ms = b.eval(
                "Math.max(performance.getEntriesByName('scans-shown')[0].startTime, \
                 performance.getEntriesByName('visits-shown')[0].startTime)",
            );
            let rows = b.eval("document.querySelectorAll('#scans tbody tr[data-scan-id]').length");
            assert_eq!(rows, 50, "the first view shows one page");
            worst = worst.max(ms.as_f64().unwrap());
        }
        say(
            "dashboard first view in headless Chromium (both tables drawn), worst of 3, ms",
            worst,
            Some(1000.0),
        );
    } else {
        println!(
            "archive: no {}: the dashboard's first view not timed",
            chromium::CHROMIUM
        );
    }
    let (p50, _) = timed(&d, 5, |_| "/api/scans".to_string());
    say(
        "the unpaged list (every scan, the answer before pages), p50 ms",
        p50,
        None,
    );
    drop(d);

    if verdicts.is_empty() {
        println!("archive: every target met");
    } else {
        println!("archive: OVER: {}", verdicts.join("; "));
        // exit() skips destructors: the 70,000 files go first.
        drop(tmp);
        std::process::exit(1);
    }
}
