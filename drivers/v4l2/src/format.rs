//! Pixel formats the driver accepts and their conversion to footscan's grey frames.
//!
//! Colour is reduced where it enters: each device buffer is converted once, straight into the
//! grey [`Channel`] the detectors see (docs/method.md section 4), into the pooled frame, so a
//! steady stream allocates nothing per frame (MJPG: only inside the decoder).
//!
//! | V4L2 fourcc | frame | conversion |
//! | --- | --- | --- |
//! | `GREY` | Gray8 | copied row by row (the stride's padding dropped) |
//! | `Y10 ` | Gray16 | 10 bits in a little-endian u16, scaled to 16 bits by bit replication |
//! | `Y12 ` | Gray16 | 12 bits in a little-endian u16, scaled to 16 bits by bit replication |
//! | `Y16 ` | Gray16 | little-endian u16, kept as is |
//! | `YUYV` | Gray8 | luma: the Y byte; other channels: BT.601 limited-range YCbCr to RGB, chroma shared by two pixels |
//! | `MJPG` | Gray8 | decoded by `zune-jpeg`: to luma directly, or to RGB (a reused buffer) for the other channels |
//! | `RGB3`, `BGR3` | Gray8 | the channel of each 8-bit R, G, B triple |
//! | `RGGB`, `BA81` (BGGR), `GBRG`, `GRBG` | Gray8 | 8-bit Bayer, bilinear demosaic (edges mirrored), then the channel |
//!
//! Channels: a grey format (GREY, Y10, Y12, Y16) has only luma; RGB3, BGR3 and Bayer carry no
//! grey of their own and need a channel named; YUYV and MJPG give their luma when none is named
//! (their Y is the camera's own grey, as before colour was supported).
//!
//! Scaling of Y10/Y12: footscan's Gray16 frames are full-scale (65535 is saturation; thresholds
//! of an 8-bit frame are multiplied by 257), whatever the sensor's bit depth. Bit replication
//! `v << (16 - b) | v >> (2b - 16)` maps 0 to 0 and the sensor's maximum to exactly 65535, is
//! monotone, and keeps the sensor value recoverable as `v16 >> (16 - b)`. Bits above the
//! sensor's depth (undefined in V4L2) are masked off.
//!
//! MJPG decoder: `zune-jpeg`, the decoder the `image` crate itself moved to (`jpeg-decoder` is
//! in maintenance only): pure Rust with SIMD colour conversion, decodes into a caller's buffer,
//! and can output luma alone, which skips the colour conversion on the grey path.

use footscan_hal::{Channel, PixelFormat, Pixels, CHANNEL_NAMES};
use v4l::FourCC;

/// A V4L2 pixel format the driver can convert.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SourceFormat {
    Grey,
    Y10,
    Y12,
    Y16,
    Yuyv,
    Mjpg,
    /// `RGB3`: R, G, B bytes.
    Rgb24,
    /// `BGR3`: B, G, R bytes.
    Bgr24,
    /// `RGGB`: 8-bit Bayer, first row R G, second G B.
    BayerRggb,
    /// `BA81`: 8-bit Bayer, first row B G, second G R.
    BayerBggr,
    /// `GBRG`: 8-bit Bayer, first row G B, second R G.
    BayerGbrg,
    /// `GRBG`: 8-bit Bayer, first row G R, second B G.
    BayerGrbg,
}

impl SourceFormat {
    /// Preference order without a channel (grey): raw gray first (no loss), deepest first
    /// among the 16-bit ones, then YUYV (exact luma), MJPG last (lossy).
    pub const PREFERENCE: [SourceFormat; 6] = [
        SourceFormat::Grey,
        SourceFormat::Y16,
        SourceFormat::Y12,
        SourceFormat::Y10,
        SourceFormat::Yuyv,
        SourceFormat::Mjpg,
    ];

    /// Preference order for a colour channel: full RGB per pixel first, then Bayer (one sample
    /// per pixel, interpolated), YUYV (chroma at half the horizontal resolution), MJPG (lossy,
    /// chroma usually subsampled in both directions).
    pub const COLOUR_PREFERENCE: [SourceFormat; 8] = [
        SourceFormat::Rgb24,
        SourceFormat::Bgr24,
        SourceFormat::BayerRggb,
        SourceFormat::BayerBggr,
        SourceFormat::BayerGbrg,
        SourceFormat::BayerGrbg,
        SourceFormat::Yuyv,
        SourceFormat::Mjpg,
    ];

    /// Every format the driver converts.
    pub const ALL: [SourceFormat; 12] = [
        SourceFormat::Grey,
        SourceFormat::Y10,
        SourceFormat::Y12,
        SourceFormat::Y16,
        SourceFormat::Yuyv,
        SourceFormat::Mjpg,
        SourceFormat::Rgb24,
        SourceFormat::Bgr24,
        SourceFormat::BayerRggb,
        SourceFormat::BayerBggr,
        SourceFormat::BayerGbrg,
        SourceFormat::BayerGrbg,
    ];

    /// The formats to try, in order, when the caller names none.
    pub fn preference(channel: Option<Channel>) -> Vec<SourceFormat> {
        match channel {
            None => Self::PREFERENCE.to_vec(),
            // Luma named: grey formats first, then any colour one reduced to luma.
            Some(Channel::Luma) => {
                let mut v = Self::PREFERENCE.to_vec();
                v.extend(&Self::COLOUR_PREFERENCE[..6]);
                v
            }
            Some(_) => Self::COLOUR_PREFERENCE.to_vec(),
        }
    }

    pub fn fourcc(self) -> FourCC {
        FourCC::new(match self {
            SourceFormat::Grey => b"GREY",
            SourceFormat::Y10 => b"Y10 ",
            SourceFormat::Y12 => b"Y12 ",
            SourceFormat::Y16 => b"Y16 ",
            SourceFormat::Yuyv => b"YUYV",
            SourceFormat::Mjpg => b"MJPG",
            SourceFormat::Rgb24 => b"RGB3",
            SourceFormat::Bgr24 => b"BGR3",
            SourceFormat::BayerRggb => b"RGGB",
            SourceFormat::BayerBggr => b"BA81",
            SourceFormat::BayerGbrg => b"GBRG",
            SourceFormat::BayerGrbg => b"GRBG",
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
            b"RGB3" => SourceFormat::Rgb24,
            b"BGR3" => SourceFormat::Bgr24,
            b"RGGB" => SourceFormat::BayerRggb,
            b"BA81" => SourceFormat::BayerBggr,
            b"GBRG" => SourceFormat::BayerGbrg,
            b"GRBG" => SourceFormat::BayerGrbg,
            _ => return None,
        })
    }

    /// Parse `GREY`, `Y10`, `y16`, `yuyv`, `mjpg`, `rgb3`, `BA81`, ... (case-insensitive,
    /// trailing spaces optional).
    pub fn parse(s: &str) -> Option<Self> {
        let u = s.trim().to_ascii_uppercase();
        let mut b = [b' '; 4];
        if u.is_empty() || u.len() > 4 {
            return None;
        }
        b[..u.len()].copy_from_slice(u.as_bytes());
        Self::from_fourcc(FourCC::new(&b))
    }

    /// Every fourcc [`SourceFormat::parse`] accepts, for error messages.
    pub fn names() -> String {
        Self::ALL
            .iter()
            .map(|f| f.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// The frame format it converts to.
    pub fn pixel_format(self) -> PixelFormat {
        match self {
            SourceFormat::Y10 | SourceFormat::Y12 | SourceFormat::Y16 => PixelFormat::Gray16,
            _ => PixelFormat::Gray8,
        }
    }

    /// Whether the format carries colour (then any [`Channel`] can be taken from it).
    pub fn is_colour(self) -> bool {
        !matches!(
            self,
            SourceFormat::Grey | SourceFormat::Y10 | SourceFormat::Y12 | SourceFormat::Y16
        )
    }

    /// Whether the format has a grey of its own to give when no channel is named.
    pub fn has_own_grey(self) -> bool {
        !self.is_colour() || matches!(self, SourceFormat::Yuyv | SourceFormat::Mjpg)
    }

    /// Why `channel` cannot be taken from this format, if it cannot.
    pub fn check_channel(self, channel: Option<Channel>) -> Result<(), String> {
        match channel {
            None if !self.has_own_grey() => Err(format!(
                "{self} is a colour format without a grey of its own: set a channel, one of {CHANNEL_NAMES} (or use a grey format: GREY, Y10, Y12, Y16, YUYV, MJPG)"
            )),
            Some(c) if c != Channel::Luma && !self.is_colour() => Err(format!(
                "{self} is a grey format: channel {c} needs a colour one (RGB3, BGR3, RGGB, BA81, GBRG, GRBG, YUYV, MJPG), or set channel = luma"
            )),
            _ => Ok(()),
        }
    }

    /// Bytes of one pixel in the device buffer (None: compressed).
    pub fn bytes_per_pixel(self) -> Option<usize> {
        match self {
            SourceFormat::Grey
            | SourceFormat::BayerRggb
            | SourceFormat::BayerBggr
            | SourceFormat::BayerGbrg
            | SourceFormat::BayerGrbg => Some(1),
            SourceFormat::Y10 | SourceFormat::Y12 | SourceFormat::Y16 | SourceFormat::Yuyv => {
                Some(2)
            }
            SourceFormat::Rgb24 | SourceFormat::Bgr24 => Some(3),
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

    /// The colours of a Bayer format's 2x2 tile, row-major (0 = R, 1 = G, 2 = B).
    fn bayer_tile(self) -> Option<[u8; 4]> {
        Some(match self {
            SourceFormat::BayerRggb => [0, 1, 1, 2],
            SourceFormat::BayerBggr => [2, 1, 1, 0],
            SourceFormat::BayerGbrg => [1, 2, 0, 1],
            SourceFormat::BayerGrbg => [1, 0, 2, 1],
            _ => return None,
        })
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
    /// The channel cannot be taken from the format ([`SourceFormat::check_channel`]).
    Channel(String),
}

impl std::fmt::Display for ConvertError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ConvertError::Short { needed, got } => {
                write!(f, "buffer holds {got} bytes, the format needs {needed}")
            }
            ConvertError::Destination(s) => write!(f, "destination: {s}"),
            ConvertError::Jpeg(s) => write!(f, "MJPG: {s}"),
            ConvertError::Channel(s) => f.write_str(s),
        }
    }
}

impl std::error::Error for ConvertError {}

/// Converts device buffers of one negotiated format to grey frames in one channel.
#[derive(Clone, Debug)]
pub struct Converter {
    pub format: SourceFormat,
    pub width: u32,
    pub height: u32,
    /// Bytes from one row to the next in the device buffer (`bytesperline`); ignored for MJPG.
    pub stride: usize,
    /// The channel taken from a colour format; None: the format's own grey.
    pub channel: Option<Channel>,
    /// MJPG decoded to RGB for a colour channel: kept between frames.
    rgb: Vec<u8>,
}

impl Converter {
    /// A converter for `format` at `width` x `height` to its own grey (see
    /// [`Converter::with_channel`]); `stride` 0 means rows are packed.
    pub fn new(format: SourceFormat, width: u32, height: u32, stride: usize) -> Self {
        let packed = format.bytes_per_pixel().unwrap_or(0) * width as usize;
        Converter {
            format,
            width,
            height,
            stride: if stride == 0 { packed } else { stride },
            channel: None,
            rgb: Vec::new(),
        }
    }

    /// The same converter taking `channel`; an error says why the format cannot give it.
    pub fn with_channel(mut self, channel: Option<Channel>) -> Result<Self, ConvertError> {
        self.format
            .check_channel(channel)
            .map_err(ConvertError::Channel)?;
        self.channel = channel;
        Ok(self)
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
    pub fn convert(&mut self, src: &[u8], dst: &mut Pixels) -> Result<(), ConvertError> {
        let (w, h) = (self.width as usize, self.height as usize);
        if dst.format() != self.format.pixel_format() || dst.len() != w * h {
            return Err(ConvertError::Destination(format!(
                "expected {:?} of {w}x{h}, got {:?} of {} pixels",
                self.format.pixel_format(),
                dst.format(),
                dst.len()
            )));
        }
        self.format
            .check_channel(self.channel)
            .map_err(ConvertError::Channel)?;
        let need = self.min_bytes();
        if src.len() < need {
            return Err(ConvertError::Short {
                needed: need,
                got: src.len(),
            });
        }
        // The format's own grey, where that is what is asked for.
        let ch = match self.channel {
            None | Some(Channel::Luma) if self.format.has_own_grey() => None,
            c => c,
        };
        let stride = self.stride;
        let row_of = |r: usize, bpp: usize| &src[r * stride..r * stride + bpp * w];
        match (self.format, dst) {
            (SourceFormat::Grey, Pixels::Gray8(d)) => {
                for (r, row) in d.chunks_exact_mut(w).enumerate() {
                    row.copy_from_slice(row_of(r, 1));
                }
            }
            (SourceFormat::Yuyv, Pixels::Gray8(d)) => {
                for (r, row) in d.chunks_exact_mut(w).enumerate() {
                    let s = row_of(r, 2);
                    match ch {
                        None => {
                            for (o, px) in row.iter_mut().zip(s.chunks_exact(2)) {
                                *o = px[0];
                            }
                        }
                        Some(c) => yuyv_row(c, s, row),
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
                    for (o, px) in row.iter_mut().zip(row_of(r, 2).chunks_exact(2)) {
                        let v = u16::from_le_bytes([px[0], px[1]]) & mask;
                        *o = if bits == 16 {
                            v
                        } else {
                            (v << up) | (v >> down)
                        };
                    }
                }
            }
            (SourceFormat::Mjpg, Pixels::Gray8(d)) => match ch {
                None => decode_jpeg_gray(src, w, h, d)?,
                Some(c) => {
                    self.rgb.resize(3 * w * h, 0);
                    decode_jpeg_rgb(src, w, h, &mut self.rgb)?;
                    rgb_row(c, &self.rgb, d, [0, 1, 2]);
                }
            },
            (f @ (SourceFormat::Rgb24 | SourceFormat::Bgr24), Pixels::Gray8(d)) => {
                let c = ch.unwrap_or(Channel::Luma);
                let order = if f == SourceFormat::Rgb24 {
                    [0, 1, 2]
                } else {
                    [2, 1, 0]
                };
                for (r, row) in d.chunks_exact_mut(w).enumerate() {
                    rgb_row(c, row_of(r, 3), row, order);
                }
            }
            (f, Pixels::Gray8(d)) if f.bayer_tile().is_some() => {
                let tile = f.bayer_tile().expect("checked");
                demosaic(src, stride, w, h, tile, ch.unwrap_or(Channel::Luma), d);
            }
            _ => unreachable!("destination format checked above"),
        }
        Ok(())
    }
}

/// One row of packed 3-byte pixels (`order`: the byte offsets of R, G, B) into `out`.
#[inline]
fn rgb_row(c: Channel, s: &[u8], out: &mut [u8], order: [usize; 3]) {
    for (o, p) in out.iter_mut().zip(s.chunks_exact(3)) {
        *o = c.of(p[order[0]] as u32, p[order[1]] as u32, p[order[2]] as u32) as u8;
    }
}

/// BT.601 limited-range YCbCr (what YUYV cameras send) to 8-bit RGB, integer form.
#[inline(always)]
fn yuv_rgb(y: u8, u: u8, v: u8) -> (u32, u32, u32) {
    let c = 298 * (y as i32 - 16);
    let (d, e) = (u as i32 - 128, v as i32 - 128);
    let clamp = |x: i32| ((x + 128) >> 8).clamp(0, 255) as u32;
    (
        clamp(c + 409 * e),
        clamp(c - 100 * d - 208 * e),
        clamp(c + 516 * d),
    )
}

/// One YUYV row (Y0 U Y1 V per pixel pair; the pair shares its chroma) in channel `c`.
#[inline]
fn yuyv_row(c: Channel, s: &[u8], out: &mut [u8]) {
    let w = out.len();
    for (i, q) in s.chunks_exact(4).enumerate() {
        let (r, g, b) = yuv_rgb(q[0], q[1], q[3]);
        out[2 * i] = c.of(r, g, b) as u8;
        if 2 * i + 1 < w {
            let (r, g, b) = yuv_rgb(q[2], q[1], q[3]);
            out[2 * i + 1] = c.of(r, g, b) as u8;
        }
    }
    if w % 2 == 1 {
        // An odd width ends in half a pair: Y and U, no V (treated as neutral).
        let q = &s[2 * (w - 1)..2 * w];
        let (r, g, b) = yuv_rgb(q[0], q[1], 128);
        out[w - 1] = c.of(r, g, b) as u8;
    }
}

/// Bilinear demosaic of an 8-bit Bayer frame into channel `c`: at each pixel its own sample,
/// the mean of the 4 edge neighbours (green at R/B sites), of the 4 corner neighbours (B at R
/// sites, R at B sites), or of the 2 neighbours in the row or the column (R and B at G sites).
/// Edges are mirrored (index -1 reads 1), which keeps the tile's phase.
fn demosaic(
    src: &[u8],
    stride: usize,
    w: usize,
    h: usize,
    tile: [u8; 4],
    c: Channel,
    out: &mut [u8],
) {
    let mirror = |i: isize, n: usize| -> usize {
        if i < 0 {
            (-i) as usize
        } else if i as usize >= n {
            2 * (n - 1) - i as usize
        } else {
            i as usize
        }
        .min(n - 1)
    };
    if w < 2 || h < 2 {
        // No 2x2 tile: each pixel is all it has.
        for r in 0..h {
            out[r * w..(r + 1) * w].copy_from_slice(&src[r * stride..r * stride + w]);
        }
        return;
    }
    for r in 0..h {
        let up = &src[mirror(r as isize - 1, h) * stride..];
        let mid = &src[r * stride..];
        let dn = &src[mirror(r as isize + 1, h) * stride..];
        let row = &mut out[r * w..(r + 1) * w];
        for (col, o) in row.iter_mut().enumerate() {
            let (l, rt) = (mirror(col as isize - 1, w), mirror(col as isize + 1, w));
            let own = mid[col] as u32;
            let colour = tile[(r & 1) * 2 + (col & 1)];
            let (red, green, blue) = match colour {
                1 => {
                    let horiz = (mid[l] as u32 + mid[rt] as u32).div_ceil(2);
                    let vert = (up[col] as u32 + dn[col] as u32).div_ceil(2);
                    // The colour beside a G in its row.
                    if tile[(r & 1) * 2 + ((col + 1) & 1)] == 0 {
                        (horiz, own, vert)
                    } else {
                        (vert, own, horiz)
                    }
                }
                k => {
                    let cross =
                        (up[col] as u32 + dn[col] as u32 + mid[l] as u32 + mid[rt] as u32 + 2) / 4;
                    let diag =
                        (up[l] as u32 + up[rt] as u32 + dn[l] as u32 + dn[rt] as u32 + 2) / 4;
                    if k == 0 {
                        (own, cross, diag)
                    } else {
                        (diag, cross, own)
                    }
                }
            };
            *o = c.of(red, green, blue) as u8;
        }
    }
}

fn jpeg_decoder(
    src: &[u8],
    w: usize,
    h: usize,
    space: zune_core::colorspace::ColorSpace,
) -> Result<zune_jpeg::JpegDecoder<zune_core::bytestream::ZCursor<&[u8]>>, ConvertError> {
    use zune_core::bytestream::ZCursor;
    use zune_core::options::DecoderOptions;
    // Some cameras pad the buffer after the EOI marker; the decoder stops at EOI.
    let opts = DecoderOptions::default()
        .jpeg_set_out_colorspace(space)
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
    Ok(dec)
}

/// Decode a (M)JPEG image to its luma into `out` (`w * h` bytes). The decoder's scratch is
/// allocated per call; the output is written in place.
pub fn decode_jpeg_gray(
    src: &[u8],
    w: usize,
    h: usize,
    out: &mut [u8],
) -> Result<(), ConvertError> {
    jpeg_decoder(src, w, h, zune_core::colorspace::ColorSpace::Luma)?
        .decode_into(out)
        .map_err(|e| ConvertError::Jpeg(format!("{e:?}")))
}

/// Decode a (M)JPEG image to interleaved RGB into `out` (`3 * w * h` bytes).
pub fn decode_jpeg_rgb(src: &[u8], w: usize, h: usize, out: &mut [u8]) -> Result<(), ConvertError> {
    jpeg_decoder(src, w, h, zune_core::colorspace::ColorSpace::RGB)?
        .decode_into(out)
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
        assert_eq!(SourceFormat::parse("RGB3"), Some(SourceFormat::Rgb24));
        assert_eq!(SourceFormat::parse("ba81"), Some(SourceFormat::BayerBggr));
        assert_eq!(SourceFormat::parse("NV12"), None);
        for f in SourceFormat::ALL {
            assert_eq!(SourceFormat::from_fourcc(f.fourcc()), Some(f));
        }
        assert_eq!(SourceFormat::parse(""), None);
        assert_eq!(SourceFormat::Y12.to_string(), "Y12");
    }

    #[test]
    fn grey_drops_stride_padding() {
        // 3x2 image, bytesperline 4: the 4th byte of each row is padding (0xEE).
        let buf = [1, 2, 3, 0xEE, 4, 5, 6, 0xEE];
        let mut c = Converter::new(SourceFormat::Grey, 3, 2, 4);
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
        let mut c = Converter::new(SourceFormat::Grey, 2, 2, 0);
        assert_eq!(c.stride, 2);
        let mut d = gray8(4);
        c.convert(&buf, &mut d).unwrap();
        assert_eq!(d, Pixels::Gray8(vec![10, 20, 30, 40]));
    }

    #[test]
    fn short_buffer_and_wrong_destination_are_errors() {
        let mut c = Converter::new(SourceFormat::Grey, 3, 2, 4);
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
        let mut c = Converter::new(SourceFormat::Yuyv, 2, 2, 6);
        let mut d = gray8(4);
        c.convert(&buf, &mut d).unwrap();
        assert_eq!(d, Pixels::Gray8(vec![16, 235, 100, 101]));
    }

    #[test]
    fn y10_scales_to_full_range() {
        // Little-endian 10-bit values 0, 1, 512, 1023, and 1023 with garbage in the high bits.
        let buf = [0x00, 0x00, 0x01, 0x00, 0x00, 0x02, 0xFF, 0x03, 0xFF, 0xFF];
        let mut c = Converter::new(SourceFormat::Y10, 5, 1, 0);
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
        let mut c = Converter::new(SourceFormat::Y12, 2, 2, 6);
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
        let mut c = Converter::new(SourceFormat::Y16, 3, 1, 0);
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
        let mut c = Converter::new(SourceFormat::Mjpg, 32, 16, 0);
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
        let mut c = Converter::new(SourceFormat::Mjpg, 32, 16, 0);
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
        let mut c = Converter::new(SourceFormat::Mjpg, 16, 32, 0);
        let mut d = gray8(16 * 32);
        assert!(matches!(
            c.convert(&jpg, &mut d),
            Err(ConvertError::Jpeg(_))
        ));
        let mut c = Converter::new(SourceFormat::Mjpg, 32, 16, 0);
        let mut d = gray8(32 * 16);
        assert!(matches!(
            c.convert(&[0xFF, 0xD8, 1, 2, 3], &mut d),
            Err(ConvertError::Jpeg(_))
        ));
    }

    const ALL_CHANNELS: [Channel; 6] = [
        Channel::Luma,
        Channel::Red,
        Channel::Green,
        Channel::Blue,
        Channel::RedMinusOthers,
        Channel::GreenMinusOthers,
    ];

    fn convert8(c: &mut Converter, buf: &[u8]) -> Vec<u8> {
        let mut d = gray8(c.width as usize * c.height as usize);
        c.convert(buf, &mut d).unwrap();
        match d {
            Pixels::Gray8(v) => v,
            _ => unreachable!(),
        }
    }

    /// Known RGB pixels: red line, white, black, a green-ish grey.
    const PIXELS: [[u8; 3]; 4] = [[250, 30, 10], [255, 255, 255], [0, 0, 0], [90, 140, 60]];

    #[test]
    fn rgb3_and_bgr3_give_every_channel_with_stride() {
        // 2x2 image, stride 8 (2 padding bytes per row).
        let mut rgb = Vec::new();
        let mut bgr = Vec::new();
        for row in PIXELS.chunks(2) {
            for p in row {
                rgb.extend_from_slice(p);
                bgr.extend_from_slice(&[p[2], p[1], p[0]]);
            }
            rgb.extend_from_slice(&[0xEE, 0xEE]);
            bgr.extend_from_slice(&[0xEE, 0xEE]);
        }
        for ch in ALL_CHANNELS {
            let want: Vec<u8> = PIXELS
                .iter()
                .map(|p| ch.of(p[0] as u32, p[1] as u32, p[2] as u32) as u8)
                .collect();
            for (f, buf) in [(SourceFormat::Rgb24, &rgb), (SourceFormat::Bgr24, &bgr)] {
                let mut c = Converter::new(f, 2, 2, 8).with_channel(Some(ch)).unwrap();
                assert_eq!(convert8(&mut c, buf), want, "{f} {ch}");
            }
        }
        // Spot values, independent of Channel::of: red minus others of the red line.
        let mut c = Converter::new(SourceFormat::Bgr24, 2, 2, 8)
            .with_channel(Some(Channel::RedMinusOthers))
            .unwrap();
        // White is full scale: R clipped, as at a bright laser's white centre.
        assert_eq!(convert8(&mut c, &bgr), vec![230, 255, 0, 0]);
    }

    #[test]
    fn yuyv_colour_channels_follow_bt601() {
        // Pair 1: pure red in BT.601 limited range (Y 81, Cb 90, Cr 240) twice; pair 2: white
        // (Y 235) and black (Y 16) with neutral chroma.
        let buf = [81, 90, 81, 240, 235, 128, 16, 128];
        let mut c = Converter::new(SourceFormat::Yuyv, 4, 1, 0);
        assert_eq!(convert8(&mut c, &buf), vec![81, 81, 235, 16]);
        let expect = [
            (Channel::Luma, [81, 81, 235, 16]),
            (Channel::Red, [255, 255, 255, 0]),
            (Channel::Green, [0, 0, 255, 0]),
            (Channel::Blue, [0, 0, 255, 0]),
            // White: the laser's channel clipped, full scale (hal's `Channel::of_full`).
            (Channel::RedMinusOthers, [255, 255, 255, 0]),
            (Channel::GreenMinusOthers, [0, 0, 255, 0]),
        ];
        for (ch, want) in expect {
            let mut c = Converter::new(SourceFormat::Yuyv, 4, 1, 0)
                .with_channel(Some(ch))
                .unwrap();
            assert_eq!(convert8(&mut c, &buf), want.to_vec(), "{ch}");
        }
    }

    /// Mosaic an RGB image (`w` x `h`, pixel function `f`) with a Bayer tile.
    fn mosaic(
        f: SourceFormat,
        w: usize,
        h: usize,
        px: impl Fn(usize, usize) -> [u8; 3],
    ) -> Vec<u8> {
        let tile = f.bayer_tile().unwrap();
        let mut v = Vec::with_capacity(w * h);
        for r in 0..h {
            for c in 0..w {
                v.push(px(r, c)[tile[(r & 1) * 2 + (c & 1)] as usize]);
            }
        }
        v
    }

    #[test]
    fn bayer_demosaic_is_exact_on_flat_and_linear_colour() {
        let (w, h) = (8usize, 6usize);
        for f in [
            SourceFormat::BayerRggb,
            SourceFormat::BayerBggr,
            SourceFormat::BayerGbrg,
            SourceFormat::BayerGrbg,
        ] {
            // A flat colour comes back exactly everywhere, edges included.
            let flat = mosaic(f, w, h, |_, _| [200, 100, 50]);
            for ch in ALL_CHANNELS {
                let mut c = Converter::new(f, w as u32, h as u32, 0)
                    .with_channel(Some(ch))
                    .unwrap();
                let want = ch.of(200, 100, 50) as u8;
                assert!(
                    convert8(&mut c, &flat).iter().all(|&v| v == want),
                    "{f} {ch}"
                );
            }
            // Colours linear in row and column (steps of 8 DN: the means are whole) are
            // interpolated exactly inside the border.
            let px =
                |r: usize, c: usize| [(10 + 8 * c) as u8, (20 + 8 * r) as u8, (200 - 8 * c) as u8];
            let img = mosaic(f, w, h, px);
            for ch in [Channel::Red, Channel::Green, Channel::Blue] {
                let mut c = Converter::new(f, w as u32, h as u32, 0)
                    .with_channel(Some(ch))
                    .unwrap();
                let out = convert8(&mut c, &img);
                for r in 1..h - 1 {
                    for col in 1..w - 1 {
                        let p = px(r, col);
                        let want = ch.of(p[0] as u32, p[1] as u32, p[2] as u32) as u8;
                        assert_eq!(out[r * w + col], want, "{f} {ch} at {r},{col}");
                    }
                }
            }
        }
    }

    #[test]
    fn bayer_red_line_stands_out_in_red_minus_others() {
        // RGGB with stride padding: a red laser line in column 3 over a white board.
        let (w, h, stride) = (8usize, 4usize, 10usize);
        let img = mosaic(SourceFormat::BayerRggb, w, h, |_, c| {
            if c == 3 {
                [240, 40, 40]
            } else {
                [200, 200, 200]
            }
        });
        let mut buf = Vec::new();
        for row in img.chunks(w) {
            buf.extend_from_slice(row);
            buf.extend_from_slice(&[0xEE, 0xEE]);
        }
        let mut c = Converter::new(SourceFormat::BayerRggb, w as u32, h as u32, stride)
            .with_channel(Some(Channel::RedMinusOthers))
            .unwrap();
        let out = convert8(&mut c, &buf);
        for r in 0..h {
            let row = &out[r * w..(r + 1) * w];
            let max = (0..w).max_by_key(|&i| row[i]).unwrap();
            assert_eq!(max, 3, "row {r}: {row:?}");
            assert_eq!(row[0], 0, "row {r}: the white board must vanish: {row:?}");
        }
    }

    #[test]
    fn channel_and_format_mismatches_are_refused() {
        let e = Converter::new(SourceFormat::Grey, 4, 4, 0)
            .with_channel(Some(Channel::Red))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("GREY") && e.contains("red") && e.contains("RGB3"),
            "{e}"
        );
        let e = Converter::new(SourceFormat::BayerBggr, 4, 4, 0)
            .with_channel(None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("BA81") && e.contains("red-minus-others"), "{e}");
        // A converter made without a channel refuses a colour-only format at convert time.
        let mut c = Converter::new(SourceFormat::Rgb24, 1, 1, 0);
        assert!(matches!(
            c.convert(&[1, 2, 3], &mut gray8(1)),
            Err(ConvertError::Channel(_))
        ));
        // Luma is valid for all; YUYV and MJPG have their own grey.
        for f in SourceFormat::ALL {
            assert!(f.check_channel(Some(Channel::Luma)).is_ok(), "{f}");
        }
        assert!(SourceFormat::Yuyv.check_channel(None).is_ok());
        assert!(SourceFormat::Mjpg.check_channel(None).is_ok());
    }

    #[test]
    fn mjpg_colour_channel_separates_a_red_bar() {
        let (w, h) = (32usize, 16usize);
        let mut rgb = Vec::with_capacity(w * h * 3);
        for _ in 0..h {
            for c in 0..w {
                rgb.extend_from_slice(if (12..20).contains(&c) {
                    &[230, 40, 30]
                } else {
                    &[180, 180, 180]
                });
            }
        }
        let mut jpg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpg, 95)
            .encode(&rgb, w as u32, h as u32, image::ExtendedColorType::Rgb8)
            .unwrap();
        let mut c = Converter::new(SourceFormat::Mjpg, w as u32, h as u32, 0)
            .with_channel(Some(Channel::RedMinusOthers))
            .unwrap();
        let out = convert8(&mut c, &jpg);
        for r in 0..h {
            // The grey board vanishes; the bar keeps R - (G + B) / 2 = 195 (JPEG chroma is
            // subsampled and quantised: within 30 DN in its middle).
            assert!(out[r * w + 3] <= 10, "row {r}: {}", out[r * w + 3]);
            assert!(
                out[r * w + 15].abs_diff(195) <= 30,
                "row {r}: {}",
                out[r * w + 15]
            );
        }
        // The RGB scratch is kept: a second frame reuses it.
        let p = c.rgb.as_ptr();
        convert8(&mut c, &jpg);
        assert_eq!(c.rgb.as_ptr(), p);
    }
}
