//! The generic pipeline runtime: a source and a chain of stages, each on its own named thread,
//! joined by bounded channels.
//!
//! It is generic over the item type so it knows nothing about frames or point clouds; the
//! scanner supplies its item enum and registers its stages in a [`Registry`]. A TOML
//! [`PipelineSpec`] names the stages; [`Registry::build`] turns it into a [`Pipeline`];
//! [`Pipeline::start`] runs it and [`Running::wait`] returns a [`RunReport`] or the first
//! failure.
//!
//! Semantics in one place:
//! * Backpressure: every queue holds at most `capacity` items; `emit` blocks when it is full.
//! * End of stream: when the source returns, each stage drains its input, then `finish()`.
//! * Cancel ([`CancelHandle::cancel`]): every thread stops promptly, `finish()` is not called,
//!   and `wait()` returns `Ok` with `cancelled: true`.
//! * Failure (an `Err` or a panic in any node): the run is cancelled, all threads are joined,
//!   and `wait()` returns the first failure; errors other nodes hit because of it are ignored.
//! * Items emitted by the last node are collected into [`RunReport::outputs`].
//! * Counters ([`StageStats`]) are live: [`Running::stats`] can drive a progress bar.
//!
//! Dependencies: std threads, crossbeam channels, serde/toml for the spec, tracing. No async
//! runtime, no image or hardware crate, nothing of footscan: every other crate may use this one.

mod control;
mod emitter;
mod error;
mod node;
mod registry;
mod runner;
mod spec;
mod stats;

pub use control::CancelHandle;
pub use emitter::{Cancelled, Emitter};
pub use error::{BoxError, BuildError};
pub use node::{FnSource, FnStage, Node, Source, Stage};
pub use registry::{Factory, Registry};
pub use runner::{Panicked, Pipeline, PipelineError, RunReport, Running};
pub use spec::{PipelineSpec, StageSpec, DEFAULT_CAPACITY};
pub use stats::{StageState, StageStats};
