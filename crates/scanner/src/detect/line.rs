//! What a detector produces (one [`LinePeak`] per image row, or why the row has none) and the
//! [`Detector`] trait every detector implements.

use footscan_hal::Frame;
use serde::Serialize;

/// Why a row has no accepted line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reject {
    BelowThreshold,
    Saturated,
    Ambiguous,
    Border,
    /// Accepted alone: no row within [`super::coarse::NEAR_ROWS`] above or below holds a
    /// line, so it is a speck of the scene, not a line crossing the rows.
    Isolated,
}

impl Reject {
    pub fn as_str(self) -> &'static str {
        match self {
            Reject::BelowThreshold => "below_threshold",
            Reject::Saturated => "saturated",
            Reject::Ambiguous => "ambiguous",
            Reject::Border => "border",
            Reject::Isolated => "isolated",
        }
    }
}

/// The line found in one row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinePeak {
    /// Subpixel column (pixel centres at integers), NaN when no line was accepted.
    pub col: f64,
    /// Peak intensity in the frame's own units (DN).
    pub intensity: f32,
    /// Width above half the peak, px.
    pub width: f32,
    /// 0..1, higher is better.
    pub quality: f32,
    pub reject: Option<Reject>,
}

impl LinePeak {
    pub const NONE: LinePeak = LinePeak {
        col: f64::NAN,
        intensity: 0.0,
        width: 0.0,
        quality: 0.0,
        reject: Some(Reject::BelowThreshold),
    };

    pub fn rejected(reason: Reject, intensity: f32) -> Self {
        LinePeak {
            intensity,
            reject: Some(reason),
            ..Self::NONE
        }
    }

    pub fn is_valid(&self) -> bool {
        self.reject.is_none() && self.col.is_finite()
    }
}

pub trait Detector: Send {
    fn name(&self) -> &'static str;
    /// Fill `out[r]` for every row `r` of `frame` (`out.len() == frame.height`). A detector may
    /// use any row to decide another (the whole frame is given).
    fn detect(&mut self, frame: &Frame, out: &mut [LinePeak]);
}
