//! Knot insertion, refinement, degree elevation, splitting and reversing keep the shape.

use footscan_geom::nurbs::NurbsCurve;
use footscan_geom::P3;
use proptest::prelude::*;

/// A random open curve: degree 1..=5, clamped, random interior knots (some repeated),
/// optionally rational.
fn open_curve() -> impl Strategy<Value = NurbsCurve> {
    (1usize..=5, 0usize..8, any::<bool>(), any::<u64>()).prop_map(|(p, inner, rational, seed)| {
        let mut rng = Lcg(seed);
        let n = p + 1 + inner;
        // Interior knots at least 0.1 apart (or exactly repeated): nearly coincident knots
        // make ill-conditioned spans that no real fit produces.
        let mut ks: Vec<f64> = (0..inner)
            .map(|i| (i as f64 + 0.1 + 0.8 * rng.next()) * 10.0 / inner as f64)
            .collect();
        if inner >= 2 && p >= 2 {
            ks[1] = ks[0]; // a double knot
        }
        ks.sort_by(|a, b| a.total_cmp(b));
        let mut knots = vec![0.0; p + 1];
        knots.extend(ks);
        knots.extend(vec![10.0; p + 1]);
        let points = (0..n)
            .map(|_| P3::new(rng.next() * 100.0, rng.next() * 100.0, rng.next() * 50.0))
            .collect();
        let weights = rational.then(|| (0..n).map(|_| 0.3 + rng.next() * 2.0).collect());
        NurbsCurve::new(p, knots, points, weights).unwrap()
    })
}

/// A random periodic curve in stored unclamped form.
fn periodic_curve() -> impl Strategy<Value = NurbsCurve> {
    (1usize..=4, 0usize..6, any::<bool>(), any::<u64>()).prop_map(|(p, extra, rational, seed)| {
        let mut rng = Lcg(seed);
        let nu = p + 1 + extra;
        let mut period: Vec<f64> = (0..nu)
            .map(|i| (i as f64 + 0.1 + 0.8 * rng.next()) * 4.0 / nu as f64)
            .collect();
        period.sort_by(|a, b| a.total_cmp(b));
        period[0] = 0.0;
        let t = 4.0;
        let knots: Vec<f64> = (0..(nu + 2 * p + 1) as isize)
            .map(|i| {
                let j = i - p as isize;
                period[j.rem_euclid(nu as isize) as usize] + j.div_euclid(nu as isize) as f64 * t
            })
            .collect();
        let mut points: Vec<P3> = (0..nu)
            .map(|_| P3::new(rng.next() * 100.0, rng.next() * 100.0, rng.next() * 50.0))
            .collect();
        let w: Vec<f64> = (0..nu).map(|_| 0.3 + rng.next() * 2.0).collect();
        for k in 0..p {
            points.push(points[k]);
        }
        let weights = rational.then(|| (0..nu + p).map(|i| w[i % nu]).collect());
        NurbsCurve::new_periodic(p, knots, points, weights).unwrap()
    })
}

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn same_shape(a: &NurbsCurve, b: &NurbsCurve, tol: f64) -> Result<(), TestCaseError> {
    let (s, e) = a.domain();
    let (s2, e2) = b.domain();
    prop_assert!(
        (s - s2).abs() < 1e-12 && (e - e2).abs() < 1e-12,
        "domains {:?} {:?}",
        a.domain(),
        b.domain()
    );
    for i in 0..=200 {
        let u = s + (e - s) * i as f64 / 200.0;
        let d = (a.point(u) - b.point(u)).norm();
        prop_assert!(d < tol, "u = {u}: {d} mm apart");
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn insertion_keeps_shape(c in open_curve(), t in 0.0f64..1.0, r in 1usize..4) {
        let u = 10.0 * t;
        let d = c.insert_knot(u, r).unwrap();
        d.validate().unwrap();
        same_shape(&c, &d, 1e-9)?;
    }

    #[test]
    fn refinement_keeps_shape(c in open_curve(), xs in proptest::collection::vec(0.0f64..10.0, 1..12)) {
        let d = c.refine_knots(&xs).unwrap();
        d.validate().unwrap();
        prop_assert!(d.points.len() <= c.points.len() + xs.len());
        same_shape(&c, &d, 1e-9)?;
    }

    #[test]
    fn elevation_keeps_shape(c in open_curve(), t in 1usize..4) {
        let d = c.elevate_degree(t);
        d.validate().unwrap();
        prop_assert_eq!(d.degree, c.degree + t);
        same_shape(&c, &d, 1e-9)?;
    }

    #[test]
    fn periodic_refinement_keeps_shape(c in periodic_curve(), xs in proptest::collection::vec(0.0f64..4.0, 1..6)) {
        let (a, b) = c.domain();
        let xs: Vec<f64> = xs.iter().map(|x| a + (b - a) * x / 4.0).collect();
        let d = c.refine_knots(&xs).unwrap();
        d.validate().unwrap();
        prop_assert!(d.periodic);
        prop_assert!(d.points.len() <= c.points.len() + xs.len());
        same_shape(&c, &d, 1e-9)?;
    }

    #[test]
    fn periodic_elevation_keeps_shape(c in periodic_curve(), t in 1usize..3) {
        let d = c.elevate_degree(t);
        d.validate().unwrap();
        prop_assert!(d.periodic);
        same_shape(&c, &d, 1e-9)?;
    }

    #[test]
    fn periodic_seam_and_clamp(c in periodic_curve(), s in 0.0f64..1.0) {
        let (a, b) = c.domain();
        let cl = c.to_clamped();
        cl.validate().unwrap();
        same_shape(&c, &cl, 1e-9)?;
        let u0 = a + (b - a) * s;
        let d = c.with_seam_at(u0).unwrap();
        d.validate().unwrap();
        for i in 0..=50 {
            let u = u0 + (b - a) * i as f64 / 50.0;
            prop_assert!((c.point(u) - d.point(u)).norm() < 1e-9);
        }
    }

    #[test]
    fn split_and_reverse(c in open_curve(), t in 0.05f64..0.95) {
        let u = 10.0 * t;
        let (l, r) = c.split(u).unwrap();
        l.validate().unwrap();
        r.validate().unwrap();
        for i in 0..=50 {
            let v = u * i as f64 / 50.0;
            prop_assert!((l.point(v) - c.point(v)).norm() < 1e-9);
            let w = u + (10.0 - u) * i as f64 / 50.0;
            prop_assert!((r.point(w) - c.point(w)).norm() < 1e-9);
        }
        let rv = c.reversed();
        rv.validate().unwrap();
        for i in 0..=50 {
            let v = 10.0 * i as f64 / 50.0;
            prop_assert!((rv.point(10.0 - v) - c.point(v)).norm() < 1e-9);
        }
        let un = c.reparametrized_unit();
        prop_assert_eq!(un.domain(), (0.0, 1.0));
        prop_assert!((un.point(0.3) - c.point(3.0)).norm() < 1e-9);
    }
}
