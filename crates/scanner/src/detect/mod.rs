//! Laser-line detection: one subpixel column per image row (docs/method.md section 4).
//!
//! Every detector shares the coarse search of [`coarse`] (peak, extent, width, the reasons to
//! reject a row, specular spikes skipped) and differs in the subpixel step:
//!
//! | name | subpixel step |
//! | --- | --- |
//! | `bezier` | the paper's method as written: window of n + 1 pixels on the integer maximum, Bernstein curves, bisection ([`BezierLiteral`]) |
//! | `bezier-plus` | the improved Bezier detector: window sized to the line width, re-centred, bias table, continuity along the line ([`BezierPlus`]) |
//! | `cog` | centre of gravity over the run above the threshold |
//! | `parabolic` | 3-point parabola |
//! | `gaussian` | 3-point log-parabola |
//! | `blais-rioux` | zero crossing of the 4th-order derivative filter |
//! | `steger` | Gaussian-derivative zero crossing |
//!
//! Detectors write into a caller-owned slice and keep their scratch between frames, so the
//! per-frame path allocates nothing.

mod bernstein;
mod bezier_plus;
pub mod channel;
pub mod coarse;
mod error;
mod estimators;
pub mod files;
mod line;
mod list;
pub mod simd;

pub use bernstein::{bisect_literal, root_near, root_near_on, Binomials, MAX_N};
pub use bezier_plus::{BezierPlus, BezierPlusConfig};
pub use channel::{Channel, ColorImage, ColorPixels, Image, Prep};
pub use coarse::{sum_bytes, CoarseConfig, Peak, Threshold};
pub use error::DetectError;
pub use estimators::{
    BezierLiteral, BlaisRioux, Cog, Estimate, Gaussian, Parabolic, RowDetector, Steger,
};
pub use line::{Detector, LinePeak, Reject};
pub use list::{
    build, build_with_prep, DetectParams, DetectorInfo, ThresholdParam, DETECTORS, NAMES,
};
pub use simd::Isa;
