//! Mesh scenes: parametric lasts and the real lasts in the shared data, rendered with exact
//! per-row truth, checked against footscan-geom's own BVH (an independent ray caster and
//! closest-point query).

use footscan_geom::mesh::{Bvh, TriMesh};
use footscan_geom::{P3, V3};
use footscan_sim::last::{Last, LastParams, Toe};
use footscan_sim::mesh_scene::{MeshSceneConfig, MeshSurface, Placement};
use footscan_sim::optics::Optics;
use footscan_sim::render::{FrameTruth, NoiseConfig, Renderer, RowTruth, Scene};
use std::path::PathBuf;
use std::sync::Arc;

fn lines(t: &FrameTruth) -> Vec<(usize, f64, [f64; 3])> {
    t.rows
        .iter()
        .enumerate()
        .filter_map(|(r, rt)| match rt {
            RowTruth::Line { col, point } => Some((r, *col, *point)),
            RowTruth::NoLine => None,
        })
        .collect()
}

/// The real-data directory: FOOTSCAN_DATA, else ../../shared/data from this crate.
fn lasts_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data"));
    let dir = base.join("lasts");
    assert!(
        dir.is_dir(),
        "real lasts not found at {} (set FOOTSCAN_DATA to the shared data directory holding lasts/)",
        dir.display()
    );
    dir
}

/// Renders frames across the mesh and checks every truth point: on the laser plane, on the
/// mesh, the first surface met along the laser's line from below, projected where the truth
/// says; and that the lit rows are those of the bottom's extent at that x. Returns the number
/// of points checked.
fn check_scene(mesh: &TriMesh, surface: MeshSurface, frames: usize) -> usize {
    let optics = Optics::default();
    let proj = optics.projector();
    let r = Renderer::new(
        optics.clone(),
        NoiseConfig::noise_free(),
        Scene::Surface(Arc::new(surface)),
        1,
    )
    .unwrap();
    let bvh = Bvh::new(mesh);
    let bb = mesh.bbox();
    let dir = V3::new(proj.tan_b, 0.0, 1.0);
    let mut checked = 0;
    for f in 0..frames {
        // Laser x from 3 % to 97 % of the length.
        let xw = bb.min.x + (bb.max.x - bb.min.x) * (0.03 + 0.94 * f as f64 / (frames - 1) as f64);
        let slider = xw - optics.l_mm;
        let t = r.truth(slider);
        let ls = lines(&t);
        assert!(
            ls.len() > 50,
            "laser at x {xw:.1}: only {} rows lit",
            ls.len()
        );
        for &(row, col, p) in &ls {
            assert!(
                (p[0] - proj.laser_x(slider, p[1], p[2])).abs() < 1e-9,
                "off the laser plane"
            );
            let img = proj.project(slider, p).unwrap();
            assert!((img[0] - col).abs() < 1e-6 && (img[1] - row as f64).abs() < 1e-6);
            let q = P3::new(p[0], p[1], p[2]);
            let d = bvh.closest_point(&q).unwrap().distance;
            assert!(d < 1e-6, "x {xw:.1} row {row}: {d} mm from the mesh");
            // Nothing of the mesh below it on the laser's line.
            let o = q - dir * (p[2] + 1.0);
            let hit = bvh.ray_cast(&o, &dir, f64::INFINITY).unwrap();
            assert!(
                (hit.point - q).norm() < 1e-6,
                "x {xw:.1} row {row}: first hit {:?}, truth {q:?}",
                hit.point
            );
            checked += 1;
        }
        // The lit rows are the rows the lower envelope projects to at this x (rows of its
        // points, not of its y extent: where the sides curve up, the row turns back before
        // y does), found by casting the laser's lines every 0.05 mm of y with the BVH.
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut y = bb.min.y - 0.1;
        while y <= bb.max.y + 0.1 {
            let x0 = proj.laser_x(slider, y, 0.0);
            let o = P3::new(x0 - proj.tan_b, y, -1.0);
            if let Some(h) = bvh.ray_cast(&o, &dir, f64::INFINITY) {
                let p = h.point;
                let row = proj.project(slider, [p.x, p.y, p.z]).unwrap()[1];
                lo = lo.min(row);
                hi = hi.max(row);
            }
            y += 0.05;
        }
        assert!(lo.is_finite(), "the laser crosses the mesh");
        let (first, last) = (ls[0].0 as f64, ls[ls.len() - 1].0 as f64);
        // 0.05 mm of y is under 0.5 row; allow 2 rows at the fold of a near-vertical side.
        assert!(
            (first - lo.ceil().max(0.0)).abs() <= 2.0 && (last - hi.floor()).abs() <= 2.0,
            "x {xw:.1}: rows {first}..{last}, expected {lo:.1}..{hi:.1}"
        );
    }
    // Beyond either end: no line.
    for xw in [bb.min.x - 2.0, bb.max.x + 2.0] {
        let t = r.truth(xw - optics.l_mm);
        assert_eq!(t.line_count(), 0, "laser at x {xw} misses the mesh");
    }
    checked
}

#[test]
fn parametric_lasts_render_with_exact_truth() {
    for (toe, heel) in [(Toe::Round, 0.0), (Toe::Pointed, 50.0), (Toe::Square, 80.0)] {
        let l = Last::new(LastParams {
            toe,
            heel_mm: heel,
            placement: Placement {
                heel_x_mm: 100.0,
                axis_y_mm: 4.0,
                yaw_deg: 3.0,
                lift_mm: 0.0,
            },
            ..LastParams::default()
        })
        .unwrap();
        let n = check_scene(l.mesh(), l.surface().unwrap(), 9);
        assert!(n > 3000, "{toe:?}: {n} points");
    }
}

#[test]
fn real_lasts_render_as_scenes() {
    let dir = lasts_dir();
    for (file, length) in [
        ("LastScan_Default.stl", None),
        ("LastScan_Warped.stl", None),
        ("Last_Flat_RoundTip.stl", Some(260.0)),
        ("Last_Heeled_RoundTip.stl", Some(260.0)),
    ] {
        let cfg = MeshSceneConfig {
            path: dir.join(file),
            length_mm: length,
            ..MeshSceneConfig::default()
        };
        let mesh = cfg.load_placed().unwrap_or_else(|e| panic!("{file}: {e}"));
        let ext = mesh.bbox().extent();
        assert!(ext.max() > 200.0 && ext.max() < 300.0, "{file}: {ext:?} mm");
        assert_eq!(mesh.bbox().min.z, 0.0);
        let n = check_scene(&mesh, cfg.load().unwrap(), 7);
        assert!(n > 1000, "{file}: {n} points");
    }
}

#[test]
fn unscaled_last_without_a_length_is_refused() {
    let path = lasts_dir().join("Last_Flat_RoundTip.stl");
    let e = MeshSceneConfig {
        path: path.clone(),
        ..MeshSceneConfig::default()
    }
    .load()
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("Last_Flat_RoundTip.stl") && e.contains("length_mm = MM"),
        "{e}"
    );
    let e = MeshSceneConfig {
        path,
        units: "inch".into(),
        ..MeshSceneConfig::default()
    }
    .load()
    .unwrap_err()
    .to_string();
    assert!(e.contains("mm, cm, m, auto"), "{e}");
}

/// `axes = "auto"` stands a real foot as it comes on the glass: the dupontgu pair is in
/// metres, z up, heel to toe along -y (the heel at high y, under the leg stump), the right
/// foot yawed about 17 degrees. Placed, each stands sole down (lowest z 0), heel toward -x:
/// the leg's top lies over the rear third, and the length along x is the foot's. The same
/// foot turned y up with heel to toe along +x, given as `axes = "x,y"`, stands as high, heel
/// toward -x (its yaw in plan kept: given axes are taken exactly).
/// The real lasts stand as the file has them (x heel to toe, z up) under "auto" as under
/// "file": the same extent within a millimetre.
#[test]
fn auto_axes_stand_a_real_foot_heel_toward_minus_x() {
    let feet = lasts_dir().join("../feet/dupontgu_my_feet");
    for f in ["left_foot.stl", "right_foot.stl"] {
        let cfg = MeshSceneConfig {
            path: feet.join(f),
            ..MeshSceneConfig::default()
        };
        let m = cfg.load_placed().unwrap_or_else(|e| panic!("{f}: {e}"));
        let bb = m.bbox();
        let (len, h) = (bb.max.x - bb.min.x, bb.max.z - bb.min.z);
        let top: Vec<&P3> = m
            .vertices
            .iter()
            .filter(|p| p.z > bb.min.z + 0.8 * h)
            .collect();
        let top_x = top.iter().map(|p| p.x).sum::<f64>() / top.len() as f64;
        let at = (top_x - bb.min.x) / len;
        println!("{f}: {len:.1} mm along x, {h:.1} high, the leg's top at {at:.2} of the length");
        assert_eq!(bb.min.z, 0.0, "{f}");
        assert!((255.0..290.0).contains(&len), "{f}: {len}");
        assert!(h < 0.45 * len, "{f}: {h} high: not standing");
        assert!(
            at < 0.35,
            "{f}: the leg is at {at:.2} of the length, not over the heel"
        );
        // Given the axes of a y-up copy.
        let mut y_up = TriMesh::read(feet.join(f)).unwrap();
        for p in &mut y_up.vertices {
            *p = P3::new(-p.y, p.z, -p.x);
        }
        let p = std::env::temp_dir().join(format!("footscan_sim_y_up_{}_{f}", std::process::id()));
        y_up.write(&p, footscan_geom::mesh::Format::StlBinary)
            .unwrap();
        let given = MeshSceneConfig {
            path: p.clone(),
            axes: "x,y".into(),
            ..MeshSceneConfig::default()
        }
        .load_placed();
        let _ = std::fs::remove_file(&p);
        let g = given.unwrap();
        let gb = g.bbox();
        let gtop: Vec<&P3> = g.vertices.iter().filter(|p| p.z > 0.8 * gb.max.z).collect();
        let g_at = (gtop.iter().map(|p| p.x).sum::<f64>() / gtop.len() as f64 - gb.min.x)
            / (gb.max.x - gb.min.x);
        // Given axes are taken exactly: the right foot keeps its yaw in plan.
        assert!(
            (gb.max.z - h).abs() < 0.5 && g_at < 0.35,
            "{f}: given axes stand {:?} (the leg at {g_at:.2}), auto {:?}",
            gb.extent(),
            bb.extent()
        );
    }
    for file in ["LastScan_Default.stl", "LastScan_Warped.stl"] {
        let load = |axes: &str| {
            MeshSceneConfig {
                path: lasts_dir().join(file),
                axes: axes.into(),
                ..MeshSceneConfig::default()
            }
            .load_placed()
            .unwrap_or_else(|e| panic!("{file} {axes}: {e}"))
            .bbox()
            .extent()
        };
        let (auto, file_axes) = (load("auto"), load("file"));
        println!("{file}: auto {auto:.1?}, file {file_axes:.1?}");
        assert!(
            (auto - file_axes).abs().max() < 1.0,
            "{file}: {auto:?} vs {file_axes:?}"
        );
    }
    let e = MeshSceneConfig {
        path: feet.join("left_foot.stl"),
        axes: "y,y".into(),
        ..MeshSceneConfig::default()
    }
    .load()
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("left_foot.stl") && e.contains("different axes"),
        "{e}"
    );
}
