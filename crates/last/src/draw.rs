//! Pictures for people: an RGB canvas with a world-to-pixel view, lines, dots, 8x8 text,
//! colour maps with a labelled bar, written atomically as PNG.
//!
//! Every last stage draws what it did (heat maps of deviation, zebra stripes of a join, side
//! and top views), so one small canvas serves them all rather than each stage its own.

use image::{Rgb, RgbImage};
use std::path::Path;

pub type Colour = Rgb<u8>;
pub const WHITE: Colour = Rgb([255, 255, 255]);
pub const BLACK: Colour = Rgb([0, 0, 0]);
pub const GREY: Colour = Rgb([128, 128, 128]);
pub const RED: Colour = Rgb([200, 30, 30]);
pub const BLUE: Colour = Rgb([30, 60, 200]);
pub const GREEN: Colour = Rgb([20, 150, 40]);
pub const AMBER: Colour = Rgb([210, 130, 0]);

/// Maps world (x, y) in mm to pixels: uniform scale, y up, a margin around the content box.
#[derive(Clone, Copy, Debug)]
pub struct View {
    pub x0: f64,
    pub y0: f64,
    pub scale: f64,
    pub left: f64,
    pub bottom: f64,
}

impl View {
    /// Fit the box `[xmin, xmax] x [ymin, ymax]` into the pixel rectangle with its lower-left
    /// corner at (`left`, `bottom`) (pixel coordinates, rows grow downward) and size w x h.
    pub fn fit(bounds: [f64; 4], left: f64, bottom: f64, w: f64, h: f64) -> View {
        let [xmin, xmax, ymin, ymax] = bounds;
        let sx = w / (xmax - xmin).max(1e-9);
        let sy = h / (ymax - ymin).max(1e-9);
        let scale = sx.min(sy);
        // Centre the content in the rectangle.
        let cx = left + 0.5 * (w - (xmax - xmin) * scale);
        let cy = bottom - 0.5 * (h - (ymax - ymin) * scale);
        View {
            x0: xmin,
            y0: ymin,
            scale,
            left: cx,
            bottom: cy,
        }
    }
    /// Pixel (column, row) of world (x, y).
    pub fn px(&self, x: f64, y: f64) -> (f64, f64) {
        (
            self.left + (x - self.x0) * self.scale,
            self.bottom - (y - self.y0) * self.scale,
        )
    }
    /// World (x, y) of pixel (column, row) centre.
    pub fn world(&self, c: f64, r: f64) -> (f64, f64) {
        (
            self.x0 + (c - self.left) / self.scale,
            self.y0 + (self.bottom - r) / self.scale,
        )
    }
}

/// An RGB picture being drawn.
pub struct Canvas {
    pub img: RgbImage,
}

impl Canvas {
    pub fn new(w: u32, h: u32, background: Colour) -> Canvas {
        Canvas {
            img: RgbImage::from_pixel(w, h, background),
        }
    }
    pub fn width(&self) -> u32 {
        self.img.width()
    }
    pub fn height(&self) -> u32 {
        self.img.height()
    }
    /// Set one pixel, clipped to the picture.
    pub fn put(&mut self, c: i64, r: i64, colour: Colour) {
        if c >= 0 && r >= 0 && (c as u32) < self.img.width() && (r as u32) < self.img.height() {
            self.img.put_pixel(c as u32, r as u32, colour);
        }
    }
    /// A line in pixel coordinates, `width` pixels thick.
    pub fn line_px(&mut self, a: (f64, f64), b: (f64, f64), colour: Colour, width: i64) {
        let n = ((b.0 - a.0).abs().max((b.1 - a.1).abs()).ceil() as i64).max(1);
        let h = width / 2;
        for k in 0..=n {
            let t = k as f64 / n as f64;
            let c = (a.0 + t * (b.0 - a.0)).round() as i64;
            let r = (a.1 + t * (b.1 - a.1)).round() as i64;
            for dc in -h..=(width - 1 - h) {
                for dr in -h..=(width - 1 - h) {
                    self.put(c + dc, r + dr, colour);
                }
            }
        }
    }
    /// A line between world points.
    pub fn line(&mut self, v: &View, a: (f64, f64), b: (f64, f64), colour: Colour, width: i64) {
        self.line_px(v.px(a.0, a.1), v.px(b.0, b.1), colour, width);
    }
    /// A polyline through world points, closed if asked.
    pub fn polyline(
        &mut self,
        v: &View,
        pts: &[(f64, f64)],
        closed: bool,
        colour: Colour,
        width: i64,
    ) {
        for w in pts.windows(2) {
            self.line(v, w[0], w[1], colour, width);
        }
        if closed && pts.len() > 2 {
            self.line(v, pts[pts.len() - 1], pts[0], colour, width);
        }
    }
    /// A dashed line between world points (dash and gap in pixels).
    pub fn dashed(&mut self, v: &View, a: (f64, f64), b: (f64, f64), colour: Colour, dash: f64) {
        let (pa, pb) = (v.px(a.0, a.1), v.px(b.0, b.1));
        let len = ((pb.0 - pa.0).powi(2) + (pb.1 - pa.1).powi(2)).sqrt();
        let mut s = 0.0;
        while s < len {
            let e = (s + dash).min(len);
            let p = |t: f64| {
                (
                    pa.0 + (pb.0 - pa.0) * t / len,
                    pa.1 + (pb.1 - pa.1) * t / len,
                )
            };
            self.line_px(p(s), p(e), colour, 1);
            s += 2.0 * dash;
        }
    }
    /// A filled disc of radius `r` pixels at a world point.
    pub fn dot(&mut self, v: &View, p: (f64, f64), r: i64, colour: Colour) {
        let (c, row) = v.px(p.0, p.1);
        let (c, row) = (c.round() as i64, row.round() as i64);
        for dr in -r..=r {
            for dc in -r..=r {
                if dc * dc + dr * dr <= r * r {
                    self.put(c + dc, row + dr, colour);
                }
            }
        }
    }
    /// 8x8 bitmap text with its top-left corner at pixel (x, y), each dot `scale` pixels.
    pub fn text(&mut self, x: i64, y: i64, s: &str, colour: Colour, scale: i64) {
        use font8x8::UnicodeFonts;
        for (n, ch) in s.chars().enumerate() {
            let Some(glyph) = font8x8::BASIC_FONTS.get(ch) else {
                continue;
            };
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits & (1 << col) != 0 {
                        for a in 0..scale {
                            for b in 0..scale {
                                self.put(
                                    x + (n as i64 * 8 + col) * scale + a,
                                    y + row as i64 * scale + b,
                                    colour,
                                );
                            }
                        }
                    }
                }
            }
        }
    }
    /// Text width in pixels at `scale`.
    pub fn text_width(s: &str, scale: i64) -> i64 {
        s.chars().count() as i64 * 8 * scale
    }
    /// A vertical colour bar at pixel (x, y), w x h, from `lo` (bottom) to `hi` (top), with
    /// `ticks` labelled values and a title above it.
    #[allow(clippy::too_many_arguments)]
    pub fn colour_bar(
        &mut self,
        x: i64,
        y: i64,
        w: i64,
        h: i64,
        map: &dyn Fn(f64) -> Colour,
        lo: f64,
        hi: f64,
        ticks: usize,
        title: &str,
    ) {
        for r in 0..h {
            let t = 1.0 - r as f64 / (h - 1).max(1) as f64;
            let c = map(lo + t * (hi - lo));
            for dc in 0..w {
                self.put(x + dc, y + r, c);
            }
        }
        let ticks = ticks.max(2);
        for k in 0..ticks {
            let t = k as f64 / (ticks - 1) as f64;
            let value = lo + t * (hi - lo);
            let r = y + ((1.0 - t) * (h - 1) as f64).round() as i64;
            self.line_px(
                ((x + w) as f64, r as f64),
                ((x + w + 5) as f64, r as f64),
                BLACK,
                1,
            );
            self.text(x + w + 8, r - 4, &format!("{value:+.2}"), BLACK, 1);
        }
        self.text(x, y - 14, title, BLACK, 1);
    }
    /// Write the picture as a PNG, atomically (a reader sees the old file or the new one).
    pub fn save_png(&self, path: &Path) -> std::io::Result<()> {
        let mut png = Vec::new();
        self.img
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .map_err(|e| std::io::Error::other(format!("{}: {e}", path.display())))?;
        write_atomic(path, &png)
    }
}

/// Diverging map for signed values in [-range, range]: blue (negative) to white to red.
pub fn diverging(value: f64, range: f64) -> Colour {
    let t = (value / range.max(1e-12)).clamp(-1.0, 1.0);
    let lerp = |a: f64, b: f64, s: f64| (a + (b - a) * s).round() as u8;
    if t < 0.0 {
        let s = -t;
        Rgb([
            lerp(255.0, 33.0, s),
            lerp(255.0, 102.0, s),
            lerp(255.0, 172.0, s),
        ])
    } else {
        Rgb([
            lerp(255.0, 178.0, t),
            lerp(255.0, 24.0, t),
            lerp(255.0, 43.0, t),
        ])
    }
}

/// Sequential map for t in [0, 1] (dark blue, teal, green, yellow: perceptually ordered).
pub fn sequential(t: f64) -> Colour {
    const STOPS: [[f64; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let t = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let s = t - i as f64;
    let c = |k: usize| (STOPS[i][k] + (STOPS[i + 1][k] - STOPS[i][k]) * s).round() as u8;
    Rgb([c(0), c(1), c(2)])
}

/// [`footscan_util::write_atomic`] with errors that name the path, as the last stages' error
/// messages expect.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    footscan_util::write_atomic(path, bytes)
        .map_err(|e| std::io::Error::new(e.kind(), format!("writing {}: {e}", path.display())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn view_round_trips_world_and_pixels() {
        let v = View::fit([-10.0, 250.0, -50.0, 60.0], 20.0, 580.0, 760.0, 500.0);
        for &(x, y) in &[(-10.0, -50.0), (250.0, 60.0), (12.5, 3.25)] {
            let (c, r) = v.px(x, y);
            let (x2, y2) = v.world(c, r);
            assert!((x - x2).abs() < 1e-9 && (y - y2).abs() < 1e-9);
        }
        // The box fits inside the rectangle on both axes.
        let (c0, r0) = v.px(-10.0, -50.0);
        let (c1, r1) = v.px(250.0, 60.0);
        assert!(c0 >= 20.0 - 1e-9 && c1 <= 780.0 + 1e-9);
        assert!(r0 <= 580.0 + 1e-9 && r1 >= 80.0 - 1e-9);
    }

    #[test]
    fn diverging_map_is_white_at_zero_and_saturates() {
        assert_eq!(diverging(0.0, 1.0), WHITE);
        assert_eq!(diverging(5.0, 1.0), diverging(1.0, 1.0));
        assert_eq!(diverging(-5.0, 1.0), diverging(-1.0, 1.0));
        assert!(diverging(1.0, 1.0)[0] > diverging(1.0, 1.0)[2]);
        assert!(diverging(-1.0, 1.0)[2] > diverging(-1.0, 1.0)[0]);
    }

    #[test]
    fn png_is_written_atomically_and_decodes() {
        let dir = tempfile::tempdir().unwrap();
        let mut c = Canvas::new(64, 32, WHITE);
        c.line_px((0.0, 0.0), (63.0, 31.0), BLACK, 2);
        c.text(2, 2, "ok", RED, 1);
        let p = dir.path().join("a.png");
        c.save_png(&p).unwrap();
        let back = image::open(&p).unwrap().to_rgb8();
        assert_eq!(back.dimensions(), (64, 32));
        assert_eq!(*back.get_pixel(0, 0), BLACK);
        // Only the PNG is left: no temporary file.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        let err = c.save_png(&dir.path().join("missing/a.png")).unwrap_err();
        assert!(err.to_string().contains("missing/a.png"), "{err}");
    }
}
