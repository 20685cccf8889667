//! What a pipeline is made of: the [`Source`] and [`Stage`] traits and the [`Node`] that holds
//! either.
//!
//! The traits are generic over the item type `T` so the runtime can be tested with plain
//! integers and reused for any item enum the scanner defines. Both take `&mut self` and run on
//! their own thread, so implementations keep their state in fields without locks.

use super::emitter::Emitter;
use super::error::BoxError;

/// The first node of a pipeline: produces items (frames from a camera, a recorded scan, ...).
pub trait Source<T>: Send {
    /// Produce items with `out.emit(..)` until done, then return `Ok(())`.
    ///
    /// Must return promptly once [`Emitter::emit`] returns `Err(Cancelled)` (propagating it
    /// with `?` is fine) or [`Emitter::is_cancelled`] becomes true; a source that waits on
    /// hardware should poll `is_cancelled()` between waits, or a cancelled run cannot end.
    fn run(&mut self, out: &mut Emitter<T>) -> Result<(), BoxError>;
}

/// Any later node: transforms, filters, accumulates or writes items.
pub trait Stage<T>: Send {
    /// Handle one item, emitting zero or more items downstream. Report discarded items with
    /// [`Emitter::dropped`] so they are counted.
    fn process(&mut self, item: T, out: &mut Emitter<T>) -> Result<(), BoxError>;

    /// Upstream ended normally and every item has been processed: flush buffered state here.
    ///
    /// Called only on a normal end of stream. When the run is cancelled or another node fails,
    /// the stage's thread just stops and `finish` is not called, so a sink never marks a
    /// partial result as complete (clean up partial files in `Drop` if needed).
    fn finish(&mut self, out: &mut Emitter<T>) -> Result<(), BoxError> {
        let _ = out;
        Ok(())
    }
}

/// A built node, ready to be placed in a [`Pipeline`](super::Pipeline).
pub enum Node<T> {
    Source(Box<dyn Source<T>>),
    Stage(Box<dyn Stage<T>>),
}

impl<T> Node<T> {
    /// Box a source.
    pub fn source(s: impl Source<T> + 'static) -> Self {
        Self::Source(Box::new(s))
    }

    /// Box a stage.
    pub fn stage(s: impl Stage<T> + 'static) -> Self {
        Self::Stage(Box::new(s))
    }

    /// Whether this is a source.
    pub fn is_source(&self) -> bool {
        matches!(self, Self::Source(_))
    }
}

impl<T> std::fmt::Debug for Node<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Source(_) => "Node::Source",
            Self::Stage(_) => "Node::Stage",
        })
    }
}

/// A [`Source`] from a closure: `FnSource(|out| { out.emit(1)?; Ok(()) })`.
pub struct FnSource<F>(pub F);

impl<T, F> Source<T> for FnSource<F>
where
    F: FnMut(&mut Emitter<T>) -> Result<(), BoxError> + Send,
{
    fn run(&mut self, out: &mut Emitter<T>) -> Result<(), BoxError> {
        (self.0)(out)
    }
}

/// A [`Stage`] without `finish` from a closure: `FnStage(|x, out| Ok(out.emit(x + 1)?))`.
pub struct FnStage<F>(pub F);

impl<T, F> Stage<T> for FnStage<F>
where
    F: FnMut(T, &mut Emitter<T>) -> Result<(), BoxError> + Send,
{
    fn process(&mut self, item: T, out: &mut Emitter<T>) -> Result<(), BoxError> {
        (self.0)(item, out)
    }
}
