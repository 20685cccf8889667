//! footscan: a laser-line foot scanner and last-design toolkit.
//!
//! The library (package `footscan-scanner`, imported as `footscan`) holds the scanner's logic;
//! the CLI `footscan` (the workspace's root package) and the daemon (crate `footscand`) are thin
//! shells over it. Hardware is reached only through `footscan-hal`, so the simulator
//! (`footscan-sim`) is one more backend behind the same traits.

pub mod cad;
pub mod calib;
pub mod compact;
pub mod detect;
pub mod geom;
pub mod io;
pub mod lastcustom;
pub mod lastfit;
pub mod measure;
pub mod report;
pub mod scan;
pub mod scandata;
pub mod startup;
pub mod surface;

/// The generic pipeline runtime (crate `footscan-pipeline`).
pub use footscan_pipeline as pipeline;

/// The general helpers (crate `footscan-util`), for callers written before it was a crate.
pub use footscan_util as util;
