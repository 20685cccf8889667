//! `footscan fleet` against a real PostgreSQL (started by this test): a whole-foot simulated
//! scan made by `footscan scan`, pushed as a daemon would (footscan_fleet::push), then
//! `footscan fleet migrate`, `list` with filters, `show`, and `fetch` into a directory whose
//! files are byte-identical to the scan's; `footscan last adjust` runs on the fetched scan.

use footscan_fleet::testing::{PgServer, PASSWORD};
use footscan_fleet::{LocalFile, ScanUpload};
use std::path::{Path, PathBuf};
use std::process::Command;

fn footscan() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footscan"));
    c.env(footscan_fleet::settings::PASSWORD_ENV, PASSWORD);
    c
}

fn run(c: &mut Command) -> String {
    let o = c.output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "{c:?}: {}\n{out}",
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

fn lasts_dir() -> PathBuf {
    std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
        .join("lasts")
}

fn upload(dir: &Path, scanner: &str, id: &str, subject: &str) -> ScanUpload {
    let mut files: Vec<LocalFile> = std::fs::read_dir(dir)
        .unwrap()
        .flatten()
        .filter(|e| e.path().is_file())
        .map(|e| LocalFile {
            name: e.file_name().to_string_lossy().into_owned(),
            path: e.path(),
            content_type: "application/octet-stream".into(),
        })
        .collect();
    files.sort_by(|a, b| a.name.cmp(&b.name));
    ScanUpload {
        scanner: scanner.into(),
        clinic: "north".into(),
        scan_id: id.into(),
        subject: subject.into(),
        side: "right".into(),
        notes: String::new(),
        status: "complete".into(),
        reason: None,
        started: "2026-11-24T10:00:00Z".into(),
        finished: Some("2026-11-24T10:00:30Z".into()),
        frames: 320,
        points: 1,
        record: serde_json::json!({"id": id}),
        files,
    }
}

#[test]
fn list_show_fetch_and_a_last_stage_on_the_fetched_scan() {
    let last = lasts_dir().join("Last_Flat_RoundTip.stl");
    assert!(
        last.is_file(),
        "{} missing (set FOOTSCAN_DATA)",
        last.display()
    );
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    // A whole foot at 1 mm a frame (measured, so the last stages can use it).
    let cfg =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml"))
            .unwrap()
            .lines()
            .map(|l| {
                let k = l.split('=').next().unwrap_or("").trim();
                match k {
                    "step_mm" if l.contains("advance") => "step_mm = 1.0".to_string(),
                    _ => l.to_string(),
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
    std::fs::write(t.join("sim.toml"), cfg).unwrap();
    let scan = t.join("scan");
    run(footscan()
        .args(["scan", "--quiet", "--config"])
        .arg(t.join("sim.toml"))
        .arg("--out")
        .arg(&scan));
    assert!(scan.join("grid.bin").is_file() && scan.join("measurements.json").is_file());

    let pg = PgServer::start();
    let url = pg.url();
    let out = run(footscan().args(["fleet", "--url", &url, "migrate"]));
    assert!(
        out.contains("now at schema version") && out.contains("compatible from"),
        "{out}"
    );
    let mut c = pg.fleet_client();
    let id = "20261124T100000Z-00aa";
    footscan_fleet::push(&mut c, &upload(&scan, "scanner-7", id, "alice")).unwrap();
    footscan_fleet::push(
        &mut c,
        &upload(&scan, "scanner-8", "20261124T110000Z-00bb", "bob"),
    )
    .unwrap();

    let out = run(footscan().args(["fleet", "--url", &url, "list"]));
    assert!(
        out.contains("2 scans") && out.contains("alice") && out.contains("bob"),
        "{out}"
    );
    let out = run(footscan().args([
        "fleet",
        "list",
        "--url",
        &url,
        "--subject",
        "alice",
        "--json",
    ]));
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v.as_array().unwrap().len(), 1);
    assert_eq!(v[0]["scanner"], "scanner-7");
    let out = run(footscan().args(["fleet", "list", "--url", &url, "--since", "2026-11-25"]));
    assert!(out.contains("0 scans"), "{out}");
    let out = run(footscan().args(["fleet", "show", "--url", &url, id]));
    assert!(
        out.contains("scanner-7") && out.contains("grid.bin") && out.contains("foot_length_mm"),
        "{out}"
    );

    // A daemon config's [fleet] section works as well as --url.
    let dcfg = t.join("footscand.toml");
    std::fs::write(
        &dcfg,
        format!("[daemon]\narchive = \"a\"\nscanner_config = \"s.toml\"\n\n[fleet]\nurl = {url:?}\nscanner = \"x\"\nclinic = \"y\"\n"),
    )
    .unwrap();
    let fetched = t.join("fetched");
    run(footscan()
        .args(["fleet", "fetch", "--config"])
        .arg(&dcfg)
        .arg(id)
        .arg("--out")
        .arg(&fetched));
    for e in std::fs::read_dir(&scan).unwrap().flatten() {
        let n = e.file_name();
        assert_eq!(
            std::fs::read(e.path()).unwrap(),
            std::fs::read(fetched.join(&n)).unwrap(),
            "{n:?}"
        );
    }
    // Errors name what is wrong.
    let o = footscan().args(["fleet", "list"]).output().unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("--url"));
    let o = footscan()
        .env(footscan_fleet::settings::PASSWORD_ENV, "wrong-pw-1234")
        .args(["fleet", "list", "--url", &url])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("password authentication failed"),
        "{err}"
    );
    assert!(!err.contains("wrong-pw-1234"), "{err}");

    // The last stage on the fetched scan.
    let adj = t.join("adjusted");
    let out = run(footscan()
        .args(["last", "adjust", "--scan"])
        .arg(&fetched)
        .arg("--last")
        .arg(&last)
        .args(["--length", "262", "--out"])
        .arg(&adj));
    println!("{out}");
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(adj.join("adjust.json")).unwrap()).unwrap();
    assert!(r["after"]["outline_rms_mm"].as_f64().unwrap() <= 0.3, "{r}");
}
