use crate::detect::LinePeak;
use footscan_hal::{Frame, Timestamp};
use std::sync::Arc;

use super::ScanGrid;

/// What flows between scan stages.
pub enum Item {
    Frame(AcquiredFrame),
    Lines(FrameLines),
    Points(FramePoints),
    Grid(Arc<ScanGrid>),
    /// The plantar model built from the grid (stage `model.bezier`).
    Model(Arc<crate::surface::BezierNetwork>),
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
            Item::Summary(_) => "summary",
        }
    }
}

/// Where and when a frame was taken.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FrameMeta {
    /// Position in the scan (0, 1, 2, ... over accepted frames).
    pub index: u64,
    /// Camera sequence number.
    pub seq: u64,
    pub timestamp: Timestamp,
    /// Slider position reported by the controller, interpolated at the capture time (mm).
    pub x_mm: f64,
}

pub struct AcquiredFrame {
    pub meta: FrameMeta,
    pub frame: Frame,
}

pub struct FrameLines {
    pub meta: FrameMeta,
    pub lines: Vec<LinePeak>,
}

pub struct FramePoints {
    pub meta: FrameMeta,
    pub lines: Vec<LinePeak>,
    /// One per row; NaN where the row has no line.
    pub points: Vec<[f64; 3]>,
}

/// A stage received an item it cannot handle: a pipeline declared in the wrong order.
pub fn unexpected(stage: &str, item: &Item, wants: &str) -> crate::pipeline::BoxError {
    format!(
        "stage `{stage}` received {} items but takes {wants}: check the order of [[pipeline.stages]]",
        item.kind()
    )
    .into()
}
