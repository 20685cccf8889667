//! Evaluation and validation against analytic shapes.

use footscan_geom::nurbs::{NurbsCurve, NurbsError, NurbsSurface};
use footscan_geom::P3;

/// The classic 9-point rational quadratic full circle of radius `r` in the xy plane.
pub fn circle(r: f64) -> NurbsCurve {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let pts = [
        (1.0, 0.0),
        (1.0, 1.0),
        (0.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 0.0),
        (-1.0, -1.0),
        (0.0, -1.0),
        (1.0, -1.0),
        (1.0, 0.0),
    ]
    .iter()
    .map(|&(x, y)| P3::new(r * x, r * y, 0.0))
    .collect();
    let w = vec![1.0, s, 1.0, s, 1.0, s, 1.0, s, 1.0];
    let knots = vec![
        0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0,
    ];
    NurbsCurve::new(2, knots, pts, Some(w)).unwrap()
}

#[test]
fn nurbs_circle_is_a_circle() {
    let c = circle(30.0);
    assert_eq!(c.domain(), (0.0, 1.0));
    for i in 0..=1000 {
        let p = c.point(i as f64 / 1000.0);
        assert!(
            (p.coords.norm() - 30.0).abs() < 1e-12,
            "radius {}",
            p.coords.norm()
        );
        assert_eq!(p.z, 0.0);
    }
}

#[test]
fn degree_one_curve_is_the_polyline() {
    let pts = vec![
        P3::new(0.0, 0.0, 0.0),
        P3::new(1.0, 2.0, 0.0),
        P3::new(4.0, 2.0, 1.0),
    ];
    let c = NurbsCurve::new(1, vec![0.0, 0.0, 0.5, 2.0, 2.0], pts.clone(), None).unwrap();
    assert!((c.point(0.25) - P3::new(0.5, 1.0, 0.0)).norm() < 1e-15);
    assert!((c.point(0.5) - pts[1]).norm() < 1e-15);
    let t = (1.25 - 0.5) / 1.5;
    let want = pts[1] + t * (pts[2] - pts[1]);
    assert!((c.point(1.25) - want).norm() < 1e-14);
    assert_eq!(c.point(2.0), pts[2]);
    // Clamped outside the domain.
    assert_eq!(c.point(-1.0), pts[0]);
}

#[test]
fn validation_names_the_problem() {
    let pts = vec![P3::origin(); 4];
    let e = NurbsCurve::new(3, vec![0.0; 7], pts.clone(), None).unwrap_err();
    assert!(
        matches!(
            e,
            NurbsError::KnotCount {
                expected: 8,
                got: 7,
                ..
            }
        ),
        "{e}"
    );
    let e = NurbsCurve::new(
        3,
        vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.5, 1.0],
        pts.clone(),
        None,
    )
    .unwrap_err();
    assert!(
        matches!(e, NurbsError::KnotsDecreasing { index: 6, .. }),
        "{e}"
    );
    assert!(e.to_string().contains("non-decreasing"));
    let k = vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
    let e = NurbsCurve::new(3, k.clone(), pts.clone(), Some(vec![1.0; 3])).unwrap_err();
    assert!(
        matches!(
            e,
            NurbsError::WeightCount {
                expected: 4,
                got: 3,
                ..
            }
        ),
        "{e}"
    );
    let e = NurbsCurve::new(3, k.clone(), pts.clone(), Some(vec![1.0, 0.0, 1.0, 1.0])).unwrap_err();
    assert!(
        matches!(e, NurbsError::WeightNotPositive { index: 1, .. }),
        "{e}"
    );
    let e = NurbsCurve::new(0, k.clone(), pts.clone(), None).unwrap_err();
    assert!(matches!(e, NurbsError::Degree { .. }), "{e}");
    let e = NurbsCurve::new(4, k.clone(), pts.clone(), None).unwrap_err();
    assert!(matches!(e, NurbsError::TooFewPoints { .. }), "{e}");
    // Periodic: wrap must hold.
    let pp: Vec<P3> = (0..7).map(|i| P3::new(i as f64, 0.0, 0.0)).collect();
    let kk: Vec<f64> = (0..11).map(|i| i as f64).collect();
    let e = NurbsCurve::new_periodic(3, kk, pp, None).unwrap_err();
    assert!(
        matches!(
            e,
            NurbsError::PeriodicWrap {
                index: 4,
                index_first: 0,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn periodic_uniform_cubic_wraps() {
    // 6 unique points of a hexagon, uniform unclamped knots.
    let uniq: Vec<P3> = (0..6)
        .map(|i| {
            let a = i as f64 * std::f64::consts::TAU / 6.0;
            P3::new(10.0 * a.cos(), 10.0 * a.sin(), 0.0)
        })
        .collect();
    let mut pts = uniq.clone();
    pts.extend_from_slice(&uniq[..3]);
    let knots: Vec<f64> = (0..13).map(|i| i as f64).collect();
    let c = NurbsCurve::new_periodic(3, knots, pts, None).unwrap();
    assert_eq!(c.domain(), (3.0, 9.0));
    assert!((c.point(3.0) - c.point(9.0)).norm() < 1e-12);
    assert!((c.point(3.5) - c.point(9.5)).norm() < 1e-12);
    // Uniform cubic: the point at a knot is (P0 + 4 P1 + P2) / 6.
    let want = (uniq[0].coords + 4.0 * uniq[1].coords + uniq[2].coords) / 6.0;
    assert!((c.point(3.0).coords - want).norm() < 1e-12);
}

#[test]
fn bilinear_and_cylinder_surface() {
    let pts = vec![
        P3::new(0.0, 0.0, 0.0),
        P3::new(0.0, 1.0, 0.0),
        P3::new(2.0, 0.0, 0.0),
        P3::new(2.0, 1.0, 1.0),
    ];
    let s = NurbsSurface::new(
        1,
        1,
        vec![0.0, 0.0, 1.0, 1.0],
        vec![0.0, 0.0, 1.0, 1.0],
        2,
        2,
        pts,
        None,
    )
    .unwrap();
    let p = s.point(0.5, 0.5);
    assert!((p - P3::new(1.0, 0.5, 0.25)).norm() < 1e-15);
    assert_eq!(s.domain_u(), (0.0, 1.0));
    // Cylinder: circle in v, line in u.
    let c = circle(5.0);
    let mut pts = Vec::new();
    let mut w = Vec::new();
    for z in [0.0, 10.0] {
        for (k, q) in c.points.iter().enumerate() {
            pts.push(P3::new(q.x, q.y, z));
            w.push(c.weight(k));
        }
    }
    let s = NurbsSurface::new(
        1,
        2,
        vec![0.0, 0.0, 1.0, 1.0],
        c.knots.clone(),
        2,
        9,
        pts,
        Some(w),
    )
    .unwrap();
    assert_eq!(s.domain_v(), (0.0, 1.0));
    for i in 0..=20 {
        for j in 0..=50 {
            let p = s.point(i as f64 / 20.0, j as f64 / 50.0);
            assert!(((p.x * p.x + p.y * p.y).sqrt() - 5.0).abs() < 1e-12);
            assert!((p.z - 10.0 * i as f64 / 20.0).abs() < 1e-12);
        }
    }
    let e = NurbsSurface::new(
        1,
        1,
        vec![0.0, 0.0, 1.0, 1.0],
        vec![0.0, 0.0, 1.0, 1.0],
        2,
        2,
        vec![],
        None,
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            NurbsError::GridSize {
                expected: 4,
                got: 0,
                ..
            }
        ),
        "{e}"
    );
}

#[test]
fn circle_derivatives_curvature_length_closest() {
    let r = 30.0;
    let c = circle(r);
    for i in 0..=200 {
        let u = i as f64 / 200.0;
        assert!(
            (c.curvature(u) - 1.0 / r).abs() < 1e-12,
            "curvature {}",
            c.curvature(u)
        );
        let p = c.point(u);
        let kv = c.curvature_vector(u);
        // Points to the centre.
        assert!((kv + p.coords / (r * r)).norm() < 1e-12);
        assert!(c.tangent(u).dot(&p.coords).abs() < 1e-9);
        // Derivative against central differences.
        let h = 1e-6;
        let fd = (c.point((u + h).min(1.0)) - c.point((u - h).max(0.0)))
            / ((u + h).min(1.0) - (u - h).max(0.0));
        assert!((c.derivative(u) - fd).norm() < 1e-4 * c.derivative(u).norm());
    }
    assert!(
        (c.length() - std::f64::consts::TAU * r).abs() < 1e-9,
        "length {}",
        c.length()
    );
    let q = P3::new(50.0, 50.0, 3.0);
    let cp = c.closest_point(&q);
    let want = P3::new(r / 2f64.sqrt(), r / 2f64.sqrt(), 0.0);
    assert!((cp.point - want).norm() < 1e-9, "{:?}", cp);
    assert!((cp.distance - ((50f64.hypot(50.0) - r).powi(2) + 9.0).sqrt()).abs() < 1e-9);
}

#[test]
fn cubic_derivatives_match_power_form() {
    // A clamped cubic Bezier is the Bernstein form: C''(t) = 6 [(1-t)(P2 - 2P1 + P0) + t(P3 - 2P2 + P1)].
    let p: Vec<P3> = vec![
        P3::new(0.0, 0.0, 0.0),
        P3::new(1.0, 3.0, 0.0),
        P3::new(4.0, 3.0, 1.0),
        P3::new(6.0, 0.0, 2.0),
    ];
    let c = NurbsCurve::new(
        3,
        vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
        p.clone(),
        None,
    )
    .unwrap();
    let t = 0.3;
    let d = c.derivatives(t, 4);
    let d2 = 6.0
        * ((1.0 - t) * (p[2] - 2.0 * p[1] + p[0].coords) + t * (p[3] - 2.0 * p[2] + p[1].coords));
    assert!((d[2] - d2).norm() < 1e-12);
    let d3 = 6.0 * (p[3] - 3.0 * p[2] + 3.0 * p[1].coords - p[0].coords);
    assert!((d[3] - d3).norm() < 1e-12);
    assert_eq!(d[4], footscan_geom::V3::zeros());
}
