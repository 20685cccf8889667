//! An analytic foot sole and last bottoms made from it, for tests and benches: exact
//! outline and heights, and a bottom that is the foot scaled, turned and shifted by known
//! amounts, so an adjustment must recover exactly those amounts.

use super::outline;
use super::{FootLandmarks, FootPlantar, HeightMap, LastBottom, Side};
use footscan_geom::{P2, V2};

/// A smooth foot sole of length `length` (mm), heel at x = 0, toe toward +x.
#[derive(Clone, Copy, Debug)]
pub struct AnalyticFoot {
    pub length: f64,
    pub side: Side,
    /// Medial arch height (mm).
    pub arch_mm: f64,
}

/// Smooth interpolation through (s, v) knots (cosine blend between neighbours).
fn blend(k: &[(f64, f64)], s: f64) -> f64 {
    for w in k.windows(2) {
        let ((s0, v0), (s1, v1)) = (w[0], w[1]);
        if s <= s1 {
            let t = ((s - s0) / (s1 - s0)).clamp(0.0, 1.0);
            let b = 0.5 - 0.5 * (std::f64::consts::PI * t).cos();
            return v0 + (v1 - v0) * b;
        }
    }
    k.last().unwrap().1
}

impl AnalyticFoot {
    pub fn new(length: f64, side: Side) -> AnalyticFoot {
        AnalyticFoot {
            length,
            side,
            arch_mm: 14.0,
        }
    }
    fn sign(&self) -> f64 {
        match self.side {
            Side::Right => 1.0,
            Side::Left => -1.0,
        }
    }
    /// Medial and lateral half-widths at s = x / length (before the rounded ends).
    fn halves(&self, s: f64) -> (f64, f64) {
        let l = self.length / 235.0;
        let med = [
            (0.0, 27.0),
            (0.15, 30.0),
            (0.42, 22.0),
            (0.72, 49.0),
            (0.92, 40.0),
            (1.0, 30.0),
        ];
        let lat = [
            (0.0, 27.0),
            (0.15, 31.0),
            (0.42, 35.0),
            (0.64, 46.0),
            (0.88, 30.0),
            (1.0, 22.0),
        ];
        (blend(&med, s) * l, blend(&lat, s) * l)
    }
    /// Rounded ends: an elliptic cap over the rear and front 12 % of the length.
    fn cap(s: f64) -> f64 {
        let e = 0.12;
        let q = if s < e {
            (s / e).clamp(0.0, 1.0)
        } else if s > 1.0 - e {
            ((1.0 - s) / e).clamp(0.0, 1.0)
        } else {
            1.0
        };
        (1.0 - (1.0 - q) * (1.0 - q)).sqrt()
    }
    /// y of the medial and lateral edges at x.
    pub fn edges(&self, x: f64) -> (f64, f64) {
        let s = x / self.length;
        let (m, l) = self.halves(s);
        let c = Self::cap(s);
        (self.sign() * m * c, -self.sign() * l * c)
    }
    /// The outline, counterclockwise, `n` points per side.
    pub fn outline(&self, n: usize) -> Vec<P2> {
        let xs: Vec<f64> = (0..=n)
            .map(|k| {
                let t = k as f64 / n as f64;
                // Denser near the ends.
                self.length * (0.5 - 0.5 * (std::f64::consts::PI * t).cos())
            })
            .collect();
        let mut p: Vec<P2> = xs
            .iter()
            .map(|&x| P2::new(x, self.edges(x).1.min(self.edges(x).0)))
            .collect();
        p.extend(
            xs.iter()
                .rev()
                .skip(1)
                .take(n - 1)
                .map(|&x| P2::new(x, self.edges(x).0.max(self.edges(x).1))),
        );
        outline::make_ccw(&mut p);
        p
    }
    /// Sole height at (x, y), None outside the sole.
    pub fn height(&self, x: f64, y: f64) -> Option<f64> {
        let s = x / self.length;
        if !(0.0..=1.0).contains(&s) {
            return None;
        }
        let (a, b) = self.edges(x);
        let (ymax, ymin) = (a.max(b), a.min(b));
        if y <= ymin || y >= ymax {
            return None;
        }
        // Position across: 0 on the axis, 1 at the medial edge, -1 at the lateral edge.
        let q = if self.sign() * y >= 0.0 {
            y / a
        } else {
            -(y / b)
        };
        let medial = q.max(0.0);
        let arch = self.arch_mm * (-((s - 0.45) / 0.14).powi(2)).exp() * medial.powf(1.5);
        let rim = 3.0 * q.abs().powi(8);
        let toe = 8.0 * ((s - 0.8).max(0.0) / 0.2).powi(2);
        let heel = 2.0 * ((0.1 - s).max(0.0) / 0.1).powi(2);
        Some(arch + rim + toe + heel)
    }

    /// The foot as a scan would give it (no toe pads: the outline is the whole sole), heights
    /// on `cell_mm` cells, landmarks by [`outline::outline_landmarks`].
    pub fn plantar(&self, cell_mm: f64) -> FootPlantar {
        let out = self.outline(1500);
        let lm = outline::outline_landmarks(&out, V2::x(), Some(self.side)).expect("landmarks");
        let w = 60.0 * self.length / 235.0;
        let (x0, y0) = (-2.0, -w);
        let nx = ((self.length + 4.0) / cell_mm).ceil() as usize + 1;
        let ny = (2.0 * w / cell_mm).ceil() as usize + 1;
        let mut g = HeightMap::new(x0, y0, cell_mm, nx, ny);
        for j in 0..ny {
            for i in 0..nx {
                if let Some(h) = self.height(g.x(i), g.y(j)) {
                    g.set(i, j, h);
                }
            }
        }
        // The arch point: highest sole point over the medial midfoot.
        let (mut best, mut at) = (f64::NEG_INFINITY, P2::origin());
        for j in 0..ny {
            for i in 0..nx {
                let (x, y) = (g.x(i), g.y(j));
                let s = x / self.length;
                let (a, _) = self.edges(x);
                if (0.3..0.6).contains(&s) && y * self.sign() > 0.0 && (y / a) < 0.8 {
                    let h = g.get(i, j);
                    if h > best {
                        (best, at) = (h, P2::new(x, y));
                    }
                }
            }
        }
        FootPlantar {
            source: format!("analytic foot {} mm", self.length),
            side: self.side,
            outline: out,
            toe_outlines: Vec::new(),
            landmarks: FootLandmarks {
                heel_point: lm.heel,
                toe_tip: lm.toe,
                hallux: lm.toe,
                mt1_head: lm.ball_medial,
                mt5_head: lm.ball_lateral,
                waist_inner: lm.waist_medial,
                waist_outer: lm.waist_lateral,
                arch_point: at,
                arch_height_mm: best,
            },
            heights: g,
        }
    }

    /// A bottom made from this foot: scaled by 1/`k_xy` about `centre` (and its heights by
    /// 1/`k_z`), turned by `turn_deg` about `centre`, then shifted by `shift`. Adjusting it to
    /// the foot must give eps = k_xy, zeta = k_z, rotation -turn_deg and shift -shift (for
    /// no turn).
    pub fn bottom(
        &self,
        centre: P2,
        k_xy: f64,
        k_z: f64,
        turn_deg: f64,
        shift: V2,
        cell_mm: f64,
    ) -> LastBottom {
        let (c, s) = (turn_deg.to_radians().cos(), turn_deg.to_radians().sin());
        let to_b = |p: P2| {
            let d = (p - centre) / k_xy;
            P2::new(
                centre.x + c * d.x - s * d.y + shift.x,
                centre.y + s * d.x + c * d.y + shift.y,
            )
        };
        let to_f = |b: P2| {
            let d = b - centre - shift;
            P2::new(
                centre.x + k_xy * (c * d.x + s * d.y),
                centre.y + k_xy * (-s * d.x + c * d.y),
            )
        };
        let out: Vec<P2> = self.outline(1500).iter().map(|&p| to_b(p)).collect();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &out {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let nx = ((hi[0] - lo[0] + 4.0) / cell_mm).ceil() as usize + 1;
        let ny = ((hi[1] - lo[1] + 4.0) / cell_mm).ceil() as usize + 1;
        let mut g = HeightMap::new(lo[0] - 2.0, lo[1] - 2.0, cell_mm, nx, ny);
        for j in 0..ny {
            for i in 0..nx {
                let f = to_f(P2::new(g.x(i), g.y(j)));
                if let Some(h) = self.height(f.x, f.y) {
                    g.set(i, j, h / k_z);
                }
            }
        }
        LastBottom {
            source: format!(
                "bottom made from the analytic foot (1/{k_xy} in plan, 1/{k_z} in height)"
            ),
            outline: out,
            heights: g,
        }
    }
}
