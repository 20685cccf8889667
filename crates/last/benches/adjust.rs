//! Bottom adjustment timing (no file I/O): a full-resolution foot (0.1 mm height grid, as a
//! scan's measurement uses) against each real last, prepared beforehand. Also the last
//! preparation (bottom found and measured by rays) and the deformation of the whole last,
//! which run once per last and per adjustment.
//!
//! cargo bench -p footscan-last --bench adjust

use criterion::{criterion_group, criterion_main, Criterion};
use footscan_geom::mesh::Units;
use footscan_last::adjust::last::{deform_last, prepare_last, LastOptions};
use footscan_last::adjust::synthetic::AnalyticFoot;
use footscan_last::adjust::{adjust, AdjustOptions, Side};
use std::path::{Path, PathBuf};

fn data() -> PathBuf {
    std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"))
}

fn bench(c: &mut Criterion) {
    let foot = AnalyticFoot::new(240.0, Side::Right).plantar(0.1);
    eprintln!(
        "foot grid {} x {} cells of 0.1 mm ({} valid)",
        foot.heights.nx,
        foot.heights.ny,
        foot.heights.valid_count()
    );
    let mut g = c.benchmark_group("adjust");
    g.sample_size(20);
    for (name, units, length) in [
        ("LastScan_Default.stl", Units::M, None),
        ("LastScan_Warped.stl", Units::M, None),
        ("Last_Flat_RoundTip.stl", Units::Auto, Some(252.0)),
        ("Last_Heeled_RoundTip.stl", Units::Auto, Some(252.0)),
    ] {
        let path = data().join("lasts").join(name);
        let opts = LastOptions {
            units,
            length_mm: length,
            ..LastOptions::default()
        };
        let prep = prepare_last(&path, &opts).unwrap();
        let short = name.trim_end_matches(".stl");
        g.bench_function(format!("adjust/{short}"), |b| {
            b.iter(|| adjust(&foot, &prep.bottom, &AdjustOptions::default()).unwrap())
        });
        if name == "LastScan_Default.stl" {
            g.bench_function(format!("prepare/{short}"), |b| {
                b.iter(|| prepare_last(&path, &opts).unwrap())
            });
            let a = adjust(&foot, &prep.bottom, &AdjustOptions::default()).unwrap();
            g.bench_function(format!("deform/{short}"), |b| {
                b.iter(|| deform_last(&prep, &a, 30.0).unwrap())
            });
        }
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
