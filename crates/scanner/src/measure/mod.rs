//! Foot landmarks and measurements (docs/method.md section 8) from a plantar height map.
//!
//! Input: a [`HeightMap`](crate::geom::HeightMap) (heights in mm on regular cells, NaN outside the footprint). For a
//! scan ([`measure_grid`], the `measure.foot` stage, `footscan measure`) the footprint comes
//! from the scan grid ([`rasterize_grid`], 0.1 mm cells) and the heights from the Bezier model
//! where it has them ([`scan_heightmap`]). Output:
//! [`Measurements`], written as `measurements.json`, and a labelled PNG
//! ([`render_plantar`]). Everything is computed from the height map alone; the
//! simulator's truth only enters through [`compare_with_truth`] for tests and reports.
//!
//! # Operational definitions
//! Footprint: the 4-connected regions of valid cells; the largest is the body (the toe-less
//! sole), regions of at least 0.5 % of its area in front of its centroid are toe pads (the
//! scanner sees no sole between the toes and the ball, so they come apart); smaller specks
//! are ignored. Outlines: marching squares halfway between inside and outside cell centres.
//! Extreme points are located between outline vertices by a two-sided parabola fit over the
//! outline near the extreme (a common vertex with a different curvature on each side).
//!
//! - Axis: from the heel centre to the second metatarsal head. The height map shows no bones,
//!   so the second metatarsal head is found by the rule that the second metatarsal is the
//!   longest: its head directs the most anterior part of the toe-less forefoot. The axis
//!   direction is iterated to the fixed point where the line from the heel centre meets the
//!   body outline at its most anterior point along that line (the body front). The head
//!   itself is placed on the axis level with the first metatarsal head (the heads of the
//!   first two metatarsals lie at about the same distance from the heel).
//! - Heel centre: centre of the circle fitted to the heel outline from the rearmost point up
//!   to the level of the circle's centre (iterated), i.e. the middle of the widest heel
//!   breadth for a round heel. Heel point: rearmost outline point along the axis; toe tip:
//!   most anterior point of the footprint (toes included); foot length: their distance
//!   along the axis.
//! - Medial side: the side of the axis holding the largest toe pad (the hallux); without toe
//!   pads, the side with the higher midfoot (the medial arch). A right foot has its medial
//!   side to the left of the heel-to-toe axis seen from above.
//! - First / fifth metatarsal heads: the most prominent bulges (at least 0.5 mm) of the medial
//!   / lateral side profile (half-widths from the axis along it, smoothed over 2 mm) in the
//!   forefoot, ties within 2 mm going to the one nearest where feet have the head; a side with
//!   no bulge takes its extreme with a warning. Ball width: the sum of their distances from
//!   the axis. With toes joined to the ball (no toe pad apart) the axis runs from the heel
//!   centre to the second head's place on the ball line (0.46 of the way from the first head
//!   to the fifth) instead of the body front, which is then a toe.
//! - Waist inner / outer: the deepest hollows of the side profiles in the midfoot (from 0.2 L
//!   to 0.1 L behind the head of that side).
//! - Mid-foot width: breadth of the footprint perpendicular to the axis at half the length.
//!   Heel width: maximum breadth perpendicular to the axis over the rear quarter, on side
//!   profiles smoothed over 2 mm (outline quantisation would otherwise bias a maximum up); the
//!   breadth through the heel centre where the foot still widens at the quarter.
//! - Plausibility (docs/method.md 8.2.1): heads outside 60-80 % of the length, a forefoot
//!   wider than the ball, waists not behind the heads, widths out of order or out of
//!   proportion, an arch on the glass: each a warning, never a silent figure.
//! - Hallux point: most medial outline point of the hallux pad.
//! - Arch height: highest point of the medial arch vault that still faces the glass: the
//!   maximum sole height, over the medial half of the middle third of the body, among
//!   points where the sole (a plane fitted over 1 mm) slopes less than 0.1 (6 degrees).
//!   Toward the medial border the sole turns up into the side wall of the foot; that wall
//!   is not arch. (The scan cannot see the edge rounding radius the simulator's definition
//!   uses; this rule needs none.) Where no point there slopes under 0.1 (a foot bearing no
//!   weight, e.g. the FIND meshes), the limits 0.2 to 0.5 are tried in turn, with a warning.
//! - Arch index (Cavanagh-Rodgers): contact = cells with h <= 1 mm on the body (toes
//!   excluded); the body from the heel point to its most anterior point along the axis is
//!   cut in three equal lengths; index = middle third's contact area over the total.
//!
//! # Accuracy (against the simulator's analytic foot)
//! On height maps sampled from the analytic foot at 0.1 mm (tests/measure_analytic.rs, six
//! feet): landmarks within 0.3 mm, lengths and widths within 0.06 mm, axis within 0.07 deg,
//! arch index within 1e-4. On simulated scans (tests/measure_scan.rs) widths come out 0.1 to
//! 0.35 mm short: the camera cannot see the rounded sole edge beyond its silhouette (the
//! last 0.05 to 0.25 mm before the edge turns vertical, more for larger edge radii), and no
//! rule recovers that from a plantar scan without a model of the edge; a circle fitted to
//! the visible part of the edge was tried and was too noisy. The second metatarsal head is
//! placed along the axis by convention (level with the first), 1.7 to 2.5 mm from where the
//! simulator puts it (0.71 L against 0.72 L); its distance from the true axis is what the
//! axis depends on and is under 0.2 mm on the analytic maps, 0.5 mm on the scans. Cells coarser than 0.1 mm cost accuracy quickly on
//! flat stretches of the outline (at 0.2 mm the fifth metatarsal head moves by up to 1 mm).

mod fit;
mod foot;
mod outline;
mod picture;
mod profile;
mod rasterize;
mod scanned;
mod truth;

pub use foot::{measure_foot, measure_foot_with, Measurements, Planar, Side};
pub use outline::{line_crossings, regions, signed_area, simplify, Region};
pub use picture::{render_plantar, PlantarImage};
pub use rasterize::{grid_truncation, rasterize_grid};
pub use scanned::{
    footprint_ahead, measure_grid, measure_grid_with, measure_scan_dir, scan_heightmap,
    write_measurements, Ahead, Footprint, MeasureOutput, DEFAULT_CELL_MM,
};
pub use truth::{compare_with_truth, ErrorKind, ErrorRow, TruthComparison};

/// Why a height map could not be measured.
#[derive(Debug, thiserror::Error)]
pub enum MeasureError {
    #[error("the height map has no valid cells: no footprint to measure")]
    NoFootprint,
    #[error(
        "the largest footprint region is {area_mm2:.0} mm^2; a foot needs at least {min_mm2:.0} mm^2 \
         (is the foot on the glass and inside the scanned range?)"
    )]
    TooSmall { area_mm2: f64, min_mm2: f64 },
    #[error("cannot locate the {what}: {why}")]
    Landmark { what: &'static str, why: String },
    #[error("scan grid: {0}")]
    Grid(String),
    #[error("plantar model of {0}")]
    Model(String),
    #[error("{}", path.display())]
    Io {
        path: std::path::PathBuf,
        source: std::io::Error,
    },
}
