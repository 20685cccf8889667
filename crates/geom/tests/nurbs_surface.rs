//! Surface curvature on analytic shapes, surface knot operations, skinning, grid
//! interpolation and the Gordon-style sum of compatible surfaces.

use footscan_geom::nurbs::fit::{fit_closed_adaptive, interpolate_closed, parameters};
use footscan_geom::nurbs::skin::{interpolate_grid, make_compatible, skin, skin_closed};
use footscan_geom::nurbs::{make_surfaces_compatible, FitOptions, NurbsCurve, NurbsSurface, Param};
use footscan_geom::{P3, V3};
use proptest::prelude::*;

fn circle(r: f64, z: f64) -> NurbsCurve {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let xy = [
        (1.0, 0.0),
        (1.0, 1.0),
        (0.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 0.0),
        (-1.0, -1.0),
        (0.0, -1.0),
        (1.0, -1.0),
        (1.0, 0.0),
    ];
    let pts = xy.iter().map(|&(x, y)| P3::new(r * x, r * y, z)).collect();
    let w = vec![1.0, s, 1.0, s, 1.0, s, 1.0, s, 1.0];
    let knots = vec![
        0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0,
    ];
    NurbsCurve::new(2, knots, pts, Some(w)).unwrap()
}

/// A sphere of radius r as the surface of revolution of a half circle (rational).
fn sphere(r: f64) -> NurbsSurface {
    let s = std::f64::consts::FRAC_1_SQRT_2;
    // Meridian in the xz plane from the south to the north pole.
    let mer = [
        (0.0, -1.0, 1.0),
        (1.0, -1.0, s),
        (1.0, 0.0, 1.0),
        (1.0, 1.0, s),
        (0.0, 1.0, 1.0),
    ];
    let c = circle(1.0, 0.0);
    let mut pts = Vec::new();
    let mut w = Vec::new();
    for &(mx, mz, mw) in &mer {
        for (j, q) in c.points.iter().enumerate() {
            pts.push(P3::new(r * mx * q.x, r * mx * q.y, r * mz));
            w.push(mw * c.weight(j));
        }
    }
    NurbsSurface::new(
        2,
        2,
        vec![0.0, 0.0, 0.0, 0.5, 0.5, 1.0, 1.0, 1.0],
        c.knots.clone(),
        5,
        9,
        pts,
        Some(w),
    )
    .unwrap()
}

#[test]
fn sphere_curvatures() {
    let r = 20.0;
    let s = sphere(r);
    for i in 1..10 {
        for j in 0..=10 {
            let (u, v) = (0.05 + 0.9 * i as f64 / 10.0, j as f64 / 10.0);
            let p = s.point(u, v);
            assert!((p.coords.norm() - r).abs() < 1e-12);
            let k = s.curvature(u, v);
            // The normal Su x Sv points inward or outward; curvatures follow its sign.
            let sign = -k.normal.dot(&p.coords.normalize()).signum();
            assert!(
                (k.gaussian - 1.0 / (r * r)).abs() < 1e-9,
                "K = {}",
                k.gaussian
            );
            assert!((k.mean - sign / r).abs() < 1e-9, "H = {}", k.mean);
            assert!((k.k1 - k.k2).abs() < 1e-6);
            let t = V3::new(1.0, 2.0, 3.0);
            let t = t - t.dot(&k.normal) * k.normal;
            assert!((s.normal_curvature(u, v, &t) - sign / r).abs() < 1e-9);
        }
    }
}

#[test]
fn cylinder_principal_curvatures() {
    let r = 7.0;
    let secs = vec![circle(r, 0.0), circle(r, 30.0)];
    let s = skin(&secs, None, 1).unwrap();
    for i in 0..=10 {
        let (u, v) = (i as f64 / 10.0, 0.37);
        let k = s.curvature(u, v);
        assert!(k.gaussian.abs() < 1e-12);
        assert!((k.k1.abs().max(k.k2.abs()) - 1.0 / r).abs() < 1e-9);
        assert!(k.k1.abs().min(k.k2.abs()) < 1e-9);
        // Principal direction of zero curvature runs along the axis.
        let d0 = if k.k1.abs() < k.k2.abs() {
            k.dir1
        } else {
            k.dir2
        };
        assert!(d0.cross(&V3::z()).norm() < 1e-6, "{d0:?}");
    }
}

fn wavy_surface() -> NurbsSurface {
    let (nu, nv) = (6, 7);
    let pts: Vec<P3> = (0..nu)
        .flat_map(|i| {
            (0..nv).map(move |j| {
                P3::new(
                    10.0 * i as f64,
                    12.0 * j as f64,
                    5.0 * ((i * j) as f64).sin(),
                )
            })
        })
        .collect();
    let ku = vec![0.0, 0.0, 0.0, 0.0, 0.3, 0.6, 1.0, 1.0, 1.0, 1.0];
    let kv = vec![0.0, 0.0, 0.0, 0.2, 0.4, 0.7, 0.8, 1.0, 1.0, 1.0];
    NurbsSurface::new(3, 2, ku, kv, nu, nv, pts, None).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    #[test]
    fn surface_refinement_and_elevation_keep_shape(xu in proptest::collection::vec(0.01f64..0.99, 0..5),
                                                   xv in proptest::collection::vec(0.01f64..0.99, 0..5),
                                                   tu in 0usize..3, tv in 0usize..3, rational in any::<bool>()) {
        let mut s = wavy_surface();
        if rational {
            s.weights = Some((0..s.points.len()).map(|k| 0.5 + (k % 5) as f64 * 0.3).collect());
        }
        let r = s.refine_u(&xu).refine_v(&xv).elevate_u(tu).elevate_v(tv);
        r.validate().unwrap();
        prop_assert_eq!(r.degree_u, 3 + tu);
        for i in 0..=12 {
            for j in 0..=12 {
                let (u, v) = (i as f64 / 12.0, j as f64 / 12.0);
                let d = (s.point(u, v) - r.point(u, v)).norm();
                prop_assert!(d < 1e-9, "({u}, {v}): {d}");
            }
        }
    }

    #[test]
    fn skinning_passes_its_sections(n_sec in 2usize..8, q in 1usize..4, seed in 0u64..1000) {
        // Closed girth-like sections fitted adaptively (different knots each), then skinned.
        let secs: Vec<NurbsCurve> = (0..n_sec).map(|k| {
            let z = 15.0 * k as f64;
            let a = 40.0 + 5.0 * ((k as u64 + seed) % 7) as f64;
            let pts: Vec<P3> = (0..60).map(|i| {
                let t = i as f64 / 60.0 * std::f64::consts::TAU;
                P3::new(a * t.cos(), 30.0 * t.sin() * (1.0 + 0.1 * (k as f64 * t).cos()), z + 2.0 * t.sin())
            }).collect();
            fit_closed_adaptive(&pts, &FitOptions { tolerance: 0.05, ..Default::default() }).unwrap().curve
        }).collect();
        let v: Vec<f64> = (0..n_sec).map(|k| k as f64 / (n_sec - 1) as f64).collect();
        let s = skin(&secs, Some(&v), q).unwrap();
        prop_assert!(s.periodic_u);
        for (k, c) in secs.iter().enumerate() {
            let (a, b) = c.domain();
            for i in 0..=40 {
                let t = i as f64 / 40.0;
                let d = (s.point(t, v[k]) - c.point(a + (b - a) * t)).norm();
                prop_assert!(d < 1e-9, "section {k} at {t}: {d}");
            }
        }
    }
}

#[test]
fn compatible_curves_keep_shape() {
    let a = circle(10.0, 0.0);
    let pts: Vec<P3> = (0..30)
        .map(|i| {
            let t = i as f64 / 29.0;
            P3::new(100.0 * t, 10.0 * (5.0 * t).sin(), 0.0)
        })
        .collect();
    let b = footscan_geom::nurbs::fit::interpolate(&pts, 3, Param::ChordLength).unwrap();
    let c = make_compatible(&[a.clone(), b.clone()]).unwrap();
    assert_eq!(c[0].degree, 3);
    assert_eq!(c[0].knots, c[1].knots);
    for i in 0..=100 {
        let t = i as f64 / 100.0;
        assert!((c[0].point(t) - a.point(t)).norm() < 1e-9);
        assert!((c[1].point(t) - b.point(t)).norm() < 1e-9);
    }
    let e = make_compatible(&[
        a,
        interpolate_closed(&pts[..10], 3, Param::ChordLength).unwrap(),
    ])
    .unwrap_err();
    assert!(e.to_string().contains("periodic"), "{e}");
}

/// The Gordon construction on a network from a known surface: sections (u-curves at v_l),
/// guides (v-curves at u_k) and the crossing grid give S_sections + S_guides - T, which
/// passes through every curve of the network.
#[test]
fn gordon_sum_passes_the_network() {
    let f = |u: f64, v: f64| {
        P3::new(
            60.0 * (std::f64::consts::TAU * u).cos() * (1.0 + 0.2 * v),
            40.0 * (std::f64::consts::TAU * u).sin(),
            100.0 * v + 3.0 * (4.0 * std::f64::consts::PI * u).sin() * v * v,
        )
    };
    let (nk, nl) = (8, 5);
    let us: Vec<f64> = (0..nk).map(|k| k as f64 / nk as f64).collect();
    let vs: Vec<f64> = (0..nl).map(|l| l as f64 / (nl - 1) as f64).collect();
    // Sections: closed u-curves through 40 samples each, at parameters shared by all.
    let su: Vec<f64> = (0..40).map(|i| i as f64 / 40.0).collect();
    let sections: Vec<NurbsCurve> = vs
        .iter()
        .map(|&v| {
            let pts: Vec<P3> = su.iter().map(|&u| f(u, v)).collect();
            footscan_geom::nurbs::fit::interpolate_closed_with(&pts, &su, 3).unwrap()
        })
        .collect();
    // Guides: open v-curves through 20 samples at each u_k.
    let sv: Vec<f64> = (0..20).map(|i| i as f64 / 19.0).collect();
    let guides: Vec<NurbsCurve> = us
        .iter()
        .map(|&u| {
            let pts: Vec<P3> = sv.iter().map(|&v| f(u, v)).collect();
            footscan_geom::nurbs::fit::interpolate_with(&pts, &sv, 3, None).unwrap()
        })
        .collect();
    // The crossings must agree between sections and guides (they do up to interpolation
    // error, which the construction inherits); use the sections' values.
    let grid: Vec<P3> = (0..nk)
        .flat_map(|k| (0..nl).map(move |l| (k, l)))
        .map(|(k, l)| sections[l].point(us[k]))
        .collect();
    let s1 = skin(&sections, Some(&vs), 3).unwrap(); // u: section parameter, v: across
                                                     // Guides skinned along u (closed), then transposed so u stays the periodic direction.
    let g_closed = skin_closed(&guides, &us, 3).unwrap().transposed();
    let t = interpolate_grid(&grid, &us, &vs, 3, 3, true).unwrap();
    let c = make_surfaces_compatible(&[s1, g_closed, t]).unwrap();
    let g = c[0].try_add(&c[1]).unwrap().try_sub(&c[2]).unwrap();
    // The network is consistent only up to the interpolation error of its curves (the
    // crossing values differ by that much between a section and a guide); the Gordon
    // surface reproduces every curve to within that mismatch.
    let mismatch = (0..nk)
        .flat_map(|k| (0..nl).map(move |l| (k, l)))
        .map(|(k, l)| (sections[l].point(us[k]) - guides[k].point(vs[l])).norm())
        .fold(0.0f64, f64::max);
    let mut worst = 0.0f64;
    for (l, sec) in sections.iter().enumerate() {
        for i in 0..=50 {
            let u = i as f64 / 50.0;
            worst = worst.max((g.point(u, vs[l]) - sec.point(u)).norm());
        }
    }
    for (k, gd) in guides.iter().enumerate() {
        for i in 0..=50 {
            let v = i as f64 / 50.0;
            worst = worst.max((g.point(us[k], v) - gd.point(v)).norm());
        }
    }
    eprintln!("gordon: network mismatch {mismatch:.2e} mm, surface to curves {worst:.2e} mm");
    assert!(
        worst <= 2.0 * mismatch + 1e-9,
        "{worst} vs mismatch {mismatch}"
    );
}

#[test]
fn grid_interpolation_passes_its_points() {
    let us: Vec<f64> = (0..9).map(|k| k as f64 / 9.0).collect();
    let vs: Vec<f64> = vec![0.0, 0.1, 0.35, 0.6, 1.0];
    let f = |u: f64, v: f64| P3::new(30.0 * (5.0 * u).cos(), 30.0 * (5.0 * u).sin(), 50.0 * v * v);
    let grid: Vec<P3> = us
        .iter()
        .flat_map(|&u| vs.iter().map(move |&v| f(u, v)))
        .collect();
    for periodic in [false, true] {
        let s = interpolate_grid(&grid, &us, &vs, 3, 3, periodic).unwrap();
        for (k, &u) in us.iter().enumerate() {
            for (l, &v) in vs.iter().enumerate() {
                assert!((s.point(u, v) - grid[k * vs.len() + l]).norm() < 1e-9);
            }
        }
    }
    let _ = parameters;
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(60))]

    /// Periodic grid interpolation reaches every grid point, also with unevenly spaced
    /// sites in u (a gap as wide as a third of the period), any start u0, and degrees 1-4.
    #[test]
    fn periodic_grid_interpolation_passes_its_data(
        gaps in proptest::collection::vec(0.2f64..5.0, 5..30),
        u0 in -0.7f64..0.7,
        p in 1usize..5,
        q in 1usize..4,
        nl in 2usize..6,
    ) {
        let total: f64 = gaps.iter().sum();
        let mut us = Vec::with_capacity(gaps.len());
        let mut acc = u0;
        for g in &gaps {
            us.push(acc);
            acc += g / total;
        }
        let vs: Vec<f64> = (0..nl).map(|l| (l as f64 / (nl - 1) as f64).powf(1.3)).collect();
        let f = |u: f64, v: f64| {
            let t = std::f64::consts::TAU * u;
            P3::new(40.0 * t.cos() * (1.0 + 0.3 * v), 25.0 * t.sin() + 4.0 * (3.0 * t).cos(), 80.0 * v + 5.0 * t.sin() * v)
        };
        let grid: Vec<P3> = us.iter().flat_map(|&u| vs.iter().map(move |&v| f(u, v))).collect();
        let s = interpolate_grid(&grid, &us, &vs, p, q, true).unwrap();
        prop_assert!(s.periodic_u);
        for (k, &u) in us.iter().enumerate() {
            for (l, &v) in vs.iter().enumerate() {
                let d = (s.point(u, v) - grid[k * nl + l]).norm();
                prop_assert!(d < 1e-9, "site {k} u={u} v={v}: {d} mm");
            }
        }
    }
}
