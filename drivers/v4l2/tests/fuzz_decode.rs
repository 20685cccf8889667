//! Fuzzing of the V4L2 buffer decoding: `Converter::convert` for every source format with
//! any buffer bytes, sizes and strides, and the (M)JPEG decoders with arbitrary and mutated
//! JPEG data. Nothing may panic; what a conversion holds beyond its output frame is at most
//! 4 x the buffer plus a fixed bound (the JPEG decoder's tables and scratch).
//!
//! A stable-Rust harness with its own generator (this driver's dependencies stay as they
//! are). The normal run tries a bounded number of cases; a longer one:
//!
//! ```text
//! FOOTSCAN_FUZZ_CASES=200000 cargo test -p footscan-v4l2 --release --test fuzz_decode
//! ```

use footscan_fuzzkit::{cases, peak_of, Counting, Rng};
use footscan_hal::{Channel, PixelFormat, Pixels};
use footscan_v4l2::format::{decode_jpeg_gray, decode_jpeg_rgb};
use footscan_v4l2::{Converter, SourceFormat};

// The allocator that counts what each thread holds (crates/fuzzkit).
#[global_allocator]
static A: Counting = Counting;

/// Beyond 4 x the buffer: the JPEG decoder's Huffman and quantisation tables and its row
/// scratch for frames up to 64 x 64.
const FIXED: usize = 256 * 1024;

fn out_for(f: SourceFormat, w: usize, h: usize) -> Pixels {
    match f.pixel_format() {
        PixelFormat::Gray8 => Pixels::Gray8(vec![0; w * h]),
        PixelFormat::Gray16 => Pixels::Gray16(vec![0; w * h]),
    }
}

fn a_jpeg(w: u32, h: u32) -> Vec<u8> {
    let img = image::GrayImage::from_fn(w, h, |x, y| image::Luma([(x * 7 + y * 13) as u8]));
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new(&mut out)
        .encode_image(&img)
        .unwrap();
    out
}

#[test]
fn buffers_never_panic_nor_hoard() {
    let mut rng = Rng(0x243f_6a88_85a3_08d3);
    let channels = [
        None,
        Some(Channel::Luma),
        Some(Channel::Red),
        Some(Channel::Green),
        Some(Channel::Blue),
        Some(Channel::RedMinusOthers),
        Some(Channel::GreenMinusOthers),
    ];
    let jpeg = a_jpeg(16, 8);
    let n = cases(20_000);
    for i in 0..n {
        let f = SourceFormat::ALL[rng.below(SourceFormat::ALL.len())];
        let (w, h) = (1 + rng.below(64), 1 + rng.below(64));
        let stride = match rng.below(3) {
            0 => 0,
            1 => f.bytes_per_pixel().unwrap_or(1) * w + rng.below(8),
            _ => rng.below(512),
        };
        let Ok(mut c) = Converter::new(f, w as u32, h as u32, stride)
            .with_channel(channels[rng.below(channels.len())])
        else {
            continue;
        };
        let src = if f == SourceFormat::Mjpg && rng.below(2) == 0 {
            rng.mutate(&jpeg)
        } else {
            let want = c.min_bytes().max(1);
            match rng.below(3) {
                0 => rng.bytes(want * 2),
                1 => (0..want).map(|_| rng.next_u64() as u8).collect(),
                _ => rng.bytes(64),
            }
        };
        let mut dst = out_for(f, w, h);
        let (peak, panicked) = peak_of(|| drop(c.convert(&src, &mut dst)));
        assert!(
            !panicked,
            "case {i}: {f:?} {w}x{h} stride {stride}, {} bytes: panicked",
            src.len()
        );
        // The converter keeps an RGB frame between MJPG frames for colour channels.
        let keep = 3 * w * h;
        let bound = 4 * src.len() + keep + FIXED;
        assert!(
            peak <= bound,
            "case {i}: {f:?} {w}x{h}: held {peak} bytes for {} (bound {bound})",
            src.len()
        );
    }
    println!("{n} V4L2 buffers fuzzed");
}

#[test]
fn jpeg_decoders_never_panic_nor_hoard() {
    let mut rng = Rng(0x1319_8a2e_0370_7344);
    let seeds = [a_jpeg(16, 8), a_jpeg(33, 17), a_jpeg(1, 1)];
    let n = cases(20_000);
    for i in 0..n {
        let src = match i % 4 {
            0 => rng.bytes(512),
            _ => {
                let k = rng.below(seeds.len());
                rng.mutate(&seeds[k])
            }
        };
        let (w, h) = (1 + rng.below(40), 1 + rng.below(40));
        let mut g = vec![0u8; w * h];
        let mut rgb = vec![0u8; 3 * w * h];
        let (peak, panicked) = peak_of(|| drop(decode_jpeg_gray(&src, w, h, &mut g)));
        assert!(
            !panicked,
            "case {i}: gray {w}x{h}, {} bytes: panicked",
            src.len()
        );
        let bound = 4 * src.len() + FIXED;
        assert!(
            peak <= bound,
            "case {i}: gray {w}x{h}: held {peak} bytes for {} (bound {bound})",
            src.len()
        );
        let (peak, panicked) = peak_of(|| drop(decode_jpeg_rgb(&src, w, h, &mut rgb)));
        assert!(
            !panicked,
            "case {i}: rgb {w}x{h}, {} bytes: panicked",
            src.len()
        );
        assert!(
            peak <= bound,
            "case {i}: rgb {w}x{h}: held {peak} bytes for {} (bound {bound})",
            src.len()
        );
    }
    println!("{n} JPEG buffers fuzzed");
}
