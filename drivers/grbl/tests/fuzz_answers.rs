//! Fuzzing of what the controller says on the serial line: `parse_line`, `parse_status` and
//! `BuildInfo::parse` take arbitrary bytes (as lossy text) and mutations of real GRBL 1.1
//! answers without panicking, holding at most 4 x the line plus a fixed 16 KiB.
//!
//! A stable-Rust harness with its own generator (this driver's dependencies stay as they
//! are). The normal run tries a bounded number of cases; a longer one:
//!
//! ```text
//! FOOTSCAN_FUZZ_CASES=2000000 cargo test -p footscan-grbl --release --test fuzz_answers
//! ```

use footscan_fuzzkit::{cases, peak_of, Counting, Rng};
use footscan_grbl::{parse_line, parse_status, BuildInfo};

// The allocator that counts what each thread holds (crates/fuzzkit).
#[global_allocator]
static A: Counting = Counting;

/// Real answers of a GRBL 1.1 controller, to mutate.
const SEEDS: &[&str] = &[
    "ok",
    "error:9",
    "ALARM:1",
    "<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>",
    "<Run|MPos:12.500,0.000,0.000|FS:1500,0|Ov:100,100,100|Pn:X>",
    "<Home|WPos:-1.000,2.000,3.000|Bf:15,128|Ln:99|F:500>",
    "<Alarm|MPos:0,0,0|A:SF>",
    "Grbl 1.1h ['$' for help]",
    "[VER:1.1h.20190825:footscan]",
    "[OPT:VNM,15,128]",
    "[MSG:'$H'|'$X' to unlock]",
    "[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]",
    "$100=250.000",
    "$110=500.000",
    "[PRB:0.000,0.000,1.492:1]",
];

const FIXED: usize = 16 * 1024;

fn check(bytes: &[u8]) -> Result<(), String> {
    let line = String::from_utf8_lossy(bytes).into_owned();
    let bound = 4 * bytes.len() + FIXED;
    let lines: Vec<&str> = line.split('\n').collect();
    for (name, f) in [
        (
            "parse_line",
            Box::new(|| drop(parse_line(&line))) as Box<dyn FnOnce()>,
        ),
        ("parse_status", Box::new(|| drop(parse_status(&line)))),
        (
            "BuildInfo::parse",
            Box::new(|| drop(BuildInfo::parse(&lines))),
        ),
    ] {
        let (peak, panicked) = peak_of(f);
        if panicked {
            return Err(format!("{name} panicked on {line:?}"));
        }
        if peak > bound {
            return Err(format!(
                "{name} held {peak} bytes for a {}-byte line: {line:?}",
                bytes.len()
            ));
        }
    }
    Ok(())
}

#[test]
fn answers_never_panic_nor_hoard() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let n = cases(100_000);
    for i in 0..n {
        let b = match i % 3 {
            0 => rng.bytes(256),
            _ => {
                let s = SEEDS[rng.below(SEEDS.len())];
                rng.mutate(s.as_bytes())
            }
        };
        if let Err(e) = check(&b) {
            panic!("case {i}: {e}");
        }
    }
    println!("{n} GRBL answers fuzzed");
}

/// Inputs kept from fuzzing and from the controller's own edge cases.
#[test]
fn regressions() {
    for l in [
        "<|>",
        "<>",
        "<Idle|MPos:1e309,nan,-inf|FS:99999999999999999999,0>",
        "<Idle|MPos:,,,,,,,,,,,,,,,,,,,,|FS:>",
        "error:99999999999999999999",
        "ALARM:-1",
        "[OPT:,,,,]",
        "[VER::]",
        "$=",
        "$100=",
    ] {
        check(l.as_bytes()).unwrap();
    }
}
