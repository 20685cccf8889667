//! The real shoe lasts: loading, validation, units, sections. The data directory is read at
//! test time (FOOTSCAN_DATA, default: the shared data directory beside the repository); a
//! missing directory fails the test.

use footscan_geom::mesh::{Bvh, Format, MeshError, TriMesh, Units, UnitsDecision};
use footscan_geom::plane::Plane;
use footscan_geom::V3;
use std::path::PathBuf;

fn lasts_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let dir = base.join("lasts");
    assert!(
        dir.is_dir(),
        "the real lasts are not at {} (set FOOTSCAN_DATA to the directory holding lasts/)",
        dir.display()
    );
    dir
}

const LASTS: [&str; 4] = [
    "LastScan_Default.stl",
    "LastScan_Warped.stl",
    "Last_Flat_RoundTip.stl",
    "Last_Heeled_RoundTip.stl",
];

#[test]
fn all_lasts_load_closed_and_units_are_detected() {
    let dir = lasts_dir();
    for name in LASTS {
        let path = dir.join(name);
        let m = TriMesh::read(&path).unwrap();
        let r = m.validate(&path).unwrap();
        assert_eq!(r.components, 1, "{name}");
        let size = r.bbox.extent();
        let auto = TriMesh::load_solid(&path, Units::Auto, None);
        if name.starts_with("LastScan") {
            // Metres: detected, and refused as millimetres with the fix named.
            let (mm, rep) = auto.unwrap();
            assert_eq!(rep.decision, UnitsDecision::Metres { detected: true });
            let len = mm.bbox().longest_extent();
            assert!((200.0..330.0).contains(&len), "{name}: {len} mm long");
            let e = TriMesh::load_solid(&path, Units::Mm, None).unwrap_err();
            assert!(matches!(e, MeshError::MetresAsMm { .. }));
            let msg = e.to_string();
            assert!(msg.contains(name) && msg.contains("--units m"), "{msg}");
            println!("{name}: {}", rep.describe());
        } else {
            // Unscaled model units: a length is needed.
            let e = auto.unwrap_err();
            assert!(matches!(e, MeshError::Unscaled { .. }), "{e}");
            assert!(e.to_string().contains("--length"), "{e}");
            let (mm, rep) = TriMesh::load_solid(&path, Units::Auto, Some(270.0)).unwrap();
            assert!((mm.bbox().longest_extent() - 270.0).abs() < 1e-9);
            assert!(rep.mesh.volume > 0.0);
            println!("{name}: {}", rep.describe());
        }
        assert!(size.max() > 0.0);
    }
}

#[test]
fn hundred_sections_of_the_default_last_are_closed_loops() {
    let path = lasts_dir().join("LastScan_Default.stl");
    let (m, _) = TriMesh::load_solid(&path, Units::Auto, None).unwrap();
    let b = m.bbox();
    let axis = b.longest_axis();
    let (lo, hi) = (b.min[axis], b.max[axis]);
    let e = b.extent();
    let across = 2.0 * (e.sum() - e[axis]);
    let mut perims = Vec::new();
    for k in 0..100 {
        let at = lo + (hi - lo) * (k as f64 + 0.5) / 100.0;
        let plane = Plane::axis_aligned(axis, at);
        let loops = m.section(&plane);
        assert!(!loops.is_empty(), "no section at {at}");
        let mut total = 0.0;
        for l in &loops {
            assert!(l.closed, "open section at {at}");
            assert!(l.max_plane_distance(&plane) < 1e-9);
            total += l.length();
        }
        assert!(
            loops
                .iter()
                .map(|l| l.to_polygon(&plane).signed_area())
                .sum::<f64>()
                > 0.0,
            "section at {at} is not counterclockwise about the plane normal"
        );
        // A girth is positive and below the perimeter of the box's cross-section.
        assert!(total > 1.0 && total < across, "girth {total} mm at {at}");
        perims.push(total);
    }
    let max = perims.iter().cloned().fold(0.0, f64::max);
    // The largest girth of an adult last is some 200 to 300 mm.
    assert!((150.0..400.0).contains(&max), "largest girth {max} mm");
    println!(
        "girths: min {:.1} max {max:.1} mm, mid {:.1} mm",
        perims.iter().cloned().fold(f64::INFINITY, f64::min),
        perims[50]
    );
}

#[test]
fn written_last_reads_back_and_passes_the_independent_checker() {
    let path = lasts_dir().join("LastScan_Default.stl");
    let (m, _) = TriMesh::load_solid(&path, Units::Auto, None).unwrap();
    let dir = std::env::temp_dir().join(format!("footscan-geom-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut written = Vec::new();
    for (f, ext) in [
        (Format::StlBinary, "stl"),
        (Format::PlyBinary, "ply"),
        (Format::Obj, "obj"),
    ] {
        let out = dir.join(format!("last.{ext}"));
        m.write(&out, f).unwrap();
        let back = TriMesh::read(&out).unwrap();
        let r = back.validate(&out).unwrap();
        assert!((r.volume - m.volume()).abs() < 1e-6 * r.volume);
        written.push(out);
    }
    // An open copy for the checker to refuse.
    let mut open = m.clone();
    open.triangles.pop();
    let open_path = dir.join("open.stl");
    open.write(&open_path, Format::StlBinary).unwrap();
    let e = TriMesh::read(&open_path)
        .unwrap()
        .validate(&open_path)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("open.stl") && e.contains("not closed: edge"),
        "{e}"
    );

    // The independent numpy checker, with the test venv's interpreter (scripts/setup.sh makes
    // it; FOOTSCAN_PYTHON overrides).
    let checker =
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/tools/mesh_check.py");
    let venv = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/venv-occt/bin/python");
    let py =
        std::env::var("FOOTSCAN_PYTHON").unwrap_or_else(|_| venv.to_string_lossy().into_owned());
    let has_numpy = std::process::Command::new(&py)
        .args(["-c", "import numpy"])
        .status()
        .is_ok_and(|s| s.success());
    assert!(
        has_numpy,
        "no python with numpy at {py}: run scripts/setup.sh (it makes target/venv-occt) or set FOOTSCAN_PYTHON"
    );
    if checker.is_file() {
        let run = |p: &PathBuf| {
            std::process::Command::new(&py)
                .arg(&checker)
                .arg(p)
                .output()
                .unwrap()
        };
        let ok = run(&written[0]);
        let line = String::from_utf8_lossy(&ok.stdout);
        println!("mesh_check.py last.stl: {line}");
        assert!(ok.status.success() && line.contains(": closed"), "{line}");
        let v: f64 = line
            .split("volume ")
            .nth(1)
            .unwrap()
            .split(',')
            .next()
            .unwrap()
            .parse()
            .unwrap();
        assert!(
            (v - m.volume()).abs() < 1e-3 * v,
            "checker volume {v} vs {}",
            m.volume()
        );
        let bad = run(&open_path);
        assert!(
            !bad.status.success(),
            "{}",
            String::from_utf8_lossy(&bad.stdout)
        );
    } else {
        eprintln!(
            "NOTE: mesh_check.py cross-check not run: {} is missing",
            checker.display()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    // The tree answers on the real last too.
    let bvh = Bvh::new(&m);
    let c = m.bbox().center();
    assert!(
        bvh.signed_distance(&(c + V3::new(0.0, 0.0, 1e4)))
            .unwrap()
            .distance
            > 0.0
    );
}
