//! The per-frame path allocates nothing once its buffers are sized: every detector, the V4L2
//! driver's colour conversions (MJPG aside: its decoder allocates inside) and the detect
//! stage's channel conversion of colour files.

use footscan::detect::{build, DetectParams, LinePeak, NAMES};
use footscan_bench::detect::{noise_config, sweep_frames};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;
thread_local! {
    /// Per thread: the test harness's own thread prints (and allocates) while a test runs.
    static ALLOCS: Cell<usize> = const { Cell::new(0) };
}

fn allocs() -> usize {
    ALLOCS.with(Cell::get)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCS.with(|n| n.set(n.get() + 1));
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCS.with(|n| n.set(n.get() + 1));
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn detectors_do_not_allocate_per_frame() {
    let frames = sweep_frames(&noise_config("default", 1.6), &[5.0], &[150.0, 180.0], 3);
    // On every instruction set: the SIMD kernels work on the stack too.
    for isa in footscan::detect::Isa::available() {
        footscan::detect::simd::with_isa(isa, || {
            for name in NAMES {
                let mut d = build(name, &DetectParams::default()).unwrap();
                let mut out = vec![LinePeak::NONE; frames[0].0.height as usize];
                d.detect(&frames[0].0, &mut out); // sizes the scratch
                let before = allocs();
                for _ in 0..3 {
                    for (f, _) in &frames {
                        d.detect(f, &mut out);
                    }
                }
                let n = allocs() - before;
                assert_eq!(n, 0, "{name} on {isa:?} allocated {n} times in 9 frames");
            }
        })
        .unwrap();
    }
}

#[test]
fn colour_conversion_does_not_allocate_per_frame() {
    use footscan::detect::{Channel, ColorImage, ColorPixels, Image, Prep};
    use footscan_hal::Pixels;
    use footscan_v4l2::{Converter, SourceFormat};
    let (w, h) = (64u32, 48u32);
    let n = (w * h) as usize;
    let buf: Vec<u8> = (0..3 * n).map(|i| (i * 7 % 251) as u8).collect();
    let mut out = Pixels::Gray8(vec![0; n]);
    for f in [
        SourceFormat::Yuyv,
        SourceFormat::Rgb24,
        SourceFormat::Bgr24,
        SourceFormat::BayerRggb,
        SourceFormat::BayerBggr,
        SourceFormat::BayerGbrg,
        SourceFormat::BayerGrbg,
    ] {
        for ch in [Channel::Luma, Channel::RedMinusOthers] {
            let mut c = Converter::new(f, w, h, 0).with_channel(Some(ch)).unwrap();
            c.convert(&buf, &mut out).unwrap();
            let before = allocs();
            for _ in 0..3 {
                c.convert(&buf, &mut out).unwrap();
            }
            let k = allocs() - before;
            assert_eq!(k, 0, "{f} to {ch} allocated {k} times in 3 frames");
        }
    }
    // A colour file's frames through the detect stage's Prep (channel and background).
    let img = Image::Color(ColorImage::new(w, h, ColorPixels::Rgb8(buf.clone())));
    let mut prep = Prep::new(Some(Channel::RedMinusOthers));
    prep.set_background(&img, "off").unwrap();
    prep.prepare(&img, "on").unwrap();
    let before = allocs();
    for _ in 0..3 {
        prep.prepare(&img, "on").unwrap();
    }
    let k = allocs() - before;
    assert_eq!(k, 0, "Prep allocated {k} times in 3 frames");
}
