//! Mesh benchmarks on the real last LastScan_Default.stl (6,784 triangles): 100 plane
//! sections, signed-distance queries, STL loading. The data directory is FOOTSCAN_DATA or
//! the shared data directory beside the repository.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use footscan_geom::mesh::{Bvh, TriMesh, Units};
use footscan_geom::plane::Plane;
use footscan_geom::{P3, V3};
use std::path::PathBuf;

fn last_path() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let p = base.join("lasts/LastScan_Default.stl");
    assert!(p.is_file(), "{} not found (set FOOTSCAN_DATA)", p.display());
    p
}

fn bench(c: &mut Criterion) {
    let path = last_path();
    let (m, _) = TriMesh::load_solid(&path, Units::Auto, None).unwrap();
    let b = m.bbox();
    let axis = b.longest_axis();
    let planes: Vec<Plane> = (0..100)
        .map(|k| {
            Plane::axis_aligned(
                axis,
                b.min[axis] + b.extent()[axis] * (k as f64 + 0.5) / 100.0,
            )
        })
        .collect();
    c.bench_function("section_100_planes_last_6784", |bn| {
        bn.iter(|| planes.iter().map(|p| m.section(p).len()).sum::<usize>())
    });
    // Oblique planes too (sections across the last at 30 degrees).
    let oblique: Vec<Plane> = (0..100)
        .map(|k| {
            let mut o = b.center();
            o[axis] = b.min[axis] + b.extent()[axis] * (k as f64 + 0.5) / 100.0;
            let mut n = V3::new(0.0, 0.0, 0.5);
            n[axis] = 0.866;
            Plane::new(o, n).unwrap()
        })
        .collect();
    c.bench_function("section_100_oblique_planes_last_6784", |bn| {
        bn.iter(|| oblique.iter().map(|p| m.section(p).len()).sum::<usize>())
    });

    c.bench_function("bvh_build_last_6784", |bn| bn.iter(|| Bvh::new(&m)));
    let bvh = Bvh::new(&m);
    // 1000 query points in the box grown by 20 mm (inside, near and outside the surface).
    let g = b.inflated(20.0);
    let mut x = 0x9E3779B97F4A7C15u64;
    let mut r = || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let pts: Vec<P3> = (0..1000)
        .map(|_| {
            let e = g.extent();
            g.min + V3::new(r() * e.x, r() * e.y, r() * e.z)
        })
        .collect();
    let mut grp = c.benchmark_group("signed_distance_last_6784");
    grp.throughput(Throughput::Elements(pts.len() as u64));
    grp.bench_function("1000_queries", |bn| {
        bn.iter(|| {
            pts.iter()
                .map(|p| bvh.signed_distance(p).unwrap().distance)
                .sum::<f64>()
        })
    });
    grp.bench_function("1000_rays", |bn| {
        bn.iter(|| {
            pts.iter()
                .filter_map(|p| bvh.ray_cast(p, &V3::new(0.0, 0.0, -1.0), f64::INFINITY))
                .count()
        })
    });
    grp.finish();

    let bytes = std::fs::read(&path).unwrap();
    c.bench_function("stl_parse_last_6784", |bn| {
        bn.iter(|| TriMesh::parse_stl(&bytes, &path).unwrap().0.vertices.len())
    });
    c.bench_function("stl_load_validate_scale_last_6784", |bn| {
        bn.iter(|| {
            TriMesh::load_solid(&path, Units::Auto, None)
                .unwrap()
                .0
                .triangles
                .len()
        })
    });
    c.bench_function("validate_last_6784", |bn| {
        bn.iter(|| m.check().unwrap().volume)
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(std::time::Duration::from_secs(3));
    targets = bench
}
criterion_main!(benches);
