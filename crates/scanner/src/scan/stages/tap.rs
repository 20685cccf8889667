//! A look at the scan while it runs, for live previews: the detect stage shows every frame
//! and its detected line to a tap. A tap must return at once (it runs on the detect thread
//! and the pipeline never waits for a viewer): it may skip frames, never block.

use crate::detect::LinePeak;
use crate::scan::item::FrameMeta;
use footscan_hal::Frame;

pub trait FrameTap: Send + Sync {
    /// Called for every frame right after detection, before the buffer returns to its pool.
    fn frame(&self, meta: &FrameMeta, frame: &Frame, lines: &[LinePeak]);
}
