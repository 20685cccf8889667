//! Laser-line detection: one subpixel column per image row (SPEC section 4).
//!
//! Every detector shares the coarse search of [`coarse`] (peak, extent, width, the reasons to
//! reject a row, specular spikes skipped) and differs in the subpixel step:
//!
//! | name | subpixel step |
//! | --- | --- |
//! | `bezier` | the paper's method as written: window of n + 1 pixels on the integer maximum, Bernstein curves, bisection ([`BezierLiteral`]) |
//! | `bezier-plus` | the improved Bezier detector: window sized to the line width, re-centred, bias table, continuity along the line ([`BezierPlus`]) |
//! | `cog` | centre of gravity over the run above the threshold |
//! | `parabolic` | 3-point parabola |
//! | `gaussian` | 3-point log-parabola |
//! | `blais-rioux` | zero crossing of the 4th-order derivative filter |
//! | `steger` | Gaussian-derivative zero crossing |
//!
//! Detectors write into a caller-owned slice and keep their scratch between frames, so the
//! per-frame path allocates nothing.

mod bernstein;
mod bezier_plus;
pub mod coarse;
mod estimators;
pub mod files;
mod stages;

pub use bernstein::{bisect_literal, root_near, Binomials, MAX_N};
pub use bezier_plus::{BezierPlus, BezierPlusConfig};
pub use coarse::{sum_bytes, CoarseConfig, Peak};
pub use estimators::{
    BezierLiteral, BlaisRioux, Cog, Estimate, Gaussian, Parabolic, RowDetector, Steger,
};
pub use stages::register_stages;

use footscan_hal::Frame;
use serde::{Deserialize, Serialize};

/// Why a row has no accepted line.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Reject {
    BelowThreshold,
    Saturated,
    Ambiguous,
    Border,
}

impl Reject {
    pub fn as_str(self) -> &'static str {
        match self {
            Reject::BelowThreshold => "below_threshold",
            Reject::Saturated => "saturated",
            Reject::Ambiguous => "ambiguous",
            Reject::Border => "border",
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

/// Every detector name, in the order tables list them.
pub const NAMES: [&str; 7] = [
    "bezier",
    "bezier-plus",
    "cog",
    "parabolic",
    "gaussian",
    "blais-rioux",
    "steger",
];

/// Parameters of any detector (`detect.<name>` stage table, `footscan detect` options).
/// Keys a detector does not use are rejected by [`build`].
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DetectParams {
    /// Minimum peak, DN of an 8-bit frame (x257 for Gray16). Default 30.
    pub threshold: Option<f32>,
    /// Second peak / line peak (both over the background) that makes a row ambiguous. Default 0.8.
    pub ambiguity: Option<f32>,
    /// Longest saturated run accepted, px. Default 12.
    pub max_saturated_px: Option<usize>,
    /// Skip specular spikes (saturated runs of <= 6 px with dark neighbours). Default true.
    pub skip_spikes: Option<bool>,
    /// `bezier`: n (window of n + 1 pixels), default 6. `bezier-plus`: fixed even n, 0 = auto.
    pub window: Option<usize>,
    /// `bezier-plus`: half window in line sigmas. Default 6.0.
    pub window_sigmas: Option<f64>,
    /// `bezier-plus`: smoothing along the line, Gaussian sigma in rows (0 = off). Default 1.5.
    pub smooth_rows: Option<f64>,
    /// `bezier-plus`: column step between rows that breaks the line, px. Default 1.0.
    pub jump_px: Option<f64>,
    /// `bezier-plus`: residual-bias table. Default true.
    pub bias_correction: Option<bool>,
    /// `steger`: Gaussian sigma of the derivative kernels, px. Default 1.5.
    pub sigma: Option<f64>,
}

/// Build the detector `name` with `p`.
pub fn build(name: &str, p: &DetectParams) -> Result<Box<dyn Detector>, String> {
    let coarse = CoarseConfig {
        threshold: p.threshold.unwrap_or(30.0),
        ambiguity: p.ambiguity.unwrap_or(0.8),
        max_saturated_px: p.max_saturated_px.unwrap_or(12),
        skip_spikes: p.skip_spikes.unwrap_or(true),
    };
    coarse.validate()?;
    let only = |allowed: &[&str]| -> Result<(), String> {
        let given = [
            ("window", p.window.is_some()),
            ("window_sigmas", p.window_sigmas.is_some()),
            ("smooth_rows", p.smooth_rows.is_some()),
            ("jump_px", p.jump_px.is_some()),
            ("bias_correction", p.bias_correction.is_some()),
            ("sigma", p.sigma.is_some()),
        ];
        for (k, set) in given {
            if set && !allowed.contains(&k) {
                return Err(format!("detector `{name}` takes no `{k}`"));
            }
        }
        Ok(())
    };
    Ok(match name {
        "bezier" => {
            only(&["window"])?;
            Box::new(RowDetector::new(
                coarse,
                BezierLiteral::new(p.window.unwrap_or(6))?,
            ))
        }
        "bezier-plus" => {
            only(&[
                "window",
                "window_sigmas",
                "smooth_rows",
                "jump_px",
                "bias_correction",
            ])?;
            let d = BezierPlusConfig::default();
            Box::new(BezierPlus::new(BezierPlusConfig {
                coarse,
                window_sigmas: p.window_sigmas.unwrap_or(d.window_sigmas),
                window: p.window.unwrap_or(d.window),
                smooth_rows: p.smooth_rows.unwrap_or(d.smooth_rows),
                jump_px: p.jump_px.unwrap_or(d.jump_px),
                bias_correction: p.bias_correction.unwrap_or(d.bias_correction),
            })?)
        }
        "cog" => {
            only(&[])?;
            Box::new(RowDetector::new(coarse, Cog))
        }
        "parabolic" => {
            only(&[])?;
            Box::new(RowDetector::new(coarse, Parabolic))
        }
        "gaussian" => {
            only(&[])?;
            Box::new(RowDetector::new(coarse, Gaussian))
        }
        "blais-rioux" => {
            only(&[])?;
            Box::new(RowDetector::new(coarse, BlaisRioux))
        }
        "steger" => {
            only(&["sigma"])?;
            let s = p.sigma.unwrap_or(1.5);
            if !(0.5..=10.0).contains(&s) {
                return Err(format!("sigma = {s}: valid range is 0.5..10 px"));
            }
            Box::new(RowDetector::new(coarse, Steger::new(s)))
        }
        other => {
            return Err(format!(
                "unknown detector `{other}`: one of {}",
                NAMES.join(", ")
            ))
        }
    })
}
