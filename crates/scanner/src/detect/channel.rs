//! Colour frames and the background: what the detectors see is one grey channel, made once per
//! frame into a reused buffer.
//!
//! A laser line under room light is often separable only in its own colour: a red line across a
//! black-and-white board is as bright as the white squares in luma, but the white squares vanish
//! in red minus the mean of green and blue. [`Channel`] names the conversion; a colour frame
//! without one is refused (never silently made grey), and so is a grey frame asked for a colour.
//! A frame taken with the laser off ([`Prep::set_background`]) is converted the same way and
//! subtracted (saturating at 0) from every laser-on frame, so the scene's own light drops out.

use super::DetectError;
use footscan_hal::{Frame, PixelFormat, Pixels, Timestamp};

pub use footscan_hal::{Channel, CHANNEL_NAMES};

/// Interleaved RGB samples, row-major, no padding.
#[derive(Clone, Debug, PartialEq)]
pub enum ColorPixels {
    Rgb8(Vec<u8>),
    Rgb16(Vec<u16>),
}

/// A colour frame (three samples per pixel).
#[derive(Clone, Debug, PartialEq)]
pub struct ColorImage {
    pub width: u32,
    pub height: u32,
    pub pixels: ColorPixels,
}

impl ColorImage {
    pub fn new(width: u32, height: u32, pixels: ColorPixels) -> Self {
        let n = match &pixels {
            ColorPixels::Rgb8(v) => v.len(),
            ColorPixels::Rgb16(v) => v.len(),
        };
        assert_eq!(
            n,
            3 * width as usize * height as usize,
            "colour buffer does not match {width}x{height}"
        );
        ColorImage {
            width,
            height,
            pixels,
        }
    }
}

/// A frame as it enters detection: grey, or colour needing a [`Channel`].
#[derive(Debug)]
pub enum Image {
    Gray(Frame),
    Color(ColorImage),
}

impl Image {
    pub fn size(&self) -> (u32, u32) {
        match self {
            Image::Gray(f) => (f.width, f.height),
            Image::Color(c) => (c.width, c.height),
        }
    }

    /// "1280x1024 Gray8", "640x480 RGB8", ...
    pub fn describe(&self) -> String {
        let (w, h) = self.size();
        let f = match self {
            Image::Gray(f) => match f.format() {
                PixelFormat::Gray8 => "Gray8",
                PixelFormat::Gray16 => "Gray16",
            },
            Image::Color(c) => match c.pixels {
                ColorPixels::Rgb8(_) => "RGB8",
                ColorPixels::Rgb16(_) => "RGB16",
            },
        };
        format!("{w}x{h} {f}")
    }

    /// A copy (a grey frame's copy owns its buffer, outside any pool).
    pub fn clone_image(&self) -> Image {
        match self {
            Image::Gray(f) => Image::Gray(Frame::new(
                f.seq,
                f.timestamp,
                f.width,
                f.height,
                f.pixels.clone(),
            )),
            Image::Color(c) => Image::Color(c.clone()),
        }
    }

    /// Transposed (rows become columns): for lines stored one row per column.
    pub fn transposed(&self) -> Image {
        fn tr<T: Copy>(v: &[T], w: usize, h: usize, k: usize) -> Vec<T> {
            let mut out = Vec::with_capacity(v.len());
            for c in 0..w {
                for r in 0..h {
                    out.extend_from_slice(&v[(r * w + c) * k..(r * w + c + 1) * k]);
                }
            }
            out
        }
        let (w, h) = self.size();
        let (wu, hu) = (w as usize, h as usize);
        match self {
            Image::Gray(f) => Image::Gray(Frame::new(
                f.seq,
                f.timestamp,
                h,
                w,
                match &f.pixels {
                    Pixels::Gray8(v) => Pixels::Gray8(tr(v, wu, hu, 1)),
                    Pixels::Gray16(v) => Pixels::Gray16(tr(v, wu, hu, 1)),
                },
            )),
            Image::Color(c) => Image::Color(ColorImage::new(
                h,
                w,
                match &c.pixels {
                    ColorPixels::Rgb8(v) => ColorPixels::Rgb8(tr(v, wu, hu, 3)),
                    ColorPixels::Rgb16(v) => ColorPixels::Rgb16(tr(v, wu, hu, 3)),
                },
            )),
        }
    }

    /// The columns `x0..x1` of rows `y0..y1`.
    pub fn crop(&self, x0: u32, y0: u32, x1: u32, y1: u32) -> Image {
        fn cut<T: Copy>(
            v: &[T],
            w: usize,
            k: usize,
            x: (usize, usize),
            y: (usize, usize),
        ) -> Vec<T> {
            let mut out = Vec::with_capacity((x.1 - x.0) * (y.1 - y.0) * k);
            for r in y.0..y.1 {
                out.extend_from_slice(&v[(r * w + x.0) * k..(r * w + x.1) * k]);
            }
            out
        }
        let (w, h) = self.size();
        let (x1, y1) = (x1.min(w), y1.min(h));
        let (x0, y0) = (x0.min(x1), y0.min(y1));
        let (x, y) = ((x0 as usize, x1 as usize), (y0 as usize, y1 as usize));
        let (cw, ch) = (x1 - x0, y1 - y0);
        match self {
            Image::Gray(f) => Image::Gray(Frame::new(
                f.seq,
                f.timestamp,
                cw,
                ch,
                match &f.pixels {
                    Pixels::Gray8(v) => Pixels::Gray8(cut(v, w as usize, 1, x, y)),
                    Pixels::Gray16(v) => Pixels::Gray16(cut(v, w as usize, 1, x, y)),
                },
            )),
            Image::Color(c) => Image::Color(ColorImage::new(
                cw,
                ch,
                match &c.pixels {
                    ColorPixels::Rgb8(v) => ColorPixels::Rgb8(cut(v, w as usize, 3, x, y)),
                    ColorPixels::Rgb16(v) => ColorPixels::Rgb16(cut(v, w as usize, 3, x, y)),
                },
            )),
        }
    }
}

/// Channel conversion and background subtraction into a reused grey frame.
pub struct Prep {
    channel: Option<Channel>,
    /// The laser-off frame, already in the channel, and its description for errors.
    background: Option<(Pixels, String, String)>,
    out: Frame,
}

impl Prep {
    /// `channel` None: grey frames only (a colour frame is an error naming the channels).
    pub fn new(channel: Option<Channel>) -> Self {
        Prep {
            channel,
            background: None,
            out: Frame::new(0, Timestamp::default(), 0, 0, Pixels::Gray8(Vec::new())),
        }
    }

    pub fn channel(&self) -> Option<Channel> {
        self.channel
    }

    /// Subtract `off` (a frame taken with the laser off, named `name` in errors) from every frame
    /// from now on.
    pub fn set_background(&mut self, off: &Image, name: &str) -> Result<(), DetectError> {
        let mut px = Pixels::Gray8(Vec::new());
        convert(self.channel, off, name, &mut px)?;
        self.background = Some((px, off.describe(), name.to_string()));
        Ok(())
    }

    /// `img` (named `name` in errors) as the grey frame the detectors take. Grey frames in luma
    /// without a background pass through without a copy.
    pub fn prepare<'a>(&'a mut self, img: &'a Image, name: &str) -> Result<&'a Frame, DetectError> {
        if let (Image::Gray(f), None, None | Some(Channel::Luma)) =
            (img, &self.background, self.channel)
        {
            return Ok(f);
        }
        let (w, h) = img.size();
        let mut px = std::mem::replace(&mut self.out.pixels, Pixels::Gray8(Vec::new()));
        let seq_ts = match img {
            Image::Gray(f) => (f.seq, f.timestamp),
            Image::Color(_) => (self.out.seq, self.out.timestamp),
        };
        let r = convert(self.channel, img, name, &mut px);
        if let Err(e) = r {
            self.out.pixels = px;
            return Err(e);
        }
        if let Some((bg, what, bname)) = &self.background {
            let mismatch = || {
                DetectError::Param(format!(
                "background {bname} ({what}) does not match frame {name} ({}): the laser-off frame must have the frame's size and format",
                img.describe()
            ))
            };
            if bg.len() != px.len() {
                self.out.pixels = px;
                return Err(mismatch());
            }
            match (&mut px, bg) {
                (Pixels::Gray8(v), Pixels::Gray8(b)) => v
                    .iter_mut()
                    .zip(b)
                    .for_each(|(a, b)| *a = a.saturating_sub(*b)),
                (Pixels::Gray16(v), Pixels::Gray16(b)) => v
                    .iter_mut()
                    .zip(b)
                    .for_each(|(a, b)| *a = a.saturating_sub(*b)),
                _ => {
                    self.out.pixels = px;
                    return Err(mismatch());
                }
            }
        }
        // Frame::new only checks the size; the buffer moves in, nothing is allocated.
        self.out = Frame::new(seq_ts.0, seq_ts.1, w, h, px);
        Ok(&self.out)
    }
}

/// `img` in `channel` into `out` (resized only when the size or depth changes).
fn convert(
    channel: Option<Channel>,
    img: &Image,
    name: &str,
    out: &mut Pixels,
) -> Result<(), DetectError> {
    match (img, channel) {
        (Image::Gray(f), None | Some(Channel::Luma)) => {
            match (&f.pixels, &mut *out) {
                (Pixels::Gray8(s), Pixels::Gray8(d)) => {
                    d.clear();
                    d.extend_from_slice(s)
                }
                (Pixels::Gray16(s), Pixels::Gray16(d)) => {
                    d.clear();
                    d.extend_from_slice(s)
                }
                (p, d) => *d = p.clone(),
            }
            Ok(())
        }
        (Image::Gray(_), Some(c)) => Err(DetectError::Param(format!(
            "frame {name} is grey ({}): channel {} needs a colour frame (use channel = luma)",
            img.describe(),
            c.as_str()
        ))),
        (Image::Color(_), None) => Err(DetectError::Param(format!(
            "frame {name} is colour ({}): set a channel, one of {CHANNEL_NAMES}",
            img.describe()
        ))),
        (Image::Color(c), Some(ch)) => {
            let n = c.width as usize * c.height as usize;
            match &c.pixels {
                ColorPixels::Rgb8(s) => {
                    if !matches!(out, Pixels::Gray8(_)) {
                        *out = Pixels::Gray8(Vec::new());
                    }
                    let Pixels::Gray8(d) = out else {
                        unreachable!()
                    };
                    d.resize(n, 0);
                    for (o, p) in d.iter_mut().zip(s.chunks_exact(3)) {
                        *o = ch.of(p[0] as u32, p[1] as u32, p[2] as u32) as u8;
                    }
                }
                ColorPixels::Rgb16(s) => {
                    if !matches!(out, Pixels::Gray16(_)) {
                        *out = Pixels::Gray16(Vec::new());
                    }
                    let Pixels::Gray16(d) = out else {
                        unreachable!()
                    };
                    d.resize(n, 0);
                    for (o, p) in d.iter_mut().zip(s.chunks_exact(3)) {
                        *o = ch.of_full(p[0] as u32, p[1] as u32, p[2] as u32, 65535) as u16;
                    }
                }
            }
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rgb(px: &[[u8; 3]]) -> Image {
        Image::Color(ColorImage::new(
            px.len() as u32,
            1,
            ColorPixels::Rgb8(px.iter().flatten().copied().collect()),
        ))
    }

    #[test]
    fn channels_of_a_red_line_on_white() {
        let img = rgb(&[[200, 200, 200], [200, 60, 40], [10, 10, 10]]);
        let mut p = Prep::new(Some(Channel::RedMinusOthers));
        let f = p.prepare(&img, "t").unwrap();
        assert_eq!(f.pixels, Pixels::Gray8(vec![0, 150, 0]));
        let mut p = Prep::new(Some(Channel::Luma));
        let f = p.prepare(&img, "t").unwrap();
        assert_eq!(f.pixels, Pixels::Gray8(vec![200, 99, 10]));
        // Near clipping, white is taken for a clipped laser's white centre (hal's
        // `Channel::of_full`): over-exposed white paper is no longer 0.
        let img = rgb(&[[250, 250, 250], [255, 255, 255], [255, 60, 40]]);
        let f = Prep::new(Some(Channel::RedMinusOthers))
            .prepare(&img, "t")
            .unwrap()
            .pixels
            .clone();
        assert_eq!(f, Pixels::Gray8(vec![213, 255, 255]));
    }

    #[test]
    fn colour_without_channel_and_grey_with_colour_channel_are_refused() {
        let img = rgb(&[[1, 2, 3]]);
        let e = Prep::new(None).prepare(&img, "a.png").unwrap_err();
        assert!(e.to_string().contains("a.png") && e.to_string().contains("red-minus-others"));
        let g = Image::Gray(Frame::new(
            0,
            Timestamp::default(),
            1,
            1,
            Pixels::Gray8(vec![5]),
        ));
        let e = Prep::new(Some(Channel::Red))
            .prepare(&g, "g.png")
            .unwrap_err();
        assert!(e.to_string().contains("g.png") && e.to_string().contains("grey"));
    }

    #[test]
    fn background_is_subtracted_and_a_mismatch_names_both() {
        let on = rgb(&[[100, 0, 0], [40, 0, 0]]);
        let off = rgb(&[[30, 0, 0], [50, 0, 0]]);
        let mut p = Prep::new(Some(Channel::Red));
        p.set_background(&off, "off.png").unwrap();
        assert_eq!(
            p.prepare(&on, "on.png").unwrap().pixels,
            Pixels::Gray8(vec![70, 0])
        );
        let small = rgb(&[[1, 1, 1]]);
        let e = p.prepare(&small, "on2.png").unwrap_err().to_string();
        assert!(e.contains("off.png") && e.contains("on2.png"), "{e}");
    }
}
