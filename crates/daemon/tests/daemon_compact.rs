//! Compact scans (docs/method.md 14h.2): a real simulated scan compacted by
//! `footscand archive compact` serves every file it served before byte for byte, measures
//! the same, and a migration of 100 scans killed half-way (twice) and run again loses
//! nothing. Two real (short) scans: one compacted by the command and reused for the rest, one
//! compacted by the daemon when it ends.

mod daemon_support;

use daemon_support::{Footscand, Opts};
use footscan::compact::{self, MANIFEST};
use footscan::scandata::ScanDir;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

fn compact_cmd(archive: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footscand"));
    c.arg("archive").arg("compact").arg(archive);
    c.env_remove("FOOTSCAND_TEST_ABORT_AT_SCAN");
    c
}

/// Every file the API lists for scan `id`, downloaded.
fn served(d: &Footscand, id: &str) -> BTreeMap<String, Vec<u8>> {
    let rec = d.get_json(&format!("/api/scans/{id}"));
    let arts = rec["artifacts"].as_array().expect("artifacts").clone();
    let mut out = BTreeMap::new();
    for a in arts {
        let name = a["name"].as_str().unwrap().to_string();
        let bytes = d.download(id, &name);
        assert_eq!(
            bytes.len() as u64,
            a["bytes"].as_u64().unwrap(),
            "{name}: listed length"
        );
        out.insert(name, bytes);
    }
    out
}

/// Every file of every scan directory of `root` as a reader sees it (originals, or the
/// compact form decoded and checked).
fn read_all(root: &Path) -> BTreeMap<(String, String), Vec<u8>> {
    let mut out = BTreeMap::new();
    for (id, dir) in footscan_daemon::archive::compact::scan_dirs(root).unwrap() {
        for (name, _, _) in compact::listing(&dir).unwrap() {
            let b = ScanDir::new(&dir)
                .read_file(&name)
                .unwrap_or_else(|e| panic!("{id}/{name}: {e}"));
            out.insert((id.clone(), name), b);
        }
    }
    out
}

/// The keys whose bytes differ between two readings (a failed comparison names them only).
fn differ(
    a: &BTreeMap<(String, String), Vec<u8>>,
    b: &BTreeMap<(String, String), Vec<u8>>,
) -> Vec<String> {
    let keys: std::collections::BTreeSet<_> = a.keys().chain(b.keys()).collect();
    keys.into_iter()
        .filter(|k| a.get(*k) != b.get(*k))
        .map(|k| format!("{}/{}", k.0, k.1))
        .collect()
}

fn measure(dir: &Path, out: &Path) -> (Vec<u8>, Vec<u8>, String) {
    std::fs::create_dir_all(out).unwrap();
    let (json, png) = (out.join("m.json"), out.join("m.png"));
    let m = footscan::measure::measure_scan_dir(dir, Some(&json), Some(&png), 0.1, true).unwrap();
    (
        std::fs::read(&json).unwrap(),
        std::fs::read(&png).unwrap(),
        serde_json::to_string(&m.comparison).unwrap(),
    )
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap().flatten() {
        if e.file_type().unwrap().is_file() {
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    }
}

/// A generated scan: its record and a small grid.bin, points.ply and model.step.
fn generated_scan(root: &Path, k: usize) -> String {
    let id = format!(
        "2025{:02}{:02}T1000{:02}Z-{:04x}",
        1 + k % 12,
        1 + k % 28,
        k % 60,
        k
    );
    let dir = root.join(&id);
    std::fs::create_dir_all(&dir).unwrap();
    let rec = serde_json::json!({
        "id": id, "subject": format!("p-{k:03}"), "side": "left", "notes": "",
        "status": "complete", "reason": null, "frames": 3, "points": 10,
        "started": "2025-01-01T10:00:00Z", "finished": "2025-01-01T10:00:20Z",
    });
    std::fs::write(
        dir.join("record.json"),
        serde_json::to_vec_pretty(&rec).unwrap(),
    )
    .unwrap();
    let (nf, rows) = (3u32, 40u32);
    let mut g = b"FSGRID01".to_vec();
    g.extend_from_slice(&nf.to_le_bytes());
    g.extend_from_slice(&rows.to_le_bytes());
    let body = 32 * nf as usize + 45 * (nf * rows) as usize;
    g.extend((0..body).map(|i| ((i * 31 + k * 7) % 253) as u8));
    std::fs::write(dir.join("grid.bin"), &g).unwrap();
    std::fs::write(dir.join("points.ply"), format!("ply {k}\n").repeat(500)).unwrap();
    std::fs::write(
        dir.join("model.step"),
        format!("ISO-10303-21; {k}\n").repeat(800),
    )
    .unwrap();
    id
}

#[test]
fn compacted_scans_serve_the_same_bytes_and_migration_survives_kills() {
    let tmp = tempfile::tempdir().unwrap();
    let mut d = Footscand::start(
        tmp.path(),
        Opts {
            daemon_extra: "\n[archive]\ncompact = false\n",
            ..Default::default()
        },
    );
    let archive = d.archive.clone();
    let id = d.start_scan("p-compact");
    let end = d.wait_scan_end(Duration::from_secs(240));
    assert_eq!(end["state"], "complete", "{end}");
    // The model is written after the results: wait for the scan's files to settle.
    let _ = d.wait_json(&format!("/api/scans/{id}"), Duration::from_secs(120), |v| {
        v["artifacts"]
            .as_array()
            .is_some_and(|a| a.iter().any(|x| x["name"] == "model.stl"))
    });
    std::thread::sleep(Duration::from_secs(1));
    let before = served(&d, &id);
    for f in [
        "grid.bin",
        "points.ply",
        "model.stl",
        "scan.json",
        "record.json",
    ] {
        assert!(
            before.contains_key(f),
            "{f} served before: {:?}",
            before.keys()
        );
    }
    let original = tmp.path().join("original");
    copy_dir(&archive.join(&id), &original);

    // Refused beside the running daemon, naming why.
    let out = compact_cmd(&archive).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("stop the daemon"),
        "{err}"
    );
    d.terminate(Duration::from_secs(30));

    // Compact: the scan shrinks, and reads back byte for byte.
    let out = compact_cmd(&archive).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let dir = archive.join(&id);
    assert!(dir.join(MANIFEST).is_file());
    assert!(!dir.join("grid.bin").exists() && dir.join("grid.bin.shuf.gz").is_file());
    let man = compact::Manifest::load(&dir).unwrap().unwrap();
    assert_eq!(
        man.files["points.ply"].codec,
        compact::Codec::RebuildPly,
        "the cloud is rebuilt from the grid, byte for byte"
    );
    let size = |p: &Path| -> u64 {
        std::fs::read_dir(p)
            .unwrap()
            .flatten()
            .map(|e| e.metadata().unwrap().len())
            .sum()
    };
    let (was, now) = (size(&original), size(&dir));
    eprintln!("scan {id}: {was} bytes -> {now} bytes");
    assert!(now * 3 < was, "{was} -> {now}");

    // `footscan measure` on the compacted directory: the same figures, files and errors.
    let m0 = measure(&original, &tmp.path().join("m0"));
    let m1 = measure(&dir, &tmp.path().join("m1"));
    assert!(m0 == m1, "measuring the compacted scan differs");

    let d = Footscand::start(
        tmp.path(),
        Opts {
            daemon_extra: "\n[archive]\ncompact = false\n",
            ..Default::default()
        },
    );
    let after = served(&d, &id);
    assert_eq!(
        before.keys().collect::<Vec<_>>(),
        after.keys().collect::<Vec<_>>()
    );
    for (name, b) in &before {
        assert!(
            after[name] == *b,
            "{name} served differently after compaction"
        );
    }
    // A range of a rebuilt file, from the cache.
    let r = d
        .client
        .get(d.url(&format!("/api/scans/{id}/files/model.stl")))
        .header("Range", "bytes=100-199")
        .send()
        .unwrap();
    assert_eq!(r.status(), 206);
    assert_eq!(r.bytes().unwrap().as_ref(), &before["model.stl"][100..200]);
    drop(d);

    // As after an upgrade whose point writer changed: the manifest's points.ply says other
    // bytes, written by another footscan. The strict reader refuses it, naming why; the
    // daemon serves the rebuild (not its stale cache) with the header that says so; a file
    // that still matches has no such header.
    let man_path = dir.join(MANIFEST);
    let saved = std::fs::read(&man_path).unwrap();
    let mut m: compact::Manifest = serde_json::from_slice(&saved).unwrap();
    let e = m.files.get_mut("points.ply").unwrap();
    e.sha256 = "0".repeat(64);
    e.made_by = Some("footscan 0.0.1".into());
    std::fs::write(&man_path, serde_json::to_vec(&m).unwrap()).unwrap();
    let err = ScanDir::new(&dir).read_file("points.ply").unwrap_err();
    assert!(
        err.to_string().contains("footscan 0.0.1") && err.to_string().contains("rebuilt"),
        "{err}"
    );
    let d = Footscand::start(
        tmp.path(),
        Opts {
            daemon_extra: "\n[archive]\ncompact = false\n",
            ..Default::default()
        },
    );
    for round in ["rebuilt", "from the cache"] {
        let r = d
            .client
            .get(d.url(&format!("/api/scans/{id}/files/points.ply")))
            .send()
            .unwrap();
        assert_eq!(r.status(), 200, "{round}");
        let note = r
            .headers()
            .get("x-footscan-rebuilt")
            .unwrap_or_else(|| panic!("{round}: no x-footscan-rebuilt header"))
            .to_str()
            .unwrap()
            .to_string();
        assert!(
            note.contains("footscan 0.0.1") && note.contains(&"0".repeat(64)),
            "{round}: {note}"
        );
        assert!(
            r.bytes().unwrap().as_ref() == before["points.ply"],
            "{round}"
        );
    }
    let r = d
        .client
        .get(d.url(&format!("/api/scans/{id}/files/model.stl")))
        .send()
        .unwrap();
    assert_eq!(r.status(), 200);
    assert!(r.headers().get("x-footscan-rebuilt").is_none());
    // The compact form's own files are not the scan's: not served by name.
    for own in [MANIFEST, "grid.bin.shuf.gz"] {
        let r = d
            .client
            .get(d.url(&format!("/api/scans/{id}/files/{own}")))
            .send()
            .unwrap();
        assert_eq!(r.status(), 404, "{own}");
    }
    drop(d);
    std::fs::write(&man_path, &saved).unwrap();

    // With the default `[archive] compact = true`, the daemon compacts a scan when it ends,
    // and serves it as it would the original files.
    let d = Footscand::start(tmp.path(), Opts::default());
    let id2 = d.start_scan("p-compact-2");
    let end = d.wait_scan_end(Duration::from_secs(240));
    assert_eq!(end["state"], "complete", "{end}");
    let dir2 = archive.join(&id2);
    let t = std::time::Instant::now();
    while !dir2.join(MANIFEST).exists() || dir2.join("grid.bin").exists() {
        assert!(
            t.elapsed() < Duration::from_secs(120),
            "scan {id2} not compacted"
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let got = served(&d, &id2);
    for f in [
        "grid.bin",
        "points.ply",
        "model.stl",
        "model.glb",
        "model.step",
    ] {
        assert!(got.contains_key(f), "{f} served: {:?}", got.keys());
    }
    for (name, b) in &got {
        assert!(
            ScanDir::new(&dir2).read_file(name).unwrap() == *b,
            "{name} of the scan compacted at its end"
        );
    }
    drop(d);

    // Migration of 100 scans (98 generated, 2 copies of the real one, old form), killed
    // twice half-way (a hook aborting inside scan 37, then SIGKILL at a random moment), then
    // run to the end: nothing lost, every scan compact.
    let big = tmp.path().join("big");
    std::fs::create_dir_all(&big).unwrap();
    let ids: Vec<String> = (0..98).map(|k| generated_scan(&big, k)).collect();
    for (k, rid) in ["20250601T120000Z-aaa1", "20250601T120500Z-aaa2"]
        .iter()
        .enumerate()
    {
        copy_dir(&original, &big.join(rid));
        let mut rec: serde_json::Value =
            serde_json::from_slice(&std::fs::read(original.join("record.json")).unwrap()).unwrap();
        rec["id"] = (*rid).into();
        rec["subject"] = format!("p-real-{k}").into();
        std::fs::write(
            big.join(rid).join("record.json"),
            serde_json::to_vec(&rec).unwrap(),
        )
        .unwrap();
    }
    assert_eq!(ids.len() + 2, 100);
    let all = read_all(&big);
    assert!(all.len() >= 98 * 4 + 2 * 8, "{}", all.len());

    let out = compact_cmd(&big)
        .env("FOOTSCAND_TEST_ABORT_AT_SCAN", "37")
        .output()
        .unwrap();
    assert!(!out.status.success(), "the hook aborts");
    assert_eq!(
        differ(&read_all(&big), &all),
        Vec::<String>::new(),
        "after the abort in scan 37"
    );
    let compacted = |root: &Path| {
        footscan_daemon::archive::compact::scan_dirs(root)
            .unwrap()
            .iter()
            .filter(|(_, d)| d.join(MANIFEST).exists() && !d.join("grid.bin").exists())
            .count()
    };
    let n1 = compacted(&big);
    assert!((30..=40).contains(&n1), "{n1} compacted before the abort");

    let mut child = compact_cmd(&big)
        .stdout(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos();
    std::thread::sleep(Duration::from_millis(200 + (nanos % 600) as u64));
    child.kill().unwrap();
    child.wait().unwrap();
    eprintln!(
        "migration: {n1} scans compact after the abort, {} after SIGKILL",
        compacted(&big)
    );
    assert_eq!(
        differ(&read_all(&big), &all),
        Vec::<String>::new(),
        "after SIGKILL"
    );

    let t = std::time::Instant::now();
    let out = compact_cmd(&big).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    eprintln!(
        "migration: the rest in {:.1} s: {}",
        t.elapsed().as_secs_f64(),
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .last()
            .unwrap_or("")
    );
    assert_eq!(compacted(&big), 100);
    assert_eq!(
        differ(&read_all(&big), &all),
        Vec::<String>::new(),
        "after the migration"
    );
    // No temporary file of compaction is left behind.
    for (_, dir) in footscan_daemon::archive::compact::scan_dirs(&big).unwrap() {
        for e in std::fs::read_dir(&dir).unwrap().flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            assert!(!n.starts_with('.'), "{} left in {}", n, dir.display());
        }
    }
    // A rerun changes nothing.
    let out = compact_cmd(&big).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("100 scans, 0 compacted, 0 failed"), "{text}");
    // And the daemon lists and serves them (the index rebuilt from the records).
    let a = footscan_daemon::archive::Archive::open(&big).unwrap();
    let list = a.list().unwrap();
    assert_eq!(list.len(), 100);
    for r in list.iter().take(5) {
        let arts = a.artifacts(r).unwrap();
        for art in arts {
            let p: PathBuf = a.artifact_path(r, &art.name).unwrap();
            let b = std::fs::read(&p).unwrap();
            assert_eq!(
                b,
                all[&(r.id.clone(), art.name.clone())],
                "{} {}",
                r.id,
                art.name
            );
        }
    }
}
