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
//! - [`draw`]: the pictures every stage writes (heat maps, zebra stripes, views with labels).
//! - [`join`]: the toe part of one last joined to the back part of another by a Gordon
//!   surface through a curve network, with seam figures, IGES/STEP/STL and pictures.

pub mod adjust;
pub mod blend;
pub mod customize;
pub mod draw;
pub mod join;
