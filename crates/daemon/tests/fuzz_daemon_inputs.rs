//! Fuzzing of the daemon's own readers of outside input on stable Rust: its TOML config
//! (footscand.toml) and the JSON bodies its API parses, on arbitrary bytes and mutations of
//! valid ones, with the counting allocator of crates/fuzzkit. None may panic; each holds at
//! most 4 x its input plus a fixed bound. (The bodies are also fuzzed over HTTP in
//! daemon_doors.rs; the libFuzzer targets are in fuzz/.)
//!
//! The normal run tries a bounded number of cases (about a second); a longer one:
//!
//! ```text
//! FOOTSCAN_FUZZ_CASES=200000 cargo test -p footscand --release --test fuzz_daemon_inputs
//! ```

use footscan_daemon::daemon::lastjob::{LastRequest, RankRequest};
use footscan_daemon::daemon::DaemonConfig;
use footscan_fuzzkit::{cases, peak_of, Counting, Rng};
use std::path::Path;

#[global_allocator]
static A: Counting = Counting;

/// Held whatever the input: the config's structures, the TOML parser's tables, messages.
const FIXED: usize = 512 * 1024;

fn check(name: &str, len: usize, read: impl FnOnce()) {
    let (peak, panicked) = peak_of(read);
    assert!(!panicked, "{name} panicked on {len} bytes");
    let bound = 4 * len + FIXED;
    assert!(
        peak <= bound,
        "{name} held {peak} bytes for {len} bytes of input (bound {bound})"
    );
}

fn repo_config() -> Vec<u8> {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/footscand.toml");
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn daemon_config_never_panics_nor_hoards() {
    let seed = repo_config();
    assert!(
        DaemonConfig::parse(
            Path::new("footscand.toml"),
            std::str::from_utf8(&seed).unwrap(),
            None,
            None
        )
        .is_ok(),
        "the repository's config is valid"
    );
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let n = cases(30_000);
    let (t, mut valid) = (std::time::Instant::now(), 0);
    for i in 0..n {
        let b = match i % 4 {
            0 => rng.bytes(512),
            _ => rng.mutate(&seed),
        };
        let text = String::from_utf8_lossy(&b).into_owned();
        check("daemon config", b.len(), || {
            let r = DaemonConfig::parse(Path::new("fuzz/footscand.toml"), &text, None, None);
            valid += r.is_ok() as usize;
        });
    }
    println!(
        "{n} daemon configs fuzzed in {:.2} s ({valid} valid)",
        t.elapsed().as_secs_f64()
    );
}

#[test]
fn a_config_file_too_long_to_be_one_is_refused_unread() {
    // /dev/zero never ends: a reader that reads to the end would grow without bound.
    let e = DaemonConfig::load(Path::new("/dev/zero"), None).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("/dev/zero") && msg.contains("MiB"), "{msg}");
}

#[test]
fn json_bodies_never_panic_nor_hoard() {
    let seeds: [&[u8]; 4] = [
        br#"{"girths": {"ball": 260.0, "instep": 248.0, "long_heel": 367.0, "ankle": 200.5}, "stock": "sim-245-right.stl"}"#,
        br#"{"girths": {"ball": 260.0, "instep": 248.0, "long_heel": 367.0, "ankle": 200.5}, "shoe": "oxford", "heel_mm": 20}"#,
        br#"{"patient": "P-1", "notes": "", "scan": "20261127-120000-abcd", "move": true}"#,
        br#"[[[[[[[[[[1e999, -0, "\ud800", {"a": null}]]]]]]]]]]"#,
    ];
    let mut rng = Rng(0x243f_6a88_85a3_08d3);
    let n = cases(200_000);
    let (t, mut valid) = (std::time::Instant::now(), 0);
    for i in 0..n {
        let b = match i % 4 {
            0 => rng.bytes(256),
            _ => rng.mutate(seeds[(i / 4) % seeds.len()]),
        };
        check("JSON value", b.len(), || {
            drop(serde_json::from_slice::<serde_json::Value>(&b))
        });
        check("last request", b.len(), || {
            valid += serde_json::from_slice::<LastRequest>(&b).is_ok() as usize
        });
        check("rank request", b.len(), || {
            drop(serde_json::from_slice::<RankRequest>(&b))
        });
    }
    println!(
        "{n} JSON bodies fuzzed in {:.2} s ({valid} valid last requests)",
        t.elapsed().as_secs_f64()
    );
}

/// The cargo-fuzz targets of grid.bin and calibration plans start from seeds made here
/// (fuzz/seeds/grid_bin, fuzz/seeds/calibration_plan), not copied from a scan: a grid of
/// three frames of four rows, written by the scanner's own writer, and the default plan.
/// This checks they are current; `FOOTSCAN_WRITE_SEEDS=1` rewrites them. (Here rather than
/// in tests/fuzz_inputs.rs, whose binary needs OpenCV: this one builds without it.)
#[test]
fn the_fuzz_seeds_are_current() {
    use footscan::scandata::{FrameMeta, ScanGrid};
    let tmp = tempfile::tempdir().unwrap();
    let mut g = ScanGrid::new(4);
    for i in 0..3u64 {
        g.frames.push(FrameMeta {
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
    g.save(&tmp.path().join("grid.bin")).unwrap();
    let grid = std::fs::read(tmp.path().join("grid.bin")).unwrap();
    assert!(ScanGrid::parse(&grid, Path::new("seed grid.bin")).is_ok());
    let plan = toml::to_string(&footscan::calib::CalibrationPlan::default()).unwrap();
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz/seeds");
    for (dir, name, bytes) in [
        ("grid_bin", "three_frames.bin", grid),
        ("calibration_plan", "default.toml", plan.into_bytes()),
    ] {
        let p = root.join(dir).join(name);
        if std::env::var_os("FOOTSCAN_WRITE_SEEDS").is_some() {
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(&p, &bytes).unwrap();
        }
        let kept = std::fs::read(&p)
            .unwrap_or_else(|e| panic!("{}: {e} (FOOTSCAN_WRITE_SEEDS=1 makes it)", p.display()));
        assert!(
            kept == bytes,
            "{} differs from the seed made here: FOOTSCAN_WRITE_SEEDS=1 rewrites it",
            p.display()
        );
    }
}
