//! footscan: a laser-line foot scanner and last-design toolkit.
//!
//! The library holds all the logic; the binaries `footscan` (command line) and `footscand`
//! (daemon) are thin shells over it. Hardware is reached only through `footscan-hal`, so the
//! simulator (`footscan-sim`) is one more backend behind the same traits.

pub mod api;
pub mod archive;
pub mod bench;
pub mod calib;
pub mod daemon;
pub mod detect;
pub mod geom;
pub mod io;
pub mod measure;
pub mod pipeline;
pub mod scan;
pub mod scandata;
pub mod surface;
pub mod util;
