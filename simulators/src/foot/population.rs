//! A population of parametric feet of the kinds a clinic scans, each with its exact truth: the
//! measurement stage is judged on all of them, not on the one reference foot.

use super::model::{FootParams, FootShape, Side};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// One foot of [`population`]: its kind (what makes it differ) and its parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct PopulationFoot {
    pub kind: &'static str,
    pub params: FootParams,
}

/// The kinds, in the order [`population`] cycles through them.
pub const KINDS: [&str; 10] = [
    "plain",
    "flat arch, weight-bearing",
    "high arch",
    "hallux valgus",
    "wide forefoot",
    "narrow forefoot",
    "short toes",
    "long toes",
    "relaxed",
    "toes joined",
];

/// `n` feet cycling through [`KINDS`], every other parameter drawn uniformly from its
/// plausible range (length 220-300 mm, either side, yaw within +-12 degrees): the same `seed`
/// gives the same feet.
pub fn population(n: usize, seed: u64) -> Vec<PopulationFoot> {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    (0..n)
        .map(|i| {
            let kind = KINDS[i % KINDS.len()];
            let mut u = |a: f64, b: f64| a + (b - a) * rng.gen::<f64>();
            let mut shape = FootShape {
                mt1_x_ratio: u(0.69, 0.75),
                mt5_x_ratio: u(0.61, 0.67),
                medial_waist_ratio: u(0.85, 0.95),
                lateral_waist_ratio: u(0.90, 0.97),
                ..FootShape::default()
            };
            let mut p = FootParams {
                length_mm: u(220.0, 300.0),
                ball_width_ratio: u(0.38, 0.42),
                heel_width_ratio: u(0.23, 0.27),
                arch_height_mm: u(12.0, 18.0),
                side: if u(0.0, 1.0) < 0.5 {
                    Side::Right
                } else {
                    Side::Left
                },
                heel_x_mm: 110.0,
                axis_y_mm: u(-8.0, 8.0),
                yaw_deg: u(-12.0, 12.0),
                press_mm: u(2.0, 3.5),
                edge_radius_mm: u(4.5, 6.0),
                shape: FootShape::default(),
            };
            match kind {
                "flat arch, weight-bearing" => {
                    shape.medial_waist_ratio = u(0.95, 0.98);
                    shape.lateral_waist_ratio = u(0.97, 0.99);
                    shape.toes_joined = true;
                    p.arch_height_mm = u(8.0, 10.0);
                    p.press_mm = u(3.0, 4.0);
                }
                "high arch" => {
                    shape.medial_waist_ratio = u(0.70, 0.80);
                    shape.lateral_waist_ratio = u(0.80, 0.88);
                    p.arch_height_mm = u(20.0, 25.0);
                }
                "hallux valgus" => shape.hallux_valgus_mm = u(4.0, 10.0),
                "wide forefoot" => {
                    p.ball_width_ratio = u(0.42, 0.44);
                    p.heel_width_ratio = u(0.22, 0.24);
                }
                "narrow forefoot" => {
                    p.ball_width_ratio = u(0.36, 0.37);
                    p.heel_width_ratio = u(0.26, 0.28);
                }
                "short toes" => {
                    shape.body_front_ratio = u(0.82, 0.84);
                    shape.mt1_x_ratio = u(0.72, 0.76);
                    shape.mt5_x_ratio = u(0.64, 0.69);
                }
                "long toes" => {
                    shape.body_front_ratio = u(0.76, 0.78);
                    shape.mt1_x_ratio = u(0.66, 0.70);
                    shape.mt5_x_ratio = u(0.58, 0.62);
                }
                "relaxed" => {
                    p.edge_radius_mm = u(6.0, 9.0);
                    p.press_mm = u(0.0, 0.5);
                    p.arch_height_mm = u(15.0, 22.0);
                }
                "toes joined" => shape.toes_joined = true,
                _ => {}
            }
            // The heads keep 0.05 L clear of the body front.
            let room = shape.body_front_ratio - 0.05;
            shape.mt1_x_ratio = shape.mt1_x_ratio.min(room);
            shape.mt5_x_ratio = shape.mt5_x_ratio.min(room);
            p.shape = shape;
            PopulationFoot { kind, params: p }
        })
        .collect()
}
