//! `footscan last measure` on a real last (table, JSON, picture), and the size checks every
//! last command makes: a last read with the wrong units is refused by name with the size
//! found and the valid range, and `last join` refuses a pair more than a size group apart
//! unless told, writing nothing.

use footscan_geom::mesh::{Format, TriMesh, Units};
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

fn footscan() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footscan"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn lasts_dir() -> PathBuf {
    std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
        .join("lasts")
}

fn run(args: &[&std::ffi::OsStr]) -> (bool, String, String) {
    let o = footscan().args(args).output().unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn last_measure_prints_table_json_and_picture() {
    let dir = tempfile::tempdir().unwrap();
    let last = lasts_dir().join("LastScan_Default.stl");
    let png = dir.path().join("measure.png");
    let (ok, out, err) = run(&[
        "last".as_ref(),
        "measure".as_ref(),
        last.as_os_str(),
        "--picture".as_ref(),
        png.as_os_str(),
    ]);
    assert!(ok, "{err}");
    for s in [
        "left last",
        "stick length",
        "joint girth",
        "long heel girth",
        "MT1",
    ] {
        assert!(out.contains(s), "{s:?} not in {out}");
    }
    assert!(png.metadata().unwrap().len() > 10_000);
    let (ok, out, err) = run(&[
        "last".as_ref(),
        "measure".as_ref(),
        last.as_os_str(),
        "--json".as_ref(),
    ]);
    assert!(ok, "{err}");
    let v: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["side"], "left");
    let stick = v["stick_length"].as_f64().unwrap();
    assert!((stick - 238.69).abs() < 0.05, "{stick}");
    assert_eq!(v["girth_planes"].as_array().unwrap().len(), 6);
}

#[test]
fn last_commands_refuse_a_last_of_the_wrong_size() {
    let dir = tempfile::tempdir().unwrap();
    let (m, _) =
        TriMesh::load_solid(lasts_dir().join("LastScan_Default.stl"), Units::Auto, None).unwrap();
    // The same last in millimetres, and 25 % longer.
    let mm = dir.path().join("default_mm.stl");
    m.write(&mm, Format::StlBinary).unwrap();
    let mut big = m.clone();
    big.scale(1.25);
    let big_p = dir.path().join("default_125.stl");
    big.write(&big_p, Format::StlBinary).unwrap();
    // Read as metres it is a 245 m last.
    let (ok, _, err) = run(&[
        "last".as_ref(),
        "measure".as_ref(),
        mm.as_os_str(),
        "--units".as_ref(),
        "m".as_ref(),
    ]);
    assert!(!ok);
    assert!(
        err.contains("default_mm.stl") && err.contains("100-380") && err.contains("mm long"),
        "{err}"
    );
    let out = dir.path().join("joined");
    let (ok, _, err) = run(&[
        "last".as_ref(),
        "join".as_ref(),
        "--units".as_ref(),
        "m".as_ref(),
        "--back".as_ref(),
        mm.as_os_str(),
        "--toe".as_ref(),
        mm.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!ok);
    assert!(
        err.contains("default_mm.stl") && err.contains("100-380"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
    // A pair more than a size group apart.
    let (ok, _, err) = run(&[
        "last".as_ref(),
        "join".as_ref(),
        "--units".as_ref(),
        "mm".as_ref(),
        "--back".as_ref(),
        mm.as_os_str(),
        "--toe".as_ref(),
        big_p.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(!ok);
    assert!(
        err.contains("default_mm.stl")
            && err.contains("default_125.stl")
            && err.contains("--allow-size-mismatch"),
        "{err}"
    );
    assert!(!out.exists(), "nothing written");
    // Told to, it joins them.
    let (ok, out_text, err) = run(&[
        "last".as_ref(),
        "join".as_ref(),
        "--units".as_ref(),
        "mm".as_ref(),
        "--allow-size-mismatch".as_ref(),
        "--back".as_ref(),
        mm.as_os_str(),
        "--toe".as_ref(),
        big_p.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert!(ok, "{out_text}{err}");
    assert!(out.join("joined.stl").exists());
}
