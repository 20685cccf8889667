//! `footscan last choose` (docs/method.md 9.5) on a simulated scan: a collection of scaled,
//! mirrored and turned copies of a last made for the simulator's 250 mm foot, ranked; the
//! copy nearest the foot first, and the best one customized.

use footscan_geom::mesh::{Format, TriMesh, Units};
use footscan_geom::P3;
use std::path::Path;
use std::process::Command;

mod common;

fn footscan(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_footscan"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("footscan runs");
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into(),
        String::from_utf8_lossy(&o.stderr).into(),
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// A collection that mixes a last in metres with one in a modelling tool's units is ranked in
/// one run once its `lasts.toml` gives the second one's length; without the entry that last is
/// read at its file's scale and cannot be used; an entry naming no file is refused, naming it.
fn mixed_units_collection(last: &TriMesh, shop: &Path, args: &[&str]) {
    std::fs::create_dir(shop).unwrap();
    let mut metres = copy(last, 0.97, false, 0.0);
    metres.scale(1e-3);
    metres
        .write(shop.join("in_metres.stl"), Format::StlBinary)
        .unwrap();
    let model = copy(last, 1.00, false, 0.0);
    let longest = model.bbox().longest_extent();
    let mut model_units = model;
    model_units.scale(1.0 / 131.0);
    model_units
        .write(shop.join("model_units.stl"), Format::StlBinary)
        .unwrap();
    let dir_arg = |a: &[&str]| -> Vec<String> {
        let mut v: Vec<String> = a.iter().map(|s| s.to_string()).collect();
        let i = v.iter().position(|s| s == "--stock-dir").unwrap();
        v[i + 1] = s(shop).to_string();
        v.push("--json".into());
        v
    };
    let run = || {
        let a = dir_arg(args);
        footscan(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let rank = |out: &str| -> Vec<serde_json::Value> { serde_json::from_str(out).unwrap() };
    let eligible = |r: &[serde_json::Value], n: &str| {
        r.iter()
            .find(|c| c["name"].as_str().unwrap().ends_with(n))
            .unwrap_or_else(|| panic!("{n} not ranked: {r:?}"))["eligible"]
            .as_bool()
            .unwrap()
    };
    // Without lasts.toml the model-unit file (longest side 2 units) is not a last's size.
    let (ok, out, err) = run();
    assert!(ok, "{out}{err}");
    let r = rank(&out);
    assert!(eligible(&r, "in_metres.stl"), "{r:?}");
    assert!(!eligible(&r, "model_units.stl"), "{r:?}");
    let why = r
        .iter()
        .find(|c| c["name"].as_str().unwrap().ends_with("model_units.stl"))
        .unwrap()["cannot"][0]
        .to_string();
    assert!(
        why.contains("model units") && why.contains("length_mm") && why.contains("lasts.toml"),
        "{why}"
    );
    // With its length, both are ranked and the model-unit copy (the foot's own size) leads.
    std::fs::write(
        shop.join("lasts.toml"),
        format!("[\"model_units.stl\"]\nlength_mm = {longest:.3}\n"),
    )
    .unwrap();
    let (ok, out, err) = run();
    assert!(ok, "{out}{err}");
    let r = rank(&out);
    assert!(
        r[0]["name"].as_str().unwrap().ends_with("model_units.stl"),
        "{r:?}"
    );
    assert!(eligible(&r, "in_metres.stl"), "{r:?}");
    assert!(
        r[0]["largest_change_mm"].as_f64().unwrap() < 2.0,
        "{}",
        r[0]
    );
    // An entry for a file that is not there: refused, naming the file and the entry.
    std::fs::write(shop.join("lasts.toml"), "[\"gone.stl\"]\nunits = \"mm\"\n").unwrap();
    let (ok, out, err) = run();
    assert!(!ok, "{out}{err}");
    assert!(
        err.contains("lasts.toml") && err.contains("gone.stl"),
        "{err}"
    );
}

/// A copy of `m` scaled by `k` about the origin, mirrored in y if asked, turned about z.
fn copy(m: &TriMesh, k: f64, mirror: bool, turn_deg: f64) -> TriMesh {
    let mut c = m.clone();
    let (sn, cs) = turn_deg.to_radians().sin_cos();
    for p in &mut c.vertices {
        let y = if mirror { -p.y } else { p.y };
        let (x, y) = (k * p.x, k * y);
        *p = P3::new(cs * x - sn * y, sn * x + cs * y, k * p.z + 40.0);
    }
    if mirror {
        c.flip();
    }
    c
}

#[test]
fn ranking_puts_the_nearest_copy_first_and_customizes_it() {
    let dir = tempfile::tempdir().unwrap();
    let p = |n: &str| dir.path().join(n);
    // The simulator's 250 mm right foot: the package's shared default scan (tests/common).
    let scan = common::default_scan();
    let (ok, out, err) = footscan(&["sim", "foot", "--length", "250", "--out", s(&p("f250.stl"))]);
    assert!(ok, "{out}{err}");
    let (ok, out, err) = footscan(&[
        "last",
        "customize",
        "--foot",
        s(&p("f250.stl")),
        "--out",
        s(&p("made")),
    ]);
    assert!(ok, "{out}{err}");
    let (last, _) = TriMesh::load_solid(p("made").join("last.stl"), Units::Mm, None).unwrap();
    std::fs::create_dir(p("shop")).unwrap();
    for (name, k, mirror, turn) in [
        ("a_090", 0.90, false, 0.0),
        ("b_094", 0.94, true, 35.0),
        ("c_097", 0.97, false, 200.0),
        ("d_100", 1.00, false, 90.0),
        ("e_103", 1.03, true, 0.0),
        ("f_106", 1.06, false, 300.0),
        ("g_080", 0.80, false, 10.0),
    ] {
        copy(&last, k, mirror, turn)
            .write(p("shop").join(format!("{name}.stl")), Format::StlBinary)
            .unwrap();
    }
    std::fs::write(
        p("girths.toml"),
        "ball = 260.0\ninstep = 247.6\nlong_heel = 367.3\nankle = 196.4\n",
    )
    .unwrap();
    let (girths, shop) = (p("girths.toml"), p("shop"));
    let args = [
        "last",
        "choose",
        "--scan",
        s(scan),
        "--girths",
        s(&girths),
        "--stock-dir",
        s(&shop),
    ];
    let (ok, out, err) = footscan(&[&args[..], &["--json"]].concat());
    assert!(ok, "{out}{err}");
    let rank: serde_json::Value = serde_json::from_str(&out).unwrap();
    let rank = rank.as_array().unwrap();
    let names: Vec<&str> = rank.iter().map(|c| c["name"].as_str().unwrap()).collect();
    println!("{names:?}");
    assert!(names[0].ends_with("d_100.stl"), "{names:?}");
    assert!(
        rank[0]["largest_change_mm"].as_f64().unwrap() < 2.0,
        "{}",
        rank[0]
    );
    // The mirrored copies are said to be; the 0.80 copy is more than a size group short.
    for c in rank {
        let n = c["name"].as_str().unwrap();
        let mirrored = c["mirrored"].as_bool().unwrap();
        assert_eq!(mirrored, n.contains("b_094") || n.contains("e_103"), "{c}");
    }
    let last_one = rank.last().unwrap();
    assert!(last_one["name"].as_str().unwrap().ends_with("g_080.stl"));
    assert!(!last_one["eligible"].as_bool().unwrap());
    assert!(
        last_one["cannot"][0]
            .as_str()
            .unwrap()
            .contains("more than a size group")
            || last_one["cannot"]
                .as_array()
                .unwrap()
                .iter()
                .any(|c| c.as_str().unwrap().contains("more than a size group")),
        "{last_one}"
    );
    // The largest change grows with the distance from the nearest copy.
    let ch = |n: &str| {
        rank.iter()
            .find(|c| c["name"].as_str().unwrap().ends_with(n))
            .unwrap()["largest_change_mm"]
            .as_f64()
            .unwrap()
    };
    assert!(ch("d_100.stl") < ch("c_097.stl") && ch("c_097.stl") < ch("b_094.stl"));
    assert!(ch("b_094.stl") < ch("a_090.stl") && ch("e_103.stl") < ch("f_106.stl"));
    // Customized into --out by the clinic path.
    let (ok, out, err) = footscan(&[&args[..], &["--out", s(&p("chosen"))]].concat());
    assert!(ok, "{out}{err}");
    assert!(
        err.contains("customized") && err.contains("d_100.stl"),
        "{err}"
    );
    assert!(p("chosen").join("last.stl").exists() && p("chosen").join("report.json").exists());
    mixed_units_collection(&last, &p("mixed"), &args);
    // A shop of lasts all too short: nothing to customize, non-zero, nothing written.
    std::fs::remove_dir_all(p("shop")).unwrap();
    std::fs::create_dir(p("shop")).unwrap();
    copy(&last, 0.8, false, 0.0)
        .write(p("shop").join("short.stl"), Format::StlBinary)
        .unwrap();
    let (ok, out, err) = footscan(&[&args[..], &["--out", s(&p("none"))]].concat());
    assert!(!ok && err.contains("no last of"), "{out}{err}");
    assert!(!p("none").exists());
}
