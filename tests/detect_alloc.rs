//! The per-frame path of every detector allocates nothing once its scratch is sized.

use footscan::bench::detect::{noise_config, sweep_frames};
use footscan::detect::{build, DetectParams, LinePeak, NAMES};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;
static ALLOCS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn detectors_do_not_allocate_per_frame() {
    let frames = sweep_frames(&noise_config("default", 1.6), &[5.0], &[150.0, 180.0], 3);
    for name in NAMES {
        let mut d = build(name, &DetectParams::default()).unwrap();
        let mut out = vec![LinePeak::NONE; frames[0].0.height as usize];
        d.detect(&frames[0].0, &mut out); // sizes the scratch
        let before = ALLOCS.load(Ordering::Relaxed);
        for _ in 0..3 {
            for (f, _) in &frames {
                d.detect(f, &mut out);
            }
        }
        let n = ALLOCS.load(Ordering::Relaxed) - before;
        assert_eq!(n, 0, "{name} allocated {n} times in 9 frames");
    }
}
