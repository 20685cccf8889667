//! `footscan last join` as a last maker runs it: lasts of different sizes and a turned copy
//! join with the planes the landmarks give; a toe last of the other side is refused with an
//! error naming both files and the option, the command exits non-zero and --out is not
//! created. The lasts are read at test time (FOOTSCAN_DATA, else ../shared/data).

use footscan_geom::mesh::{Format, TriMesh, Units};
use footscan_geom::{P3, V3};
use std::path::{Path, PathBuf};
use std::process::Command;

fn lasts() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    let dir = base.join("lasts");
    assert!(dir.is_dir(), "no lasts at {}", dir.display());
    dir
}

fn join(back: &Path, toe: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_footscan"))
        .args(["last", "join", "--back"])
        .arg(back)
        .arg("--toe")
        .arg(toe)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

#[test]
fn join_places_by_landmarks_and_refuses_the_other_side() {
    let tmp = tempfile::tempdir().unwrap();
    let default = lasts().join("LastScan_Default.stl");
    let warped = lasts().join("LastScan_Warped.stl");
    let read = |p: &Path| TriMesh::load_solid(p, Units::Auto, None).unwrap().0;
    // The back last 12 % longer, written heel to toe along +y as OBJ.
    let mut big = read(&default);
    big.scale(1.12);
    let r = nalgebra::Rotation3::from_axis_angle(&V3::z_axis(), std::f64::consts::FRAC_PI_2);
    big.transform(&nalgebra::Isometry3::from_parts(
        nalgebra::Translation3::new(10.0, 20.0, 0.0),
        r.into(),
    ));
    let big_path = tmp.path().join("big_along_y.obj");
    big.write(&big_path, Format::Obj).unwrap();
    let out = tmp.path().join("joined");
    let o = join(&big_path, &warped, &out, &[]);
    let text = String::from_utf8_lossy(&o.stdout);
    println!("{text}");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(text.contains("placed: back last left"), "{text}");
    for f in ["joined.stl", "joined.step", "joined.igs", "seams.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let seams: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("seams.json")).unwrap()).unwrap();
    println!("{seams}");
    // No temporary sibling is left beside --out.
    let left: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(left.is_empty(), "{left:?}");

    // A right toe on a left back: refused, nothing written; --mirror-toe joins them.
    let mut right = read(&warped);
    right.scale_about(&P3::origin(), &V3::new(1.0, -1.0, 1.0));
    let right_path = tmp.path().join("right_warped.ply");
    right.write(&right_path, Format::PlyBinary).unwrap();
    let out = tmp.path().join("sides");
    let o = join(&default, &right_path, &out, &[]);
    let err = String::from_utf8_lossy(&o.stderr);
    println!("{err}");
    assert!(!o.status.success());
    assert!(
        err.contains("right_warped.ply")
            && err.contains("LastScan_Default.stl")
            && err.contains("--mirror-toe"),
        "{err}"
    );
    assert!(!out.exists(), "{} written", out.display());
    let o = join(&default, &right_path, &out, &["--mirror-toe"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.join("joined.stl").is_file());
}
