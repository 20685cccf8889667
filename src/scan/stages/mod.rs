//! The scan stages, each registered under a name for `[[pipeline.stages]]`.

mod acquire;
mod process;
mod sinks;
mod tap;

pub use acquire::Acquire;
pub use process::{Accumulate, Detect, Triangulate};
pub use sinks::{GridSink, HeightMapSink, PlySink, SummarySink};
pub use tap::FrameTap;
