//! The plantar height map with the foot measurements drawn on it (plantar.png): outline,
//! axis, landmarks with labels, the widths and the length as dimension lines, the arch-index
//! thirds, a colour bar and a table of the figures. Seen from below, as the scanner sees the
//! sole: x (heel to toe) left to right, y top to bottom, like heightmap.png.

use super::{line_crossings, Measurements, Side};
use crate::geom::HeightMap;
use crate::io::heightmap::{colour, colour_bar, nice_step, BG, FG};
use footscan_geom::{quarter_turn, P2, V2};
use image::{Rgb, RgbImage};
use std::path::Path;

/// Pixels per millimetre of the drawing.
const SCALE: f64 = 3.0;
const MARGIN_MM: f64 = 20.0;
const OUTLINE: Rgb<u8> = Rgb([255, 255, 255]);
const AXIS: Rgb<u8> = Rgb([90, 220, 255]);
const POINT: Rgb<u8> = Rgb([255, 70, 70]);
const WIDTH: Rgb<u8> = Rgb([255, 165, 40]);
const THIRDS: Rgb<u8> = Rgb([200, 200, 200]);
const LABEL_BG: Rgb<u8> = Rgb([0, 0, 0]);

pub struct PlantarImage {
    pub image: RgbImage,
    /// Height at the top of the colour scale, mm.
    pub max_mm: f64,
}

impl PlantarImage {
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        crate::io::write_png_atomic(path, &self.image)
    }
}

/// World (mm) to pixel mapping of the drawing area.
struct View {
    x0: f64,
    y0: f64,
    left: f64,
    top: f64,
}

impl View {
    fn px(&self, p: P2) -> (f64, f64) {
        (
            self.left + (p.x - self.x0) * SCALE,
            self.top + (p.y - self.y0) * SCALE,
        )
    }
    fn world(&self, u: f64, v: f64) -> P2 {
        P2::new(
            self.x0 + (u - self.left) / SCALE,
            self.y0 + (v - self.top) / SCALE,
        )
    }
}

/// Draw `m` over `map` (the height map it was measured on).
pub fn render_plantar(map: &HeightMap, m: &Measurements) -> PlantarImage {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in m.outline.iter().chain(m.toe_outlines.iter().flatten()) {
        x0 = x0.min(p.x);
        x1 = x1.max(p.x);
        y0 = y0.min(p.y);
        y1 = y1.max(p.y);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 100.0, 0.0, 50.0);
    }
    // The length's dimension line runs outside the lateral border.
    for p in length_line(m) {
        x0 = x0.min(p.x);
        x1 = x1.max(p.x);
        y0 = y0.min(p.y);
        y1 = y1.max(p.y);
    }
    let (x0, x1, y0, y1) = (
        x0 - MARGIN_MM,
        x1 + MARGIN_MM,
        y0 - MARGIN_MM,
        y1 + MARGIN_MM,
    );
    let draw_w = ((x1 - x0) * SCALE).ceil() as u32;
    let draw_h = ((y1 - y0) * SCALE).ceil() as u32;
    let title_h = 44u32;
    let panel_w = 300u32;
    let bar_w = 70u32;
    let img_w = draw_w + bar_w + panel_w + 20;
    let img_h = (draw_h + title_h + 10).max(title_h + 330);
    let mut img = RgbImage::from_pixel(img_w, img_h, BG);
    let view = View {
        x0,
        y0,
        left: 10.0,
        top: title_h as f64,
    };

    // Heights.
    let zmax = map
        .z
        .iter()
        .copied()
        .filter(|z| z.is_finite())
        .fold(1.0f64, f64::max);
    let step = nice_step(zmax / 5.0);
    let max_mm = (zmax / step).ceil() * step;
    for v in 0..draw_h {
        for u in 0..draw_w {
            let (pu, pv) = (view.left as u32 + u, view.top as u32 + v);
            let w = view.world(pu as f64 + 0.5, pv as f64 + 0.5);
            if let Some((i, j)) = map.cell_of(w.x, w.y) {
                let z = map.get(i, j);
                if z.is_finite() {
                    img.put_pixel(pu, pv, colour(z / max_mm));
                }
            }
        }
    }

    let d = m.axis_dir;
    let medial = medial_dir(m);
    let along = |p: P2| (p - m.heel_point).dot(&d);
    let on_axis = |s: f64| m.heel_point + d * s;

    // Arch-index thirds, perpendicular to the axis across the body.
    let x_front = along(m.body_front);
    for k in 1..3 {
        let c = on_axis(x_front * k as f64 / 3.0);
        let ts = line_crossings(&m.outline, c, medial);
        if ts.len() >= 2 {
            let lo = ts.iter().copied().fold(f64::INFINITY, f64::min) - 4.0;
            let hi = ts.iter().copied().fold(f64::NEG_INFINITY, f64::max) + 4.0;
            let (a, b) = (c + medial * lo, c + medial * hi);
            dashed(&mut img, &view, a, b, THIRDS, 1, 6.0);
        }
    }
    // Outlines.
    for o in std::iter::once(&m.outline).chain(m.toe_outlines.iter()) {
        for i in 0..o.len() {
            line(&mut img, &view, o[i], o[(i + 1) % o.len()], OUTLINE, 2);
        }
    }
    // Axis, a little beyond both ends.
    let l = m.foot_length_mm;
    dashed(
        &mut img,
        &view,
        on_axis(-6.0),
        on_axis(l + 6.0),
        AXIS,
        2,
        10.0,
    );

    // Widths: ball (each head to the axis), mid-foot, heel.
    for p in [m.mt1_head, m.mt5_head] {
        line(&mut img, &view, p, on_axis(along(p)), WIDTH, 2);
    }
    line(&mut img, &view, m.midfoot_inner, m.midfoot_outer, WIDTH, 2);
    line(
        &mut img,
        &view,
        m.heel_width_inner,
        m.heel_width_outer,
        WIDTH,
        2,
    );
    let mid = |a: P2, b: P2| nalgebra::center(&a, &b);
    let ball_mid = mid(m.mt5_head, on_axis(along(m.mt5_head)));
    for (p, s) in [
        (ball_mid, format!("ball {:.1}", m.ball_width_mm)),
        (
            mid(m.midfoot_inner, m.midfoot_outer),
            format!("mid-foot {:.1}", m.midfoot_width_mm),
        ),
        (
            mid(m.heel_width_inner, m.heel_width_outer),
            format!("heel {:.1}", m.heel_width_mm),
        ),
    ] {
        label(&mut img, &view, p - medial * 9.0, &s, d);
    }
    // Foot length: a dimension line on the lateral side, parallel to the axis.
    let [a, b] = length_line(m);
    line(&mut img, &view, a, b, WIDTH, 1);
    for p in [a, b] {
        line(
            &mut img,
            &view,
            p - medial * 3.0,
            p + medial * 3.0,
            WIDTH,
            1,
        );
    }
    label(
        &mut img,
        &view,
        mid(a, b),
        &format!("length {:.1} mm", l),
        -medial,
    );

    // Landmarks, labelled away from the foot's middle.
    let centre = on_axis(l / 2.0);
    let points: [(P2, &str); 10] = [
        (m.heel_point, "heel"),
        (m.toe_tip, "toe tip"),
        (m.heel_centre, "heel centre"),
        (m.mt2_head, "MT2"),
        (m.mt1_head, "MT1"),
        (m.mt5_head, "MT5"),
        (m.waist_inner, "waist in"),
        (m.waist_outer, "waist out"),
        (m.hallux_point, "hallux"),
        (m.arch_point, "arch"),
    ];
    for (p, name) in points {
        // Toes joined to the ball leave no hallux point: the measurement puts it on the toe
        // tip, whose label it would overwrite.
        if name == "hallux" && p == m.toe_tip {
            continue;
        }
        dot(&mut img, &view, p, POINT);
        let mut away = p - centre;
        if matches!(name, "heel centre" | "MT2") {
            away = medial; // on the axis: label to the medial side
        }
        if name == "arch" {
            away = -medial; // next to the medial border: label inward
        }
        label(&mut img, &view, p, name, away);
    }
    // Sides.
    let at = on_axis(l * 0.22);
    for (sign, name) in [(1.0, "medial"), (-1.0, "lateral")] {
        let p = at + medial * (sign * (m.heel_width_mm * 0.5 + 8.0));
        let (u, v) = view.px(p);
        text(
            &mut img,
            u as i64 - 4 * name.len() as i64,
            v as i64 - 4,
            name,
            THIRDS,
            1,
        );
    }

    // Title.
    let side = m.side.as_str();
    text(
        &mut img,
        10,
        6,
        &format!("plantar height map, {side} foot, seen from below"),
        FG,
        2,
    );
    text(
        &mut img,
        10,
        28,
        &format!(
            "x {:.0}..{:.0} mm left to right, y {:.0}..{:.0} mm top to bottom, cell {} mm",
            x0, x1, y0, y1, m.cell_mm
        ),
        FG,
        1,
    );

    // Colour bar.
    let bx = draw_w + 24;
    let by = title_h + 4;
    let bh = (img_h - by - 30).min(260);
    colour_bar(&mut img, (bx, by, bh), max_mm, step, |img, x, y, s| {
        text(img, x as i64, y as i64, s, FG, 1)
    });
    text(
        &mut img,
        bx as i64,
        (by + bh + 10) as i64,
        "height mm",
        FG,
        1,
    );

    // Figures.
    let px = (draw_w + bar_w + 24) as i64;
    let rows = [
        format!("foot length    {:6.1} mm", m.foot_length_mm),
        format!("ball width     {:6.1} mm", m.ball_width_mm),
        format!("mid-foot width {:6.1} mm", m.midfoot_width_mm),
        format!("heel width     {:6.1} mm", m.heel_width_mm),
        format!("arch height    {:6.1} mm", m.arch_height_mm),
        format!("arch index     {:6.3}", m.arch_index),
        format!("axis angle     {:6.1} deg", m.axis_angle_deg),
    ];
    text(&mut img, px, (title_h + 4) as i64, "measurements", FG, 2);
    for (k, r) in rows.iter().enumerate() {
        text(
            &mut img,
            px,
            (title_h + 30 + 16 * k as u32) as i64,
            r,
            FG,
            1,
        );
    }
    let mut y = title_h as i64 + 30 + 16 * rows.len() as i64 + 12;
    for (c, what) in [
        (OUTLINE, "outline"),
        (AXIS, "axis: heel centre - MT2"),
        (WIDTH, "widths and length"),
        (THIRDS, "arch index thirds"),
        (POINT, "landmarks"),
    ] {
        for v in 0..8 {
            for u in 0..14 {
                img.put_pixel((px + u) as u32, (y + v) as u32, c);
            }
        }
        text(&mut img, px + 20, y, what, FG, 1);
        y += 14;
    }
    for w in &m.warnings {
        y += 6;
        for chunk in wrap(&format!("! {w}"), 34) {
            text(&mut img, px, y, &chunk, POINT, 1);
            y += 11;
        }
    }
    PlantarImage { image: img, max_mm }
}

fn medial_dir(m: &Measurements) -> V2 {
    let left = quarter_turn(&m.axis_dir);
    match m.side {
        Side::Right => left,
        Side::Left => -left,
    }
}

/// End points of the foot-length dimension line, parallel to the axis outside the lateral
/// border.
fn length_line(m: &Measurements) -> [P2; 2] {
    let (d, med) = (m.axis_dir, medial_dir(m));
    let off = -(m.ball_width_mm * 0.6 + 4.0);
    let at = |s: f64| m.heel_point + d * s + med * off;
    [at(0.0), at(m.foot_length_mm)]
}

fn wrap(s: &str, width: usize) -> Vec<String> {
    let mut out = Vec::new();
    let mut cur = String::new();
    for word in s.split_whitespace() {
        if !cur.is_empty() && cur.len() + 1 + word.len() > width {
            out.push(std::mem::take(&mut cur));
        }
        if !cur.is_empty() {
            cur.push(' ');
        }
        cur.push_str(word);
    }
    if !cur.is_empty() {
        out.push(cur);
    }
    out
}

fn put(img: &mut RgbImage, u: i64, v: i64, c: Rgb<u8>) {
    if u >= 0 && v >= 0 && (u as u32) < img.width() && (v as u32) < img.height() {
        img.put_pixel(u as u32, v as u32, c);
    }
}

/// A line of `width` pixels between two world points.
fn line(img: &mut RgbImage, view: &View, a: P2, b: P2, c: Rgb<u8>, width: i64) {
    let (ua, va) = view.px(a);
    let (ub, vb) = view.px(b);
    let n = (ub - ua).abs().max((vb - va).abs()).ceil().max(1.0) as usize;
    for k in 0..=n {
        let f = k as f64 / n as f64;
        let (u, v) = (ua + f * (ub - ua), va + f * (vb - va));
        for du in 0..width {
            for dv in 0..width {
                put(img, u as i64 + du - width / 2, v as i64 + dv - width / 2, c);
            }
        }
    }
}

/// A dashed line with dashes of `dash` pixels.
fn dashed(img: &mut RgbImage, view: &View, a: P2, b: P2, c: Rgb<u8>, width: i64, dash: f64) {
    let (ua, va) = view.px(a);
    let (ub, vb) = view.px(b);
    let len = (ub - ua).hypot(vb - va);
    let n = (len / dash).ceil().max(1.0) as usize;
    for k in (0..n).step_by(2) {
        let (f0, f1) = (k as f64 / n as f64, ((k + 1) as f64 / n as f64).min(1.0));
        let p = |f: f64| a + (b - a) * f;
        line(img, view, p(f0), p(f1), c, width);
    }
}

/// A filled marker with a dark rim.
fn dot(img: &mut RgbImage, view: &View, p: P2, c: Rgb<u8>) {
    let (u, v) = view.px(p);
    for dv in -5i64..=5 {
        for du in -5i64..=5 {
            let r2 = du * du + dv * dv;
            if r2 <= 25 {
                let col = if r2 > 12 { LABEL_BG } else { c };
                put(img, u as i64 + du, v as i64 + dv, col);
            }
        }
    }
}

/// A label next to a world point, on the side of `away` (a world direction), on a dark box.
fn label(img: &mut RgbImage, view: &View, p: P2, s: &str, away: V2) {
    let (u, v) = view.px(p);
    let n = away.x.hypot(away.y).max(1e-9);
    let (dx, dy) = (away.x / n, away.y / n);
    let (w, h) = (8.0 * s.len() as f64, 8.0);
    // Box centre 14 px from the point along `away`, then pushed out by half the box.
    let cx = u + dx * (14.0 + w / 2.0);
    let cy = v + dy * (12.0 + h / 2.0);
    let (x, y) = ((cx - w / 2.0) as i64, (cy - h / 2.0) as i64);
    for yy in y - 2..y + h as i64 + 2 {
        for xx in x - 2..x + w as i64 + 2 {
            put(img, xx, yy, LABEL_BG);
        }
    }
    text(img, x, y, s, FG, 1);
}

/// 8x8 bitmap text (font8x8) at `scale`, clipped to the image.
fn text(img: &mut RgbImage, x: i64, y: i64, s: &str, c: Rgb<u8>, scale: i64) {
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
                            put(
                                img,
                                x + (n as i64 * 8 + col) * scale + a,
                                y + row as i64 * scale + b,
                                c,
                            );
                        }
                    }
                }
            }
        }
    }
}
