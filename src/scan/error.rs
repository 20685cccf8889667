//! Why a scan failed.

use crate::pipeline::PipelineError;
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum ScanError {
    #[error("{0}")]
    Config(String),
    #[error("cannot use scan directory {path}: {source}")]
    OutDir {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("scanner setup failed: {0}")]
    Setup(String),
    #[error(transparent)]
    Pipeline(#[from] PipelineError),
    #[error("writing {path}: {source}")]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
}
