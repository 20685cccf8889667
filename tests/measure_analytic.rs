//! Measurements on height maps sampled from the simulator's analytic foot (0.1 mm cells),
//! against its truth: right and left feet, other lengths, widths, arches, edges and yaws.
//! The height map sees the whole sole up to its vertical edge, so these bounds are tighter
//! than the scan's (tests/measure_scan.rs).

use footscan::geom::HeightMap;
use footscan::measure::{
    compare_with_truth, measure_foot, measure_foot_with, ErrorKind, MeasureError, Measurements,
    Planar, Side, TruthComparison,
};
use footscan_bench::measure::{analytic_map, population_rows};
use footscan_sim::foot::{Foot, FootParams, Side as SimSide};

const CELL: f64 = 0.1;

fn measure(p: FootParams) -> (Measurements, TruthComparison) {
    let foot = Foot::new(p).unwrap();
    let m = measure_foot(&analytic_map(&foot, CELL, true)).unwrap();
    let c = compare_with_truth(&m, &serde_json::to_string(&foot.truth()).unwrap()).unwrap();
    (m, c)
}

/// Bounds on the analytic height map: landmarks 0.5 mm (the second metatarsal head is
/// checked apart: its place along the axis is a convention), lengths and widths 0.15 mm,
/// axis 0.15 degrees, arch index 0.005.
fn assert_bounds(c: &TruthComparison, what: &str) {
    println!("{what}\n{}", c.table());
    assert!(c.side_correct, "{what}: wrong side");
    for r in &c.rows {
        let bound = match (r.kind, r.name) {
            (_, "mt2_head") => 4.0,
            (ErrorKind::Landmark, _) => 0.5,
            (ErrorKind::Length, _) => 0.15,
            (ErrorKind::Angle, _) => 0.15,
            (ErrorKind::Index, _) => 0.005,
        };
        assert!(
            r.error.abs() <= bound,
            "{what}: {} error {:.4} exceeds {bound}",
            r.name,
            r.error
        );
    }
}

/// Distance of the measured second metatarsal head from the true axis line.
fn mt2_off_axis(m: &Measurements, p: &FootParams) -> f64 {
    let t = Foot::new(p.clone()).unwrap().truth();
    let d = [
        m.mt2_head[0] - t.heel_point[0],
        m.mt2_head[1] - t.heel_point[1],
    ];
    (d[0] * t.axis_dir[1] - d[1] * t.axis_dir[0]).abs()
}

#[test]
fn default_right_foot() {
    let p = FootParams::default();
    let (m, c) = measure(p.clone());
    assert_bounds(&c, "default right foot");
    assert_eq!(m.side, Side::Right);
    assert_eq!(m.toe_outlines.len(), 5);
    assert!(mt2_off_axis(&m, &p) < 0.2, "{}", mt2_off_axis(&m, &p));
}

#[test]
fn left_foot_is_the_mirror_image() {
    let p = FootParams::default();
    let (r, _) = measure(p.clone());
    let (l, c) = measure(p.mirrored());
    assert_bounds(&c, "mirrored left foot");
    assert_eq!(l.side, Side::Left);
    for (a, b, name) in [
        (r.heel_point, l.heel_point, "heel point"),
        (r.toe_tip, l.toe_tip, "toe tip"),
        (r.mt1_head, l.mt1_head, "MT1"),
        (r.mt5_head, l.mt5_head, "MT5"),
    ] {
        // Mirror y -> -y; the cell grids differ, so agreement is to the bounds.
        let e = (a[0] - b[0]).hypot(a[1] + b[1]);
        assert!(e < 0.5, "{name}: right {a:?} vs left {b:?}");
    }
    assert!((r.foot_length_mm - l.foot_length_mm).abs() < 0.1);
    assert!((r.axis_angle_deg + l.axis_angle_deg).abs() < 0.15);
}

#[test]
fn long_narrow_foot_turned_outward() {
    let p = FootParams {
        length_mm: 280.0,
        yaw_deg: -8.0,
        axis_y_mm: 12.0,
        ball_width_ratio: 0.37,
        ..FootParams::default()
    };
    let (m, c) = measure(p.clone());
    assert_bounds(&c, "280 mm, yaw -8");
    assert!(mt2_off_axis(&m, &p) < 0.2);
}

#[test]
fn short_left_foot_high_arch_small_edge() {
    let p = FootParams {
        length_mm: 230.0,
        yaw_deg: 12.0,
        side: SimSide::Left,
        heel_width_ratio: 0.27,
        arch_height_mm: 22.0,
        press_mm: 1.0,
        edge_radius_mm: 3.0,
        ..FootParams::default()
    };
    let (m, c) = measure(p);
    assert_bounds(&c, "230 mm left, yaw 12, arch 22");
    assert_eq!(m.side, Side::Left);
}

#[test]
fn extreme_feet() {
    for p in [
        FootParams {
            length_mm: 300.0,
            yaw_deg: 19.0,
            ball_width_ratio: 0.43,
            arch_height_mm: 9.0,
            edge_radius_mm: 9.0,
            press_mm: 5.0,
            ..FootParams::default()
        },
        FootParams {
            length_mm: 260.0,
            yaw_deg: -17.0,
            side: SimSide::Left,
            heel_width_ratio: 0.23,
            edge_radius_mm: 1.5,
            press_mm: 0.5,
            ..FootParams::default()
        },
    ] {
        let what = format!("{p:?}");
        let (_, c) = measure(p);
        assert_bounds(&c, &what);
    }
}

#[test]
fn foot_without_toe_pads_uses_the_arch_for_the_side() {
    for p in [FootParams::default(), FootParams::default().mirrored()] {
        let foot = Foot::new(p.clone()).unwrap();
        let m = measure_foot(&analytic_map(&foot, CELL, false)).unwrap();
        let c = compare_with_truth(&m, &serde_json::to_string(&foot.truth()).unwrap()).unwrap();
        assert!(c.side_correct, "{:?}", p.side);
        assert!(m.toe_outlines.is_empty());
        // Without toes the foot length (and so the mid-foot station) is the body's; the
        // figures that do not depend on it still hold.
        for name in [
            "ball_width_mm",
            "heel_width_mm",
            "arch_index",
            "arch_height_mm",
        ] {
            let e = c.row(name).unwrap().error.abs();
            assert!(e < 0.15, "{name}: {e}");
        }
    }
}

/// A scan measures the outline on the footprint before the model's heights go into it
/// (`Planar::of`); with the same valid cells and other heights, the measurements are
/// measure_foot's exactly, with toes apart and joined (where the side waits for the heights),
/// and a footprint of another lattice is not used.
#[test]
fn the_outline_measured_on_the_footprint_alone_is_the_maps() {
    for (p, toes) in [
        (FootParams::default(), true),
        (FootParams::default().mirrored(), false),
    ] {
        let foot = Foot::new(p).unwrap();
        let map = analytic_map(&foot, CELL, toes);
        let mut footprint = map.clone();
        for z in footprint.z.iter_mut().filter(|z| z.is_finite()) {
            *z = 40.0 - *z;
        }
        let whole = measure_foot(&map).unwrap();
        let early = measure_foot_with(&map, Planar::of(&footprint).unwrap()).unwrap();
        assert_eq!(early, whole, "toes apart: {toes}");
        assert_eq!(early.toe_outlines.is_empty(), !toes);
        let mut other = map.clone();
        other.x0 += CELL;
        let moved = measure_foot_with(&map, Planar::of(&other).unwrap()).unwrap();
        assert_eq!(moved, whole, "toes apart: {toes}");
    }
}

#[test]
fn empty_and_tiny_footprints_are_errors() {
    let mut m = HeightMap::new(0.0, 0.0, 1.0, 50, 50);
    let e = measure_foot(&m).unwrap_err();
    assert!(matches!(e, MeasureError::NoFootprint), "{e}");
    for j in 10..20 {
        for i in 10..30 {
            m.set(i, j, 0.0);
        }
    }
    let e = measure_foot(&m).unwrap_err();
    assert!(matches!(e, MeasureError::TooSmall { .. }), "{e}");
    assert!(e.to_string().contains("200 mm^2"), "{e}");
}

/// The targets on a population (footscan_bench::measure: heads 3 mm, widths 0.5 mm, length
/// 0.3 mm): a foot outside any of them must carry a warning, a plain foot none, and nearly
/// every foot is within them (flagging is the fallback, not the method).
#[test]
fn a_population_of_sixty_feet_of_every_kind() {
    let rows = population_rows(60, 2026, CELL).unwrap();
    let mut failures = Vec::new();
    for (i, r) in rows.iter().enumerate() {
        println!(
            "{i:2} {:26} L {:5.1} MT1 {:5.2} MT5 {:5.2} ball {:4.2} heel {:4.2} mid {:4.2} \
             length {:4.2} axis {:4.2} waists {:4.1} {:4.1} warnings {}",
            r.kind,
            r.length_mm,
            r.mt1_mm,
            r.mt5_mm,
            r.ball_mm,
            r.heel_mm,
            r.midfoot_mm,
            r.length_err_mm,
            r.axis_deg,
            r.waist_inner_mm,
            r.waist_outer_mm,
            r.warnings.len()
        );
        if !r.within_targets() && r.warnings.is_empty() {
            failures.push(format!(
                "foot {i} ({}) is off the targets without a warning",
                r.kind
            ));
        }
        if r.kind == "plain" && !r.warnings.is_empty() {
            failures.push(format!("plain foot {i} warns: {:?}", r.warnings));
        }
    }
    let within = rows.iter().filter(|r| r.within_targets()).count();
    println!("{within} of {} feet within every target", rows.len());
    assert!(failures.is_empty(), "{failures:#?}");
    assert!(
        within >= 57,
        "only {within} of {} feet within the targets",
        rows.len()
    );
}
