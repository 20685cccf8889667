//! Timing of the blend fill beside the Gordon join: both real pairs, every blending function
//! (the fairings included), the join's default placement and planes. The lasts are read from
//! FOOTSCAN_DATA (default: the shared data directory beside the repository).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use footscan_last::blend::fair::Functional;
use footscan_last::blend::weight::Weight;
use footscan_last::blend::{fill, Blend, BlendParams};
use footscan_last::join::{self, study, JoinParams};
use std::path::PathBuf;

fn data_dir() -> PathBuf {
    std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"))
}

fn bench(c: &mut Criterion) {
    let pairs = study::real_pairs(&data_dir()).expect("real last pairs (set FOOTSCAN_DATA)");
    let mut g = c.benchmark_group("blend");
    g.sample_size(20);
    let blends = [
        Blend::Fixed(Weight::Morph),
        Blend::Fixed(Weight::Linear),
        Blend::Fixed(Weight::Poly),
        Blend::Fair(Functional::Variation),
        Blend::Fair(Functional::Energy),
    ];
    for pair in &pairs {
        for b in &blends {
            let p = BlendParams {
                blend: b.clone(),
                ..BlendParams::default()
            };
            g.bench_function(format!("{} blend {}", pair.name, b.name()), |bch| {
                bch.iter(|| fill(black_box(&pair.back), black_box(&pair.toe), &p).unwrap())
            });
        }
        // The Gordon join on the same inputs, for the side-by-side figure.
        // The join itself, without the fits of the kept parts (timed by `footscan bench join`).
        let jp = JoinParams {
            fit_parts: false,
            ..JoinParams::default()
        };
        g.bench_function(format!("{} gordon 45 deg", pair.name), |bch| {
            bch.iter(|| join::join(black_box(&pair.back), black_box(&pair.toe), &jp).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
