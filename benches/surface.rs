//! Criterion benchmarks of the plantar model on the simulator's analytic foot sampled like a
//! scan (0.5 mm frames, 0.125 mm rows): the Bezier network's build and evaluation in the
//! Table-1 configuration (88 x 91 sub-grid, 32 points per segment) and at full resolution,
//! its height map, and the comparators' builds on the Table-1 grid.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use footscan::surface::compare::{Fitted, Method};
use footscan::surface::{BezierNetwork, PointGrid};
use footscan_sim::foot::{Foot, FootParams};

fn scan_like_grid() -> PointGrid {
    let foot = Foot::new(FootParams::default()).expect("default foot");
    let xs: Vec<f64> = (0..642).map(|i| 70.0 + 0.5 * i as f64).collect();
    let ys: Vec<f64> = (0..1024).map(|j| -64.0 + 0.125 * j as f64).collect();
    PointGrid::sample(|x, y| foot.height(x, y), &xs, &ys)
}

fn bench(c: &mut Criterion) {
    let full = scan_like_grid();
    let t1 = full.subsample(&full.even_subsample(88, 91).unwrap());
    let us: Vec<f64> = (0..4).map(|p| (p as f64 + 0.5) / 4.0).collect();
    let vs: Vec<f64> = (0..8).map(|q| (q as f64 + 0.5) / 8.0).collect();
    let mut g = c.benchmark_group("bezier_network");
    g.bench_function("table1_build_and_eval", |b| {
        b.iter(|| {
            let n = BezierNetwork::build(black_box(&t1)).unwrap();
            let mut out = Vec::new();
            n.eval_pattern(&us, &vs, &mut out);
            out
        })
    });
    g.sample_size(20);
    g.bench_function("full_build", |b| {
        b.iter(|| BezierNetwork::build(black_box(&full)).unwrap())
    });
    let net = BezierNetwork::build(&full).unwrap();
    g.bench_function("full_eval_32_per_segment", |b| {
        b.iter(|| {
            let mut out = Vec::new();
            net.eval_pattern(&us, &vs, &mut out);
            out
        })
    });
    g.bench_function("full_heightmap_0.5mm", |b| {
        b.iter(|| net.eval_heightmap(0.5))
    });
    g.finish();
    let mut g = c.benchmark_group("table1_build");
    g.sample_size(20);
    for m in Method::all() {
        g.bench_function(m.name(), |b| {
            b.iter(|| Fitted::build(m, black_box(&t1)).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
