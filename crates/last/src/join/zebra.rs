//! Pictures of a joined last: zebra stripes of the join region and shaded top and side
//! views, drawn by a small orthographic rasteriser with a depth buffer onto the shared canvas.
//!
//! The stripes are isophotes of one fixed light direction: bands of equal angle between the
//! surface normal and the light. A position-only (G0) seam breaks the stripes off, a tangent
//! (G1) seam without matching curvature puts a kink in them, and a curvature-continuous seam
//! lets them run straight through.

use super::tessellation::Tessellation;
use crate::draw::{Canvas, Colour, View, BLACK, WHITE};
use footscan_geom::{P3, V3};
use image::Rgb;
use std::path::Path;

/// An orthographic view: screen right, screen up; the viewer looks along -(right x up).
#[derive(Clone, Copy)]
pub struct Ortho {
    pub right: V3,
    pub up: V3,
    pub title: &'static str,
}

impl Ortho {
    pub fn top() -> Ortho {
        Ortho {
            right: V3::x(),
            up: V3::y(),
            title: "top",
        }
    }
    /// Seen from the -y side (x to the right, z up).
    pub fn side() -> Ortho {
        Ortho {
            right: V3::x(),
            up: V3::z(),
            title: "side",
        }
    }
    fn toward(&self) -> V3 {
        self.right.cross(&self.up)
    }
}

/// Rasterise `t` into the pixel rectangle of `view`, colouring each covered pixel by
/// `shade(normal, part, point)`. Only points inside `clip` (x range) are drawn.
pub fn render(
    c: &mut Canvas,
    view: &View,
    o: &Ortho,
    t: &Tessellation,
    clip: (f64, f64),
    shade: &dyn Fn(&V3, u8, &P3) -> Colour,
) {
    let (w, h) = (c.width() as usize, c.height() as usize);
    let mut depth = vec![f64::NEG_INFINITY; w * h];
    let d = o.toward();
    let scr: Vec<(f64, f64, f64)> = t
        .vertices
        .iter()
        .map(|p| {
            let (x, y) = view.px(p.coords.dot(&o.right), p.coords.dot(&o.up));
            (x, y, p.coords.dot(&d))
        })
        .collect();
    for tri in &t.triangles {
        let [a, b, cc] = tri.map(|i| i as usize);
        let (pa, pb, pc) = (scr[a], scr[b], scr[cc]);
        let area = (pb.0 - pa.0) * (pc.1 - pa.1) - (pb.1 - pa.1) * (pc.0 - pa.0);
        if area.abs() < 1e-12 {
            continue;
        }
        let xmin = pa.0.min(pb.0).min(pc.0).floor().max(0.0) as usize;
        let xmax = (pa.0.max(pb.0).max(pc.0).ceil() as usize).min(w - 1);
        let ymin = pa.1.min(pb.1).min(pc.1).floor().max(0.0) as usize;
        let ymax = (pa.1.max(pb.1).max(pc.1).ceil() as usize).min(h - 1);
        if xmin > xmax
            || ymin > ymax
            || pa.0.max(pb.0).max(pc.0) < 0.0
            || pa.1.max(pb.1).max(pc.1) < 0.0
        {
            continue;
        }
        for py in ymin..=ymax {
            for px in xmin..=xmax {
                let (x, y) = (px as f64 + 0.5, py as f64 + 0.5);
                let w0 = ((pb.0 - x) * (pc.1 - y) - (pb.1 - y) * (pc.0 - x)) / area;
                let w1 = ((pc.0 - x) * (pa.1 - y) - (pc.1 - y) * (pa.0 - x)) / area;
                let w2 = 1.0 - w0 - w1;
                if w0 < -1e-9 || w1 < -1e-9 || w2 < -1e-9 {
                    continue;
                }
                let z = w0 * pa.2 + w1 * pb.2 + w2 * pc.2;
                let k = py * w + px;
                if z <= depth[k] {
                    continue;
                }
                let p = P3::from(
                    t.vertices[a].coords * w0
                        + t.vertices[b].coords * w1
                        + t.vertices[cc].coords * w2,
                );
                if p.x < clip.0 || p.x > clip.1 {
                    continue;
                }
                depth[k] = z;
                let n = (t.normals[a] * w0 + t.normals[b] * w1 + t.normals[cc] * w2).normalize();
                let col = shade(&n, t.part[a].max(t.part[b]).max(t.part[cc]), &p);
                c.put(px as i64, py as i64, col);
            }
        }
    }
}

/// The fixed light of the stripes: from above, ahead and to the side.
pub fn light() -> V3 {
    V3::new(0.45, -0.35, 0.82).normalize()
}

/// Isophote stripes: `bands` black and white bands over the normal-to-light angle.
pub fn stripe(n: &V3, bands: f64) -> Colour {
    let a = n.dot(&light()).clamp(-1.0, 1.0).acos();
    if ((a / std::f64::consts::PI * bands).floor() as i64) % 2 == 0 {
        Rgb([20, 20, 20])
    } else {
        Rgb([245, 245, 245])
    }
}

fn part_colour(part: u8) -> [f64; 3] {
    match part {
        0 => [90.0, 130.0, 200.0],
        1 => [230.0, 140.0, 40.0],
        _ => [90.0, 170.0, 100.0],
    }
}

fn lambert(n: &V3, part: u8) -> Colour {
    let l = V3::new(0.3, -0.5, 0.8).normalize();
    let s = 0.35 + 0.65 * n.dot(&l).abs();
    let c = part_colour(part);
    Rgb([
        (c[0] * s).min(255.0) as u8,
        (c[1] * s).min(255.0) as u8,
        (c[2] * s).min(255.0) as u8,
    ])
}

/// Bounds of the tessellation in the view's plane, over the points inside the x range `clip`.
pub fn bounds(t: &Tessellation, o: &Ortho, clip: (f64, f64)) -> [f64; 4] {
    let mut b = [
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    ];
    for p in &t.vertices {
        if p.x < clip.0 || p.x > clip.1 {
            continue;
        }
        let (x, y) = (p.coords.dot(&o.right), p.coords.dot(&o.up));
        b = [b[0].min(x), b[1].max(x), b[2].min(y), b[3].max(y)];
    }
    b
}

/// Draw the seam curves (points given) over a panel.
pub fn seams(c: &mut Canvas, view: &View, o: &Ortho, seam_pts: &[Vec<P3>]) {
    for s in seam_pts {
        let pts: Vec<(f64, f64)> = s
            .iter()
            .map(|p| (p.coords.dot(&o.right), p.coords.dot(&o.up)))
            .collect();
        for w in pts.windows(2) {
            c.line(view, w[0], w[1], Rgb([220, 30, 30]), 1);
        }
    }
}

/// Zebra picture of the join region (from `x0` to `x1`): top and side views stacked.
pub fn zebra_png(
    path: &Path,
    t: &Tessellation,
    clip: (f64, f64),
    seam_pts: &[Vec<P3>],
    caption: &str,
) -> std::io::Result<()> {
    let (w, h) = (1000u32, 900u32);
    let mut c = Canvas::new(w, h, WHITE);
    let panels = [Ortho::top(), Ortho::side()];
    for (k, o) in panels.iter().enumerate() {
        let top = 40.0 + k as f64 * 430.0;
        let view = View::fit(
            bounds(t, o, clip),
            20.0,
            top + 400.0,
            w as f64 - 40.0,
            390.0,
        );
        render(&mut c, &view, o, t, clip, &|n, _, _| stripe(n, 18.0));
        seams(&mut c, &view, o, seam_pts);
        c.text(
            20,
            top as i64 - 16,
            &format!(
                "{} view, stripes of one light direction; red: seams",
                o.title
            ),
            BLACK,
            1,
        );
    }
    c.text(20, 6, caption, BLACK, 1);
    c.save_png(path)
}

/// Shaded top and side views of the whole joined last (back part blue, join patch orange,
/// toe part green) with the seams in red.
pub fn views_png(
    path: &Path,
    t: &Tessellation,
    seam_pts: &[Vec<P3>],
    caption: &str,
) -> std::io::Result<()> {
    let (w, h) = (1200u32, 900u32);
    let mut c = Canvas::new(w, h, WHITE);
    let clip = (f64::NEG_INFINITY, f64::INFINITY);
    for (k, o) in [Ortho::top(), Ortho::side()].iter().enumerate() {
        let top = 40.0 + k as f64 * 430.0;
        let b = bounds(t, o, clip);
        let view = View::fit(b, 20.0, top + 400.0, w as f64 - 40.0, 390.0);
        render(&mut c, &view, o, t, clip, &|n, part, _| lambert(n, part));
        seams(&mut c, &view, o, seam_pts);
        c.text(
            20,
            top as i64 - 16,
            &format!(
                "{} view: {:.1} x {:.1} mm; back part blue, join patch orange, toe part green",
                o.title,
                b[1] - b[0],
                b[3] - b[2]
            ),
            BLACK,
            1,
        );
    }
    c.text(20, 6, caption, BLACK, 1);
    c.save_png(path)
}
