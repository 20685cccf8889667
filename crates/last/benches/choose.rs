//! Ranking a shop's collection (docs/method.md 9.5): 40 lasts written as scaled, mirrored and
//! turned copies of the two shared scanned lasts into a temporary directory, each read, size
//! checked, measured (`measure_last`), cut as the clinic path cuts it and judged against the
//! rule targets of a 250 mm right foot. The 2 s asked for 40 lasts is checked here, not in a
//! test.
//!
//! cargo bench -p footscan-last --bench choose

use criterion::{criterion_group, criterion_main, Criterion};
use footscan_geom::mesh::{Format, TriMesh, Units};
use footscan_geom::P3;
use footscan_last::choose::{judge_files, rank, Wanted};
use footscan_last::customize::clinic::{Plantar, TapeGirths};
use footscan_last::customize::measure::Side;
use footscan_last::customize::rules::RuleSet;
use footscan_last::customize::Inputs;
use std::path::{Path, PathBuf};

fn data() -> PathBuf {
    std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"))
}

fn bench(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for (i, name) in ["LastScan_Default.stl", "LastScan_Warped.stl"]
        .iter()
        .enumerate()
    {
        let (m, _) = TriMesh::load_solid(data().join("lasts").join(name), Units::Auto, None)
            .expect("shared last reads");
        for k in 0..20 {
            let s = 0.95 + 0.015 * k as f64;
            let (sn, cs) = ((37.0 * (k + 20 * i) as f64).to_radians()).sin_cos();
            let mirror = k % 2 == 1;
            let mut c = m.clone();
            for p in &mut c.vertices {
                let y = if mirror { -p.y } else { p.y };
                let (x, y) = (s * p.x, s * y);
                *p = P3::new(cs * x - sn * y, sn * x + cs * y, s * p.z);
            }
            if mirror {
                c.flip();
            }
            let f = dir.path().join(format!("{i}_{k:02}.stl"));
            c.write(&f, Format::StlBinary).unwrap();
            files.push(f);
        }
    }
    let foot = Plantar {
        side: Side::Right,
        length: 249.9,
        ball_width: 100.0,
        waist_width: 58.4,
        heel_width: 62.5,
        footprint: Vec::new(),
    };
    let g = TapeGirths::checked(260.0, 248.0, 367.0, 200.5).unwrap();
    let (rules, inp) = (RuleSet::default_rules(), Inputs::default());
    let want = Wanted {
        girths: &g,
        rules: &rules,
        inp: &inp,
    };
    let t = std::time::Instant::now();
    let mut cands: Vec<_> = judge_files(&files, Units::Mm, None, &foot, &want)
        .into_iter()
        .map(|(c, _)| c)
        .collect();
    rank(&mut cands);
    eprintln!(
        "40 lasts ranked in {:.0} ms (first {}, largest change {:.2} mm)",
        t.elapsed().as_secs_f64() * 1e3,
        cands[0].name,
        cands[0].largest_change_mm
    );
    let mut grp = c.benchmark_group("choose");
    grp.sample_size(10);
    grp.bench_function("rank 40 lasts", |b| {
        b.iter(|| {
            let mut c: Vec<_> = judge_files(&files, Units::Mm, None, &foot, &want)
                .into_iter()
                .map(|(c, _)| c)
                .collect();
            rank(&mut c);
            c
        })
    });
    grp.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
