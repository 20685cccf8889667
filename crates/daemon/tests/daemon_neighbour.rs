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

use footscan_daemon::archive::{Archive, NewScan, Outcome, Status};

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
                    Outcome {
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
    while frames < 30 || t0.elapsed() < Duration::from_millis(2500) {
        let s = d.get_json("/api/status");
        assert_eq!(s["scan"]["state"], "running", "ended too soon: {s}");
        frames = s["scan"]["frames"].as_u64().unwrap();
        assert!(t0.elapsed() < Duration::from_secs(60));
        std::thread::sleep(Duration::from_millis(20));
    }
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
        kept >= 10 && kept <= frames + 50,
        "frames kept {kept}, {frames} seen before the kill"
    );
    println!("killed at >= {frames} frames; the record keeps {kept}");
}
