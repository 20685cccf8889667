//! Retention (`[archive] keep_raw_days`, `keep_days`, `max_gb`; docs/method.md 14h.2): old
//! scans go, raw data goes after its days, the archive is kept under max_gb oldest first, and
//! a scan in a visit, with a last, or not yet pushed to the fleet is kept and reported. No
//! real scan: generated records with files of known sizes.

mod daemon_support;

use daemon_support::{Footscand, Opts};
use footscan::compact;
use footscan_daemon::archive::retention::{now_secs, Rules};
use footscan_daemon::archive::{Archive, ScanId};
use std::path::Path;
use std::time::Duration;

/// A scan started `days_ago` days ago (`n` tells ids apart) with `bytes` of grid.bin (and a
/// small model.step, model.glb, points.ply, measurements.json).
fn scan(root: &Path, days_ago: f64, n: u16, subject: &str, bytes: usize) -> String {
    let t = jiff::Timestamp::from_second(now_secs() - (days_ago * 86400.0) as i64).unwrap();
    let id = format!("{}-{n:04x}", t.strftime("%Y%m%dT%H%M%SZ"));
    let dir = root.join(&id);
    std::fs::create_dir_all(&dir).unwrap();
    let rec = serde_json::json!({
        "id": id, "subject": subject, "side": "left", "notes": "",
        "status": "complete", "reason": null, "frames": 3, "points": 10,
        "started": t.to_string(), "finished": t.to_string(),
    });
    std::fs::write(
        dir.join("record.json"),
        serde_json::to_vec_pretty(&rec).unwrap(),
    )
    .unwrap();
    let noise: Vec<u8> = (0..bytes)
        .map(|i| ((i * 2654435761usize) >> 13) as u8)
        .collect();
    std::fs::write(dir.join("grid.bin"), &noise).unwrap();
    for f in ["model.step", "model.glb", "points.ply", "measurements.json"] {
        std::fs::write(dir.join(f), format!("{f} of {id}")).unwrap();
    }
    id
}

fn ids(v: &[impl AsRef<str>]) -> Vec<String> {
    let mut v: Vec<String> = v.iter().map(|s| s.as_ref().to_string()).collect();
    v.sort();
    v
}

#[test]
fn retention_drops_old_scans_keeps_protected_ones_and_honours_max_gb() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    std::fs::create_dir_all(&root).unwrap();
    let old = scan(&root, 400.0, 1, "p-old", 1000);
    let in_visit = scan(&root, 401.0, 2, "p-visit", 1000);
    let with_last = scan(&root, 402.0, 3, "p-last", 1000);
    let unpushed = scan(&root, 403.0, 4, "p-fleet", 1000);
    let with_insole = scan(&root, 404.0, 7, "p-insole", 1000);
    let raw_due = scan(&root, 40.0, 5, "p-raw", 1000);
    // A raw-due scan in compact form (no real grid here: its files are stored as gzip).
    let raw_compact = scan(&root, 41.0, 6, "p-rawc", 1000);
    compact::compact_dir(&root.join(&raw_compact), &Default::default()).unwrap();
    // Recent, large: max_gb drops the oldest of them until the scans fit.
    let big: Vec<String> = (0..4)
        .map(|k| scan(&root, 10.0 - k as f64, 10 + k, "p-big", 400_000))
        .collect();
    std::fs::create_dir_all(root.join(&with_last).join("last")).unwrap();
    std::fs::create_dir_all(root.join(&with_insole).join("insole")).unwrap();

    let a = Archive::open(&root).unwrap();
    let v = a.new_visit("p-visit", "").unwrap();
    a.add_visit_scan(
        &ScanId::parse(&v.id).unwrap(),
        &ScanId::parse(&in_visit).unwrap(),
        false,
    )
    .unwrap();
    a.outbox_enqueue(&unpushed).unwrap();

    // First the ages: keep_days and keep_raw_days.
    let rules = Rules {
        keep_raw_days: Some(30.0),
        keep_days: Some(365.0),
        max_gb: None,
        fleet: false,
    };
    let run = a.retain(&rules, now_secs());
    assert!(run.errors.is_empty(), "{:?}", run.errors);
    let dropped = |run: &footscan_daemon::archive::retention::RetentionRun, what: &str| {
        ids(&run
            .dropped
            .iter()
            .filter(|d| d.what == what)
            .map(|d| d.id.clone())
            .collect::<Vec<_>>())
    };
    assert_eq!(dropped(&run, "scan"), [old.as_str()]);
    assert_eq!(
        dropped(&run, "raw data"),
        ids(&[raw_due.clone(), raw_compact.clone()])
    );
    assert!(!root.join(&old).exists());
    // Kept, each saying why.
    let kept = |run: &footscan_daemon::archive::retention::RetentionRun, id: &str| -> Vec<String> {
        run.kept
            .iter()
            .filter(|k| k.id == id)
            .flat_map(|k| k.protected_by.clone())
            .collect()
    };
    assert_eq!(kept(&run, &in_visit), [format!("in visit {}", v.id)]);
    assert_eq!(kept(&run, &with_last), ["has a last"]);
    assert_eq!(kept(&run, &unpushed), ["not yet pushed to the fleet"]);
    assert_eq!(kept(&run, &with_insole), ["has an insole"]);
    for id in [&in_visit, &with_last, &unpushed, &with_insole] {
        assert!(root.join(id).join("grid.bin").is_file(), "{id} kept whole");
    }
    // Raw data gone, the rest served as before.
    for id in [&raw_due, &raw_compact] {
        let rec = a.get(&ScanId::parse(id).unwrap()).unwrap();
        let names: Vec<String> = a
            .artifacts(&rec)
            .unwrap()
            .into_iter()
            .map(|x| x.name)
            .collect();
        assert_eq!(
            names,
            [
                "measurements.json",
                "model.glb",
                "model.step",
                "record.json"
            ],
            "{id}"
        );
        for f in ["model.step", "model.glb"] {
            let p = a.artifact_path(&rec, f).unwrap();
            assert_eq!(std::fs::read(p).unwrap(), format!("{f} of {id}").as_bytes());
        }
    }
    // Listed no more.
    assert!(a.get(&ScanId::parse(&old).unwrap()).is_err());
    assert!(run.bytes_after < run.bytes_before);

    // Then max_gb: 1 MB holds the four protected scans and two of the four 0.4 MB ones;
    // the oldest unprotected scans go first (the two raw-less ones, then big 0 and 1).
    let rules = Rules {
        max_gb: Some(0.001),
        ..Default::default()
    };
    let run = a.retain(&rules, now_secs());
    assert!(run.errors.is_empty(), "{:?}", run.errors);
    assert_eq!(
        dropped(&run, "scan"),
        ids(&[
            raw_due.clone(),
            raw_compact.clone(),
            big[0].clone(),
            big[1].clone()
        ]),
        "{run:?}"
    );
    assert!(!run.over_max_gb && run.bytes_after <= 1_000_000, "{run:?}");
    assert_eq!(run.kept.len(), 4, "{:?}", run.kept);
    assert!(root.join(&big[2]).is_dir() && root.join(&big[3]).is_dir());
    // A second run drops nothing more and still reports the protected ones.
    let again = a.retain(&rules, now_secs());
    assert!(again.dropped.is_empty(), "{:?}", again.dropped);
    drop(a);

    // The daemon runs it at start and shows it on its status; bad values are refused with
    // the key and the range.
    let bad = daemon_support::command(
        tmp.path(),
        &Opts {
            daemon_extra: "\n[archive]\nkeep_days = 0.5\n",
            ..Default::default()
        },
    )
    .0
    .output()
    .unwrap();
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(
        !bad.status.success() && err.contains("[archive] keep_days = 0.5: must be 0"),
        "{err}"
    );
    let d = Footscand::start(
        tmp.path(),
        Opts {
            daemon_extra: "\n[archive]\nkeep_days = 365\nkeep_raw_days = 30\nmax_gb = 0.001\n",
            ..Default::default()
        },
    );
    let st = d.wait_json("/api/status", Duration::from_secs(30), |s| {
        s["archive"]["retention"].is_object()
    });
    let r = &st["archive"]["retention"];
    assert_eq!(r["rules"]["keep_days"], 365.0);
    assert_eq!(r["kept"].as_array().unwrap().len(), 4, "{r}");
    assert_eq!(r["kept_total"], 4, "{r}");
    assert!(!r["over_max_gb"].as_bool().unwrap(), "{r}");
    assert!(r["dropped"].as_array().unwrap().is_empty(), "{r}");
    assert!(d
        .stderr()
        .contains("kept against keep_days = 365: in visit"));

    // The dashboard's Retention line, as a browser shows it: visible, no problem badge, the
    // protected scans counted, each with what protects it in its tooltip.
    let dom = daemon_support::chromium::run(
        &format!("{}/", d.base),
        &tmp.path().join("profile"),
        (1280, 900),
        &["--virtual-time-budget=5000", "--dump-dom"],
        Duration::from_secs(120),
    );
    let dom = String::from_utf8(dom).unwrap();
    let at = dom
        .find("id=\"st-retention\"")
        .unwrap_or_else(|| panic!("no retention line in the page"));
    let tag_end = at + dom[at..].find('>').unwrap();
    assert!(
        !dom[at..tag_end].contains("hidden"),
        "retention line hidden: {}",
        &dom[at..tag_end]
    );
    let line = &dom[tag_end..tag_end + dom[tag_end..].find("</dd>").unwrap()];
    assert!(
        line.contains("4 protected scans kept against a rule")
            && line.contains("has an insole")
            && line.contains("0 scans and the raw data of 0 dropped"),
        "{line}"
    );
    assert!(!line.contains("over max_gb"), "{line}");
}
