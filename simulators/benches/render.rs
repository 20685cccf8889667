//! Renderer throughput: frames per second at 1280x1024 on one core.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use footscan_hal::Pixels;
use footscan_sim::foot::{Foot, FootParams};
use footscan_sim::optics::Optics;
use footscan_sim::render::{FrameTruth, NoiseConfig, Renderer, Scene};

fn bench(c: &mut Criterion) {
    let mut g = c.benchmark_group("render_1280x1024_gray8");
    g.throughput(Throughput::Elements(1));
    let scenes = [
        (
            "foot",
            Scene::Foot(Foot::new(FootParams::default()).unwrap()),
        ),
        ("plate", Scene::Plate { height_mm: 10.0 }),
        ("empty", Scene::Empty),
    ];
    for (name, scene) in scenes {
        let mut r =
            Renderer::new(Optics::default(), NoiseConfig::default(), scene.clone(), 1).unwrap();
        let mut px = Pixels::Gray8(Vec::new());
        let mut t = FrameTruth::default();
        let mut k = 0u64;
        g.bench_function(format!("{name}_noise"), |b| {
            b.iter(|| {
                // Sweep the head so the foot scene shows different sections.
                let x = (k % 640) as f64 * 0.5;
                r.render_into(x, k, &mut px, &mut t);
                k += 1;
            })
        });
        let r2 = Renderer::new(Optics::default(), NoiseConfig::default(), scene, 1).unwrap();
        g.bench_function(format!("{name}_truth_only"), |b| {
            b.iter(|| {
                let x = (k % 640) as f64 * 0.5;
                r2.truth_into(x, &mut t);
                k += 1;
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
