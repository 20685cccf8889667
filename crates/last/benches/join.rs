//! Timing of the Gordon join: both real pairs at the paper's settings (2 + 2 auxiliary
//! sections, 500 points) at 45 and 10 deg, then the parameter study table (auxiliary
//! sections, points per section, rotation angle against time and seam quality). The lasts are
//! read from FOOTSCAN_DATA (default: the shared data directory beside the repository).

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use footscan_last::join::{self, study, JoinParams};
use std::path::PathBuf;

fn data_dir() -> PathBuf {
    std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"))
}

fn bench(c: &mut Criterion) {
    let pairs = study::real_pairs(&data_dir()).expect("real last pairs (set FOOTSCAN_DATA)");
    let mut g = c.benchmark_group("join");
    g.sample_size(20);
    for pair in &pairs {
        for angle in [45.0, 10.0] {
            let p = JoinParams {
                angle_deg: angle,
                // The join itself; the fits of the kept parts (seconds, per last) are timed
                // by `footscan bench join`.
                fit_parts: false,
                ..JoinParams::default()
            };
            g.bench_function(format!("{} {angle} deg 500 pts", pair.name), |b| {
                b.iter(|| join::join(black_box(&pair.back), black_box(&pair.toe), &p).unwrap())
            });
        }
    }
    g.finish();
    let rows = study::run(&pairs, &study::paper_cases(), 5).unwrap();
    eprintln!(
        "\nparameter study (time: best of 5 joins)\n{}",
        study::table(&rows)
    );
}

criterion_group!(benches, bench);
criterion_main!(benches);
