//! Parameters, shape functions and mesh of the parametric last (see [`crate::last`]).

use crate::foot::Side;
use crate::mesh_scene::{place_at, MeshSurface, Placement};
use crate::optics::{check_range, SimError};
use footscan_geom::mesh::TriMesh;
use footscan_geom::{P2, P3};
use serde::{Deserialize, Serialize};

/// Toe shape of the bottom outline.
#[derive(Clone, Copy, Debug, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum Toe {
    Round,
    Pointed,
    Square,
}

impl Toe {
    pub const ALL: [Toe; 3] = [Toe::Round, Toe::Pointed, Toe::Square];

    /// Fraction of the metatarsal half-width left at t of the way to the toe tip.
    fn shape(self, t: f64) -> f64 {
        let t = t.clamp(0.0, 1.0);
        match self {
            Toe::Round => (1.0 - t * t).max(0.0).sqrt(),
            Toe::Square => (1.0 - t.powi(5)).max(0.0).powf(0.2),
            Toe::Pointed => 1.0 - t.powf(1.6),
        }
    }

    /// Toe tip offset toward the medial side, per ball width.
    fn tip_offset(self) -> f64 {
        match self {
            Toe::Round => 0.10,
            Toe::Square => 0.08,
            Toe::Pointed => 0.05,
        }
    }
}

/// A toe shape name that is not one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown toe {0:?}; valid: round, pointed, square")]
pub struct UnknownToe(pub String);

impl std::str::FromStr for Toe {
    type Err = UnknownToe;
    fn from_str(s: &str) -> Result<Toe, UnknownToe> {
        match s {
            "round" => Ok(Toe::Round),
            "pointed" => Ok(Toe::Pointed),
            "square" => Ok(Toe::Square),
            _ => Err(UnknownToe(s.to_string())),
        }
    }
}

/// Shape, size and placement of a parametric last (`[sim.last]` in a scan config).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct LastParams {
    pub toe: Toe,
    /// Heel height: how far the heel seat stands above the glass (mm): [0, 100].
    pub heel_mm: f64,
    /// Bottom length, heel point to toe tip along x (mm): [150, 350].
    pub length_mm: f64,
    /// Shoe size in Paris points (2/3 cm each): when given, the bottom length is
    /// `size_paris * 20 / 3` mm and `length_mm` is ignored.
    pub size_paris: Option<f64>,
    /// Ball width (MT1 to MT5 across the axis) per bottom length: [0.30, 0.44].
    pub ball_width_ratio: f64,
    pub side: Side,
    pub placement: Placement,
}

impl Default for LastParams {
    fn default() -> Self {
        LastParams {
            toe: Toe::Round,
            heel_mm: 25.0,
            length_mm: 260.0,
            size_paris: None,
            ball_width_ratio: 0.36,
            side: Side::Right,
            placement: Placement::default(),
        }
    }
}

impl LastParams {
    /// The bottom length in effect (mm).
    pub fn length(&self) -> f64 {
        match self.size_paris {
            Some(s) => s * 20.0 / 3.0,
            None => self.length_mm,
        }
    }

    pub fn validate(&self) -> Result<(), SimError> {
        check_range("heel_mm", self.heel_mm, 0.0, 100.0)?;
        if let Some(s) = self.size_paris {
            check_range("size_paris", s, 22.5, 52.5)?;
        }
        check_range("length_mm (bottom length)", self.length(), 150.0, 350.0)?;
        check_range("ball_width_ratio", self.ball_width_ratio, 0.30, 0.44)?;
        self.placement.validate()
    }
}

/// Analytic truth of a last's bottom, in world coordinates (mm).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LastTruth {
    /// Heel point to toe tip along the last's axis (its x before placement).
    pub bottom_length_mm: f64,
    /// MT1 and MT5 distances from the axis, summed.
    pub ball_width_mm: f64,
    pub heel_mm: f64,
    /// Rearmost bottom point.
    pub heel_point: P3,
    /// Foremost bottom point.
    pub toe_tip: P3,
    /// Most medial bottom outline point (first metatarsal head).
    pub mt1: P3,
    /// Most lateral bottom outline point (fifth metatarsal head).
    pub mt5: P3,
    /// Narrowest points of the waist, medial and lateral.
    pub waist_medial: P3,
    pub waist_lateral: P3,
    /// A lowest point, under the ball (on the glass, or at the placement's lift); a flat last
    /// (heel 0) rests on its whole middle line from heel to ball.
    pub ball_contact: P3,
    /// The bottom outline (feather edge) as the mesh has it: heel point, the lateral side to
    /// the toe tip, the medial side back (a closed polygon, last point not repeated).
    pub outline: Vec<P3>,
}

/// A parametric last: its mesh in the last frame and placed in the world, with the truth.
#[derive(Clone, Debug)]
pub struct Last {
    params: LastParams,
    local: TriMesh,
    world: TriMesh,
    truth: LastTruth,
}

/// Stations from the cosine spacing (besides the landmarks).
const BASE_STATIONS: usize = 140;
/// Points across the bottom and top are 2 J + 1.
const HALF_ACROSS: usize = 8;
/// Rows up each side.
const WALL_ROWS: usize = 14;
/// Height of the feather edge above the bottom's middle (mm).
const EDGE_RISE_MM: f64 = 1.5;

/// The analytic shape in the last frame of a right last.
struct Shape {
    l: f64,
    toe: Toe,
    heel: f64,
    h: f64,
    m1: f64,
    m5: f64,
    tip_y: f64,
}

/// Landmark and profile stations as fractions of L.
const X_WAIST_LAT: f64 = 0.35;
const X_WAIST_MED: f64 = 0.42;
const X_MT5: f64 = 0.64;
const X_BALL: f64 = 0.68;
const X_MT1: f64 = 0.72;
const X_SEAT: f64 = 0.25;
const X_CUT: f64 = 0.40;

fn smoothstep(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

impl Shape {
    fn new(p: &LastParams) -> Shape {
        let l = p.length();
        let bw = p.ball_width_ratio * l;
        Shape {
            l,
            toe: p.toe,
            heel: p.heel_mm,
            h: 0.325 * bw,
            m1: 0.46 * bw,
            m5: 0.54 * bw,
            tip_y: p.toe.tip_offset() * bw,
        }
    }

    /// Half-width of the heel disc, or a Hermite between two stations.
    fn side(&self, x: f64, waist_x: f64, waist_w: f64, mt_x: f64, mt_w: f64) -> f64 {
        let (h, l) = (self.h, self.l);
        if x <= h {
            let d = h - x;
            (h * h - d * d).max(0.0).sqrt()
        } else if x <= waist_x * l {
            h + (waist_w - h) * smoothstep((x - h) / (waist_x * l - h))
        } else {
            waist_w + (mt_w - waist_w) * smoothstep((x - waist_x * l) / ((mt_x - waist_x) * l))
        }
    }

    /// Medial outline y at x.
    fn y_medial(&self, x: f64) -> f64 {
        let xm = X_MT1 * self.l;
        if x >= self.l {
            self.tip_y
        } else if x > xm {
            let t = (x - xm) / (self.l - xm);
            self.tip_y + (self.m1 - self.tip_y) * self.toe.shape(t)
        } else {
            self.side(x, X_WAIST_MED, 0.80 * self.h, X_MT1, self.m1)
        }
    }

    /// Lateral outline y at x (negative).
    fn y_lateral(&self, x: f64) -> f64 {
        let xm = X_MT5 * self.l;
        if x >= self.l {
            self.tip_y
        } else if x > xm {
            let t = (x - xm) / (self.l - xm);
            self.tip_y - (self.m5 + self.tip_y) * self.toe.shape(t)
        } else {
            -self.side(x, X_WAIST_LAT, 0.95 * self.h, X_MT5, self.m5)
        }
    }

    /// Bottom profile along the middle.
    fn b(&self, x: f64) -> f64 {
        let (xs, xb) = (X_SEAT * self.l, X_BALL * self.l);
        if x <= xs {
            self.heel
        } else if x < xb {
            self.heel * smoothstep((xb - x) / (xb - xs))
        } else {
            let spring = (14.0 - 0.1 * self.heel).max(5.0);
            spring * ((x - xb) / (self.l - xb)).powi(2)
        }
    }

    /// Fraction of the top's height drop toward the toe still to come (1 behind the cut's
    /// end, 0 at the tip).
    fn g(&self, x: f64) -> f64 {
        let xc = X_CUT * self.l;
        if x <= xc {
            1.0
        } else {
            let t = ((x - xc) / (self.l - xc)).min(1.0);
            (1.0 - t.powf(1.5)).powi(2)
        }
    }

    /// Height of the top at its edge.
    fn z_top(&self, x: f64) -> f64 {
        let cut = self.heel + 0.40 * self.l;
        let low = self.b(x) + 0.07 * self.l;
        low + (cut - low) * self.g(x)
    }

    /// Rise of the top's middle above its edge.
    fn crown(&self, x: f64) -> f64 {
        0.025 * self.l * (1.0 - self.g(x))
    }

    /// Stations along x: cosine-spaced, plus every landmark, profile break and the ball.
    fn stations(&self) -> Vec<f64> {
        let l = self.l;
        let marks: Vec<f64> = [
            self.h,
            X_SEAT * l,
            X_WAIST_LAT * l,
            X_CUT * l,
            X_WAIST_MED * l,
            X_MT5 * l,
            X_BALL * l,
            X_MT1 * l,
        ]
        .to_vec();
        let mut xs: Vec<f64> = (0..=BASE_STATIONS)
            .map(|i| {
                0.5 * l * (1.0 - (std::f64::consts::PI * i as f64 / BASE_STATIONS as f64).cos())
            })
            .filter(|x| marks.iter().all(|m| (x - m).abs() > 1.0))
            .collect();
        xs[0] = 0.0;
        *xs.last_mut().unwrap() = l;
        xs.extend_from_slice(&marks);
        xs.sort_by(f64::total_cmp);
        xs
    }
}

impl Last {
    pub fn new(params: LastParams) -> Result<Last, SimError> {
        params.validate()?;
        let s = Shape::new(&params);
        let xs = s.stations();
        let n = xs.len() - 1;
        let (jn, kn) = (2 * HALF_ACROSS, WALL_ROWS);
        let ring = 2 * n;
        // Ring position r of station i on the lateral (r = i) and medial (r = 2n - i) side.
        let ring_x = |r: usize| if r <= n { xs[r] } else { xs[ring - r] };
        let mut v: Vec<P3> = Vec::with_capacity(ring * (kn + 1) + 2 * (n - 1) * (jn - 1));
        // Sides: ring r, height row k at index r (K + 1) + k.
        for r in 0..ring {
            let x = ring_x(r);
            let (yl, ym) = (s.y_lateral(x), s.y_medial(x));
            let c = 0.5 * (yl + ym);
            let y_edge = if r <= n { yl } else { ym };
            let z0 = s.b(x) + EDGE_RISE_MM;
            let z1 = s.z_top(x);
            for k in 0..=kn {
                let t = k as f64 / kn as f64;
                let y = c + (y_edge - c) * (1.0 - 0.3 * t * t);
                v.push(P3::new(x, y, z0 + (z1 - z0) * t));
            }
        }
        let wall = |r: usize, k: usize| (r * (kn + 1) + k) as u32;
        // Cap interiors: stations 1..n-1, across j = 1..2J-1; bottom then top.
        let mut cap_base = [0u32; 2];
        for (side, base) in cap_base.iter_mut().enumerate() {
            *base = v.len() as u32;
            for &x in &xs[1..n] {
                let (yl, ym) = (s.y_lateral(x), s.y_medial(x));
                let (c, w) = (0.5 * (yl + ym), 0.5 * (ym - yl));
                for j in 1..jn {
                    let q = 2.0 * j as f64 / jn as f64 - 1.0;
                    v.push(if side == 0 {
                        P3::new(x, c + q * w, s.b(x) + EDGE_RISE_MM * q * q)
                    } else {
                        P3::new(x, c + q * w * 0.7, s.z_top(x) + s.crown(x) * (1.0 - q * q))
                    });
                }
            }
        }
        // Cap point (station i, across j) of the bottom (k = 0) or top (k = K).
        let cap = |i: usize, j: usize, top: bool| -> u32 {
            let k = if top { kn } else { 0 };
            if i == 0 || i == n || j == 0 {
                wall(i, k)
            } else if j == jn {
                wall(ring - i, k)
            } else {
                cap_base[top as usize] + ((i - 1) * (jn - 1) + (j - 1)) as u32
            }
        };
        let mut t: Vec<[u32; 3]> = Vec::new();
        // Sides (outward: the ring runs counterclockwise seen from above).
        for r in 0..ring {
            let r1 = (r + 1) % ring;
            for k in 0..kn {
                let (a, b, c, d) = (wall(r, k), wall(r1, k), wall(r1, k + 1), wall(r, k + 1));
                t.push([a, b, c]);
                t.push([a, c, d]);
            }
        }
        // Bottom (facing down) and top (facing up).
        for top in [false, true] {
            let mut quad = |a: u32, b: u32, c: u32, d: u32| {
                // a (i, j), b (i + 1, j), c (i + 1, j + 1), d (i, j + 1)
                if top {
                    t.push([a, b, c]);
                    t.push([a, c, d]);
                } else {
                    t.push([a, c, b]);
                    t.push([a, d, c]);
                }
            };
            for i in 1..n - 1 {
                for j in 0..jn {
                    quad(
                        cap(i, j, top),
                        cap(i + 1, j, top),
                        cap(i + 1, j + 1, top),
                        cap(i, j + 1, top),
                    );
                }
            }
            for j in 0..jn {
                let (heel, b, c) = (cap(0, 0, top), cap(1, j, top), cap(1, j + 1, top));
                let (p, q, tip) = (cap(n - 1, j, top), cap(n - 1, j + 1, top), cap(n, 0, top));
                if top {
                    t.push([heel, b, c]);
                    t.push([p, tip, q]);
                } else {
                    t.push([heel, c, b]);
                    t.push([p, q, tip]);
                }
            }
        }
        let mut local = TriMesh::new(v, t);
        if params.side == Side::Left {
            for p in &mut local.vertices {
                p.y = -p.y;
            }
            local.flip();
        }
        let mirror = if params.side == Side::Left { -1.0 } else { 1.0 };
        let world = place_at(&local, &params.placement, P2::origin());
        let tf = params.placement.transform(P2::origin(), 0.0);
        let at = |x: f64, y: f64, z: f64| tf.apply(P3::new(x, mirror * y, z));
        let l = s.l;
        // Landmarks are feather-edge vertices: station i on the lateral (ring i) or medial
        // (ring 2n - i) side.
        let station = |f: f64| {
            xs.iter()
                .position(|&x| x == f * l)
                .expect("landmark station")
        };
        let vertex = |r: usize| tf.apply(local.vertices[wall(r, 0) as usize]);
        let medial = |f: f64| vertex(ring - station(f));
        let lateral = |f: f64| vertex(station(f));
        let outline = (0..ring).map(vertex).collect();
        let x_ball = X_BALL * l;
        let truth = LastTruth {
            bottom_length_mm: l,
            ball_width_mm: s.m1 + s.m5,
            heel_mm: params.heel_mm,
            heel_point: vertex(0),
            toe_tip: vertex(n),
            mt1: medial(X_MT1),
            mt5: lateral(X_MT5),
            waist_medial: medial(X_WAIST_MED),
            waist_lateral: lateral(X_WAIST_LAT),
            ball_contact: at(
                x_ball,
                0.5 * (s.y_lateral(x_ball) + s.y_medial(x_ball)),
                0.0,
            ),
            outline,
        };
        Ok(Last {
            params,
            local,
            world,
            truth,
        })
    }

    pub fn params(&self) -> &LastParams {
        &self.params
    }

    /// The mesh in the last frame (heel point at the origin, bottom on z = 0 at the ball).
    pub fn local_mesh(&self) -> &TriMesh {
        &self.local
    }

    /// The mesh placed in the world.
    pub fn mesh(&self) -> &TriMesh {
        &self.world
    }

    /// The bottom's truth, in world coordinates.
    pub fn truth(&self) -> &LastTruth {
        &self.truth
    }

    /// The placed last as a renderer surface.
    pub fn surface(&self) -> Result<MeshSurface, SimError> {
        MeshSurface::new(&self.world)
    }
}
