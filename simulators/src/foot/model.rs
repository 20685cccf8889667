//! Parameters, plan region and sole heights of the parametric foot (see the module doc of
//! [`crate::foot`]).

use crate::optics::{check_range, SimError};
use crate::surface::Surface;
use footscan_geom::{P2, P3, V2};
use serde::{Deserialize, Serialize};

pub use footscan_geom::Side;

/// Foot shape and placement on the platform.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct FootParams {
    /// Foot length L (mm), heel point to toe tip along the axis: [220, 300].
    pub length_mm: f64,
    /// Ball width / L: [0.36, 0.44].
    pub ball_width_ratio: f64,
    /// Heel width / L: [0.22, 0.28].
    pub heel_width_ratio: f64,
    /// Medial arch height above the glass (mm): [8, 25].
    pub arch_height_mm: f64,
    pub side: Side,
    /// World x of the heel point (mm).
    pub heel_x_mm: f64,
    /// World y of the heel point, i.e. the axis offset (mm).
    pub axis_y_mm: f64,
    /// Axis rotation, counterclockwise seen from above (degrees): [-20, 20].
    pub yaw_deg: f64,
    /// How far the unloaded sole is pushed onto the glass (mm): [0, edge_radius_mm - 0.5].
    pub press_mm: f64,
    /// Edge rounding radius (mm): [1, 10].
    pub edge_radius_mm: f64,
    /// The shape's variations within a population (defaults: the reference foot).
    pub shape: FootShape,
}

/// How one foot differs from the reference foot in shape: where its metatarsal heads are,
/// how deep its waists are, how long its toes, how far its toes lean out (hallux valgus) and
/// whether its toes lie joined to the ball (a weight-bearing foot seen from below). Every
/// variation keeps the definitions of the module doc exact: each metatarsal head stays the
/// extreme of its side and each waist the narrowest point between heel and head.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct FootShape {
    /// First metatarsal head station x' / L: [0.66, 0.76].
    pub mt1_x_ratio: f64,
    /// Fifth metatarsal head station x' / L: [0.58, 0.70].
    pub mt5_x_ratio: f64,
    /// Medial waist half-width / heel half-width: [0.70, 0.98]; near 1 the medial border runs
    /// straight from heel to ball (a collapsed arch), low it curves in (a high arch).
    pub medial_waist_ratio: f64,
    /// Lateral waist half-width / heel half-width: [0.80, 0.99].
    pub lateral_waist_ratio: f64,
    /// Front of the body (toe-less sole) x' / L: [0.76, 0.84]; the toes fill the rest, so a
    /// low value is a foot with long toes.
    pub body_front_ratio: f64,
    /// Hallux valgus: the toe pads lean toward the lateral side by this much at the hallux
    /// (mm, less on the lesser toes) and the first metatarsal head stands out by 0.3 of it
    /// (the bunion): [0, 10].
    pub hallux_valgus_mm: f64,
    /// The toe pads reach back into the ball (weight-bearing: the footprint is one region).
    pub toes_joined: bool,
}

impl Default for FootShape {
    fn default() -> Self {
        FootShape {
            mt1_x_ratio: 0.72,
            mt5_x_ratio: 0.64,
            medial_waist_ratio: 0.92,
            lateral_waist_ratio: 0.95,
            body_front_ratio: 0.80,
            hallux_valgus_mm: 0.0,
            toes_joined: false,
        }
    }
}

impl FootShape {
    pub fn validate(&self) -> Result<(), SimError> {
        check_range("shape.mt1_x_ratio", self.mt1_x_ratio, 0.66, 0.76)?;
        check_range("shape.mt5_x_ratio", self.mt5_x_ratio, 0.58, 0.70)?;
        check_range(
            "shape.medial_waist_ratio",
            self.medial_waist_ratio,
            0.70,
            0.98,
        )?;
        check_range(
            "shape.lateral_waist_ratio",
            self.lateral_waist_ratio,
            0.80,
            0.99,
        )?;
        check_range("shape.body_front_ratio", self.body_front_ratio, 0.76, 0.84)?;
        check_range("shape.hallux_valgus_mm", self.hallux_valgus_mm, 0.0, 10.0)?;
        // The heads lie behind the front quarter ellipses' ends with room for the toes' rise.
        let room = self.body_front_ratio - self.mt1_x_ratio.max(self.mt5_x_ratio);
        if room < 0.05 {
            return Err(SimError::InvalidParameter {
                key: "shape.body_front_ratio".into(),
                value: format!("{}", self.body_front_ratio),
                expected: format!(
                    "at least 0.05 more than the metatarsal heads' x'/L ({}, {})",
                    self.mt1_x_ratio, self.mt5_x_ratio
                ),
            });
        }
        Ok(())
    }
}

impl Default for FootParams {
    fn default() -> Self {
        FootParams {
            length_mm: 250.0,
            ball_width_ratio: 0.40,
            heel_width_ratio: 0.25,
            arch_height_mm: 15.0,
            side: Side::Right,
            heel_x_mm: 110.0,
            axis_y_mm: 0.0,
            yaw_deg: 1.5,
            press_mm: 3.0,
            edge_radius_mm: 5.0,
            shape: FootShape::default(),
        }
    }
}

impl FootParams {
    pub fn validate(&self) -> Result<(), SimError> {
        check_range("length_mm", self.length_mm, 220.0, 300.0)?;
        check_range("ball_width_ratio", self.ball_width_ratio, 0.36, 0.44)?;
        check_range("heel_width_ratio", self.heel_width_ratio, 0.22, 0.28)?;
        check_range("arch_height_mm", self.arch_height_mm, 8.0, 25.0)?;
        check_range("heel_x_mm", self.heel_x_mm, -1e4, 1e4)?;
        check_range("axis_y_mm", self.axis_y_mm, -1e4, 1e4)?;
        check_range("yaw_deg", self.yaw_deg, -20.0, 20.0)?;
        check_range("edge_radius_mm", self.edge_radius_mm, 1.0, 10.0)?;
        check_range("press_mm", self.press_mm, 0.0, self.edge_radius_mm - 0.5)?;
        self.shape.validate()
    }

    /// The mirror image: other side, opposite yaw and axis offset.
    pub fn mirrored(&self) -> FootParams {
        FootParams {
            side: self.side.other(),
            yaw_deg: -self.yaw_deg,
            axis_y_mm: -self.axis_y_mm,
            ..self.clone()
        }
    }
}

/// Piecewise cubic Hermite interpolant with Fritsch-Carlson slopes (zero at local extrema and
/// at both ends), so it is monotone between stations and each extreme sits on a station.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Pchip {
    xs: Vec<f64>,
    ys: Vec<f64>,
    ms: Vec<f64>,
}

impl Pchip {
    pub(crate) fn new(pts: &[(f64, f64)]) -> Self {
        let xs: Vec<f64> = pts.iter().map(|p| p.0).collect();
        let ys: Vec<f64> = pts.iter().map(|p| p.1).collect();
        let n = xs.len();
        let d: Vec<f64> = (0..n - 1)
            .map(|i| (ys[i + 1] - ys[i]) / (xs[i + 1] - xs[i]))
            .collect();
        let mut ms = vec![0.0; n];
        for i in 1..n - 1 {
            if d[i - 1] * d[i] > 0.0 {
                let (h0, h1) = (xs[i] - xs[i - 1], xs[i + 1] - xs[i]);
                let (w1, w2) = (2.0 * h1 + h0, h1 + 2.0 * h0);
                ms[i] = (w1 + w2) / (w1 / d[i - 1] + w2 / d[i]);
            }
        }
        Pchip { xs, ys, ms }
    }

    /// Value and derivative; clamped to the end values outside the stations.
    pub(crate) fn eval(&self, x: f64) -> (f64, f64) {
        let n = self.xs.len();
        if x <= self.xs[0] {
            return (self.ys[0], 0.0);
        }
        if x >= self.xs[n - 1] {
            return (self.ys[n - 1], 0.0);
        }
        let i = self.xs.partition_point(|&s| s <= x) - 1;
        let h = self.xs[i + 1] - self.xs[i];
        let t = (x - self.xs[i]) / h;
        let (y0, y1, m0, m1) = (
            self.ys[i],
            self.ys[i + 1],
            self.ms[i] * h,
            self.ms[i + 1] * h,
        );
        let t2 = t * t;
        let t3 = t2 * t;
        let v = (2.0 * t3 - 3.0 * t2 + 1.0) * y0
            + (t3 - 2.0 * t2 + t) * m0
            + (-2.0 * t3 + 3.0 * t2) * y1
            + (t3 - t2) * m1;
        let dv = (6.0 * t2 - 6.0 * t) * y0
            + (3.0 * t2 - 4.0 * t + 1.0) * m0
            + (-6.0 * t2 + 6.0 * t) * y1
            + (3.0 * t2 - 2.0 * t) * m1;
        (v, dv / h)
    }
}

/// One side of the body outline for x' in [H, x_f]: Hermite through stations up to the
/// metatarsal head station, then a quarter ellipse closing at (x_f, 0).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct SideCurve {
    pub(crate) hermite: Pchip,
    /// Metatarsal head station (x', half-width): start of the front quarter ellipse.
    pub(crate) x_head: f64,
    pub(crate) w_head: f64,
    pub(crate) x_front: f64,
    /// Waist station (x', half-width).
    pub(crate) x_waist: f64,
    pub(crate) w_waist: f64,
}

impl SideCurve {
    /// Half-width and its derivative at x' (x' in [H, x_f]).
    pub(crate) fn eval(&self, x: f64) -> (f64, f64) {
        if x <= self.x_head {
            return self.hermite.eval(x);
        }
        let a = self.x_front - self.x_head;
        let t = (x - self.x_head) / a;
        if t >= 1.0 {
            return (0.0, f64::NEG_INFINITY);
        }
        let s = (1.0 - t * t).sqrt();
        (self.w_head * s, -self.w_head * t / (a * s))
    }

    /// The x' of the front quarter ellipse at half-width w (0 <= w <= w_head).
    pub(crate) fn front_x(&self, w: f64) -> f64 {
        let r = (w / self.w_head).clamp(0.0, 1.0);
        self.x_head + (self.x_front - self.x_head) * (1.0 - r * r).sqrt()
    }
}

/// An elliptic toe pad in the foot frame.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ToePad {
    /// Centre (x', y').
    pub xc: f64,
    pub yc: f64,
    /// Semi-axis along x' and across (y').
    pub a: f64,
    pub b: f64,
}

impl ToePad {
    fn rho2(&self, x: f64, y: f64) -> f64 {
        let (u, v) = ((x - self.xc) / self.a, (y - self.yc) / self.b);
        u * u + v * v
    }
}

/// The parametric foot: a [`Surface`] with its own exact measurement truth.
#[derive(Clone, Debug, PartialEq)]
pub struct Foot {
    pub(crate) p: FootParams,
    pub(crate) l: f64,
    /// Heel half-width = heel disc radius.
    pub(crate) hh: f64,
    pub(crate) medial: SideCurve,
    pub(crate) lateral: SideCurve,
    pub(crate) toes: [ToePad; 5],
    pub(crate) toe_lift: f64,
    pub(crate) mt2_x: f64,
    cos: f64,
    sin: f64,
    sgn: f64,
    dorsum: Pchip,
    y_bounds: (f64, f64),
}

impl Foot {
    pub fn new(p: FootParams) -> Result<Foot, SimError> {
        p.validate()?;
        let l = p.length_mm;
        let sh = &p.shape;
        let hh = p.heel_width_ratio * l / 2.0;
        let bw = p.ball_width_ratio * l;
        let (m1, m5) = (0.46 * bw, 0.54 * bw);
        let bunion = 0.3 * sh.hallux_valgus_mm;
        let x_f = sh.body_front_ratio * l;
        let (x1, x5) = (sh.mt1_x_ratio * l, sh.mt5_x_ratio * l);
        let medial = SideCurve {
            hermite: Pchip::new(&[
                (hh, hh),
                (0.42 * l, sh.medial_waist_ratio * hh),
                (x1, m1 + bunion),
            ]),
            x_head: x1,
            w_head: m1 + bunion,
            x_front: x_f,
            x_waist: 0.42 * l,
            w_waist: sh.medial_waist_ratio * hh,
        };
        let lateral = SideCurve {
            hermite: Pchip::new(&[(hh, hh), (0.35 * l, sh.lateral_waist_ratio * hh), (x5, m5)]),
            x_head: x5,
            w_head: m5,
            x_front: x_f,
            x_waist: 0.35 * l,
            w_waist: sh.lateral_waist_ratio * hh,
        };
        // Toe pads across, medial to lateral; hallux valgus leans them laterally, the hallux
        // most (the gaps shrink by at most 0.15 of it, so the pads stay apart).
        let (b1, b, gap) = (0.115 * bw, 0.068 * bw, 0.02 * bw);
        let mut ycs = [0.0; 5];
        let mut bs = [b; 5];
        bs[0] = b1;
        ycs[0] = 0.8 * m1 - b1;
        for i in 1..5 {
            ycs[i] = ycs[i - 1] - bs[i - 1] - gap - bs[i];
        }
        for (i, y) in ycs.iter_mut().enumerate() {
            *y -= sh.hallux_valgus_mm * (1.0 - 0.15 * i as f64);
        }
        // Tips behind the hallux's in proportion to the toes' length (L - x_f).
        let toe_len = (l - x_f) / (0.2 * l);
        let tips = [0.0, 0.015, 0.04, 0.07, 0.105].map(|d| l - d * l * toe_len);
        let body_front = |y: f64| -> f64 {
            if y >= 0.0 {
                if y >= medial.w_head {
                    f64::NEG_INFINITY
                } else {
                    medial.front_x(y)
                }
            } else if -y >= m5 {
                f64::NEG_INFINITY
            } else {
                lateral.front_x(-y)
            }
        };
        // Joined toes reach 0.015 L into the ball instead of stopping 0.012 L short of it.
        let toe_gap = if sh.toes_joined {
            -0.015 * l
        } else {
            0.012 * l
        };
        let mut toes = [ToePad {
            xc: 0.0,
            yc: 0.0,
            a: 1.0,
            b: 1.0,
        }; 5];
        for i in 0..5 {
            let (yc, bi, tip) = (ycs[i], bs[i], tips[i]);
            let mut a = 0.05 * l;
            for _ in 0..50 {
                // Rear end such that the pad clears the body front by toe_gap everywhere.
                let mut rear = f64::NEG_INFINITY;
                for k in 0..=200 {
                    let v = -1.0 + 2.0 * k as f64 / 200.0;
                    let dx = a * (1.0 - (1.0 - v * v).max(0.0).sqrt());
                    rear = rear.max(body_front(yc + v * bi) - dx);
                }
                a = (tip - (rear + toe_gap)) / 2.0;
            }
            toes[i] = ToePad {
                xc: tip - a,
                yc,
                a,
                b: bi,
            };
        }
        let (sin, cos) = p.yaw_deg.to_radians().sin_cos();
        let sgn = match p.side {
            Side::Right => 1.0,
            Side::Left => -1.0,
        };
        let dorsum = Pchip::new(&[
            (0.0, 0.18 * l),
            (0.50 * l, 0.25 * l),
            (0.80 * l, 0.12 * l),
            (0.90 * l, 0.09 * l),
            (l, 0.05 * l),
        ]);
        let mut foot = Foot {
            l,
            hh,
            medial,
            lateral,
            toes,
            toe_lift: 0.03 * l,
            mt2_x: x1 - 0.01 * l,
            cos,
            sin,
            sgn,
            dorsum,
            p,
            y_bounds: (0.0, 0.0),
        };
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        for q in foot
            .outline_body()
            .iter()
            .chain(foot.toes_outlines().iter().flatten())
        {
            lo = lo.min(q.y);
            hi = hi.max(q.y);
        }
        foot.y_bounds = (lo - 1.0, hi + 1.0);
        Ok(foot)
    }

    pub fn params(&self) -> &FootParams {
        &self.p
    }

    /// Toe pads in the foot frame, hallux first.
    pub fn toe_pads(&self) -> &[ToePad; 5] {
        &self.toes
    }

    /// x' of the front of the body (toes excluded).
    pub fn body_front(&self) -> f64 {
        self.p.shape.body_front_ratio * self.l
    }

    /// World (x, y) to foot frame (x', y').
    #[inline]
    pub fn to_foot(&self, x: f64, y: f64) -> P2 {
        let (dx, dy) = (x - self.p.heel_x_mm, y - self.p.axis_y_mm);
        P2::new(
            self.cos * dx + self.sin * dy,
            self.sgn * (-self.sin * dx + self.cos * dy),
        )
    }

    /// Foot frame (x', y') to world (x, y).
    #[inline]
    pub fn to_world(&self, xf: f64, yf: f64) -> P2 {
        let ym = self.sgn * yf;
        P2::new(
            self.p.heel_x_mm + self.cos * xf - self.sin * ym,
            self.p.axis_y_mm + self.sin * xf + self.cos * ym,
        )
    }

    /// Direction of a foot-frame vector in world.
    pub(crate) fn dir_world(&self, dxf: f64, dyf: f64) -> V2 {
        let ym = self.sgn * dyf;
        V2::new(
            self.cos * dxf - self.sin * ym,
            self.sin * dxf + self.cos * ym,
        )
    }

    /// Body half-widths (medial, lateral) at x' (None outside [0, x_f]).
    pub fn body_half_widths(&self, xf: f64) -> Option<(f64, f64)> {
        if !(0.0..=self.body_front()).contains(&xf) {
            return None;
        }
        if xf <= self.hh {
            let w = (self.hh * self.hh - (self.hh - xf).powi(2)).max(0.0).sqrt();
            return Some((w, w));
        }
        Some((self.medial.eval(xf).0, self.lateral.eval(xf).0))
    }

    /// Inward distance to the body outline (exact in the heel disc, first order elsewhere);
    /// None outside the body.
    fn body_distance(&self, xf: f64, yf: f64) -> Option<f64> {
        if !(0.0..=self.body_front()).contains(&xf) {
            return None;
        }
        if xf <= self.hh {
            let d = self.hh - ((self.hh - xf).powi(2) + yf * yf).sqrt();
            return (d >= 0.0).then_some(d);
        }
        let (wm, dm) = self.medial.eval(xf);
        let (wl, dl) = self.lateral.eval(xf);
        if yf > wm || yf < -wl {
            return None;
        }
        let f = |gap: f64, slope: f64| {
            if slope.is_finite() {
                gap / (1.0 + slope * slope).sqrt()
            } else {
                0.0
            }
        };
        Some(f(wm - yf, dm).min(f(wl + yf, dl)))
    }

    /// Unloaded sole of the body (no pressing), None outside the body.
    fn body_unloaded(&self, xf: f64, yf: f64) -> Option<f64> {
        let d = self.body_distance(xf, yf)?;
        Some(rounding(d, self.p.edge_radius_mm) + self.arch(xf, yf))
    }

    /// Medial arch term of the unloaded sole.
    fn arch(&self, xf: f64, yf: f64) -> f64 {
        let (xc, hw) = (0.42 * self.l, 0.24 * self.l);
        let u = (xf - xc) / hw;
        if u.abs() >= 1.0 || xf <= self.hh {
            return 0.0;
        }
        let fx = (std::f64::consts::FRAC_PI_2 * u).cos().powi(2);
        let (wm, _) = self.medial.eval(xf);
        let (wl, _) = self.lateral.eval(xf);
        let y0 = -0.25 * wl;
        let y1 = (wm - self.p.edge_radius_mm - 2.0).max(y0 + 5.0);
        let t = ((yf - y0) / (y1 - y0)).clamp(0.0, 1.0);
        let fy = t * t * (3.0 - 2.0 * t);
        (self.p.arch_height_mm + self.p.press_mm) * fx * fy
    }

    /// Unloaded sole of toe pad i, None outside it.
    fn toe_unloaded(&self, i: usize, xf: f64, yf: f64) -> Option<f64> {
        let t = &self.toes[i];
        let rho2 = t.rho2(xf, yf);
        if rho2 > 1.0 {
            return None;
        }
        let (gx, gy) = (
            2.0 * (xf - t.xc) / (t.a * t.a),
            2.0 * (yf - t.yc) / (t.b * t.b),
        );
        let g = (gx * gx + gy * gy).sqrt();
        let d = if g > 0.0 {
            (1.0 - rho2) / g
        } else {
            f64::INFINITY
        };
        let r = self.p.edge_radius_mm.min(0.8 * t.b);
        let back = ((t.xc - xf) / t.a).max(0.0);
        Some(rounding(d, r) + self.toe_lift * back * back)
    }

    /// Index of the toe pad containing (x', y'), if any.
    pub fn toe_at(&self, xf: f64, yf: f64) -> Option<usize> {
        (0..5).find(|&i| self.toes[i].rho2(xf, yf) <= 1.0)
    }

    /// Pressed sole height at foot-frame (x', y'), None outside Omega.
    pub fn height_foot_frame(&self, xf: f64, yf: f64) -> Option<f64> {
        let u = if xf <= self.body_front() {
            self.body_unloaded(xf, yf)
        } else {
            None
        };
        let u = match u {
            Some(u) => u,
            None => (0..5).find_map(|i| self.toe_unloaded(i, xf, yf))?,
        };
        Some((u - self.p.press_mm).max(0.0))
    }

    /// Pressed sole height on the body only (toes excluded), None outside the body.
    pub fn body_height_foot_frame(&self, xf: f64, yf: f64) -> Option<f64> {
        self.body_unloaded(xf, yf)
            .map(|u| (u - self.p.press_mm).max(0.0))
    }

    /// Sole height at world (x, y), None outside the footprint (no laser return).
    pub fn height(&self, x: f64, y: f64) -> Option<f64> {
        let f = self.to_foot(x, y);
        self.height_foot_frame(f.x, f.y)
    }

    /// Height gradient (dh/dx, dh/dy) in world by central differences (1e-5 mm), None where
    /// either neighbour is outside the footprint.
    pub fn gradient(&self, x: f64, y: f64) -> Option<V2> {
        let e = 1e-5;
        Some(V2::new(
            (self.height(x + e, y)? - self.height(x - e, y)?) / (2.0 * e),
            (self.height(x, y + e)? - self.height(x, y - e)?) / (2.0 * e),
        ))
    }

    /// Dorsal (top of foot) height profile T(x') above the glass.
    pub fn dorsum_height(&self, xf: f64) -> f64 {
        self.dorsum.eval(xf.clamp(0.0, self.l)).0
    }

    /// Extent of Omega across the axis at x': (lowest y', highest y'), None if empty.
    pub fn extent_at(&self, xf: f64) -> Option<(f64, f64)> {
        let mut lo = f64::INFINITY;
        let mut hi = f64::NEG_INFINITY;
        if let Some((wm, wl)) = self.body_half_widths(xf) {
            lo = -wl;
            hi = wm;
        }
        for t in &self.toes {
            let u = (xf - t.xc) / t.a;
            if u.abs() <= 1.0 {
                let half = t.b * (1.0 - u * u).sqrt();
                lo = lo.min(t.yc - half);
                hi = hi.max(t.yc + half);
            }
        }
        (lo <= hi).then_some((lo, hi))
    }

    /// Closed cross-section perpendicular to the axis at x' (0 < x' < L), in the foot frame
    /// as (x', y', z): the sole from the height field (across gaps between toes linearly
    /// bridged) from the lateral to the medial edge, then up the medial side and over the
    /// dorsum as a superellipse of exponent 2.5 (vertical at both edges) reaching the dorsal
    /// height T(x') (about 0.18 L at the heel, 0.25 L at the instep, 0.1 L at the toes), back
    /// down to the lateral edge. Empty outside (0, L).
    pub fn section(&self, xf: f64) -> Vec<P3> {
        let Some((lo, hi)) = self.extent_at(xf) else {
            return Vec::new();
        };
        if hi - lo < 1e-6 {
            return Vec::new();
        }
        let n = ((hi - lo) / 0.5).ceil().max(2.0) as usize;
        let y_at = |i: usize| {
            if i == n {
                hi
            } else {
                lo + (hi - lo) * i as f64 / n as f64
            }
        };
        let mut sole: Vec<Option<f64>> = (0..=n)
            .map(|i| self.height_foot_frame(xf, y_at(i)))
            .collect();
        // The extreme points are on the outline. Where the evaluation there falls outside
        // by rounding, it is taken a hair inside: the outline height includes the arch's
        // lift, so a constant edge height would hang a zero-thickness fin from the medial
        // arch down to the glass (it did, up to 15.8 mm tall, wherever the rounding fell
        // outside).
        let edge_h = (self.p.edge_radius_mm - self.p.press_mm).max(0.0);
        for (i, inward) in [(0, 1.0), (n, -1.0)] {
            if sole[i].is_none() {
                sole[i] = [1e-9, 1e-6, 1e-3]
                    .iter()
                    .find_map(|e| self.height_foot_frame(xf, y_at(i) + inward * e))
                    .or(Some(edge_h));
            }
        }
        // Bridge gaps linearly.
        let mut i = 0;
        while i <= n {
            if sole[i].is_none() {
                let a = i - 1;
                let mut b = i;
                while sole[b].is_none() {
                    b += 1;
                }
                let (za, zb) = (sole[a].unwrap(), sole[b].unwrap());
                for (k, s) in sole.iter_mut().enumerate().take(b).skip(i) {
                    *s = Some(za + (zb - za) * (k - a) as f64 / (b - a) as f64);
                }
                i = b;
            }
            i += 1;
        }
        let mut pts: Vec<P3> = sole
            .iter()
            .enumerate()
            .map(|(i, z)| P3::new(xf, y_at(i), z.unwrap()))
            .collect();
        let (zl, zh) = (pts[0].z, pts[n].z);
        let top = self.dorsum_height(xf).max(zl.max(zh) + 1.0);
        let (yc, a) = ((lo + hi) / 2.0, (hi - lo) / 2.0);
        let m = 200;
        let e = 2.0 / 2.5;
        for k in 1..m {
            let phi = std::f64::consts::PI * k as f64 / m as f64;
            let (s, c) = phi.sin_cos();
            let y = yc + a * c.signum() * c.abs().powf(e);
            let base = if c >= 0.0 { zh } else { zl };
            pts.push(P3::new(xf, y, base + (top - base) * s.abs().powf(e)));
        }
        pts
    }

    /// Perimeter of [`Foot::section`] at x' (mm), 0 outside (0, L).
    pub fn girth(&self, xf: f64) -> f64 {
        let s = self.section(xf);
        if s.len() < 3 {
            return 0.0;
        }
        (0..s.len())
            .map(|i| {
                let (a, b) = (s[i], s[(i + 1) % s.len()]);
                ((a.y - b.y).powi(2) + (a.z - b.z).powi(2)).sqrt()
            })
            .sum()
    }

    /// World y range of the footprint (padded by 1 mm).
    pub fn world_y_bounds(&self) -> (f64, f64) {
        self.y_bounds
    }

    /// Upper bound of the sole height.
    pub fn max_sole_height(&self) -> f64 {
        self.p.edge_radius_mm + self.p.arch_height_mm + self.p.press_mm + self.toe_lift
    }
}

/// Quarter-circle edge rounding: R at the outline (vertical there), 0 from d = R inward.
#[inline]
pub(crate) fn rounding(d: f64, r: f64) -> f64 {
    if d >= r {
        0.0
    } else {
        let d = d.max(0.0);
        r - (r * r - (r - d) * (r - d)).max(0.0).sqrt()
    }
}

impl Surface for Foot {
    fn height(&self, x: f64, y: f64) -> Option<f64> {
        Foot::height(self, x, y)
    }
    fn max_height(&self) -> f64 {
        self.max_sole_height()
    }
    fn y_bounds(&self) -> (f64, f64) {
        self.world_y_bounds()
    }
}
