//! The discrete extension and the morph against a smooth surface with known slices.

use footscan_geom::P3;
use footscan_last::blend::blend_slices;
use footscan_last::blend::extend::{by_curve_extension, extend, morph, morph_shift};
use footscan_last::blend::weight::Weight;

/// A smooth last-like tube: slices z = const are ellipses with semi-axes varying in z.
fn at(theta: f64, z: f64) -> P3 {
    let a = 30.0 + 5.0 * (z / 20.0).sin();
    let b = 20.0 + 0.01 * z * z + 0.1 * z;
    P3::new(a * theta.cos(), b * theta.sin(), z)
}

fn slice(z: f64, n: usize, open: bool) -> Vec<P3> {
    let span = if open {
        std::f64::consts::PI
    } else {
        std::f64::consts::TAU
    };
    let m = if open { n - 1 } else { n };
    (0..n).map(|i| at(span * i as f64 / m as f64, z)).collect()
}

/// Largest distance of `pts` from the true slice at `z` (dense sampling), and the largest
/// distance from the slice plane.
fn errors(pts: &[P3], z: f64) -> (f64, f64) {
    let dense: Vec<P3> = (0..20000)
        .map(|i| at(std::f64::consts::TAU * i as f64 / 20000.0, z))
        .collect();
    let mut e: f64 = 0.0;
    let mut plane: f64 = 0.0;
    for p in pts {
        plane = plane.max((p.z - z).abs());
        let q = P3::new(p.x, p.y, z);
        let d = dense
            .iter()
            .map(|s| (s - q).norm())
            .fold(f64::INFINITY, f64::min);
        e = e.max(d);
    }
    (e, plane)
}

#[test]
fn extension_slices_lie_on_their_planes_and_converge_to_the_surface() {
    let mut prev = None;
    for d in [4.0, 2.0, 1.0] {
        let (o, p, q) = (
            slice(-2.0 * d, 200, false),
            slice(-d, 200, false),
            slice(0.0, 200, false),
        );
        let e = extend(&o, &p, &q, true);
        assert_eq!(e.by_curve, 0);
        let (er, pr) = errors(&e.r, 0.5 * d);
        let (es, ps) = errors(&e.s, d);
        println!("d {d}: R off the surface {er:.2e} mm, S {es:.2e} mm");
        assert!(
            pr < 1e-9 && ps < 1e-9,
            "slices leave their planes: {pr} {ps}"
        );
        // Position error of second order in the step (the tangent condition is a first
        // difference): it falls about 4 times per halving.
        if let Some((r0, s0)) = prev {
            assert!(
                r0 / er > 3.0 && s0 / es > 3.0,
                "d {d}: R {r0}->{er}, S {s0}->{es}"
            );
        }
        assert!(
            er < 0.05 * d * d && es < 0.05 * d * d,
            "d {d}: R {er}, S {es}"
        );
        prev = Some((er, es));
    }
}

#[test]
fn open_slices_get_their_end_points_by_curve_extension() {
    let d = 1.0;
    let (o, p, q) = (
        slice(-2.0 * d, 101, true),
        slice(-d, 101, true),
        slice(0.0, 101, true),
    );
    let e = extend(&o, &p, &q, false);
    assert_eq!(e.by_curve, 2);
    let (er, _) = errors(&e.r, 0.5 * d);
    let (es, _) = errors(&e.s, d);
    assert!(er < 0.05 && es < 0.05, "R {er}, S {es}");
    // The ends are the Bezier extension exactly.
    let (r0, s0) = by_curve_extension(&o[0], &p[0], &q[0]);
    assert_eq!(e.r[0], r0);
    assert_eq!(e.s[0], s0);
    assert!((r0.z - 0.5).abs() < 1e-12 && (s0.z - 1.0).abs() < 1e-12);
}

#[test]
fn morph_is_linear_between_its_slices_and_finds_the_shift() {
    let a = slice(0.0, 120, false);
    let mut b = slice(10.0, 120, false);
    b.rotate_left(7);
    let k = morph_shift(&a, &b, &footscan_geom::V3::y());
    assert_eq!(k, 120 - 7);
    b.rotate_left(k);
    let m = morph(&a, 0.0, &b, 10.0, 2.5);
    for (i, p) in m.iter().enumerate() {
        let want = a[i] + (b[i] - a[i]) * 0.25;
        assert!((p - want).norm() < 1e-12);
    }
}

#[test]
fn blend_of_a_smooth_tube_stays_on_it_and_the_morph_alone_is_linear() {
    // Back part below z = 0 and toe part above z = 12 of the same tube: every blend should
    // give back the tube to within the extension's and the morph's own error.
    let (gap, k) = (12.0, 3);
    let d = gap / (2 * k) as f64;
    let sl = |z: f64| slice(z, 160, false);
    let (bo, bp, bq) = (sl(-2.0 * d), sl(-d), sl(0.0));
    let (to, tp, tq) = (sl(gap + 2.0 * d), sl(gap + d), sl(gap));
    for w in [
        Weight::Morph,
        Weight::Linear,
        Weight::Poly,
        Weight::Extension,
    ] {
        let fronts = blend_slices([&bo, &bp, &bq], [&to, &tp, &tq], gap, k, &|t| w.at(t));
        let fs = fronts.slices;
        assert_eq!(fs.len(), 4 * k + 1);
        let worst = fs
            .iter()
            .map(|(z, pts)| errors(pts, *z).0)
            .fold(0.0, f64::max);
        println!("{:?}: worst distance from the tube {worst:.3} mm", w);
        assert!(worst < 0.6, "{w:?}: {worst}");
        if w == Weight::Morph {
            for (z, pts) in &fs {
                let m = morph(&bq, 0.0, &tq, gap, *z);
                let dev = pts
                    .iter()
                    .zip(&m)
                    .map(|(a, b)| (a - b).norm())
                    .fold(0.0, f64::max);
                assert!(dev < 1e-9, "morph alone at z {z}: {dev}");
            }
        }
    }
}
