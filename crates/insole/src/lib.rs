//! footscan-insole: an orthotic insole from a plantar scan (issue 38).
//!
//! The insole is a solid over its outline (the footprint plus a margin, or the shoe's
//! bottom; full length or 3/4), its bottom on the shoe's floor (z = 0, or bent onto the
//! shoe's heel and toe spring, [`design::Spring`]) and its top the surface the foot stands on:
//! the scanned plantar surface where the foot bears weight (total contact), raised by the
//! base thickness and changed by the clinician's corrections ([`Params`]): heel cup, arch
//! support, rearfoot and forefoot posts, metatarsal pad, first ray cut-out, heel lift. The
//! mesh is the shell, its top the top cover's thickness below that surface.
//!
//! Frame of every output: the foot frame of the scanner's CAD model (`footscan::cad`): origin
//! at the heel point, x along the foot axis toward the toes, y to the left seen from above
//! (medial for a right foot), z up from the insole's bottom; millimetres.
//!
//! Steps ([`design`]): the foot's heights in the foot frame, filled beyond the footprint from
//! its edge; a foot scanned without weight (midfoot off the glass) laid flat by the curve
//! under its arch, as the last stage lays it ([`Design::bottom_rise_mm`]); the corrections as
//! smooth fields; the solid by `footscan::surface::solid::outline_solid` (closed by
//! construction); then every parameter measured back on the mesh by ray casts
//! ([`measure::measure_back`]) and the files written all or nothing ([`write::write_insole`]).

pub mod design;
pub mod measure;
pub mod params;
pub mod picture;
pub mod threemf;
pub mod write;

pub use design::{design, design_in, Design, Plantar, ShoeBottom};
pub use measure::{measure_back, Check, Measured};
pub use params::{Length, Params, PostSide, PRESETS};
pub use write::{write_insole, write_insole_in, Report, Written};

use std::path::PathBuf;

/// Why an insole could not be made. Nothing is written when one is returned.
#[derive(Debug, thiserror::Error)]
pub enum InsoleError {
    #[error("{name} = {value}: must lie between {lo} and {hi}: {why}")]
    Param {
        name: &'static str,
        value: f64,
        lo: f64,
        hi: f64,
        why: String,
    },
    #[error("preset {name:?}: the presets are {}", params::PRESETS.join(", "))]
    Preset { name: String },
    #[error("the insole's parameters: {why}")]
    ParamsJson { why: String },
    #[error("{}: not a valid parameter file: {why}", path.display())]
    ParamsFile { path: PathBuf, why: String },
    #[error("reading {}", path.display())]
    Read {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{what}: {why}")]
    Foot { what: String, why: String },
    #[error("building the insole's solid: {0}")]
    Solid(String),
    #[error("writing {}: {why}", path.display())]
    Write { path: PathBuf, why: String },
}
