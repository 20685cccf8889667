//! footscan-last: what the last maker receives from the scanner.
//!
//! One job: the last-design stages, on meshes, curves and surfaces of `footscan-geom`. It
//! knows nothing of cameras, sliders, pipelines or HTTP; the `footscan` crate adapts scans to
//! its inputs (CLI commands and pipeline stages), so its tests compile no scanner code.
//!
//! - [`adjust`]: a last bottom adjusted to a scanned foot sole (outline, landmarks, heights),
//!   the whole last deformed to it, deviation before and after.
//! - [`blend`]: the same gap filled by slices that blend a linear morph with a discrete
//!   G1/G2 extension of both parts (or a blend chosen by fairing), measured the same way.
//! - [`choose`]: the shop's lasts ranked by how little each must change to fit a foot.
//! - [`draw`]: the pictures every stage writes (heat maps, zebra stripes, views with labels).
//! - [`grade`]: a last graded into a size run (Paris, UK, US, Mondopoint), steps tabled.
//! - [`join`]: the toe part of one last joined to the back part of another by a Gordon
//!   surface through a curve network, with seam figures, IGES/STEP/STL and pictures.
//! - [`measure_last`]: a last measured as shoemakers do (landmarks, bottom, widths, girths).
//! - [`size`]: the size check every last command makes before it works on a last.

pub mod adjust;
pub mod blend;
pub mod choose;
pub mod collection;
pub mod customize;
pub mod draw;
pub mod grade;
pub mod join;
pub mod measure_last;
pub mod outdir;
mod par;
pub mod size;

/// The cubic ramp 3 s^2 - 2 s^3 from 0 at s <= 0 to 1 at s >= 1, level at both ends: the
/// smooth transition the stages' fields and weights share.
pub(crate) fn smoothstep(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    s * s * (3.0 - 2.0 * s)
}

pub use customize::bottom::smoothed_lowest;
