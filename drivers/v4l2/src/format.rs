//! Pixel formats the driver accepts and their conversion to footscan's gray frames.
//!
//! | V4L2 fourcc | frame | conversion |
//! | --- | --- | --- |
//! | `GREY` | Gray8 | copied row by row (the stride's padding dropped) |
//! | `Y10 ` | Gray16 | 10 bits in a little-endian u16, scaled to 16 bits by bit replication |
//! | `Y12 ` | Gray16 | 12 bits in a little-endian u16, scaled to 16 bits by bit replication |
//! | `Y16 ` | Gray16 | little-endian u16, kept as is |
//! | `YUYV` | Gray8 | the Y (luma) byte of each pixel; chroma is dropped |
//! | `MJPG` | Gray8 | decoded to luma by `zune-jpeg` (the pure-Rust decoder `image` uses) |
//!
//! Scaling of Y10/Y12: footscan's Gray16 frames are full-scale (65535 is saturation; thresholds
//! of an 8-bit frame are multiplied by 257), whatever the sensor's bit depth. Bit replication
//! `v << (16 - b) | v >> (2b - 16)` maps 0 to 0 and the sensor's maximum to exactly 65535, is
//! monotone, and keeps the sensor value recoverable as `v16 >> (16 - b)`. Bits above the
//! sensor's depth (undefined in V4L2) are masked off.

use footscan_hal::{PixelFormat, Pixels};
use v4l::FourCC;

/// A V4L2 pixel format the driver can convert to gray.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SourceFormat {
    Grey,
    Y10,
    Y12,
    Y16,
    Yuyv,
    Mjpg,
}

impl SourceFormat {
    /// Preference order when the caller names none: raw gray first (no loss), deepest first
    /// among the 16-bit ones, then YUYV (exact luma), MJPG last (lossy).
    pub const PREFERENCE: [SourceFormat; 6] = [
        SourceFormat::Grey,
        SourceFormat::Y16,
        SourceFormat::Y12,
        SourceFormat::Y10,
        SourceFormat::Yuyv,
        SourceFormat::Mjpg,
    ];

    pub fn fourcc(self) -> FourCC {
        FourCC::new(match self {
            SourceFormat::Grey => b"GREY",
            SourceFormat::Y10 => b"Y10 ",
            SourceFormat::Y12 => b"Y12 ",
            SourceFormat::Y16 => b"Y16 ",
            SourceFormat::Yuyv => b"YUYV",
            SourceFormat::Mjpg => b"MJPG",
        })
    }

    pub fn from_fourcc(f: FourCC) -> Option<Self> {
        Some(match &f.repr {
            b"GREY" => SourceFormat::Grey,
            b"Y10 " => SourceFormat::Y10,
            b"Y12 " => SourceFormat::Y12,
            b"Y16 " => SourceFormat::Y16,
            b"YUYV" => SourceFormat::Yuyv,
            // JPEG is what some drivers call the same stream.
            b"MJPG" | b"JPEG" => SourceFormat::Mjpg,
            _ => return None,
        })
    }

    /// Parse `GREY`, `Y10`, `y16`, `yuyv`, `mjpg`, ... (case-insensitive, trailing spaces optional).
    pub fn parse(s: &str) -> Option<Self> {
        let u = s.trim().to_ascii_uppercase();
        let mut b = [b' '; 4];
        if u.is_empty() || u.len() > 4 {
            return None;
        }
        b[..u.len()].copy_from_slice(u.as_bytes());
        Self::from_fourcc(FourCC::new(&b))
    }

    /// The frame format it converts to.
    pub fn pixel_format(self) -> PixelFormat {
        match self {
            SourceFormat::Grey | SourceFormat::Yuyv | SourceFormat::Mjpg => PixelFormat::Gray8,
            SourceFormat::Y10 | SourceFormat::Y12 | SourceFormat::Y16 => PixelFormat::Gray16,
        }
    }

    /// Bytes of one pixel in the device buffer (None: compressed).
    pub fn bytes_per_pixel(self) -> Option<usize> {
        match self {
            SourceFormat::Grey => Some(1),
            SourceFormat::Y10 | SourceFormat::Y12 | SourceFormat::Y16 | SourceFormat::Yuyv => {
                Some(2)
            }
            SourceFormat::Mjpg => None,
        }
    }

    /// Significant bits of a 16-bit container format.
    fn bits(self) -> u32 {
        match self {
            SourceFormat::Y10 => 10,
            SourceFormat::Y12 => 12,
            _ => 16,
        }
    }
}

impl std::fmt::Display for SourceFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let r = self.fourcc().repr;
        f.write_str(String::from_utf8_lossy(&r).trim_end())
    }
}

/// Why a buffer could not be converted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ConvertError {
    /// Fewer bytes than the negotiated format needs.
    Short { needed: usize, got: usize },
    /// The destination buffer has the wrong format or size.
    Destination(String),
    /// MJPG decoding failed or gave another size.
    Jpeg(String),
}

impl std::fmt::Display for ConvertError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConvertError::Short { needed, got } => {
                write!(f, "buffer holds {got} bytes, the format needs {needed}")
            }
            ConvertError::Destination(s) => write!(f, "destination: {s}"),
            ConvertError::Jpeg(s) => write!(f, "MJPG: {s}"),
        }
    }
}

impl std::error::Error for ConvertError {}

/// Converts device buffers of one negotiated format to gray frames.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Converter {
    pub format: SourceFormat,
    pub width: u32,
    pub height: u32,
    /// Bytes from one row to the next in the device buffer (`bytesperline`); ignored for MJPG.
    pub stride: usize,
}

impl Converter {
    /// A converter for `format` at `width` x `height`; `stride` 0 means rows are packed.
    pub fn new(format: SourceFormat, width: u32, height: u32, stride: usize) -> Self {
        let packed = format.bytes_per_pixel().unwrap_or(0) * width as usize;
        Converter {
            format,
            width,
            height,
            stride: if stride == 0 { packed } else { stride },
        }
    }

    /// Bytes a complete uncompressed frame occupies (0 for MJPG).
    pub fn min_bytes(&self) -> usize {
        match self.format.bytes_per_pixel() {
            Some(bpp) if self.height > 0 => {
                self.stride * (self.height as usize - 1) + bpp * self.width as usize
            }
            _ => 0,
        }
    }

    /// Convert `src` (the used bytes of one buffer) into `dst`, which must already be of this
    /// converter's output format and size (a [`footscan_hal::FramePool`] frame is).
    pub fn convert(&self, src: &[u8], dst: &mut Pixels) -> Result<(), ConvertError> {
        let (w, h) = (self.width as usize, self.height as usize);
        if dst.format() != self.format.pixel_format() || dst.len() != w * h {
            return Err(ConvertError::Destination(format!(
                "expected {:?} of {w}x{h}, got {:?} of {} pixels",
                self.format.pixel_format(),
                dst.format(),
                dst.len()
            )));
        }
        let need = self.min_bytes();
        if src.len() < need {
            return Err(ConvertError::Short {
                needed: need,
                got: src.len(),
            });
        }
        match (self.format, dst) {
            (SourceFormat::Grey, Pixels::Gray8(d)) => {
                for (r, row) in d.chunks_exact_mut(w).enumerate() {
                    let s = &src[r * self.stride..r * self.stride + w];
                    row.copy_from_slice(s);
                }
            }
            (SourceFormat::Yuyv, Pixels::Gray8(d)) => {
                for (r, row) in d.chunks_exact_mut(w).enumerate() {
                    let s = &src[r * self.stride..r * self.stride + 2 * w];
                    for (o, px) in row.iter_mut().zip(s.chunks_exact(2)) {
                        *o = px[0];
                    }
                }
            }
            (
                f @ (SourceFormat::Y10 | SourceFormat::Y12 | SourceFormat::Y16),
                Pixels::Gray16(d),
            ) => {
                let bits = f.bits();
                let mask = if bits == 16 {
                    0xffff
                } else {
                    (1u16 << bits) - 1
                };
                let (up, down) = (16 - bits, 2 * bits - 16);
                for (r, row) in d.chunks_exact_mut(w).enumerate() {
                    let s = &src[r * self.stride..r * self.stride + 2 * w];
                    for (o, px) in row.iter_mut().zip(s.chunks_exact(2)) {
                        let v = u16::from_le_bytes([px[0], px[1]]) & mask;
                        *o = if bits == 16 {
                            v
                        } else {
                            (v << up) | (v >> down)
                        };
                    }
                }
            }
            (SourceFormat::Mjpg, Pixels::Gray8(d)) => decode_jpeg_gray(src, w, h, d)?,
            _ => unreachable!("destination format checked above"),
        }
        Ok(())
    }
}

/// Decode a (M)JPEG image to its luma into `out` (`w * h` bytes). The decoder's scratch is
/// allocated per call; the output is written in place.
pub fn decode_jpeg_gray(
    src: &[u8],
    w: usize,
    h: usize,
    out: &mut [u8],
) -> Result<(), ConvertError> {
    use zune_core::bytestream::ZCursor;
    use zune_core::colorspace::ColorSpace;
    use zune_core::options::DecoderOptions;
    // Some cameras pad the buffer after the EOI marker; the decoder stops at EOI.
    let opts = DecoderOptions::default()
        .jpeg_set_out_colorspace(ColorSpace::Luma)
        .set_strict_mode(false);
    let mut dec = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(src), opts);
    dec.decode_headers()
        .map_err(|e| ConvertError::Jpeg(format!("{e:?}")))?;
    let (jw, jh) = dec
        .dimensions()
        .ok_or_else(|| ConvertError::Jpeg("no dimensions".into()))?;
    if (jw, jh) != (w, h) {
        return Err(ConvertError::Jpeg(format!(
            "image is {jw}x{jh}, the stream was negotiated at {w}x{h}"
        )));
    }
    dec.decode_into(out)
        .map_err(|e| ConvertError::Jpeg(format!("{e:?}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gray8(n: usize) -> Pixels {
        Pixels::Gray8(vec![0xAA; n])
    }
    fn gray16(n: usize) -> Pixels {
        Pixels::Gray16(vec![0xAAAA; n])
    }

    #[test]
    fn fourcc_round_trip_and_parse() {
        for f in SourceFormat::PREFERENCE {
            assert_eq!(SourceFormat::from_fourcc(f.fourcc()), Some(f));
            assert_eq!(SourceFormat::parse(&f.to_string()), Some(f));
        }
        assert_eq!(SourceFormat::parse("y10"), Some(SourceFormat::Y10));
        assert_eq!(SourceFormat::parse("jpeg"), Some(SourceFormat::Mjpg));
        assert_eq!(SourceFormat::parse("RGB3"), None);
        assert_eq!(SourceFormat::parse(""), None);
        assert_eq!(SourceFormat::Y12.to_string(), "Y12");
    }

    #[test]
    fn grey_drops_stride_padding() {
        // 3x2 image, bytesperline 4: the 4th byte of each row is padding (0xEE).
        let buf = [1, 2, 3, 0xEE, 4, 5, 6, 0xEE];
        let c = Converter::new(SourceFormat::Grey, 3, 2, 4);
        assert_eq!(c.min_bytes(), 7);
        let mut d = gray8(6);
        c.convert(&buf, &mut d).unwrap();
        assert_eq!(d, Pixels::Gray8(vec![1, 2, 3, 4, 5, 6]));
        // The last row's padding may be missing.
        c.convert(&buf[..7], &mut d).unwrap();
        assert_eq!(d, Pixels::Gray8(vec![1, 2, 3, 4, 5, 6]));
    }

    #[test]
    fn grey_packed_when_stride_is_zero() {
        let buf = [10, 20, 30, 40];
        let c = Converter::new(SourceFormat::Grey, 2, 2, 0);
        assert_eq!(c.stride, 2);
        let mut d = gray8(4);
        c.convert(&buf, &mut d).unwrap();
        assert_eq!(d, Pixels::Gray8(vec![10, 20, 30, 40]));
    }

    #[test]
    fn short_buffer_and_wrong_destination_are_errors() {
        let c = Converter::new(SourceFormat::Grey, 3, 2, 4);
        let mut d = gray8(6);
        assert_eq!(
            c.convert(&[0; 6], &mut d),
            Err(ConvertError::Short { needed: 7, got: 6 })
        );
        assert!(matches!(
            c.convert(&[0; 8], &mut gray16(6)),
            Err(ConvertError::Destination(_))
        ));
        assert!(matches!(
            c.convert(&[0; 8], &mut gray8(5)),
            Err(ConvertError::Destination(_))
        ));
    }

    #[test]
    fn yuyv_takes_luma() {
        // 2x2 pixels, rows of Y0 U Y1 V, stride 6 (2 bytes padding).
        let buf = [
            16, 128, 235, 128, 0xEE, 0xEE, //
            100, 90, 101, 240, 0xEE, 0xEE,
        ];
        let c = Converter::new(SourceFormat::Yuyv, 2, 2, 6);
        let mut d = gray8(4);
        c.convert(&buf, &mut d).unwrap();
        assert_eq!(d, Pixels::Gray8(vec![16, 235, 100, 101]));
    }

    #[test]
    fn y10_scales_to_full_range() {
        // Little-endian 10-bit values 0, 1, 512, 1023, and 1023 with garbage in the high bits.
        let buf = [0x00, 0x00, 0x01, 0x00, 0x00, 0x02, 0xFF, 0x03, 0xFF, 0xFF];
        let c = Converter::new(SourceFormat::Y10, 5, 1, 0);
        let mut d = gray16(5);
        c.convert(&buf, &mut d).unwrap();
        // v << 6 | v >> 4
        assert_eq!(
            d,
            Pixels::Gray16(vec![0, 64, (512 << 6) | (512 >> 4), 65535, 65535])
        );
        if let Pixels::Gray16(v) = &d {
            let back: Vec<u16> = v.iter().map(|x| x >> 6).collect();
            assert_eq!(back, vec![0, 1, 512, 1023, 1023]);
        }
    }

    #[test]
    fn y12_scales_to_full_range_with_stride() {
        // 2x2, stride 6: values 0, 4095 / 2048, 3 (little endian), 2 bytes padding per row.
        let buf = [
            0x00, 0x00, 0xFF, 0x0F, 0xEE, 0xEE, //
            0x00, 0x08, 0x03, 0x00, 0xEE, 0xEE,
        ];
        let c = Converter::new(SourceFormat::Y12, 2, 2, 6);
        let mut d = gray16(4);
        c.convert(&buf, &mut d).unwrap();
        // v << 4 | v >> 8
        assert_eq!(
            d,
            Pixels::Gray16(vec![0, 65535, (2048 << 4) | (2048 >> 8), 3 << 4])
        );
    }

    #[test]
    fn y16_kept_as_is() {
        let buf = [0x34, 0x12, 0xFF, 0xFF, 0x01, 0x00];
        let c = Converter::new(SourceFormat::Y16, 3, 1, 0);
        let mut d = gray16(3);
        c.convert(&buf, &mut d).unwrap();
        assert_eq!(d, Pixels::Gray16(vec![0x1234, 0xFFFF, 1]));
    }

    /// A 32x16 gray image: a bright vertical bar on a dark background, like a laser line.
    fn test_image() -> Vec<u8> {
        let (w, h) = (32usize, 16usize);
        let mut v = vec![0u8; w * h];
        for r in 0..h {
            for c in 0..w {
                v[r * w + c] = if (12..20).contains(&c) { 200 } else { 20 };
            }
        }
        v
    }

    fn encode_jpeg(pixels: &[u8], w: u32, h: u32, color: bool, quality: u8) -> Vec<u8> {
        use image::codecs::jpeg::JpegEncoder;
        use image::ExtendedColorType;
        let mut out = Vec::new();
        let mut enc = JpegEncoder::new_with_quality(&mut out, quality);
        if color {
            let rgb: Vec<u8> = pixels.iter().flat_map(|&p| [p, p, p]).collect();
            enc.encode(&rgb, w, h, ExtendedColorType::Rgb8).unwrap();
        } else {
            enc.encode(pixels, w, h, ExtendedColorType::L8).unwrap();
        }
        out
    }

    fn max_abs_diff(a: &[u8], b: &[u8]) -> u8 {
        a.iter().zip(b).map(|(x, y)| x.abs_diff(*y)).max().unwrap()
    }

    #[test]
    fn mjpg_gray_jpeg_decodes_to_luma() {
        let img = test_image();
        let jpg = encode_jpeg(&img, 32, 16, false, 100);
        assert_eq!(&jpg[..2], &[0xFF, 0xD8], "not a JPEG");
        let c = Converter::new(SourceFormat::Mjpg, 32, 16, 0);
        let mut d = gray8(32 * 16);
        // Cameras hand over whole buffers: trailing bytes after EOI must not matter.
        let mut padded = jpg.clone();
        padded.extend_from_slice(&[0u8; 100]);
        c.convert(&padded, &mut d).unwrap();
        let Pixels::Gray8(out) = &d else {
            unreachable!()
        };
        // Quality 100 on 8x8-aligned flat regions: within a few DN (ringing at the bar edges).
        let diff = max_abs_diff(out, &img);
        assert!(diff <= 12, "max difference {diff}");
        // Flat interiors are exact to within 1 DN.
        for r in 0..16 {
            assert!(out[r * 32 + 2].abs_diff(20) <= 1);
            assert!(out[r * 32 + 16].abs_diff(200) <= 1);
        }
    }

    #[test]
    fn mjpg_colour_jpeg_decodes_to_luma() {
        let img = test_image();
        let jpg = encode_jpeg(&img, 32, 16, true, 95);
        let c = Converter::new(SourceFormat::Mjpg, 32, 16, 0);
        let mut d = gray8(32 * 16);
        c.convert(&jpg, &mut d).unwrap();
        let Pixels::Gray8(out) = &d else {
            unreachable!()
        };
        let diff = max_abs_diff(out, &img);
        assert!(diff <= 20, "max difference {diff}");
        assert!(out[5 * 32 + 16] > 180 && out[5 * 32 + 3] < 40);
    }

    #[test]
    fn mjpg_wrong_size_and_garbage_are_errors() {
        let jpg = encode_jpeg(&test_image(), 32, 16, false, 90);
        let c = Converter::new(SourceFormat::Mjpg, 16, 32, 0);
        let mut d = gray8(16 * 32);
        assert!(matches!(
            c.convert(&jpg, &mut d),
            Err(ConvertError::Jpeg(_))
        ));
        let c = Converter::new(SourceFormat::Mjpg, 32, 16, 0);
        let mut d = gray8(32 * 16);
        assert!(matches!(
            c.convert(&[0xFF, 0xD8, 1, 2, 3], &mut d),
            Err(ConvertError::Jpeg(_))
        ));
    }
}
