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

use footscan_grbl::{parse_line, parse_status, BuildInfo};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// Counts the bytes each thread holds, and the most it held since the last reset.
struct Counting;

thread_local! {
    static HELD: Cell<usize> = const { Cell::new(0) };
    static PEAK: Cell<usize> = const { Cell::new(0) };
}

fn note(add: usize, sub: usize) {
    let _ = HELD.try_with(|h| {
        let now = h.get().wrapping_add(add).wrapping_sub(sub);
        h.set(now);
        let _ = PEAK.try_with(|p| {
            if now > p.get() && now < usize::MAX / 2 {
                p.set(now)
            }
        });
    });
}

// SAFETY: every call forwards to the system allocator; the counting touches only
// const-initialised thread locals, which do not allocate.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            note(l.size(), 0);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        note(0, l.size());
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(l) };
        if !p.is_null() {
            note(l.size(), 0);
        }
        p
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, l, new) };
        if !q.is_null() {
            // Old and new blocks may both exist during the move.
            note(new, 0);
            note(0, l.size());
        }
        q
    }
}

#[global_allocator]
static A: Counting = Counting;

/// The most `f` held at once beyond what the thread held before, and whether it panicked.
fn peak_of(f: impl FnOnce()) -> (usize, bool) {
    let base = HELD.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let panicked = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).is_err();
    (PEAK.with(Cell::get).saturating_sub(base), panicked)
}

/// A small deterministic generator (xorshift64*): the harness needs no extra crate.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
    fn bytes(&mut self, max: usize) -> Vec<u8> {
        let n = self.below(max + 1);
        (0..n).map(|_| self.next() as u8).collect()
    }
    /// `seed` with a few bytes replaced, inserted or cut.
    fn mutate(&mut self, seed: &[u8]) -> Vec<u8> {
        let mut b = seed.to_vec();
        for _ in 0..1 + self.below(6) {
            let at = self.below(b.len() + 1);
            match self.below(4) {
                0 if at < b.len() => b[at] = self.next() as u8,
                1 => b.insert(at, self.next() as u8),
                2 => b.truncate(at),
                _ => {
                    let digits = (self.next() % 10_000_000_000).to_string();
                    for (k, d) in digits.bytes().enumerate() {
                        b.insert((at + k).min(b.len()), d);
                    }
                }
            }
        }
        b
    }
}

/// Cases per target: bounded in the normal run, more with FOOTSCAN_FUZZ_CASES.
fn cases(default: usize) -> usize {
    std::env::var("FOOTSCAN_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

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
