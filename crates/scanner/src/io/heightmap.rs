use footscan_geom::{Side, P3};
use image::{Rgb, RgbImage};
use std::path::Path;

/// Which foot a height map shows and whose it is: its title's first line.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct HeightMapLabel {
    /// The side the operator chose, if any.
    pub chosen: Option<Side>,
    /// The side measured on the scan (stage `measure.foot`), if known: the title's side.
    pub measured: Option<Side>,
    /// The subject (patient id) when the scan has one.
    pub subject: Option<String>,
}

/// Characters of the subject shown in a title at most.
const SUBJECT_CHARS: usize = 40;

impl HeightMapLabel {
    /// The title's first line: side (and where it comes from), the view, the subject.
    /// Characters the 8x8 font lacks are shown as '?'.
    pub fn title(&self) -> String {
        let word = Side::as_str;
        let side = match (self.measured, self.chosen) {
            (Some(m), Some(c)) if m != c => format!(
                "{} foot (measured; chosen: {})",
                word(m).to_uppercase(),
                word(c)
            ),
            (Some(m), _) => format!("{} foot (measured)", word(m).to_uppercase()),
            (None, Some(c)) => format!("{} foot (as chosen)", word(c).to_uppercase()),
            (None, None) => "side not given".to_string(),
        };
        let mut t = format!("{side}, plantar view seen from below");
        if let Some(subject) = self.subject.as_deref().filter(|s| !s.trim().is_empty()) {
            let mut shown: String = subject
                .trim()
                .chars()
                .map(|c| {
                    if c.is_ascii_graphic() || c == ' ' {
                        c
                    } else {
                        '?'
                    }
                })
                .take(SUBJECT_CHARS)
                .collect();
            if subject.trim().chars().count() > SUBJECT_CHARS {
                shown.push_str("...");
            }
            t.push_str(", subject ");
            t.push_str(&shown);
        }
        t
    }
}

/// A sole height map rendered for people: heights on a colour scale over the platform's
/// x (heel to toe, left to right) and y (top to bottom), seen from below as the camera sees
/// the sole, with a labelled colour bar and a title naming the side, the view and the subject.
pub struct HeightMapImage {
    pub image: RgbImage,
    /// Height at the top of the colour scale, mm.
    pub max_mm: f64,
    /// Cells that received at least one point.
    pub filled_cells: usize,
}

impl HeightMapImage {
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        super::write_png_atomic(path, &self.image)
    }
}

pub(crate) const BG: Rgb<u8> = Rgb([24, 24, 28]);
pub(crate) const FG: Rgb<u8> = Rgb([230, 230, 230]);

/// Pixels around the drawing.
pub const MARGIN_PX: u32 = 12;
/// Top of the title's first line (the label) and of its second (extent and cell), px; the
/// text is the 8x8 font of [`draw_text`] in the colour [`FG`], 8 px a character from
/// [`MARGIN_PX`].
pub const TITLE_LINES_Y: [u32; 2] = [4, 16];
/// Height of the title band above the map, px.
const TITLE_H: u32 = 28;

/// Rasterise points (mm) into `cell_mm` cells (mean height per cell) and colour them, under a
/// title of two lines: `label`'s, then the extent and the cell.
pub fn render_heightmap(points: &[P3], cell_mm: f64, label: &HeightMapLabel) -> HeightMapImage {
    assert!(cell_mm > 0.0);
    let finite = points.iter().filter(|p| p.iter().all(|v| v.is_finite()));
    let (mut x0, mut x1, mut y0, mut y1, mut zmax) =
        (f64::MAX, f64::MIN, f64::MAX, f64::MIN, 0.0f64);
    let mut any = false;
    for p in finite.clone() {
        any = true;
        x0 = x0.min(p[0]);
        x1 = x1.max(p[0]);
        y0 = y0.min(p[1]);
        y1 = y1.max(p[1]);
        zmax = zmax.max(p[2]);
    }
    if !any {
        (x0, x1, y0, y1) = (0.0, 10.0, 0.0, 10.0);
    }
    let w = (((x1 - x0) / cell_mm).floor() as usize + 1).clamp(1, 4000);
    let h = (((y1 - y0) / cell_mm).floor() as usize + 1).clamp(1, 4000);
    let mut sum = vec![0.0f64; w * h];
    let mut n = vec![0u32; w * h];
    for p in finite {
        let i = (((p[0] - x0) / cell_mm) as usize).min(w - 1);
        let j = (((p[1] - y0) / cell_mm) as usize).min(h - 1);
        sum[j * w + i] += p[2];
        n[j * w + i] += 1;
    }
    fill_single_gaps(&mut sum, &mut n, w, h);
    // A round top of scale so the legend reads well.
    let step = nice_step(zmax.max(1.0) / 5.0);
    let max_mm = (zmax.max(1.0) / step).ceil() * step;

    let margin = MARGIN_PX;
    let bar_w = 110u32;
    let title_h = TITLE_H;
    let head = label.title();
    let title = format!(
        "sole height, x {:.0}-{:.0} mm, y {:.0}-{:.0} mm, cell {} mm",
        x0, x1, y0, y1, cell_mm
    );
    // Wide enough for the title (8 px a character) on a narrow map.
    let chars = head.chars().count().max(title.len()) as u32;
    let img_w = (w as u32 + 2 * margin + bar_w).max(chars * 8 + 2 * margin);
    let img_h = (h as u32).max(160) + 2 * margin + title_h;
    let mut image = RgbImage::from_pixel(img_w, img_h, BG);
    let mut filled = 0;
    for j in 0..h {
        for i in 0..w {
            let k = j * w + i;
            if n[k] > 0 {
                filled += 1;
                let z = sum[k] / n[k] as f64;
                image.put_pixel(
                    margin + i as u32,
                    margin + title_h + j as u32,
                    colour(z / max_mm),
                );
            }
        }
    }
    draw_text(&mut image, margin, TITLE_LINES_Y[0], &head);
    draw_text(&mut image, margin, TITLE_LINES_Y[1], &title);
    // Colour bar with ticks.
    let bx = margin * 2 + w as u32;
    let by = margin + title_h;
    let bh = (img_h - by - margin - 10).max(50);
    colour_bar(&mut image, (bx, by, bh), max_mm, step, |img, x, y, s| {
        draw_text(img, x, y, s)
    });
    draw_text(&mut image, bx, by + bh + 2, "mm");
    HeightMapImage {
        image,
        max_mm,
        filled_cells: filled,
    }
}

/// A vertical colour scale `bh` px tall at (`bx`, `by`), 0 at the bottom and `max_mm` at the
/// top, with a tick and a label (drawn by `label(image, x, y, text)`) every `step` mm.
pub(crate) fn colour_bar(
    image: &mut RgbImage,
    (bx, by, bh): (u32, u32, u32),
    max_mm: f64,
    step: f64,
    mut label: impl FnMut(&mut RgbImage, u32, u32, &str),
) {
    for t in 0..bh {
        let c = colour(1.0 - t as f64 / (bh - 1) as f64);
        for u in 0..16 {
            image.put_pixel(bx + u, by + t, c);
        }
    }
    let ticks = (max_mm / step).round() as u32;
    for k in 0..=ticks {
        let v = k as f64 * step;
        let y = by + ((1.0 - v / max_mm) * (bh - 1) as f64).round() as u32;
        for u in 16..20 {
            image.put_pixel(bx + u, y, FG);
        }
        label(image, bx + 23, y.saturating_sub(3), &format_tick(v, step));
    }
}

/// Cells as wide as the frame spacing alias into empty stripes; fill an empty cell whose two
/// neighbours along x (or else along y) are filled with their mean. Wider gaps stay empty.
fn fill_single_gaps(sum: &mut [f64], n: &mut [u32], w: usize, h: usize) {
    let mean = |k: usize, sum: &[f64], n: &[u32]| sum[k] / n[k] as f64;
    let mut fills = Vec::new();
    for j in 0..h {
        for i in 0..w {
            let k = j * w + i;
            if n[k] > 0 {
                continue;
            }
            if i > 0 && i + 1 < w && n[k - 1] > 0 && n[k + 1] > 0 {
                fills.push((k, 0.5 * (mean(k - 1, sum, n) + mean(k + 1, sum, n))));
            } else if j > 0 && j + 1 < h && n[k - w] > 0 && n[k + w] > 0 {
                fills.push((k, 0.5 * (mean(k - w, sum, n) + mean(k + w, sum, n))));
            }
        }
    }
    for (k, z) in fills {
        sum[k] = z;
        n[k] = 1;
    }
}

pub(crate) fn nice_step(raw: f64) -> f64 {
    let p = 10f64.powf(raw.log10().floor());
    for m in [1.0, 2.0, 2.5, 5.0, 10.0] {
        if m * p >= raw {
            return m * p;
        }
    }
    10.0 * p
}

pub(crate) fn format_tick(v: f64, step: f64) -> String {
    if step.fract().abs() < 1e-9 {
        format!("{v:.0}")
    } else {
        format!("{v:.1}")
    }
}

/// Perceptually ordered dark-blue -> green -> yellow ramp (viridis-like, piecewise linear).
pub(crate) fn colour(t: f64) -> Rgb<u8> {
    const STOPS: [[f64; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let t = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let i = (t.floor() as usize).min(STOPS.len() - 2);
    let f = t - i as f64;
    let c = |k: usize| (STOPS[i][k] + f * (STOPS[i + 1][k] - STOPS[i][k])).round() as u8;
    Rgb([c(0), c(1), c(2)])
}

/// 8x8 bitmap text (font8x8's basic Latin), clipped to the image.
pub(crate) fn draw_text(image: &mut RgbImage, x: u32, y: u32, text: &str) {
    use font8x8::UnicodeFonts;
    for (n, ch) in text.chars().enumerate() {
        let Some(glyph) = font8x8::BASIC_FONTS.get(ch) else {
            continue;
        };
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits & (1 << col) != 0 {
                    let (px, py) = (x + n as u32 * 8 + col, y + row as u32);
                    if px < image.width() && py < image.height() {
                        image.put_pixel(px, py, FG);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn raster_covers_points_and_scale_tops_max() {
        let pts: Vec<P3> = (0..100)
            .flat_map(|i| (0..40).map(move |j| P3::new(i as f64, j as f64, (i as f64) * 0.13)))
            .collect();
        let hm = render_heightmap(&pts, 1.0, &HeightMapLabel::default());
        assert_eq!(hm.filled_cells, 100 * 40);
        // Every other column missing: filled; a two-cell gap is left.
        let sparse: Vec<P3> = pts
            .iter()
            .filter(|p| p[0] as i32 % 2 == 0 || p[0] > 90.0)
            .copied()
            .collect();
        assert_eq!(
            render_heightmap(&sparse, 1.0, &HeightMapLabel::default()).filled_cells,
            100 * 40
        );
        let gap: Vec<P3> = pts
            .iter()
            .filter(|p| p[0] != 50.0 && p[0] != 51.0)
            .copied()
            .collect();
        assert_eq!(
            render_heightmap(&gap, 1.0, &HeightMapLabel::default()).filled_cells,
            98 * 40
        );
        assert!(hm.max_mm >= 12.87 && hm.max_mm <= 15.0, "{}", hm.max_mm);
        // Highest cell is yellow-ish, lowest dark.
        let hi = hm.image.get_pixel(12 + 99, 12 + TITLE_H + 20);
        let lo = hm.image.get_pixel(12, 12 + TITLE_H + 20);
        assert!(hi.0[0] as u32 + hi.0[1] as u32 > lo.0[0] as u32 + lo.0[1] as u32 + 150);
    }

    /// Read the text of one title line back from the image: each 8 px cell matched against
    /// the font's printable ASCII glyphs.
    fn read_line(img: &RgbImage, y: u32) -> String {
        use font8x8::UnicodeFonts;
        let mut s = String::new();
        let mut x = MARGIN_PX;
        while x + 8 <= img.width() {
            let cell: [u8; 8] = std::array::from_fn(|row| {
                (0..8).fold(0u8, |b, col| {
                    b | (u8::from(*img.get_pixel(x + col, y + row as u32) == FG) << col)
                })
            });
            let c = (' '..='~')
                .find(|&c| font8x8::BASIC_FONTS.get(c) == Some(cell))
                .unwrap_or('#');
            s.push(c);
            x += 8;
        }
        s.trim_end().to_string()
    }

    #[test]
    fn title_names_side_view_and_subject() {
        let pts: Vec<P3> = (0..200)
            .flat_map(|i| (0..80).map(move |j| P3::new(i as f64, j as f64, 5.0)))
            .collect();
        let label = HeightMapLabel {
            chosen: Some(Side::Left),
            measured: Some(Side::Left),
            subject: Some("p-0042".into()),
        };
        let hm = render_heightmap(&pts, 1.0, &label);
        assert_eq!(
            read_line(&hm.image, TITLE_LINES_Y[0]),
            "LEFT foot (measured), plantar view seen from below, subject p-0042"
        );
        assert!(read_line(&hm.image, TITLE_LINES_Y[1]).starts_with("sole height, x 0-199 mm"));
        let chosen = HeightMapLabel {
            chosen: Some(Side::Right),
            measured: None,
            subject: Some("  ".into()),
        };
        let line =
            |l: &HeightMapLabel| read_line(&render_heightmap(&pts, 1.0, l).image, TITLE_LINES_Y[0]);
        assert_eq!(
            line(&chosen),
            "RIGHT foot (as chosen), plantar view seen from below"
        );
        let mismatch = HeightMapLabel {
            measured: Some(Side::Left),
            ..chosen.clone()
        };
        assert_eq!(
            line(&mismatch),
            "LEFT foot (measured; chosen: right), plantar view seen from below"
        );
        let measured = HeightMapLabel {
            chosen: None,
            ..mismatch
        };
        assert_eq!(
            measured.title(),
            "LEFT foot (measured), plantar view seen from below"
        );
        assert_eq!(
            HeightMapLabel::default().title(),
            "side not given, plantar view seen from below"
        );
        let long = HeightMapLabel {
            subject: Some(format!("M\u{fc}ller {}", "x".repeat(60))),
            ..HeightMapLabel::default()
        };
        let t = long.title();
        assert!(
            t.ends_with(&format!(", subject M?ller {}...", "x".repeat(33))),
            "{t}"
        );
        // The image is widened to the whole title.
        let narrow: Vec<P3> = pts.iter().filter(|p| p[0] < 10.0).copied().collect();
        let hm = render_heightmap(&narrow, 1.0, &long);
        assert_eq!(read_line(&hm.image, TITLE_LINES_Y[0]), t);
    }

    #[test]
    fn nice_steps() {
        assert_eq!(nice_step(3.7), 5.0);
        assert_eq!(nice_step(0.21), 0.25);
        assert_eq!(nice_step(12.0), 20.0);
    }
}
