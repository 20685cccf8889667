//! The item type of the scan pipeline: what flows between its stages.

use footscan_hal::Frame;
use std::sync::Arc;

pub use crate::scandata::{FrameLines, FrameMeta, FramePoints, ScanGrid};

/// What flows between scan stages.
pub enum Item {
    Frame(AcquiredFrame),
    Lines(FrameLines),
    Points(FramePoints),
    Grid(Arc<ScanGrid>),
    /// The plantar model built from the grid (stage `model.bezier`).
    Model(Arc<crate::surface::BezierNetwork>),
    /// The foot's measurements (stage `measure.foot`), for the last stages after it.
    Foot(Arc<crate::measure::Measurements>),
    Summary(Box<super::summary::ScanSummary>),
}

impl Item {
    pub fn kind(&self) -> &'static str {
        match self {
            Item::Frame(_) => "frame",
            Item::Lines(_) => "lines",
            Item::Points(_) => "points",
            Item::Grid(_) => "grid",
            Item::Model(_) => "model",
            Item::Foot(_) => "foot",
            Item::Summary(_) => "summary",
        }
    }
}

pub struct AcquiredFrame {
    pub meta: FrameMeta,
    pub frame: Frame,
    /// Taken with the laser off (`scan.background`): the detect stage uses it as the
    /// background and passes nothing on for it.
    pub laser_off: bool,
}

/// A stage received an item it cannot handle: a pipeline declared in the wrong order.
pub fn unexpected(stage: &str, item: &Item, wants: &str) -> crate::pipeline::BoxError {
    format!(
        "stage `{stage}` received {} items but takes {wants}: check the order of [[pipeline.stages]]",
        item.kind()
    )
    .into()
}
