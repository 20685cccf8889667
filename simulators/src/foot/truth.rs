//! Outline polygons and the measurement ground truth of the parametric foot, computed from the
//! model's own definition (see the module doc of [`crate::foot`] for every definition).

use super::model::Foot;
use super::Side;
use footscan_geom::{P2, V2};
use serde::Serialize;
use std::f64::consts::FRAC_PI_2;

/// Maximum spacing of outline polygon vertices (mm).
const OUTLINE_STEP: f64 = 0.4;

/// Measurement ground truth, world coordinates (mm), points as [x, y].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FootTruth {
    pub side: Side,
    /// Body outline (toes excluded), closed polygon (last vertex not repeated), counterclockwise.
    pub outline_body: Vec<P2>,
    /// Each toe pad outline, hallux first, counterclockwise.
    pub outline_toes: Vec<Vec<P2>>,
    pub heel_point: P2,
    pub toe_tip: P2,
    /// Heel centre and second metatarsal head: the points defining the axis.
    pub heel_centre: P2,
    pub mt2_head: P2,
    /// Unit axis direction, heel to toe.
    pub axis_dir: V2,
    pub length_mm: f64,
    pub mt1_head: P2,
    pub mt5_head: P2,
    pub ball_width_mm: f64,
    pub waist_inner: P2,
    pub waist_outer: P2,
    /// Breadth perpendicular to the axis at half the length, and its two end points.
    pub midfoot_width_mm: f64,
    pub midfoot_inner: P2,
    pub midfoot_outer: P2,
    pub heel_width_mm: f64,
    pub hallux_point: P2,
    pub arch_height_mm: f64,
    /// Where the arch height is attained (one point of the plateau).
    pub arch_point: P2,
    pub arch_index: f64,
    /// Toe-less contact area (h <= 1 mm) and its three thirds, heel first (mm^2).
    pub contact_area_mm2: f64,
    pub contact_thirds_mm2: [f64; 3],
}

impl Foot {
    /// Body outline in the foot frame, counterclockwise in (x', y').
    pub fn outline_body_foot_frame(&self) -> Vec<P2> {
        let hh = self.hh;
        let mut pts = Vec::new();
        let arc = |n: usize| (0..n).map(move |k| FRAC_PI_2 * k as f64 / n as f64);
        let n_heel = ((FRAC_PI_2 * hh) / OUTLINE_STEP).ceil() as usize;
        // Heel point to the lateral side (y' negative), counterclockwise in (x', y'):
        // going from (0, 0) toward (H, -H).
        for t in arc(n_heel) {
            pts.push(P2::new(hh - hh * t.cos(), -hh * t.sin()));
        }
        // Lateral side forward.
        push_side(&mut pts, &self.lateral, hh, -1.0);
        // Medial side backward.
        let mut med = Vec::new();
        push_side(&mut med, &self.medial, hh, 1.0);
        med.reverse();
        pts.extend(med);
        // Medial heel arc back to the heel point.
        for k in (1..n_heel).rev() {
            let t = FRAC_PI_2 * k as f64 / n_heel as f64;
            pts.push(P2::new(hh - hh * t.cos(), hh * t.sin()));
        }
        pts
    }

    /// Toe pad outlines in the foot frame, counterclockwise in (x', y').
    pub fn toes_outlines_foot_frame(&self) -> Vec<Vec<P2>> {
        self.toes
            .iter()
            .map(|t| {
                let n =
                    ((2.0 * std::f64::consts::PI * t.a.max(t.b)) / OUTLINE_STEP).ceil() as usize;
                (0..n)
                    .map(|k| {
                        let (s, c) = (2.0 * std::f64::consts::PI * k as f64 / n as f64).sin_cos();
                        P2::new(t.xc + t.a * c, t.yc + t.b * s)
                    })
                    .collect()
            })
            .collect()
    }

    fn poly_world(&self, pts: Vec<P2>) -> Vec<P2> {
        let mut w: Vec<P2> = pts.iter().map(|p| self.to_world(p.x, p.y)).collect();
        if signed_area(&w) < 0.0 {
            w.reverse();
        }
        w
    }

    /// Body outline in world, counterclockwise.
    pub fn outline_body(&self) -> Vec<P2> {
        self.poly_world(self.outline_body_foot_frame())
    }

    /// Toe pad outlines in world, hallux first, counterclockwise.
    pub fn toes_outlines(&self) -> Vec<Vec<P2>> {
        self.toes_outlines_foot_frame()
            .into_iter()
            .map(|p| self.poly_world(p))
            .collect()
    }

    /// Contact area (body, h <= 1 mm) between x' = a and b, midpoint rule with `n` lines.
    pub(crate) fn contact_area(&self, a: f64, b: f64, n: usize) -> f64 {
        let dx = (b - a) / n as f64;
        (0..n)
            .map(|i| self.contact_length(a + (i as f64 + 0.5) * dx) * dx)
            .sum()
    }

    /// Length of {y': h(x', y') <= 1} on the body along the line x' = const.
    fn contact_length(&self, xf: f64) -> f64 {
        let Some((wm, wl)) = self.body_half_widths(xf) else {
            return 0.0;
        };
        let inside = |y: f64| self.body_height_foot_frame(xf, y).is_some_and(|h| h <= 1.0);
        let (lo, hi) = (-wl, wm);
        let n = ((hi - lo) / 0.25).ceil().max(1.0) as usize;
        let mut total = 0.0;
        let mut prev_y = lo;
        let mut prev_in = inside(lo);
        let mut start = if prev_in { Some(lo) } else { None };
        for k in 1..=n {
            let y = lo + (hi - lo) * k as f64 / n as f64;
            let cur_in = inside(y);
            if cur_in != prev_in {
                let (mut a, mut b) = (prev_y, y);
                for _ in 0..60 {
                    let m = 0.5 * (a + b);
                    if inside(m) == prev_in {
                        a = m;
                    } else {
                        b = m;
                    }
                }
                let edge = 0.5 * (a + b);
                if cur_in {
                    start = Some(edge);
                } else if let Some(s) = start.take() {
                    total += edge - s;
                }
            }
            prev_y = y;
            prev_in = cur_in;
        }
        if let Some(s) = start {
            total += hi - s;
        }
        total
    }

    /// Arch height per the definition: max h over x' in [x_f/3, 2 x_f/3], y' >= 0, at least R
    /// inside the outline. Returns (height, foot-frame point).
    pub(crate) fn arch_height_numeric(&self) -> (f64, P2) {
        let xf = self.body_front();
        let r = self.p.edge_radius_mm;
        let eval = |x: f64, y: f64| -> Option<f64> {
            if !(xf / 3.0..=2.0 * xf / 3.0).contains(&x) || y < 0.0 {
                return None;
            }
            let (wm, wl) = self.body_half_widths(x)?;
            let (_, dm) = self.medial.eval(x);
            // Inside by at least R (first-order distance to the side).
            if (wm - y) / (1.0 + dm * dm).sqrt() < r || wl + y < r {
                return None;
            }
            self.body_height_foot_frame(x, y)
        };
        let mut best = (f64::NEG_INFINITY, P2::origin());
        let scan = |x0: f64, x1: f64, y0: f64, y1: f64, step: f64, best: &mut (f64, P2)| {
            let nx = ((x1 - x0) / step).ceil() as usize;
            let ny = ((y1 - y0) / step).ceil() as usize;
            for i in 0..=nx {
                let x = x0 + (x1 - x0) * i as f64 / nx as f64;
                for j in 0..=ny {
                    let y = y0 + (y1 - y0) * j as f64 / ny as f64;
                    if let Some(h) = eval(x, y) {
                        if h > best.0 {
                            *best = (h, P2::new(x, y));
                        }
                    }
                }
            }
        };
        scan(xf / 3.0, 2.0 * xf / 3.0, 0.0, 0.6 * self.l, 0.5, &mut best);
        let mut step = 0.5;
        for _ in 0..4 {
            let (bx, by) = (best.1.x, best.1.y);
            let s = step / 10.0;
            scan(
                bx - step,
                bx + step,
                (by - step).max(0.0),
                by + step,
                s,
                &mut best,
            );
            step = s * 2.0;
        }
        best
    }

    /// The measurement ground truth (takes a fraction of a second).
    pub fn truth(&self) -> FootTruth {
        let l = self.l;
        let hallux = self.toes[0];
        let heel_point = self.to_world(0.0, 0.0);
        let toe_tip = self.to_world(hallux.xc + hallux.a, hallux.yc);
        let heel_centre = self.to_world(self.hh, 0.0);
        let mt2_head = self.to_world(self.mt2_x, 0.0);
        let axis_dir = self.dir_world(1.0, 0.0);
        let length_mm = (toe_tip - heel_point).dot(&axis_dir);
        let m = &self.medial;
        let lat = &self.lateral;
        let (wm_mid, wl_mid) = self
            .body_half_widths(l / 2.0)
            .expect("midfoot is on the body");
        // Heel width: maximum breadth over the rear quarter (dense scan plus the disc centre).
        let mut heel_width = 2.0 * self.hh;
        let n = 25_000;
        for i in 0..=n {
            let x = l / 4.0 * i as f64 / n as f64;
            if let Some((a, b)) = self.body_half_widths(x) {
                heel_width = heel_width.max(a + b);
            }
        }
        let (arch_height_mm, arch_pt) = self.arch_height_numeric();
        let xf = self.body_front();
        let thirds = [
            self.contact_area(0.0, xf / 3.0, 700),
            self.contact_area(xf / 3.0, 2.0 * xf / 3.0, 700),
            self.contact_area(2.0 * xf / 3.0, xf, 700),
        ];
        let total: f64 = thirds.iter().sum();
        FootTruth {
            side: self.p.side,
            outline_body: self.outline_body(),
            outline_toes: self.toes_outlines(),
            heel_point,
            toe_tip,
            heel_centre,
            mt2_head,
            axis_dir,
            length_mm,
            mt1_head: self.to_world(m.x_head, m.w_head),
            mt5_head: self.to_world(lat.x_head, -lat.w_head),
            ball_width_mm: m.w_head + lat.w_head,
            waist_inner: self.to_world(m.x_waist, m.w_waist),
            waist_outer: self.to_world(lat.x_waist, -lat.w_waist),
            midfoot_width_mm: wm_mid + wl_mid,
            midfoot_inner: self.to_world(l / 2.0, wm_mid),
            midfoot_outer: self.to_world(l / 2.0, -wl_mid),
            heel_width_mm: heel_width,
            hallux_point: self.to_world(hallux.xc, hallux.yc + hallux.b),
            arch_height_mm,
            arch_point: self.to_world(arch_pt.x, arch_pt.y),
            arch_index: thirds[1] / total,
            contact_area_mm2: total,
            contact_thirds_mm2: thirds,
        }
    }
}

/// Side outline points for x' from H to the front end (y' = sign * w), spaced <= OUTLINE_STEP.
fn push_side(pts: &mut Vec<P2>, side: &super::model::SideCurve, hh: f64, sign: f64) {
    // Hermite part, by x'.
    let n = ((side.x_head - hh) / (OUTLINE_STEP / 2.0)).ceil() as usize;
    for k in 0..n {
        let x = hh + (side.x_head - hh) * k as f64 / n as f64;
        pts.push(P2::new(x, sign * side.eval(x).0));
    }
    // Quarter ellipse by angle, up to but excluding the front end point for the medial side
    // (the lateral side includes it: the two sides share it).
    let (a, b) = (side.x_front - side.x_head, side.w_head);
    let n = ((FRAC_PI_2 * a.max(b)) / OUTLINE_STEP).ceil() as usize;
    let last = if sign < 0.0 { n } else { n - 1 };
    for k in 0..=last {
        let t = FRAC_PI_2 * k as f64 / n as f64;
        pts.push(P2::new(side.x_head + a * t.sin(), sign * b * t.cos()));
    }
}

pub(crate) fn signed_area(p: &[P2]) -> f64 {
    let n = p.len();
    (0..n)
        .map(|i| {
            let (a, b) = (p[i], p[(i + 1) % n]);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
        / 2.0
}
