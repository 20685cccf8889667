//! Why a detector could not be built or its input frames not read.

use std::path::PathBuf;

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum DetectError {
    #[error("unknown detector `{name}`: one of {valid}")]
    UnknownDetector { name: String, valid: String },
    #[error("detector `{detector}` takes no `{key}`")]
    UnusedParam {
        detector: &'static str,
        key: &'static str,
    },
    /// A parameter outside its valid range; the message names it and the range.
    #[error("{0}")]
    Param(String),
    /// A recorded frame or directory that cannot be read.
    #[error("{}: {reason}", path.display())]
    Input { path: PathBuf, reason: String },
    #[error("no input frames")]
    NoInput,
}
