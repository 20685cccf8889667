//! The fleet database against a real PostgreSQL started by this test (initdb + pg_ctl on a
//! free loopback port): migrations from empty and from an older version, a refusal naming
//! both versions for a newer incompatible schema, a push repeated (nothing duplicated), a
//! corrupted blob refused by the database, the same scan with other files refused as a
//! conflict, list filters, show, fetch (byte-identical, all or nothing), a wrong password.

use footscan_fleet::testing::{PgServer, PASSWORD};
use footscan_fleet::*;
use std::path::Path;

fn settings(pg: &PgServer, password: &str) -> Settings {
    let mut s = Settings::from_url(&pg.url(), Tls::Disable, Some(password.into())).unwrap();
    s.scanner = "scanner-a".into();
    s.clinic = "north".into();
    s
}

/// A scan directory with a few files of distinct content (and one shared by every scan).
fn scan_dir(root: &Path, id: &str, salt: u8) -> ScanUpload {
    let dir = root.join(id);
    std::fs::create_dir_all(&dir).unwrap();
    let big: Vec<u8> = (0..300_000u32).map(|i| (i as u8) ^ salt).collect();
    std::fs::write(dir.join("grid.bin"), &big).unwrap();
    std::fs::write(dir.join("calibration.toml"), "method = \"sim\"\n").unwrap();
    std::fs::write(
        dir.join("measurements.json"),
        format!("{{\"length_mm\": {}}}", 250 + salt as u32),
    )
    .unwrap();
    std::fs::write(dir.join("scan.json"), "{\"status\": \"complete\"}").unwrap();
    let files = [
        "grid.bin",
        "calibration.toml",
        "measurements.json",
        "scan.json",
    ]
    .iter()
    .map(|n| LocalFile {
        name: n.to_string(),
        path: dir.join(n),
        content_type: "application/octet-stream".into(),
    })
    .collect();
    ScanUpload {
        scanner: "scanner-a".into(),
        clinic: "north".into(),
        scan_id: id.into(),
        subject: format!("p{salt}"),
        side: "right".into(),
        notes: String::new(),
        status: "complete".into(),
        reason: None,
        started: format!("2026-11-2{}T10:00:00Z", salt % 10),
        finished: Some(format!("2026-11-2{}T10:00:05Z", salt % 10)),
        frames: 140,
        points: 1000,
        record: serde_json::json!({"id": id}),
        files,
    }
}

fn count(c: &mut postgres::Client, sql: &str) -> i64 {
    c.query_one(sql, &[]).unwrap().get(0)
}

#[test]
fn migrate_push_list_show_fetch_against_a_real_server() {
    let pg = PgServer::start();
    let s = settings(&pg, PASSWORD);
    let mut c = connect(&s).unwrap();

    // An older schema first (version 1), then brought up to date.
    let st = migrate(&mut c, Some(1)).unwrap();
    assert_eq!((st.version, st.applied.clone()), (1, vec![1]));
    let st = migrate(&mut c, None).unwrap();
    assert_eq!((st.version, st.applied.clone()), (SCHEMA_VERSION, vec![2]));
    assert_eq!(migrate(&mut c, None).unwrap().applied, Vec::<i32>::new());
    let h = migrate::history(&mut c).unwrap();
    assert_eq!(h.iter().map(|x| x.0).collect::<Vec<_>>(), vec![1, 2]);

    // Push, then push again: one scan, each blob once.
    let tmp = tempdir();
    let a = scan_dir(&tmp, "20261121T100000Z-0001", 1);
    let o = push(&mut c, &a).unwrap();
    assert!(o.inserted && o.blobs_sent == 4 && o.files == 4, "{o:?}");
    let o = push(&mut c, &a).unwrap();
    assert!(!o.inserted && o.blobs_sent == 0, "{o:?}");
    // A second scan shares calibration.toml and scan.json: only its own blobs are sent.
    let b = scan_dir(&tmp, "20261122T100000Z-0002", 2);
    let o = push(&mut c, &b).unwrap();
    assert!(o.inserted && o.blobs_sent == 2, "{o:?}");
    assert_eq!(count(&mut c, "SELECT count(*) FROM fleet_scans"), 2);
    assert_eq!(count(&mut c, "SELECT count(*) FROM fleet_blobs"), 6);
    assert_eq!(count(&mut c, "SELECT count(*) FROM fleet_artifacts"), 8);

    // The database refuses a blob whose bytes are not the ones its key names.
    let e = c
        .execute(
            "INSERT INTO fleet_blobs (sha256, bytes, content) VALUES ($1, 3, $2)",
            &[&sha256_hex(b"abc"), &&b"abd"[..]],
        )
        .unwrap_err();
    assert!(
        e.to_string().contains("fleet_blobs_content_hash")
            || format!("{e:?}").contains("fleet_blobs_content_hash"),
        "{e:?}"
    );

    // The same scan id from the same scanner name with other files: a conflict, not stored.
    std::fs::write(tmp.join("20261121T100000Z-0001/grid.bin"), b"changed").unwrap();
    let e = push(&mut c, &a).unwrap_err();
    assert!(matches!(e, FleetError::Conflict { .. }), "{e}");
    assert!(e.to_string().contains("grid.bin"), "{e}");
    assert_eq!(count(&mut c, "SELECT count(*) FROM fleet_scans"), 2);

    // List filters.
    let all = list(&mut c, &Filter::default()).unwrap();
    assert_eq!(all.len(), 2);
    assert_eq!(all[0].scan_id, "20261121T100000Z-0001");
    assert_eq!(all[0].files, 4);
    let f = |f: Filter| list(&mut connect(&s).unwrap(), &f).unwrap().len();
    assert_eq!(
        f(Filter {
            subject: Some("p2".into()),
            ..Filter::default()
        }),
        1
    );
    assert_eq!(
        f(Filter {
            clinic: Some("south".into()),
            ..Filter::default()
        }),
        0
    );
    assert_eq!(
        f(Filter {
            since: Some("2026-11-22".into()),
            ..Filter::default()
        }),
        1
    );
    assert_eq!(
        f(Filter {
            until: Some("2026-11-22".into()),
            ..Filter::default()
        }),
        1
    );
    assert_eq!(
        f(Filter {
            status: Some("complete".into()),
            scanner: Some("scanner-a".into()),
            ..Filter::default()
        }),
        2
    );

    // Show and fetch: the bytes of the second scan, byte for byte.
    let d = show(&mut c, None, "20261122T100000Z-0002").unwrap();
    assert_eq!(d.files_list.len(), 4);
    assert_eq!(d.measurements.as_ref().unwrap()["length_mm"], 252);
    assert_eq!(d.calibration.as_deref(), Some("method = \"sim\"\n"));
    let out = tmp.join("fetched");
    let files = fetch(&mut c, None, "20261122T100000Z-0002", &out).unwrap();
    assert_eq!(files.len(), 4);
    for n in [
        "grid.bin",
        "calibration.toml",
        "measurements.json",
        "scan.json",
    ] {
        assert_eq!(
            std::fs::read(out.join(n)).unwrap(),
            std::fs::read(tmp.join("20261122T100000Z-0002").join(n)).unwrap(),
            "{n}"
        );
    }
    let e = fetch(&mut c, None, "20261122T100000Z-0002", &out).unwrap_err();
    // The cause (the file system's words) is the error's source.
    let shown = format!(
        "{e}: {}",
        std::error::Error::source(&e).map_or(String::new(), |s| s.to_string())
    );
    assert!(shown.contains("already exists"), "{shown}");
    let e = fetch(&mut c, None, "20261123T100000Z-0009", &tmp.join("none")).unwrap_err();
    assert!(e.to_string().contains("not in the fleet database"), "{e}");
    assert!(!tmp.join("none").exists());

    // A database newer than this program: compatible (additive) works, incompatible refuses
    // naming both versions.
    c.execute(
        "INSERT INTO fleet_migrations (version, name, compatible_from, software) VALUES (7, 'future additive', 1, '9.0.0')",
        &[],
    )
    .unwrap();
    let st = migrate(&mut c, None).unwrap();
    assert!(st.newer_compatible && st.version == 7, "{st:?}");
    c.execute(
        "INSERT INTO fleet_migrations (version, name, compatible_from, software) VALUES (8, 'future breaking', 8, '9.1.0')",
        &[],
    )
    .unwrap();
    let e = migrate(&mut c, None).unwrap_err().to_string();
    println!("{e}");
    assert!(
        e.contains("schema version 8")
            && e.contains("9.1.0")
            && e.contains(&format!("up to {SCHEMA_VERSION}")),
        "{e}"
    );

    // A wrong password: refused by the server, the message names the target and not the password.
    let bad = settings(&pg, "not-the-password-42");
    let e = connect(&bad)
        .err()
        .expect("a wrong password is refused")
        .to_string();
    println!("{e}");
    assert!(
        e.contains("password authentication failed") && e.contains("127.0.0.1"),
        "{e}"
    );
    assert!(
        !e.contains("not-the-password-42") && !e.contains(PASSWORD),
        "{e}"
    );
    let _ = std::fs::remove_dir_all(&tmp);
}

fn tempdir() -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("fleet-db-test-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}
