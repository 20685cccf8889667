//! Pictures of the insole as written: the mesh's top rasterised from above (a z-buffer over
//! its triangles, so the picture is the file, not the design's fields): a thickness map, a
//! shaded top view, and side profiles against the scanned sole.

use crate::design::Design;
use footscan_geom::mesh::TriMesh;
use footscan_geom::P2;
use footscan_last::draw::{sequential, Canvas, View, BLACK, BLUE, GREEN, GREY, RED, WHITE};

/// The mesh's top seen from above on pixels of `px` mm: heights (NaN off the insole).
struct Raster {
    x0: f64,
    y0: f64,
    px: f64,
    w: usize,
    h: usize,
    z: Vec<f64>,
}

fn rasterise(mesh: &TriMesh, px: f64) -> Raster {
    let bb = mesh.bbox();
    let (x0, y0) = (bb.min.x, bb.min.y);
    let w = ((bb.max.x - x0) / px).ceil() as usize + 1;
    let h = ((bb.max.y - y0) / px).ceil() as usize + 1;
    let mut z = vec![f64::NAN; w * h];
    for t in 0..mesh.triangles.len() {
        let c = mesh.corners(t);
        if mesh.face_normal_raw(t).z <= 0.0 {
            continue; // bottom and walls
        }
        let (ax, ay) = ((c[0].x - x0) / px, (c[0].y - y0) / px);
        let (bx, by) = ((c[1].x - x0) / px, (c[1].y - y0) / px);
        let (cx, cy) = ((c[2].x - x0) / px, (c[2].y - y0) / px);
        let det = (bx - ax) * (cy - ay) - (cx - ax) * (by - ay);
        if det.abs() < 1e-12 {
            continue;
        }
        let (i0, i1) = (
            ax.min(bx).min(cx).floor().max(0.0) as usize,
            ax.max(bx).max(cx).ceil() as usize,
        );
        let (j0, j1) = (
            ay.min(by).min(cy).floor().max(0.0) as usize,
            ay.max(by).max(cy).ceil() as usize,
        );
        for j in j0..=j1.min(h - 1) {
            for i in i0..=i1.min(w - 1) {
                let (x, y) = (i as f64, j as f64);
                let l1 = ((x - ax) * (cy - ay) - (cx - ax) * (y - ay)) / det;
                let l2 = ((bx - ax) * (y - ay) - (x - ax) * (by - ay)) / det;
                let l0 = 1.0 - l1 - l2;
                if l0 >= -1e-9 && l1 >= -1e-9 && l2 >= -1e-9 {
                    let v = l0 * c[0].z + l1 * c[1].z + l2 * c[2].z;
                    let k = j * w + i;
                    if z[k].is_nan() || z[k] < v {
                        z[k] = v;
                    }
                }
            }
        }
    }
    Raster {
        x0,
        y0,
        px,
        w,
        h,
        z,
    }
}

fn marks(d: &Design) -> Vec<(&'static str, P2)> {
    let m = &d.marks;
    let mut v = vec![
        ("heel centre", m.heel_centre),
        ("arch", m.arch_point),
        ("MT1", m.mt1_head),
        ("MT3", m.mt3_head),
        ("MT5", m.mt5_head),
    ];
    if d.params.met_pad_height_mm > 0.0 {
        v.push(("pad", d.pad_apex));
    }
    v
}

/// Top view of `r` with a colour per height and a title; returns the canvas and its view.
fn top_view(
    r: &Raster,
    title: &str,
    colour: &dyn Fn(usize, usize) -> Option<footscan_last::draw::Colour>,
) -> (Canvas, View) {
    let (wpx, hpx) = (1000u32, 520u32);
    let mut cv = Canvas::new(wpx, hpx, WHITE);
    let bounds = [
        r.x0,
        r.x0 + r.w as f64 * r.px,
        r.y0,
        r.y0 + r.h as f64 * r.px,
    ];
    let view = View::fit(bounds, 20.0, hpx as f64 - 30.0, 820.0, hpx as f64 - 80.0);
    for row in 0..hpx {
        for col in 0..wpx {
            let (x, y) = view.world(col as f64, row as f64);
            let i = ((x - r.x0) / r.px).round();
            let j = ((y - r.y0) / r.px).round();
            if i < 0.0 || j < 0.0 || i as usize >= r.w || j as usize >= r.h {
                continue;
            }
            if let Some(c) = colour(i as usize, j as usize) {
                cv.put(col as i64, row as i64, c);
            }
        }
    }
    cv.text(20, 12, title, BLACK, 1);
    (cv, view)
}

fn draw_marks(cv: &mut Canvas, view: &View, d: &Design) {
    let o: Vec<(f64, f64)> = d.outline.iter().map(|q| (q.x, q.y)).collect();
    cv.polyline(view, &o, true, BLACK, 1);
    for (name, p) in marks(d) {
        cv.dot(view, (p.x, p.y), 3, RED);
        let (c, r) = view.px(p.x, p.y);
        cv.text(c as i64 + 5, r as i64 - 10, name, BLACK, 1);
    }
}

/// Thickness map: the shell's thickness (top above the flat bottom) in colour.
pub fn thickness_map(d: &Design, mesh: &TriMesh) -> Canvas {
    let r = rasterise(mesh, 0.5);
    let (lo, hi) =
        r.z.iter()
            .filter(|z| z.is_finite())
            .fold((f64::MAX, f64::MIN), |(a, b), &z| (a.min(z), b.max(z)));
    let span = (hi - lo).max(1e-6);
    let title = format!(
        "shell thickness, {} foot, from above, toes right: {:.2} to {:.2} mm",
        if d.medial > 0.0 { "right" } else { "left" },
        lo,
        hi
    );
    let (mut cv, view) = top_view(&r, &title, &|i, j| {
        let z = r.z[j * r.w + i];
        z.is_finite().then(|| sequential((z - lo) / span))
    });
    draw_marks(&mut cv, &view, d);
    cv.colour_bar(
        880,
        60,
        24,
        380,
        &|v| sequential((v - lo) / span),
        lo,
        hi,
        6,
        "mm",
    );
    cv
}

/// Shaded top view: the top lit from the upper left, so the cup, the arch support, the pad
/// and the cut-out show as relief.
pub fn top_picture(d: &Design, mesh: &TriMesh) -> Canvas {
    let r = rasterise(mesh, 0.5);
    let at = |i: usize, j: usize| r.z[j * r.w + i];
    let (mut cv, view) = top_view(
        &r,
        "insole top, shaded (light from the upper left, relief x4)",
        &|i, j| {
            let z = at(i, j);
            if !z.is_finite() {
                return None;
            }
            let zx = |a: usize, b: usize| {
                let v = at(a, b);
                if v.is_finite() {
                    v
                } else {
                    z
                }
            };
            let (il, ir) = (i.saturating_sub(1), (i + 1).min(r.w - 1));
            let (jd, ju) = (j.saturating_sub(1), (j + 1).min(r.h - 1));
            let gx = 4.0 * (zx(ir, j) - zx(il, j)) / (2.0 * r.px);
            let gy = 4.0 * (zx(i, ju) - zx(i, jd)) / (2.0 * r.px);
            let n = [-gx, -gy, 1.0];
            let l = [-0.5, 0.5, std::f64::consts::FRAC_1_SQRT_2];
            let nn = (n[0] * n[0] + n[1] * n[1] + 1.0).sqrt();
            let s = ((n[0] * l[0] + n[1] * l[1] + n[2] * l[2]) / nn).clamp(0.0, 1.0);
            let g = (40.0 + 215.0 * s).round() as u8;
            Some(image_rgb([g, g, (g as f64 * 0.9 + 20.0).min(255.0) as u8]))
        },
    );
    draw_marks(&mut cv, &view, d);
    cv
}

fn image_rgb(c: [u8; 3]) -> footscan_last::draw::Colour {
    footscan_last::draw::Colour::from(c)
}

/// Side profiles: the top along the axis line and along the line through the arch point
/// (medial), over the scanned sole raised by the shell (dashed grey), vertical scale x4.
pub fn side_picture(d: &Design, mesh: &TriMesh) -> Canvas {
    let r = rasterise(mesh, 0.5);
    let (wpx, hpx) = (1000u32, 520u32);
    let mut cv = Canvas::new(wpx, hpx, WHITE);
    let (x0, x1) = (r.x0, r.x0 + r.w as f64 * r.px);
    let lines = [
        ("along the axis (y = 0)", 0.0, BLUE),
        ("through the arch point", d.marks.arch_point.y, RED),
    ];
    let profile = |y: f64| -> Vec<(f64, f64)> {
        let j = ((y - r.y0) / r.px).round();
        if j < 0.0 || j as usize >= r.h {
            return Vec::new();
        }
        (0..r.w)
            .filter_map(|i| {
                let z = r.z[j as usize * r.w + i];
                z.is_finite().then_some((r.x0 + i as f64 * r.px, z))
            })
            .collect()
    };
    let zmax =
        r.z.iter()
            .filter(|z| z.is_finite())
            .fold(0.0f64, |a, &b| a.max(b));
    let ex = 2.0;
    for (k, (name, y, colour)) in lines.iter().enumerate() {
        let top = 60.0 + k as f64 * 230.0;
        let view = View::fit(
            [x0, x1, 0.0, zmax * ex + 2.0],
            40.0,
            top + 200.0,
            920.0,
            200.0,
        );
        // The floor (the shoe's bottom curve when bent onto it), the scanned sole raised by
        // the shell, the insole's top.
        let floor: Vec<(f64, f64)> = (0..=100)
            .map(|k| x0 + (x1 - x0) * k as f64 / 100.0)
            .map(|x| (x, d.spring_at(x) * ex))
            .collect();
        cv.polyline(&view, &floor, false, BLACK, 1);
        let sole: Vec<(f64, f64)> = (0..r.w)
            .map(|i| r.x0 + i as f64 * r.px)
            .filter(|&x| d.is_measured(x, *y))
            .map(|x| {
                let z = d.params.shell_mm() + d.lift(x) + d.foot_at(x, *y) + d.spring_at(x);
                (x, z * ex)
            })
            .collect();
        // A plain line, broken where the foot was not measured (a dot every sixth sample,
        // grey and one pixel, was barely visible next to the shell's top).
        for run in sole.chunk_by(|a, b| b.0 - a.0 < 1.5 * r.px) {
            cv.polyline(&view, run, false, GREEN, 1);
        }
        let pts: Vec<(f64, f64)> = profile(*y).into_iter().map(|(x, z)| (x, z * ex)).collect();
        cv.polyline(&view, &pts, false, *colour, 2);
        for (x, z) in pts.iter().step_by(40) {
            cv.line(&view, (*x, d.spring_at(*x) * ex), (*x, *z), GREY, 1);
        }
        cv.text(
            40,
            top as i64 - 20,
            &format!(
                "{name}: shell top (colour), sole + shell (green); heel left; height x{ex}, max {:.1} mm",
                zmax
            ),
            BLACK,
            1,
        );
    }
    cv
}
