//! The scan archive on its own: atomic close, failed and cancelled scans kept with their
//! reason, interrupted scans recovered as failed, the index rebuilt from the directories.

use footscan_daemon::archive::{Archive, NewScan, ScanEnd, ScanId, Status, INTERRUPTED};

fn meta(subject: &str) -> NewScan {
    NewScan {
        subject: subject.into(),
        side: "left".into(),
        notes: "n".into(),
    }
}

fn outcome(status: Status, reason: Option<&str>) -> ScanEnd {
    ScanEnd {
        status,
        reason: reason.map(Into::into),
        frames: 12,
        points: 3400,
    }
}

#[test]
fn scans_close_atomically_and_the_index_rebuilds() {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().join("archive");
    let a = Archive::open(&root).unwrap();

    let s1 = a.begin(meta("alice")).unwrap();
    assert!(s1
        .dir
        .file_name()
        .unwrap()
        .to_string_lossy()
        .starts_with(".tmp-"));
    std::fs::write(s1.dir.join("points.ply"), b"ply\n").unwrap();
    let listed = a.list().unwrap();
    assert_eq!(listed.len(), 1);
    assert_eq!(
        listed[0].status,
        Status::Running,
        "a running scan is never complete"
    );
    let r1 = a.finish(s1, outcome(Status::Complete, None)).unwrap();
    assert!(root.join(&r1.id).join("record.json").is_file());
    assert!(!root.join(format!(".tmp-{}", r1.id)).exists());
    let arts = a.artifacts(&r1).unwrap();
    let names: Vec<_> = arts.iter().map(|x| x.name.as_str()).collect();
    assert_eq!(
        names,
        ["points.ply", "record.json"],
        "the reserve file is gone"
    );

    let s2 = a.begin(meta("bob")).unwrap();
    let r2 = a
        .finish(s2, outcome(Status::Failed, Some("camera unplugged")))
        .unwrap();
    let s3 = a.begin(meta("carol")).unwrap();
    let r3 = a
        .finish(s3, outcome(Status::Cancelled, Some("daemon shutting down")))
        .unwrap();
    assert_eq!(a.get(&ScanId::parse(&r2.id).unwrap()).unwrap(), r2);

    // A scan left running when the process dies.
    let s4 = a.begin(meta("dave")).unwrap();
    std::fs::write(s4.dir.join("truth.json"), b"{}").unwrap();
    let id4 = s4.record.id.clone();
    drop(s4);
    drop(a);

    let a = Archive::open(&root).unwrap();
    let list = a.list().unwrap();
    assert_eq!(list.len(), 4);
    let r4 = list.iter().find(|r| r.id == id4).unwrap();
    assert_eq!(r4.status, Status::Failed);
    assert_eq!(r4.reason.as_deref(), Some(INTERRUPTED));
    assert_eq!(r4.subject, "dave", "metadata comes from the index");
    assert!(root.join(&id4).join("truth.json").is_file(), "files kept");
    // Newest first: ids sort by time.
    let ids: Vec<_> = list.iter().map(|r| r.id.clone()).collect();
    let mut sorted = ids.clone();
    sorted.sort();
    sorted.reverse();
    assert_eq!(ids, sorted);
    for r in [&r1, &r2, &r3] {
        assert!(list.contains(r), "{} lost", r.id);
    }

    // Delete the index: rebuilding from the directories gives the same listing.
    drop(a);
    std::fs::remove_file(root.join("index.sqlite")).unwrap();
    let a = Archive::open(&root).unwrap();
    assert_eq!(a.list().unwrap(), list);
    assert_eq!(a.rebuild().unwrap(), 4);
    assert_eq!(a.list().unwrap(), list);
}

#[test]
fn artifact_names_cannot_leave_the_scan() {
    let tmp = tempfile::tempdir().unwrap();
    let a = Archive::open(tmp.path()).unwrap();
    std::fs::write(tmp.path().join("secret"), b"x").unwrap();
    let s = a.begin(meta("eve")).unwrap();
    std::fs::write(s.dir.join("scan.json"), b"{}").unwrap();
    let r = a.finish(s, outcome(Status::Complete, None)).unwrap();
    assert!(a.artifact_path(&r, "scan.json").is_some());
    for bad in [
        "../secret",
        "..",
        ".",
        "/etc/passwd",
        "index.sqlite",
        ".reserve",
        "a/b",
    ] {
        assert!(a.artifact_path(&r, bad).is_none(), "{bad}");
    }
    for bad in ["../etc", "%2e%2e", "..", ".tmp-x"] {
        assert!(ScanId::parse(bad).is_err());
    }
}
