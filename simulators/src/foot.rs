//! The parametric foot (docs/method.md sections 8 and 13) and its analytic measurement truth.
//!
//! # Frames
//! Foot frame: x' along the foot axis (heel point at x' = 0, toe tip at x' = L), y' toward the
//! MEDIAL side. World placement: heel point at (`heel_x_mm`, `axis_y_mm`, 0), axis direction
//! u = (cos yaw, sin yaw) (yaw counterclockwise seen from above), medial direction
//! m = s (-sin yaw, cos yaw) with s = +1 for a right foot (medial is +y when the toes point to
//! +x) and s = -1 for a left foot. World = heel + x' u + y' m. A left foot with the opposite yaw
//! and axis offset is the exact mirror image (y -> -y) of the right foot.
//!
//! # Plan region (footprint outline) Omega = body + 5 toe pads
//! With L = length, H = heel_width_ratio L / 2, BW = ball_width_ratio L, M1 = 0.46 BW,
//! M5 = 0.54 BW:
//! - heel cap: the disc of radius H centred at the heel centre (H, 0), for x' <= H;
//! - sides, for H < x' <= x_f = 0.80 L: -w_l(x') <= y' <= w_m(x'), where the medial half-width
//!   w_m passes through the stations (H, H), (0.42 L, 0.92 H) (waist), (0.72 L, M1) (first
//!   metatarsal head) and the lateral w_l through (H, H), (0.35 L, 0.95 H) (waist),
//!   (0.64 L, M5) (fifth metatarsal head); between stations a monotone cubic Hermite with zero
//!   slope at each station (every station is an extremum, so each extreme is exactly there);
//!   beyond the metatarsal head station each side is the quarter ellipse
//!   w = W sqrt(1 - ((x' - x_W) / (x_f - x_W))^2), closing at (x_f, 0);
//! - toe pads: ellipses, hallux (semi-width 0.115 BW, medial edge at y' = 0.8 M1) and toes 2-5
//!   (semi-width 0.068 BW) side by side with 0.02 BW gaps; tips at x' = L, L - 0.015 L,
//!   L - 0.04 L, L - 0.07 L, L - 0.105 L; each pad's rear end is 0.012 L in front of the body
//!   (so pads and body are disjoint).
//!
//! The fractions above are the reference foot's; [`FootShape`] moves them within a population
//! ([`population`]): the head stations (0.72 L, 0.64 L), the waists' depths (0.92 H, 0.95 H),
//! the body front x_f (0.80 L; the toe tips' offsets from L scale with L - x_f), hallux
//! valgus (the pads shifted laterally by v (1 - 0.15 i) for pad i, M1 grown by 0.3 v) and
//! joined toes (each pad reaching 0.015 L into the body instead of stopping 0.012 L short).
//! The second metatarsal head stays on the axis, 0.01 L behind the first's station.
//!
//! # Sole heights
//! Unloaded sole u >= 0, pressed sole h = max(0, u - press_mm):
//! - edge rounding: R - sqrt(R^2 - (R - d)^2) for d < R (R = edge_radius_mm; vertical at the
//!   outline, where u = R and h = R - press), with d the inward distance to the outline: exact
//!   for the heel disc, first order for the sides ((w - |y'|) / sqrt(1 + w'^2)) and the toe
//!   ellipses (F / |grad F| for F = 1 - rho^2); toe pads use min(R, 0.8 semi-width);
//! - medial arch: (arch_height_mm + press_mm) fx(x') fy(x', y') with
//!   fx = cos^2(pi/2 (x' - 0.42 L) / 0.24 L) on |x' - 0.42 L| < 0.24 L (0 outside) and fy the
//!   smoothstep of t = (y' - y0) / (y1 - y0) clamped to [0, 1], y0 = -0.25 w_l(x'),
//!   y1 = w_m(x') - R - 2 mm: the arch peaks on a plateau next to the medial edge band;
//! - toe lift: each pad's rear half rises as 0.03 L ((xc - x') / a)^2 (toe sulcus).
//!
//! # Measurement definitions ([`FootTruth`], all in world coordinates)
//! - heel point: the rearmost outline point along the axis, (0, 0); toe tip: the most anterior,
//!   the hallux tip (L, y_hallux); foot length: their distance along the axis = L.
//! - axis: heel centre (H, 0) (centre of the heel disc, the middle of the maximum heel breadth)
//!   to the second metatarsal head, placed on the axis at (0.71 L, 0).
//! - first / fifth metatarsal heads: the most medial / most lateral body outline points,
//!   (0.72 L, M1) and (0.64 L, -M5); ball width = their distances from the axis summed, M1 + M5.
//! - waist inner / outer points: the medial / lateral outline points where the half-width from
//!   the axis is minimal between the heel and the metatarsal head, (0.42 L, 0.92 H) and
//!   (0.35 L, -0.95 H).
//! - mid-foot width: breadth of Omega perpendicular to the axis at x' = L / 2.
//! - heel width: maximum breadth perpendicular to the axis over x' in [0, L / 4] (= 2 H).
//! - hallux point: the most medial point of the hallux pad.
//! - arch height: maximum of h over the midfoot region x' in [x_f / 3, 2 x_f / 3], medial half
//!   y' >= 0, restricted to points at least R (edge_radius_mm) inside the outline. By
//!   construction it is attained on a plateau more than R + 2 mm inside the medial edge and
//!   equals `arch_height_mm`; computed numerically as a check.
//! - arch index (Cavanagh-Rodgers): contact = {h <= 1 mm} on the body (toes excluded); the
//!   interval [0, x_f] from the heel point to the front of the body is split along the axis
//!   into three equal lengths; index = contact area of the middle third / total contact area.
//!   Integrated line by line (lines x' = const every 0.1 mm, midpoint rule; contact intervals
//!   along each line located to 1e-9 mm): accuracy about 1e-4 in the index (checked against
//!   half the step in the tests).

pub mod mesh;
mod model;
mod population;
mod truth;

pub use mesh::{FootMesh, FootMeshTruth, MeshResolution};
pub use model::{Foot, FootParams, FootShape, Side, ToePad};
pub use population::{population, PopulationFoot, KINDS};
pub use truth::FootTruth;

#[cfg(test)]
mod tests;
