//! The join placed by the lasts' own landmarks (docs/method.md 11.6): lasts of different
//! sizes join with closed seams, turned, mirrored, OBJ and PLY copies are stood the same way,
//! and a pair of two sides is refused unless the toe is to be mirrored. The lasts are read at
//! test time (FOOTSCAN_DATA, default: the shared data beside the repository).

use footscan_geom::mesh::{Format, TriMesh, Units};
use footscan_geom::{P3, V3};
use footscan_last::join::landmarks::{place_pair, Placed, Sides};
use footscan_last::join::{self, output, JoinError, JoinParams, Placement};
use std::path::PathBuf;

fn lasts_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let dir = base.join("lasts");
    assert!(dir.is_dir(), "no lasts at {}", dir.display());
    dir
}

fn load(f: &str) -> TriMesh {
    let len = f.contains("RoundTip").then_some(260.0);
    TriMesh::load_solid(lasts_dir().join(f), Units::Auto, len)
        .unwrap()
        .0
}

fn scaled(m: &TriMesh, s: f64) -> TriMesh {
    let mut m = m.clone();
    m.scale(s);
    m
}

/// Joins the placed pair with its landmark planes; checks the seams are closed and the kept
/// parts follow their meshes.
fn join_placed(what: &str, p: &Placed) {
    let params = JoinParams {
        back_plane: Some(p.back_plane),
        toe_plane: Some(p.toe_plane),
        placement_back: Placement::AsIs,
        placement_toe: Placement::AsIs,
        // The placement is under test, with the Gordon surface's own G2 seams (the fitted
        // parts and their G1 patch are gated in join_keep.rs).
        fit_parts: false,
        ..JoinParams::default()
    };
    let j = join::join(&p.back, &p.toe, &params).unwrap_or_else(|e| panic!("{what}: {e}"));
    let q = output::quality(&j, 200).unwrap();
    println!(
        "{what}: back {:.1} mm, toe {:.1} mm, joint x {:.1}, planes {:.1} / {:.1} mm; seams gap \
         {:.1e}/{:.1e} mm normal {:.1e}/{:.1e} deg; parts rms {:.3}/{:.3} max {:.3}/{:.3} mm",
        p.back_measures.stick_length,
        p.toe_measures.stick_length,
        p.joint_x,
        p.back_plane.origin.x,
        p.toe_plane.origin.x,
        q.back_seam.gap_max_mm,
        q.toe_seam.gap_max_mm,
        q.back_seam.normal_max_deg,
        q.toe_seam.normal_max_deg,
        q.back_deviation.rms_mm,
        q.toe_deviation.rms_mm,
        q.back_deviation.max_mm,
        q.toe_deviation.max_mm
    );
    for s in [&q.back_seam, &q.toe_seam] {
        assert!(s.gap_max_mm <= 0.01, "{what}: {s:?}");
        assert!(s.normal_max_deg <= 0.1, "{what}: {s:?}");
    }
    for d in [&q.back_deviation, &q.toe_deviation] {
        assert!(d.rms_mm <= 0.3 && d.max_mm <= 2.0, "{what}: {d:?}");
    }
}

#[test]
fn lasts_of_different_sizes_join_at_their_joints() {
    let base = load("LastScan_Default.stl");
    let big = scaled(&base, 1.15);
    // The fixed planes (62 % and 70 % of each last's length) cross when the back last is
    // 15 % longer: what the landmarks replace.
    let e = join::join(&big, &base, &JoinParams::default()).unwrap_err();
    assert!(matches!(e, JoinError::PlanesOverlap { .. }), "{e}");
    assert!(e.to_string().contains("--back-plane"), "{e}");
    for (what, b, t) in [
        ("Default x1.15 back + Default toe", &big, &base),
        ("Default back + Default x1.15 toe", &base, &big),
        (
            "LastScan Default back + Warped toe",
            &base,
            &load("LastScan_Warped.stl"),
        ),
        (
            "Heeled RoundTip back + Flat RoundTip toe",
            &load("Last_Heeled_RoundTip.stl"),
            &load("Last_Flat_RoundTip.stl"),
        ),
    ] {
        let p = place_pair(b, "back", t, "toe", Sides::Refuse).unwrap();
        assert!(p.toe_plane.origin.x > p.back_plane.origin.x + 5.0, "{what}");
        join_placed(what, &p);
    }
}

/// The same last as written by another tool: turned about z (heel to toe along y, or any
/// yaw), moved, written as OBJ or PLY.
#[test]
fn turned_moved_and_reformatted_copies_are_placed_alike() {
    let base = load("LastScan_Default.stl");
    let warped = load("LastScan_Warped.stl");
    let reference = place_pair(&base, "back", &warped, "toe", Sides::Refuse).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let turned = |deg: f64| {
        let mut m = warped.clone();
        let r = nalgebra::Rotation3::from_axis_angle(&V3::z_axis(), deg.to_radians());
        m.transform(&nalgebra::Isometry3::from_parts(
            nalgebra::Translation3::new(40.0, -75.0, 12.0),
            r.into(),
        ));
        m
    };
    let mut copies = vec![
        ("heel to toe along +y".to_string(), turned(90.0)),
        ("heel to toe along -x".to_string(), turned(180.0)),
        ("turned 37 deg".to_string(), turned(37.0)),
    ];
    for (ext, fmt) in [("obj", Format::Obj), ("ply", Format::PlyBinary)] {
        let path = dir.path().join(format!("warped.{ext}"));
        turned(90.0).write(&path, fmt).unwrap();
        copies.push((
            format!("{ext} copy along +y"),
            TriMesh::load_solid(&path, Units::Auto, None).unwrap().0,
        ));
    }
    for (what, toe) in &copies {
        let p = place_pair(&base, "back", toe, "toe", Sides::Refuse)
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        let d = (p.toe_plane.origin - reference.toe_plane.origin).norm();
        let db = (p.toe.bbox().min - reference.toe.bbox().min).norm()
            + (p.toe.bbox().max - reference.toe.bbox().max).norm();
        println!("{what}: toe plane {d:.3} mm from the reference's, bbox corners {db:.3} mm");
        assert!(
            d < 0.5 && db < 1.0,
            "{what}: plane {d} mm, bbox {db} mm off"
        );
    }
    let (what, toe) = &copies[0];
    let p = place_pair(&base, "back", toe, "toe", Sides::Refuse).unwrap();
    join_placed(what, &p);
}

#[test]
fn a_toe_of_the_other_side_is_refused_unless_mirrored() {
    let base = load("LastScan_Default.stl");
    let mut right = load("LastScan_Warped.stl");
    right.scale_about(&P3::origin(), &V3::new(1.0, -1.0, 1.0));
    let e = place_pair(&base, "left.stl", &right, "right.stl", Sides::Refuse).unwrap_err();
    let s = e.to_string();
    println!("{s}");
    assert!(matches!(e, JoinError::Sides { .. }), "{s}");
    assert!(
        s.contains("left.stl") && s.contains("right.stl") && s.contains("--mirror-toe"),
        "{s}"
    );
    let p = place_pair(&base, "left.stl", &right, "right.stl", Sides::MirrorToe).unwrap();
    assert!(p.toe_mirrored);
    assert_eq!(p.toe_measures.side, p.back_measures.side);
    // Mirrored back, it is the Warped last again: the same toe plane as the unmirrored pair.
    let q = place_pair(&base, "b", &load("LastScan_Warped.stl"), "t", Sides::Refuse).unwrap();
    let d = (p.toe_plane.origin - q.toe_plane.origin).norm();
    assert!(d < 0.5, "mirrored twice: toe plane {d} mm off");
    join_placed("Default back + mirrored right Warped toe", &p);
}
