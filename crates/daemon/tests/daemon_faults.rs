//! (d) Faults on the simulator backend, each ending the affected scan with a named reason
//! while the daemon keeps serving and earlier scans stay listed and downloadable: camera
//! unplug, slider alarm and silent slider mid-scan, a full disk, a client that disconnects
//! mid-download.

mod daemon_support;

use daemon_support::*;
use std::io::{Read, Write};
use std::path::Path;
use std::time::Duration;

/// A complete scan in `archive`; its id and its model.stl bytes.
fn good_scan(dir: &Path, archive: &Path) -> (String, Vec<u8>) {
    let d = Footscand::start(
        dir,
        Opts {
            archive: Some(archive.to_owned()),
            ..Opts::default()
        },
    );
    let id = d.start_scan("good");
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "complete", "{end}");
    let stl = d.download(&id, "model.stl");
    (id, stl)
}

/// The earlier scan is still listed, complete, and byte-identical.
fn earlier_scan_intact(d: &Footscand, id: &str, stl: &[u8]) {
    let list = d.get_json("/api/scans");
    let rec = list
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["id"] == id)
        .unwrap_or_else(|| panic!("scan {id} lost from {list}"));
    assert_eq!(rec["status"], "complete");
    assert!(
        d.download(id, "model.stl") == stl,
        "model.stl of {id} changed"
    );
}

/// Run one scan with `faults` on the archive of earlier scans: its final record.
fn faulty_scan(dir: &Path, archive: &Path, faults: &str, earlier: &(String, Vec<u8>)) -> Value {
    let d = Footscand::start(
        dir,
        Opts {
            faults,
            archive: Some(archive.to_owned()),
            ..Opts::default()
        },
    );
    let id = d.start_scan("faulty");
    let events = d.follow(&id);
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "failed", "{faults}: {end}");
    assert!(
        events
            .iter()
            .any(|(n, v)| n == "error" && v["id"] == id.as_str()),
        "no error event"
    );
    // Still serving, nothing lost.
    assert_eq!(d.get_json("/api/health")["ok"], true);
    earlier_scan_intact(&d, &earlier.0, &earlier.1);
    let rec = d.record(&id);
    assert_eq!(rec["status"], "failed");
    assert_eq!(rec["reason"], end["reason"]);
    assert!(d.archive.join(&id).join("record.json").is_file());
    let status = d.get_json("/api/status");
    println!(
        "{faults}: reason {:?}; devices {}",
        rec["reason"], status["devices"]
    );
    let mut rec = rec;
    rec["devices"] = status["devices"].clone();
    rec
}

#[test]
fn device_faults_end_the_scan_with_a_named_reason() {
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");
    let earlier = good_scan(tmp.path(), &archive);

    let rec = faulty_scan(
        tmp.path(),
        &archive,
        "camera_unplug_after_s = 3.5",
        &earlier,
    );
    let reason = rec["reason"].as_str().unwrap().to_lowercase();
    assert!(
        reason.contains("acquire") && reason.contains("disconnected"),
        "{reason}"
    );
    assert!(
        rec["frames"].as_u64().unwrap() > 0,
        "the scan had started: {rec}"
    );
    assert_eq!(rec["devices"]["camera"]["connected"], false);
    assert_eq!(rec["devices"]["slider"]["connected"], true);

    let rec = faulty_scan(
        tmp.path(),
        &archive,
        "slider_alarm_after_s = 3.5\nslider_alarm_code = 1",
        &earlier,
    );
    let reason = rec["reason"].as_str().unwrap().to_lowercase();
    assert!(reason.contains("alarm"), "{reason}");
    assert_eq!(rec["devices"]["slider"]["state"], "alarm");
    assert_eq!(rec["devices"]["camera"]["connected"], true);

    let rec = faulty_scan(
        tmp.path(),
        &archive,
        "slider_silent_after_s = 3.5",
        &earlier,
    );
    let reason = rec["reason"].as_str().unwrap().to_lowercase();
    assert!(reason.contains("timed out"), "{reason}");
    assert_eq!(rec["devices"]["slider"]["connected"], false);
    assert_eq!(rec["devices"]["camera"]["connected"], true);
    assert_eq!(
        std::fs::read_dir(&archive)
            .unwrap()
            .filter(|e| e
                .as_ref()
                .unwrap()
                .file_name()
                .to_string_lossy()
                .starts_with(".tmp-"))
            .count(),
        0,
        "no scan left half-written"
    );
}

#[test]
fn client_disconnecting_mid_download_harms_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    let id = d.start_scan("download");
    assert_eq!(
        d.wait_scan_end(Duration::from_secs(120))["state"],
        "complete"
    );
    let want = daemon_support::archived_file(&d.archive, &id, "model.stl");
    assert!(
        want.len() > 1 << 20,
        "a large artifact: {} bytes",
        want.len()
    );
    let addr = d.base.strip_prefix("http://").unwrap().to_string();
    for _ in 0..5 {
        let mut s = std::net::TcpStream::connect(&addr).unwrap();
        write!(
            s,
            "GET /api/scans/{id}/files/model.stl HTTP/1.1\r\nHost: {addr}\r\n\r\n"
        )
        .unwrap();
        let mut buf = [0u8; 4096];
        let mut got = 0;
        while got < 8192 {
            let n = s.read(&mut buf).unwrap();
            assert!(n > 0, "connection closed early");
            got += n;
        }
        drop(s); // mid-download
    }
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(d.get_json("/api/health")["ok"], true);
    let full = d.download(&id, "model.stl");
    assert_eq!(full.len(), want.len());
    assert!(full == want, "the full download differs from the file");
    println!(
        "dropped 5 downloads after 8 KiB of {} bytes; full download identical",
        want.len()
    );
}

fn is_root() -> bool {
    // SAFETY: geteuid has no preconditions.
    unsafe { libc::geteuid() == 0 }
}

struct Mount(std::path::PathBuf);

impl Drop for Mount {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount").arg(&self.0).status();
    }
}

#[test]
fn full_disk_fails_the_scan_and_keeps_earlier_ones() {
    assert!(
        is_root(),
        "this test needs root: it mounts a small tmpfs (mount -t tmpfs) for the archive"
    );
    let tmp = tempfile::tempdir().unwrap();
    let mnt = tmp.path().join("tmpfs");
    std::fs::create_dir_all(&mnt).unwrap();
    let st = std::process::Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=40m", "tmpfs"])
        .arg(&mnt)
        .status()
        .unwrap();
    assert!(st.success(), "mount -t tmpfs failed: {st:?}");
    let _mount = Mount(mnt.clone());
    let archive = mnt.join("archive");
    let d = Footscand::start(
        tmp.path(),
        Opts {
            archive: Some(archive.clone()),
            // The disk is filled to a known free space below: a compaction of the first scan
            // finishing after that would free 15 MB behind the test's back.
            daemon_extra: "\n[archive]\ncompact = false\n",
            ..Opts::default()
        },
    );
    let first = d.start_scan("before-full");
    assert_eq!(
        d.wait_scan_end(Duration::from_secs(120))["state"],
        "complete"
    );
    let stl = d.download(&first, "model.stl");
    // Leave 1 MiB: the next scan's large files cannot fit.
    let free = {
        let mut s: libc::statvfs = unsafe { std::mem::zeroed() };
        let c = std::ffi::CString::new(mnt.to_str().unwrap()).unwrap();
        // SAFETY: statvfs fills the struct we own; the path is NUL-terminated.
        assert_eq!(unsafe { libc::statvfs(c.as_ptr(), &mut s) }, 0);
        s.f_bavail as u64 * s.f_frsize as u64
    };
    let filler = mnt.join("filler");
    std::fs::write(&filler, vec![1u8; (free - (1 << 20)) as usize]).unwrap();

    let id = d.start_scan("disk-full");
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "failed", "{end}");
    let reason = end["reason"].as_str().unwrap();
    assert!(
        reason.contains("No space left on device") && reason.contains("writing"),
        "the reason names the ENOSPC write: {reason}"
    );
    let rec = d.record(&id);
    assert_eq!(rec["status"], "failed");
    assert_eq!(rec["reason"], reason);
    assert!(archive.join(&id).join("record.json").is_file());
    assert_eq!(d.get_json("/api/health")["ok"], true);
    earlier_scan_intact(&d, &first, &stl);
    println!("disk full: {reason}");

    // Space again: the daemon scans on.
    std::fs::remove_file(&filler).unwrap();
    for e in std::fs::read_dir(archive.join(&id)).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "stl" || x == "bin") {
            std::fs::remove_file(p).unwrap();
        }
    }
    let again = d.start_scan("after-full");
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "complete", "{end}");
    assert_eq!(d.record(&again)["status"], "complete");
    drop(d);
}
