#![no_main]
//! A camera buffer as the driver hands it over: the first bytes choose the source format,
//! size, stride and channel, the rest is the buffer; then the (M)JPEG decoders on it alone.
use footscan_hal::{Channel, PixelFormat, Pixels};
use footscan_v4l2::format::{decode_jpeg_gray, decode_jpeg_rgb};
use footscan_v4l2::{Converter, SourceFormat};
use libfuzzer_sys::fuzz_target;

const FIXED: usize = 256 * 1024;

fuzz_target!(|b: &[u8]| {
    if b.len() < 6 {
        return;
    }
    let (head, src) = b.split_at(6);
    let f = SourceFormat::ALL[head[0] as usize % SourceFormat::ALL.len()];
    let (w, h) = (1 + head[1] as usize % 64, 1 + head[2] as usize % 64);
    let stride = u16::from_le_bytes([head[3], head[4]]) as usize % 1024;
    let channel = [
        None,
        Some(Channel::Luma),
        Some(Channel::Red),
        Some(Channel::Green),
        Some(Channel::Blue),
        Some(Channel::RedMinusOthers),
        Some(Channel::GreenMinusOthers),
    ][head[5] as usize % 7];
    if let Ok(mut c) = Converter::new(f, w as u32, h as u32, stride).with_channel(channel) {
        let mut dst = match f.pixel_format() {
            PixelFormat::Gray8 => Pixels::Gray8(vec![0; w * h]),
            PixelFormat::Gray16 => Pixels::Gray16(vec![0; w * h]),
        };
        // The converter keeps an RGB frame between MJPG frames for colour channels.
        footscan_fuzz::check("Converter::convert", src.len(), 3 * w * h + FIXED, || {
            drop(c.convert(src, &mut dst))
        });
    }
    let mut g = vec![0u8; w * h];
    let mut rgb = vec![0u8; 3 * w * h];
    footscan_fuzz::check("decode_jpeg_gray", src.len(), FIXED, || {
        drop(decode_jpeg_gray(src, w, h, &mut g))
    });
    footscan_fuzz::check("decode_jpeg_rgb", src.len(), FIXED, || {
        drop(decode_jpeg_rgb(src, w, h, &mut rgb))
    });
});
