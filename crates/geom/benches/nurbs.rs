//! NURBS timings: the adaptive closed fit (Algorithm I on a 200-point girth to 0.05 mm),
//! surface evaluation per point, skinning 20 sections of 100 points.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use footscan_geom::nurbs::fit::{fit_closed_adaptive, interpolate_closed, interpolate_closed_with};
use footscan_geom::nurbs::skin::skin;
use footscan_geom::nurbs::{FitOptions, NurbsCurve, Param};
use footscan_geom::P3;

fn girth(n: usize, a: f64, b: f64, z: f64) -> Vec<P3> {
    (0..n)
        .map(|i| {
            let t = i as f64 / n as f64 * std::f64::consts::TAU;
            let r = 1.0 + 0.08 * (3.0 * t).sin();
            P3::new(a * r * t.cos(), b * r * t.sin(), z + 5.0 * (2.0 * t).cos())
        })
        .collect()
}

fn sections(k: usize, n: usize) -> Vec<NurbsCurve> {
    (0..k)
        .map(|s| {
            // Resampled sections share their parameters (as the joining code aligns them).
            let pts = girth(n, 40.0 + s as f64, 30.0 + 0.5 * s as f64, 10.0 * s as f64);
            let t: Vec<f64> = (0..n).map(|i| i as f64 / n as f64).collect();
            interpolate_closed_with(&pts, &t, 3).unwrap()
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let pts = girth(200, 50.0, 40.0, 0.0);
    let r = fit_closed_adaptive(&pts, &FitOptions::default()).unwrap();
    eprintln!(
        "closed fit, 200 points, tol 0.05 mm: {} control points, max {:.4} mm, rms {:.4} mm",
        r.control_points, r.max_error, r.rms_error
    );
    c.bench_function("fit_closed_adaptive 200 pts 0.05 mm", |b| {
        b.iter(|| fit_closed_adaptive(black_box(&pts), &FitOptions::default()).unwrap())
    });

    let secs = sections(20, 100);
    c.bench_function("skin 20 sections x 100 pts (common parameters)", |b| {
        b.iter(|| skin(black_box(&secs), None, 3).unwrap())
    });
    // Sections interpolated at their own chord-length parameters: the union of 20 knot
    // vectors of 100 knots each makes ~2000 control points per section.
    let chord: Vec<NurbsCurve> = (0..20)
        .map(|s| {
            interpolate_closed(
                &girth(100, 40.0 + s as f64, 30.0, 10.0 * s as f64),
                3,
                Param::ChordLength,
            )
            .unwrap()
        })
        .collect();
    c.bench_function("skin 20 sections x 100 pts (own chord-length knots)", |b| {
        b.iter(|| skin(black_box(&chord), None, 3).unwrap())
    });
    // Sections with different knots: the compatibility step (refinement to the union).
    let fitted: Vec<NurbsCurve> = (0..20)
        .map(|s| {
            let p = girth(100, 40.0 + s as f64, 30.0 + 0.5 * s as f64, 10.0 * s as f64);
            fit_closed_adaptive(&p, &FitOptions::default())
                .unwrap()
                .curve
        })
        .collect();
    c.bench_function("skin 20 fitted sections (different knots)", |b| {
        b.iter(|| skin(black_box(&fitted), None, 3).unwrap())
    });
    let surf = skin(&secs, None, 3).unwrap();
    let uv: Vec<(f64, f64)> = (0..1000)
        .map(|i| ((i as f64 * 0.618_034) % 1.0, (i as f64 * 0.414_214) % 1.0))
        .collect();
    c.bench_function("surface point x1000 (bicubic, 103 x 20 ctrl)", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for &(u, v) in &uv {
                acc += surf.point(u, v).x;
            }
            black_box(acc)
        })
    });
    c.bench_function("surface curvature x1000", |b| {
        b.iter(|| {
            let mut acc = 0.0;
            for &(u, v) in &uv {
                acc += surf.curvature(u, v).mean;
            }
            black_box(acc)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
