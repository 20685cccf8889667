//! The side check (docs/method.md section 3.3) on real foot meshes rendered by the simulator
//! (issue 18's target: "catches a mislabelled foot ... on the real foot meshes in
//! ../shared/data/feet"). Each mesh is scanned as the foot it is and mirrored (y -> -y) as the
//! other foot, every scan labelled with the wrong side: the side the scan shows must be the
//! mesh's, the run must end "side mismatch" naming both sides, and the same scan judged with
//! the right label must have no side issue. The five simulated foot shapes x 2 sides are in
//! tests/scan_quality.rs.
//!
//! The meshes (their SOURCE.txt files say units, axes and side): the FIND/FOCUS template (a
//! remeshed 3-D scan of a real left foot, non-weight-bearing, 88,786 triangles, mm), the FIND
//! demo's low-resolution foot (left, metres, 1,750 triangles), and MakeHuman's modelled right
//! foot (mm; an artist's mesh, not a scan). All have +x from heel to toe and +z up.

use footscan::measure::Side;
use footscan::scan::quality::judge;
use footscan::scan::{run_scan, LoadedConfig, ScanOptions, ScanStatus};
use footscan_geom::mesh::{Format, TriMesh, Units};
use footscan_geom::{P3, V3};
use footscan_last::customize::measure::support_pitch;
use nalgebra::Isometry3;
use std::path::{Path, PathBuf};

fn data() -> PathBuf {
    std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"))
}

/// (file under feet/, the side the mesh is).
const FEET: [(&str, Side); 3] = [
    ("find_template/template_mm.stl", Side::Left),
    ("find_lowres/find_demo_template.obj", Side::Left),
    (
        "makehuman/makehuman_default_right_foot_cut150mm.stl",
        Side::Right,
    ),
];

fn other(s: Side) -> Side {
    match s {
        Side::Left => Side::Right,
        Side::Right => Side::Left,
    }
}

fn name(s: Side) -> &'static str {
    match s {
        Side::Left => "left",
        Side::Right => "right",
    }
}

/// config/sim.toml with the mesh at `stl` (mm) on the glass, scanned in 2 mm steps (the side
/// check needs the outline, not every row).
fn config(stl: &Path) -> LoadedConfig {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let edited = text
        .replace("scene = \"foot\"", "scene = \"mesh\"")
        .replace("step_mm = 0.5 ", "step_mm = 2.0 ")
        .replace("max_rate_mm_min = 3000.0", "max_rate_mm_min = 6000.0")
        .replace("accel_mm_s2 = 500.0", "accel_mm_s2 = 2000.0")
        + &format!("\n[sim.mesh]\npath = {:?}\nunits = \"mm\"\n", stl);
    assert!(edited.contains("scene = \"mesh\"") && edited.contains("step_mm = 2.0 "));
    LoadedConfig::parse(&path, edited).unwrap()
}

#[test]
fn the_side_is_checked_on_real_feet() {
    let feet = data().join("feet");
    assert!(
        feet.is_dir(),
        "real foot meshes not found at {} (set FOOTSCAN_DATA to the shared data directory)",
        feet.display()
    );
    let tmp = tempfile::tempdir().unwrap();
    let mut wrong = Vec::new();
    for (k, (file, side)) in FEET.iter().enumerate() {
        let (mut mesh, report) = TriMesh::load_solid(feet.join(file), Units::Auto, None).unwrap();
        // Stood on the line it would rest on (docs/method.md 10.1): a scanned patient stands,
        // the FIND feet hang (heel and forefoot down, toes 20 mm up; the low-resolution one
        // on its forefoot, heel 15 mm up).
        let (slope, _) = support_pitch(&mesh);
        mesh.transform(&Isometry3::rotation(V3::y() * slope.atan()));
        let (after, _) = support_pitch(&mesh);
        println!(
            "{file}: {}; stood: pitched {:.2} deg (support slope {slope:.4} -> {after:.1e})",
            report.describe(),
            slope.atan().to_degrees()
        );
        assert!(after.abs() < 1e-9, "{file}: still pitched {after}");
        let mut mirrored = mesh.clone();
        mirrored.scale_about(&P3::origin(), &V3::new(1.0, -1.0, 1.0));
        for (m, truth, what) in [
            (&mesh, *side, "as is"),
            (&mirrored, other(*side), "mirrored"),
        ] {
            let stl = tmp.path().join(format!("foot{k}-{}.stl", name(truth)));
            m.write(&stl, Format::StlBinary).unwrap();
            let cfg = config(&stl);
            let dir = match std::env::var_os("FOOTSCAN_KEEP_SCANS") {
                Some(keep) => PathBuf::from(keep).join(format!("scan{k}-{}", name(truth))),
                None => tmp.path().join(format!("scan{k}-{}", name(truth))),
            };
            let mut opts = ScanOptions::new(&dir);
            let chosen = other(truth);
            opts.side = Some(chosen);
            let s = run_scan(&cfg, &opts, |_| {}).expect("scan runs");
            let mut q = s.quality.clone().expect("a judged scan");
            let detected = q.side.as_ref().map(|c| c.detected.clone());
            let m: serde_json::Value = std::fs::read(dir.join("measurements.json"))
                .ok()
                .and_then(|b| serde_json::from_slice(&b).ok())
                .unwrap_or_default();
            println!(
                "{file} {what} ({} foot): scan looks {detected:?}; {}; length {:.1} mm, ball \
                 width {:.1} mm, {} toe pads",
                name(truth),
                s.verdict(),
                m["foot_length_mm"].as_f64().unwrap_or(f64::NAN),
                m["ball_width_mm"].as_f64().unwrap_or(f64::NAN),
                m["toe_outlines"].as_array().map_or(0, Vec::len),
            );
            if detected.as_deref() != Some(name(truth)) {
                wrong.push(format!(
                    "{file} {what}: {} foot looks {detected:?}",
                    name(truth)
                ));
                continue;
            }
            let reason = s.reason.clone().unwrap_or_default();
            let said = format!(
                "side mismatch: chose {}, scan looks {}",
                name(chosen),
                name(truth)
            );
            assert!(reason.contains(&said), "{file} {what}: {}", s.verdict());
            assert_eq!(s.status, ScanStatus::SideMismatch, "{}", s.verdict());
            // The same scan with the right label: no side issue, nor any other than the
            // measurements' own doubts (a relaxed foot's arch, joined toes), said as warnings.
            q.side.as_mut().unwrap().chosen = Some(name(truth).into());
            let (status, reason) = judge(&mut q, &cfg.config.quality, s.frames, true);
            let expected = if q.measure_warnings.is_empty() {
                ScanStatus::Complete
            } else {
                ScanStatus::CompleteWithWarnings
            };
            assert_eq!(status, expected, "{file} {what}: {reason:?}");
            let reason = reason.unwrap_or_default();
            assert!(
                reason.is_empty() || reason.starts_with("measurements to check: "),
                "{file} {what}: {reason}"
            );
        }
    }
    assert!(wrong.is_empty(), "sides decided wrongly: {wrong:?}");
}
