//! footscan-last: what the last maker receives from the scanner.
//!
//! One job: the last-design stages, on meshes, curves and surfaces of `footscan-geom`. It
//! knows nothing of cameras, sliders, pipelines or HTTP; the `footscan` crate adapts scans to
//! its inputs (CLI commands and pipeline stages), so its tests compile no scanner code.
//!
//! - [`draw`]: the pictures every stage writes (heat maps, zebra stripes, views with labels).

pub mod draw;
