//! Shared by the fuzz harnesses of the readers of outside input (mesh files, configs, grid.bin,
//! GRBL answers, camera buffers): a global allocator that counts what each thread holds, the
//! most a call held, and a small deterministic byte generator. Test-only: a harness installs
//! the allocator in its own binary with
//! `#[global_allocator] static A: footscan_fuzzkit::Counting = footscan_fuzzkit::Counting;`.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

/// Counts the bytes each thread holds, and the most it held since the last reset.
pub struct Counting;

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

/// The most `f` held at once beyond what the thread held before, and whether it panicked.
pub fn peak_of(f: impl FnOnce()) -> (usize, bool) {
    let base = HELD.with(Cell::get);
    PEAK.with(|p| p.set(base));
    let panicked = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f)).is_err();
    (PEAK.with(Cell::get).saturating_sub(base), panicked)
}

/// A small deterministic generator (xorshift64*): the harness needs no extra crate.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }
    pub fn bytes(&mut self, max: usize) -> Vec<u8> {
        let n = self.below(max + 1);
        (0..n).map(|_| self.next_u64() as u8).collect()
    }
    /// `seed` with a few bytes replaced, inserted or cut.
    pub fn mutate(&mut self, seed: &[u8]) -> Vec<u8> {
        let mut b = seed.to_vec();
        for _ in 0..1 + self.below(6) {
            let at = self.below(b.len() + 1);
            match self.below(4) {
                0 if at < b.len() => b[at] = self.next_u64() as u8,
                1 => b.insert(at, self.next_u64() as u8),
                2 => b.truncate(at),
                _ => {
                    let digits = (self.next_u64() % 10_000_000_000).to_string();
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
pub fn cases(default: usize) -> usize {
    std::env::var("FOOTSCAN_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}
