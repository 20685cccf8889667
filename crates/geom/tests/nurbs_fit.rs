//! Interpolation, least squares and the adaptive fit, on analytic curves and random data.

use footscan_geom::nurbs::fit::{
    fit_adaptive, fit_closed_adaptive, interpolate, interpolate_closed, interpolate_with,
    least_squares, least_squares_closed_residuals, least_squares_closed_with_knots, parameters,
    solve_cyclic_band_spd,
};
use footscan_geom::nurbs::{FitOptions, Param};
use footscan_geom::{P3, V3};
use proptest::prelude::*;

/// A closed girth-like loop: an ellipse with a bump, `n` points.
fn girth(n: usize, a: f64, b: f64) -> Vec<P3> {
    (0..n)
        .map(|i| {
            let t = i as f64 / n as f64 * std::f64::consts::TAU;
            let r = 1.0 + 0.08 * (3.0 * t).sin();
            P3::new(a * r * t.cos(), b * r * t.sin(), 5.0 * (2.0 * t).cos())
        })
        .collect()
}

fn random_walk(seed: u64, n: usize) -> Vec<P3> {
    let mut s = seed;
    let mut next = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut p = P3::origin();
    (0..n)
        .map(|_| {
            p += V3::new(5.0 + 10.0 * next(), 10.0 * next() - 5.0, 6.0 * next() - 3.0);
            p
        })
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(100))]

    #[test]
    fn interpolation_passes_its_points(seed in any::<u64>(), n in 2usize..40, p in 1usize..6, centripetal in any::<bool>()) {
        let pts = random_walk(seed, n);
        let m = if centripetal { Param::Centripetal } else { Param::ChordLength };
        let c = interpolate(&pts, p, m).unwrap();
        let t = parameters(&pts, m, false).unwrap();
        for (q, u) in pts.iter().zip(&t) {
            prop_assert!((c.point(*u) - q).norm() < 1e-9, "{} mm", (c.point(*u) - q).norm());
        }
    }

    #[test]
    fn interpolation_with_end_derivatives(seed in any::<u64>(), n in 2usize..30, p in 2usize..5) {
        let pts = random_walk(seed, n);
        let t = parameters(&pts, Param::ChordLength, false).unwrap();
        let (d0, d1) = (V3::new(100.0, 20.0, 0.0), V3::new(50.0, -40.0, 10.0));
        let c = interpolate_with(&pts, &t, p, Some((d0, d1))).unwrap();
        for (q, u) in pts.iter().zip(&t) {
            prop_assert!((c.point(*u) - q).norm() < 1e-9);
        }
        prop_assert!((c.derivative(0.0) - d0).norm() < 1e-8);
        prop_assert!((c.derivative(1.0) - d1).norm() < 1e-8);
    }

    #[test]
    fn closed_interpolation_passes_its_points(n in 5usize..60, p in 1usize..6, a in 30.0f64..60.0) {
        let pts = girth(n, a, 40.0);
        let c = interpolate_closed(&pts, p, Param::ChordLength).unwrap();
        prop_assert!(c.periodic);
        let t = parameters(&pts, Param::ChordLength, true).unwrap();
        for (q, u) in pts.iter().zip(&t) {
            prop_assert!((c.point(*u) - q).norm() < 1e-9, "{} mm", (c.point(*u) - q).norm());
        }
    }

    #[test]
    fn least_squares_fixes_its_ends(seed in any::<u64>(), n in 6usize..80, p in 1usize..5, frac in 0.2f64..1.0) {
        let pts = random_walk(seed, n);
        let t = parameters(&pts, Param::ChordLength, false).unwrap();
        let nc = ((n as f64 * frac) as usize).clamp(p + 1, n);
        let c = least_squares(&pts, &t, p, nc).unwrap();
        prop_assert_eq!(c.point(0.0), pts[0]);
        prop_assert_eq!(c.point(1.0), pts[n - 1]);
    }

    /// As many control points as data points (or one fewer) is where a knot rule that does
    /// not average put knots a hair from the data and the system went singular.
    #[test]
    fn least_squares_with_as_many_control_points_as_data(seed in any::<u64>(), n in 6usize..80, p in 1usize..6, fewer in 0usize..2) {
        let pts = random_walk(seed, n);
        let t = parameters(&pts, Param::ChordLength, false).unwrap();
        let nc = (n - fewer).max(p + 1);
        let c = least_squares(&pts, &t, p, nc).unwrap();
        c.validate().unwrap();
        if nc == n {
            for (q, u) in pts.iter().zip(&t) {
                prop_assert!((c.point(*u) - q).norm() < 1e-6, "{} mm", (c.point(*u) - q).norm());
            }
        }
    }

    #[test]
    fn adaptive_fit_meets_tolerance(seed in any::<u64>(), n in 10usize..200, tol in 0.01f64..0.5) {
        // A smooth curve sampled densely (a foot outline is smooth at this scale).
        let s = (seed % 1000) as f64 / 1000.0;
        let pts: Vec<P3> = (0..n).map(|i| {
            let t = i as f64 / (n - 1) as f64;
            P3::new(250.0 * t, 40.0 * (3.0 * t + s).sin() + 10.0 * (7.0 * t).cos(), 15.0 * t * t)
        }).collect();
        let opts = FitOptions { tolerance: tol, ..Default::default() };
        let r = fit_adaptive(&pts, &opts).unwrap();
        prop_assert!(r.met, "max {} > {tol} with {} control points", r.max_error, r.control_points);
        prop_assert!(r.max_error <= tol);
        prop_assert_eq!(r.curve.point(0.0), pts[0]);
        prop_assert_eq!(r.curve.point(1.0), pts[n - 1]);
        for (q, u) in pts.iter().zip(&r.params) {
            prop_assert!((r.curve.point(*u) - q).norm() <= tol + 1e-12);
        }
    }

    #[test]
    fn closed_adaptive_fit_meets_tolerance(n in 20usize..300, a in 30.0f64..70.0, tol in 0.01f64..0.3) {
        let pts = girth(n, a, 45.0);
        let opts = FitOptions { tolerance: tol, ..Default::default() };
        let r = fit_closed_adaptive(&pts, &opts).unwrap();
        prop_assert!(r.met, "max {} > {tol} with {} control points", r.max_error, r.control_points);
        prop_assert!(r.curve.periodic);
        r.curve.validate().unwrap();
    }
}

/// Degree 4 near interpolation: the smallest cases a sweep found singular (64 points, 64
/// and 63 control points) and one of the size of CI's failure (a 76 x 76 system, so 78
/// control points).
#[test]
fn least_squares_near_interpolation_is_not_singular() {
    for (n, nc) in [(64, 64), (64, 63), (79, 78)] {
        let pts = random_walk(0, n);
        let t = parameters(&pts, Param::ChordLength, false).unwrap();
        let c = least_squares(&pts, &t, 4, nc).unwrap();
        let worst = pts
            .iter()
            .zip(&t)
            .map(|(q, u)| (c.point(*u) - q).norm())
            .fold(0.0, f64::max);
        // Interpolation when the counts match; one control point fewer stays within the walk's step.
        assert!(
            worst < if nc == n { 1e-6 } else { 15.0 },
            "{n} points, {nc} control points: {worst} mm"
        );
    }
}

#[test]
fn adaptive_fit_of_a_girth_reports_its_figures() {
    let pts = girth(200, 50.0, 40.0);
    let r = fit_closed_adaptive(&pts, &FitOptions::default()).unwrap();
    assert!(r.met && r.max_error <= 0.05);
    assert!(r.rms_error <= r.max_error);
    // Far fewer control points than data points.
    assert!(r.control_points < 60, "{} control points", r.control_points);
    eprintln!(
        "girth 200 pts: {} control points, max {:.4} mm, rms {:.4} mm, {} insertions",
        r.control_points, r.max_error, r.rms_error, r.iterations
    );
    // Curve length agrees with the polygon length (a slight underestimate) to 0.1 %.
    let poly: f64 = (0..200).map(|i| (pts[(i + 1) % 200] - pts[i]).norm()).sum();
    assert!(
        (r.curve.length() - poly).abs() < 1e-3 * poly,
        "{} vs {}",
        r.curve.length(),
        poly
    );
}

#[test]
fn degree_one_interpolation_is_the_polyline() {
    let pts = random_walk(7, 6);
    let c = interpolate(&pts, 1, Param::ChordLength).unwrap();
    let t = parameters(&pts, Param::ChordLength, false).unwrap();
    let mid = 0.5 * (t[2] + t[3]);
    assert!((c.point(mid) - P3::from(0.5 * (pts[2].coords + pts[3].coords))).norm() < 1e-12);
}

#[test]
fn bad_fit_input_is_an_error() {
    let pts = vec![P3::origin(), P3::origin(), P3::new(1.0, 0.0, 0.0)];
    let e = interpolate(&pts, 3, Param::ChordLength).unwrap_err();
    assert!(e.to_string().contains("coincide"), "{e}");
    let e = interpolate(&pts[..1], 3, Param::ChordLength).unwrap_err();
    assert!(e.to_string().contains("at least 2"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(60))]

    /// The cyclic band solver against nalgebra's dense LU on random SPD cyclic band
    /// matrices (B^T B for a random cyclic band B, plus a ridge), n from 2p + 2 up.
    #[test]
    fn cyclic_band_solve_matches_a_dense_solve(seed in any::<u64>(), p in 1usize..5, extra in 0usize..40) {
        let n = 2 * p + 2 + extra;
        let w = 2 * p + 1;
        let mut s = seed;
        let mut next = || {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        // B: row i non-zero at columns i..=i + p/2 (mod n), so B^T B stays within +-p.
        let h = p / 2;
        let mut bm = nalgebra::DMatrix::<f64>::zeros(n, n);
        for i in 0..n {
            for k in 0..=h {
                bm[(i, (i + k) % n)] = next() - 0.3;
            }
        }
        let a = bm.transpose() * &bm + nalgebra::DMatrix::<f64>::identity(n, n) * 0.05;
        let mut band = vec![0.0; n * w];
        for i in 0..n {
            for (o, slot) in band[i * w..(i + 1) * w].iter_mut().enumerate() {
                *slot = a[(i, (i + n + o - p) % n)];
            }
        }
        let b: Vec<f64> = (0..n * 3).map(|_| next() * 10.0 - 5.0).collect();
        let x = solve_cyclic_band_spd(&band, n, p, b.clone(), 3, "test").unwrap();
        let bd = nalgebra::DMatrix::from_row_slice(n, 3, &b);
        let xd = a.clone().lu().solve(&bd).unwrap();
        for i in 0..n {
            for c in 0..3 {
                prop_assert!((x[i * 3 + c] - xd[(i, c)]).abs() < 1e-8 * (1.0 + xd[(i, c)].abs()),
                    "x[{i}][{c}] {} dense {}", x[i * 3 + c], xd[(i, c)]);
            }
        }
    }
}

#[test]
fn cyclic_band_solve_reports_a_singular_matrix() {
    // A 10 x 10 cyclic band (p = 2) whose first row is zero.
    let (n, p) = (10, 2);
    let w = 2 * p + 1;
    let mut band = vec![0.0; n * w];
    for i in 0..n {
        band[i * w + p] = 1.0;
    }
    band[p] = 0.0;
    let e = solve_cyclic_band_spd(&band, n, p, vec![1.0; n], 1, "singular test").unwrap_err();
    assert!(e.to_string().contains("singular test"), "{e}");
}

/// The residuals the closed least squares returns are the distances to the curve it returns,
/// with knots of multiplicity 3 (corners) among the period's.
#[test]
fn closed_least_squares_residuals_are_the_curve_distances() {
    let pts = girth(300, 60.0, 40.0);
    let params = parameters(&pts, Param::ChordLength, true).unwrap();
    let mut period: Vec<f64> = (0..40).map(|j| params[j * 300 / 40]).collect();
    period.extend([params[150], params[150]]);
    period.sort_by(f64::total_cmp);
    let (c, res) = least_squares_closed_residuals(&pts, &params, 3, &period).unwrap();
    let c2 = least_squares_closed_with_knots(&pts, &params, 3, &period).unwrap();
    assert_eq!(c, c2);
    assert_eq!(res.len(), pts.len());
    let worst = pts
        .iter()
        .zip(&params)
        .zip(&res)
        .map(|((q, &u), r)| ((c.point(u) - q).norm() - r).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-9, "residuals differ from evaluation by {worst}");
    assert!(res.iter().cloned().fold(0.0, f64::max) < 0.05);
}
