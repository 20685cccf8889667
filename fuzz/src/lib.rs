//! What every target shares: the counting allocator (crates/fuzzkit) and the bound a reader
//! must keep whatever the bytes: at most [`RATIO`] x its input plus a fixed amount. A panic
//! or a call over the bound is a crash libFuzzer keeps in `fuzz/artifacts/<target>/`.

use footscan_fuzzkit::{peak_of, Counting};

#[global_allocator]
static A: Counting = Counting;

/// Bytes a reader may hold per byte of input.
pub const RATIO: usize = 4;

/// Run `read` on an input of `len` bytes: it must not panic nor hold more than
/// `RATIO * len + fixed` bytes at once.
pub fn check(name: &str, len: usize, fixed: usize, read: impl FnOnce()) {
    let (peak, panicked) = peak_of(read);
    assert!(!panicked, "{name} panicked on {len} bytes");
    let bound = RATIO * len + fixed;
    assert!(
        peak <= bound,
        "{name} held {peak} bytes for {len} bytes of input (bound {bound})"
    );
}
