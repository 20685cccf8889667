//! The scan stages: the orchestrator's adapters from the pipeline's items to the algorithm
//! modules. [`super::registry`] names each of them for `[[pipeline.stages]]`.

mod acquire;
mod adjust;
mod measure;
mod model;
mod process;
mod sinks;
mod tap;

pub use acquire::Acquire;
pub use adjust::{AdjustParams, AdjustStage};
pub use measure::{MeasureParams, MeasureStage};
pub use model::{ModelParams, ModelStage};
pub use process::{Accumulate, Detect, Triangulate};
pub use sinks::{GridSink, HeightMapSink, PlySink, SummarySink};
pub use tap::FrameTap;

use crate::pipeline::BoxError;
use std::path::{Path, PathBuf};

/// The one check for a stage's output file (`key = "name"`): a plain, non-empty file name,
/// which lands inside the scan directory `out_dir`.
pub fn out_file(out_dir: &Path, key: &str, f: &str) -> Result<PathBuf, BoxError> {
    let p = Path::new(f);
    if f.is_empty() || p.is_absolute() || p.components().count() != 1 || f.contains("..") {
        return Err(
            format!("{key} = {f:?}: must be a plain name inside the scan directory").into(),
        );
    }
    Ok(out_dir.join(p))
}
