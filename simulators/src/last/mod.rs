//! Parametric shoe lasts: closed, outward-oriented triangle meshes with the analytic truth of
//! their bottom.
//!
//! # Frame
//! Last frame: x from the heel point (x = 0) to the toe tip (x = L, the bottom length measured
//! along x), y across toward the MEDIAL side for a right last, z up, the bottom resting on
//! the glass at the ball (its lowest point, z = 0). A left last is the mirror image (y -> -y).
//! The world placement is a [`crate::mesh_scene::Placement`] about the heel point.
//!
//! # Bottom (what the scanner sees)
//! With BW = `ball_width_ratio` L, heel half-width H = 0.325 BW, M1 = 0.46 BW, M5 = 0.54 BW:
//! - outline: the heel is the disc of radius H about (H, 0) for x <= H; behind the ball each
//!   side runs through stations with zero slope (so each is that side's extreme): medial
//!   (H, H), waist (0.42 L, 0.80 H), first metatarsal head MT1 (0.72 L, M1); lateral
//!   (H, -H), waist (0.35 L, -0.95 H), fifth metatarsal head MT5 (0.64 L, -M5), a cubic
//!   Hermite between stations; in front of the metatarsal station each side closes on the
//!   toe tip (L, y_t) as `y_t + (W - y_t) s(t)`, t the fraction of the way to the tip and s
//!   the toe shape: round `sqrt(1 - t^2)`, square `(1 - t^5)^(1/5)`, pointed `1 - t^1.6`
//!   (meeting at an angle). y_t = 0.10 BW (round), 0.08 BW (square), 0.05 BW (pointed).
//! - height: `b(x) + E q^2` with q = -1..1 across the outline from the lateral to the medial
//!   edge and E = 1.5 mm (a slightly convex bottom: the feather edge stands 1.5 mm above the
//!   middle). The profile b is 0 at the ball x_b = 0.68 L (the lowest point of the last),
//!   rises as the cubic smoothstep to the heel height over the shank to the heel seat at
//!   0.25 L and stays there behind it; in front of the ball the toe spring
//!   `S ((x - x_b) / (L - x_b))^2` with S = max(5, 14 - 0.1 heel) mm.
//!
//! # Upper
//! The sides rise from the feather edge (a crease) and lean inward (at height fraction v
//! the half-width is `(1 - 0.3 v^2)` of the bottom's) to the top: flat (the top cut) at
//! `heel + 0.40 L` from the heel to 0.40 L, then falling toward the toe to `b + 0.07 L` at the
//! tip with a crown across. The upper is plausible rather than measured: from below only the
//! bottom is seen, and it hides everything above it.
//!
//! # Mesh
//! Stations along x (cosine-spaced toward both ends, with every landmark and the ball as a
//! station); at each station the bottom and the top are sampled across at 2J + 1 points and
//! each side at K + 1 heights; the heel point and toe tip close the caps and sides as fans.
//! The bottom's outline ([`LastTruth::outline`]) is exactly the mesh's feather-edge ring, and
//! every landmark is a vertex of it.

mod build;

pub use build::{Last, LastParams, LastTruth, Toe};

#[cfg(test)]
mod tests;
