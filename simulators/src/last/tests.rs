use super::*;
use crate::foot::Side;
use crate::mesh_scene::Placement;

fn last(toe: Toe, heel: f64) -> Last {
    Last::new(LastParams {
        toe,
        heel_mm: heel,
        placement: Placement {
            heel_x_mm: 0.0,
            ..Placement::default()
        },
        ..LastParams::default()
    })
    .unwrap()
}

#[test]
fn every_style_is_a_closed_oriented_solid() {
    for toe in Toe::ALL {
        for heel in [0.0, 25.0, 50.0, 80.0] {
            for side in [Side::Right, Side::Left] {
                let l = Last::new(LastParams {
                    toe,
                    heel_mm: heel,
                    side,
                    ..LastParams::default()
                })
                .unwrap();
                let rep = l
                    .mesh()
                    .check()
                    .unwrap_or_else(|e| panic!("{toe:?} heel {heel} {side:?}: {e}"));
                assert_eq!(rep.components, 1);
                assert!(rep.volume > 1e6, "{toe:?} {heel}: volume {}", rep.volume);
                assert_eq!(l.mesh().bbox().min.z, 0.0, "rests on the glass");
            }
        }
    }
}

#[test]
fn truth_matches_the_mesh_outline() {
    for toe in Toe::ALL {
        for heel in [0.0, 50.0] {
            let l = last(toe, heel);
            let t = l.truth();
            let o = &t.outline;
            let max_by = |k: usize, s: f64| {
                o.iter()
                    .copied()
                    .max_by(|a, b| (s * a[k]).total_cmp(&(s * b[k])))
                    .unwrap()
            };
            assert_eq!(max_by(0, -1.0), t.heel_point);
            assert_eq!(max_by(0, 1.0), t.toe_tip);
            assert_eq!(max_by(1, 1.0), t.mt1, "{toe:?}");
            assert_eq!(max_by(1, -1.0), t.mt5, "{toe:?}");
            assert!((t.toe_tip[0] - t.heel_point[0] - t.bottom_length_mm).abs() < 1e-12);
            assert!((t.mt1[1] - t.mt5[1] - t.ball_width_mm).abs() < 1e-12);
            for p in [t.waist_medial, t.waist_lateral] {
                assert!(o.contains(&p), "waist point {p:?} is an outline vertex");
            }
            // Waist points are the narrowest between heel and ball on their side.
            let narrow = |s: f64, x0: f64, x1: f64| {
                o.iter()
                    .filter(|p| p[0] > x0 && p[0] < x1 && s * p[1] > 0.0)
                    .map(|p| s * p[1])
                    .fold(f64::INFINITY, f64::min)
            };
            let l_ = t.bottom_length_mm;
            assert_eq!(narrow(1.0, 0.2 * l_, 0.6 * l_), t.waist_medial[1]);
            assert_eq!(narrow(-1.0, 0.2 * l_, 0.6 * l_), -t.waist_lateral[1]);
            // The ball contact is a vertex on the glass, and nothing is lower (a flat last
            // rests on its whole middle line from heel to ball).
            let lowest = l.mesh().bbox().min.z;
            assert_eq!(lowest, 0.0);
            assert_eq!(t.ball_contact[2], 0.0);
            assert!(l.mesh().vertices.contains(&t.ball_contact));
            assert!((t.heel_point[2] - heel - 1.5).abs() < 1e-12);
        }
    }
}

#[test]
fn size_and_proportions() {
    let p = LastParams {
        size_paris: Some(40.0),
        ..LastParams::default()
    };
    let l = Last::new(p).unwrap();
    assert!((l.truth().bottom_length_mm - 266.666_666_666_666_7).abs() < 1e-9);
    assert!((l.truth().ball_width_mm / l.truth().bottom_length_mm - 0.36).abs() < 1e-12);
    let bad = Last::new(LastParams {
        heel_mm: 120.0,
        ..LastParams::default()
    })
    .unwrap_err()
    .to_string();
    assert!(bad.contains("heel_mm") && bad.contains("[0, 100]"), "{bad}");
}

#[test]
fn toe_parses() {
    assert_eq!("square".parse::<Toe>(), Ok(Toe::Square));
    assert!("flat"
        .parse::<Toe>()
        .unwrap_err()
        .to_string()
        .contains("round, pointed, square"));
}
