//! Detector hot paths at 1280x1024 Gray8 on simulated foot frames (default noise): each
//! detector per frame, the coarse block-maximum pass, and the byte-sum floor.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use footscan::detect::coarse::{block_max, BLOCK};
use footscan::detect::{build, sum_bytes, DetectParams, LinePeak, NAMES};
use footscan_bench::detect::{noise_config, sweep_frames};
use footscan_hal::Pixels;

fn bench(c: &mut Criterion) {
    let frames: Vec<_> = sweep_frames(
        &noise_config("default", 1.6),
        &[],
        &[100.0, 160.0, 220.0],
        3,
    )
    .into_iter()
    .map(|(f, _)| f)
    .collect();
    let mut g = c.benchmark_group("detect_1280x1024_gray8");
    g.throughput(Throughput::Elements(1));
    g.sample_size(20);
    let mut k = 0usize;
    g.bench_function("floor_sum_bytes", |b| {
        b.iter(|| {
            k += 1;
            match &frames[k % frames.len()].pixels {
                Pixels::Gray8(v) => sum_bytes(v),
                Pixels::Gray16(_) => unreachable!(),
            }
        })
    });
    g.bench_function("coarse_block_max", |b| {
        let mut blocks = vec![0u8; 1280usize.div_ceil(BLOCK)];
        b.iter(|| {
            k += 1;
            if let Pixels::Gray8(v) = &frames[k % frames.len()].pixels {
                for row in v.chunks_exact(1280) {
                    block_max(row, &mut blocks);
                }
            }
            blocks[0]
        })
    });
    for name in NAMES {
        let mut d = build(name, &DetectParams::default()).unwrap();
        let mut out = vec![LinePeak::NONE; 1024];
        g.bench_function(name, |b| {
            b.iter(|| {
                k += 1;
                d.detect(&frames[k % frames.len()], &mut out);
            })
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
