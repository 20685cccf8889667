//! Fuzzing of the readers of outside files that are not meshes: grid.bin, the scanner's TOML
//! config, calibration plans and last rule files. proptest feeds each arbitrary bytes and
//! mutations of a valid file; a counting global allocator measures the most each call holds
//! at once. None may panic; each holds at most 4 x its input plus a fixed bound.
//!
//! The normal run tries a bounded number of cases (seconds); a longer one:
//!
//! ```text
//! FOOTSCAN_FUZZ_CASES=20000 cargo test -p footscan --release --test fuzz_inputs
//! ```
//!
//! The mesh readers have their own harness (crates/geom/tests/fuzz_readers.rs), the GRBL
//! answers and V4L2 buffers theirs (drivers/*/tests/fuzz_*.rs), HTTP bodies theirs
//! (crates/daemon/tests/daemon_doors.rs).

use footscan::calib::CalibrationPlan;
use footscan::scandata::ScanGrid;
use footscan_fuzzkit::{peak_of, Counting};
use proptest::prelude::*;
use std::path::Path;

/// Bytes held per byte of input, at most.
const RATIO: usize = 4;
/// Bytes held whatever the input: the config's and rule set's own structures, the TOML
/// parser's tables, error messages.
const FIXED: usize = 512 * 1024;

// The allocator that counts what each thread holds (crates/fuzzkit).
#[global_allocator]
static A: Counting = Counting;

fn grid_bin(b: &[u8]) {
    drop(ScanGrid::parse(b, Path::new("fuzz/grid.bin")));
}

fn scanner_config(b: &[u8]) {
    let text = String::from_utf8_lossy(b).into_owned();
    drop(footscan::scan::LoadedConfig::parse(
        Path::new("fuzz/scanner.toml"),
        text,
    ));
}

fn plan(b: &[u8]) {
    if let Ok(text) = std::str::from_utf8(b) {
        if let Ok(p) = toml::from_str::<CalibrationPlan>(text) {
            drop(p.validate());
        }
    }
}

fn rules(b: &[u8]) {
    if let Ok(text) = std::str::from_utf8(b) {
        drop(footscan_last::customize::rules::RuleSet::parse(
            text,
            "fuzz/rules.toml",
        ));
    }
}

type Reader = fn(&[u8]);
const READERS: [(&str, Reader); 4] = [
    ("grid.bin", grid_bin),
    ("scanner config", scanner_config),
    ("calibration plan", plan),
    ("rule file", rules),
];

fn check(name: &str, read: Reader, bytes: &[u8]) -> Result<(), String> {
    let (peak, panicked) = peak_of(|| read(bytes));
    if panicked {
        return Err(format!("{name} reader panicked on {} bytes", bytes.len()));
    }
    let bound = RATIO * bytes.len() + FIXED;
    if peak > bound {
        return Err(format!(
            "{name} reader held {peak} bytes for {} bytes (bound {bound})",
            bytes.len()
        ));
    }
    Ok(())
}

fn repo(p: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join(p)).unwrap()
}

/// A small valid grid.bin: 3 frames of 4 rows.
fn a_grid() -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let mut g = ScanGrid::new(4);
    for i in 0..3u64 {
        g.frames.push(footscan::scandata::FrameMeta {
            index: i,
            seq: i,
            timestamp: footscan_hal::Timestamp { nanos: i * 1000 },
            x_mm: i as f64,
        });
        for _ in 0..4 {
            g.lines.push(footscan::detect::LinePeak::NONE);
            g.points.push(footscan_geom::P3::new(1.0, 2.0, 3.0));
        }
    }
    let p = dir.path().join("grid.bin");
    g.save(&p).unwrap();
    std::fs::read(&p).unwrap()
}

/// A valid file for each reader, to mutate.
fn seed(i: usize) -> Vec<u8> {
    match i {
        0 => a_grid(),
        1 => repo("config/sim.toml"),
        2 => toml::to_string(&CalibrationPlan::default())
            .unwrap()
            .into_bytes(),
        _ => repo("config/last-rules.toml"),
    }
}

fn mutate(mut b: Vec<u8>, edits: Vec<(usize, u8, u8)>) -> Vec<u8> {
    for (at, byte, kind) in edits {
        if b.is_empty() {
            b.push(byte);
            continue;
        }
        let at = at % b.len();
        match kind {
            0 => b[at] = byte,
            1 => b.insert(at, byte),
            2 => b.truncate(at),
            _ => {
                let digits = format!("{}", (byte as u64).pow(5) * 7919);
                for (k, d) in digits.bytes().enumerate() {
                    b.insert((at + k).min(b.len()), d);
                }
            }
        }
    }
    b
}

fn cases() -> u32 {
    std::env::var("FOOTSCAN_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(300)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(), ..ProptestConfig::default() })]

    #[test]
    fn arbitrary_bytes(b in prop::collection::vec(any::<u8>(), 0..1024)) {
        for (name, read) in READERS {
            check(name, read, &b).map_err(TestCaseError::fail)?;
        }
    }

    #[test]
    fn mutated_files(
        which in 0usize..4,
        edits in prop::collection::vec((0usize..1 << 20, any::<u8>(), 0u8..4), 1..8),
    ) {
        let (name, read) = READERS[which];
        check(name, read, &mutate(seed(which), edits)).map_err(TestCaseError::fail)?;
    }
}

/// Inputs found, kept.
#[test]
fn regressions() {
    // A grid.bin header of 2^32-1 frames by 2^32-1 rows: the size check overflowed.
    let magic = a_grid()[..8].to_vec();
    let mut huge = magic.clone();
    huge.extend(u32::MAX.to_le_bytes());
    huge.extend(u32::MAX.to_le_bytes());
    check("grid.bin", grid_bin, &huge).unwrap();
    let mut wrap = magic;
    // 2^31 frames of 2^33/45-ish rows: a product that wraps in 64 bits.
    wrap.extend(0x8000_0000u32.to_le_bytes());
    wrap.extend(0xE38E_38E4u32.to_le_bytes());
    check("grid.bin", grid_bin, &wrap).unwrap();
}

/// The seeds read, and within the bound.
#[test]
fn valid_files_read_within_the_bound() {
    for (i, (name, read)) in READERS.into_iter().enumerate() {
        check(name, read, &seed(i)).unwrap();
    }
    assert!(ScanGrid::parse(&a_grid(), Path::new("g")).is_ok());
}
