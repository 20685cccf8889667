//! Bottom adjustment on a constructed case: a bottom made from the foot itself, scaled by a
//! known factor in plan and in height and shifted (and turned), must give back exactly those
//! factors and that shift, and end on the foot within the accuracy targets.

use footscan_geom::{P2, V2};
use footscan_last::adjust::synthetic::AnalyticFoot;
use footscan_last::adjust::{adjust, AdjustError, AdjustOptions, Side};

fn centre(f: &footscan_last::adjust::FootPlantar) -> P2 {
    let l = &f.landmarks;
    let p = [l.heel_point, l.toe_tip, l.mt1_head, l.mt5_head];
    P2::new(
        p.iter().map(|q| q.x).sum::<f64>() / 4.0,
        p.iter().map(|q| q.y).sum::<f64>() / 4.0,
    )
}

#[test]
fn eps_zeta_and_shift_are_recovered_to_a_tenth_of_a_percent() {
    for (side, k_xy, k_z, shift) in [
        (Side::Right, 1.06, 1.15, V2::new(7.0, -4.0)),
        (Side::Left, 0.95, 0.9, V2::new(-12.0, 3.0)),
    ] {
        let foot_model = AnalyticFoot::new(240.0, side);
        let foot = foot_model.plantar(0.2);
        let c = centre(&foot);
        let bottom = foot_model.bottom(c, k_xy, k_z, 0.0, shift, 0.25);
        let a = adjust(&foot, &bottom, &AdjustOptions::default()).unwrap();
        let rel = |got: f64, want: f64| (got - want).abs() / want.abs();
        let shift_err = ((a.shift.x + shift.x).hypot(a.shift.y + shift.y)) / shift.x.hypot(shift.y);
        println!(
            "{side:?}: eps {:.6} (true {k_xy}), zeta {:.6} (true {k_z}) at {:?}, shift ({:.4}, {:.4}) (true {:?}), rotation {:.5} deg; \
             after: outline RMS {:.3} max {:.3}, landmarks {:.3}, heights RMS {:.3} max {:.3}, >0.5 mm {:.4}; \
             before: heights RMS {:.3}, outline RMS {:.3}, landmarks {:.3}",
            a.eps, a.zeta, a.zeta_at, -a.shift.x, -a.shift.y, shift, a.rotation_deg,
            a.after.outline_rms_mm, a.after.outline_max_mm, a.after.landmark_max_mm,
            a.after.height_rms_mm, a.after.height_max_mm, a.after.share_beyond_0_5,
            a.before.height_rms_mm, a.before.outline_rms_mm, a.before.landmark_max_mm
        );
        assert!(rel(a.eps, k_xy) < 1e-3, "eps {} vs {k_xy}", a.eps);
        assert!(rel(a.zeta, k_z) < 1e-3, "zeta {} vs {k_z}", a.zeta);
        assert!(shift_err < 1e-3, "shift {:?} vs {:?}", a.shift, shift);
        assert!(a.rotation_deg.abs() < 0.01);
        assert!(!a.mirrored);
        assert!(a.after.outline_rms_mm <= 0.3);
        assert!(a.after.landmark_max_mm <= 0.5);
        assert!(a.after.height_rms_mm <= 0.3);
    }
}

#[test]
fn a_turned_bottom_of_the_other_foot_is_mirrored_and_fitted() {
    let foot_model = AnalyticFoot::new(260.0, Side::Right);
    let foot = foot_model.plantar(0.2);
    let c = centre(&foot);
    let mut bottom =
        AnalyticFoot::new(260.0, Side::Left).bottom(c, 1.03, 1.1, 0.0, V2::zeros(), 0.25);
    // Turn the left bottom by 4 degrees about the centre, shift it.
    let (co, si) = (4f64.to_radians().cos(), 4f64.to_radians().sin());
    for p in &mut bottom.outline {
        let d = *p - c;
        *p = P2::new(
            c.x + co * d.x - si * d.y + 5.0,
            c.y + si * d.x + co * d.y - 2.0,
        );
    }
    // Its heights do not follow the turn: they are only used after the fit, which the
    // outline drives; a height mismatch shows up as the correction field.
    let a = adjust(&foot, &bottom, &AdjustOptions::default()).unwrap();
    println!(
        "mirrored {} rotation {:.3} eps {:.4} zeta {:.4}; after outline RMS {:.3}, landmarks {:.3}, heights RMS {:.3}",
        a.mirrored, a.rotation_deg, a.eps, a.zeta, a.after.outline_rms_mm, a.after.landmark_max_mm, a.after.height_rms_mm
    );
    assert!(a.mirrored);
    assert!(a.after.outline_rms_mm <= 0.3);
    assert!(a.after.landmark_max_mm <= 0.5);
    assert!(a.after.height_rms_mm <= 0.3);
}

#[test]
fn a_foot_without_measurements_and_a_short_bottom_are_refused_by_name() {
    let foot_model = AnalyticFoot::new(250.0, Side::Right);
    let foot = foot_model.plantar(0.5);
    let c = centre(&foot);
    let mut empty = foot.clone();
    empty.outline.clear();
    empty.source = "scan-0042".into();
    let bottom = foot_model.bottom(c, 1.0, 1.0, 0.0, V2::zeros(), 0.5);
    let e = adjust(&empty, &bottom, &AdjustOptions::default()).unwrap_err();
    assert!(matches!(e, AdjustError::Foot { .. }));
    assert!(
        e.to_string().contains("scan-0042") && e.to_string().contains("no measurements"),
        "{e}"
    );
    let mut nan = foot.clone();
    nan.landmarks.mt1_head = P2::new(f64::NAN, 0.0);
    let e = adjust(&nan, &bottom, &AdjustOptions::default()).unwrap_err();
    assert!(e.to_string().contains("MT1 head"), "{e}");
    let short = foot_model.bottom(c, 1.5, 1.0, 0.0, V2::zeros(), 0.5);
    let e = adjust(&foot, &short, &AdjustOptions::default()).unwrap_err();
    assert!(matches!(e, AdjustError::TooShort { .. }), "{e}");
    assert!(e.to_string().contains("30 %"), "{e}");
}
