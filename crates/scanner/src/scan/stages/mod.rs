//! The scan stages: the orchestrator's adapters from the pipeline's items to the algorithm
//! modules. [`super::registry`] names each of them for `[[pipeline.stages]]`.

mod acquire;
mod adjust;
mod measure;
mod model;
#[cfg(feature = "plugins")]
mod plugin;
mod process;
mod sinks;
mod tap;

pub use acquire::Acquire;
pub use adjust::{AdjustParams, AdjustStage};
pub use measure::{MeasureParams, MeasureStage};
pub use model::{ModelParams, ModelStage};
#[cfg(feature = "plugins")]
pub use plugin::{
    PluginDetector, PluginInfo, PluginRunner, PluginScanStage, PluginSinkStage, PluginStageError,
};
pub use process::{Accumulate, Detect, Triangulate};
pub use sinks::{GridSink, HeightMapSink, PlySink, SummarySink};
pub use tap::FrameTap;

use crate::pipeline::BoxError;
use std::path::{Path, PathBuf};

/// The one check for a stage's output file (`key = "name"`): an artifact name
/// ([`crate::io::ARTIFACT_NAME_RULE`], the rule the archive lists and serves by), which lands
/// inside the scan directory `out_dir`.
pub fn out_file(out_dir: &Path, key: &str, f: &str) -> Result<PathBuf, BoxError> {
    if !crate::io::is_artifact_name(f) {
        return Err(format!(
            "{key} = {f:?}: an output file name must be {} (a plain name inside the scan \
             directory, e.g. \"points.ply\")",
            crate::io::ARTIFACT_NAME_RULE
        )
        .into());
    }
    Ok(out_dir.join(f))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_names_follow_the_archive_rule() {
        let dir = Path::new("/scan");
        assert_eq!(
            out_file(dir, "file", "points.ply").unwrap(),
            Path::new("/scan/points.ply")
        );
        for bad in [
            "",
            ".",
            "..",
            "../x",
            "a/b",
            "/abs",
            ".hidden",
            "my scan.ply",
        ] {
            let e = out_file(dir, "file", bad).unwrap_err().to_string();
            assert!(
                e.contains("file = ") && e.contains("1-64 characters"),
                "{bad:?}: {e}"
            );
        }
        assert!(out_file(dir, "file", &"x".repeat(65)).is_err());
    }
}
