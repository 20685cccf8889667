//! The runtime's error types: what a node returns and why a pipeline could not be built.
//! Every other file of the runtime uses these; this file uses none of them.

/// The error type nodes return: any error, boxed. Return `Err(Cancelled.into())` (or just use
/// `out.emit(x)?`) to stop quietly when the run is cancelled; that is not reported as a failure.
pub type BoxError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Why a pipeline could not be built. Indices are 0-based positions in `pipeline.stages`.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error("pipeline capacity must be at least 1, got {0}")]
    Capacity(usize),
    #[error("the pipeline has no stages; the first [[pipeline.stages]] entry must be a source")]
    Empty,
    #[error("pipeline.stages[{index}]: unknown stage `{name}`; valid stages: {}", valid.join(", "))]
    UnknownStage {
        index: usize,
        name: String,
        valid: Vec<String>,
    },
    #[error("pipeline.stages[{index}] `{stage}`")]
    Factory {
        index: usize,
        stage: String,
        source: BoxError,
    },
    #[error("pipeline.stages[0] `{stage}` is not a source; a pipeline must start with a source")]
    FirstNotSource { stage: String },
    #[error(
        "pipeline.stages[{index}] `{stage}` is a source; only the first stage may be a source"
    )]
    SourceNotFirst { index: usize, stage: String },
}
