//! The one list of detectors: name, stage name, description, the parameters each takes and
//! its constructor. `footscan detect`, the `detect.<name>` stages, calibration, the benches and
//! the tests all read it.

use super::{
    BezierLiteral, BezierPlus, BezierPlusConfig, BlaisRioux, Channel, CoarseConfig, Cog,
    DetectError, Detector, Gaussian, Parabolic, Prep, RowDetector, Steger, Threshold,
};
use serde::Deserialize;

/// `threshold` as written in a stage table or on the command line: `"auto"` or a number (DN).
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(try_from = "ThresholdRepr")]
pub struct ThresholdParam(pub Threshold);

#[derive(Deserialize)]
#[serde(untagged)]
enum ThresholdRepr {
    Dn(f32),
    Word(String),
}

impl TryFrom<ThresholdRepr> for ThresholdParam {
    type Error = String;
    fn try_from(r: ThresholdRepr) -> Result<Self, String> {
        match r {
            ThresholdRepr::Dn(v) => Ok(ThresholdParam(Threshold::Dn(v))),
            ThresholdRepr::Word(w) => w.parse(),
        }
    }
}

impl std::str::FromStr for ThresholdParam {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s.trim() == "auto" {
            return Ok(ThresholdParam(Threshold::Auto));
        }
        s.trim()
            .parse::<f32>()
            .map(|v| ThresholdParam(Threshold::Dn(v)))
            .map_err(|_| format!("threshold = {s:?}: \"auto\" or a number of DN (0..255)"))
    }
}

/// Builds a detector from the coarse search settings and its own parameters.
type Constructor = fn(CoarseConfig, &DetectParams) -> Result<Box<dyn Detector>, DetectError>;

/// One detector of [`DETECTORS`].
pub struct DetectorInfo {
    /// What `footscan detect --detector` and calibration call it.
    pub name: &'static str,
    /// Its pipeline stage (`detect.<name>`).
    pub stage: &'static str,
    /// One line for `footscan stages`.
    pub description: &'static str,
    /// The [`DetectParams`] keys besides the coarse search's that it takes.
    pub params: &'static [&'static str],
    construct: Constructor,
}

/// Every detector, in the order tables list them.
pub const DETECTORS: [DetectorInfo; 7] = [
    DetectorInfo {
        name: "bezier",
        stage: "detect.bezier",
        description: "laser line per row, the paper's Bezier method as written (threshold, window n)",
        params: &["window"],
        construct: |coarse, p| {
            Ok(Box::new(RowDetector::new(
                coarse,
                BezierLiteral::new(p.window.unwrap_or(6))?,
            )))
        },
    },
    DetectorInfo {
        name: "bezier-plus",
        stage: "detect.bezier-plus",
        description: "laser line per row, improved Bezier: width-sized re-centred window, bias table, continuity along the line (threshold, window_sigmas, smooth_rows, jump_px, ...)",
        params: &[
            "window",
            "window_sigmas",
            "smooth_rows",
            "jump_px",
            "bias_correction",
        ],
        construct: |coarse, p| {
            let d = BezierPlusConfig::default();
            Ok(Box::new(BezierPlus::new(BezierPlusConfig {
                coarse,
                window_sigmas: p.window_sigmas.unwrap_or(d.window_sigmas),
                window: p.window.unwrap_or(d.window),
                smooth_rows: p.smooth_rows.unwrap_or(d.smooth_rows),
                jump_px: p.jump_px.unwrap_or(d.jump_px),
                bias_correction: p.bias_correction.unwrap_or(d.bias_correction),
            })?))
        },
    },
    DetectorInfo {
        name: "cog",
        stage: "detect.cog",
        description: "laser line per row by thresholded centre of gravity (threshold, DN)",
        params: &[],
        construct: |coarse, _| Ok(Box::new(RowDetector::new(coarse, Cog))),
    },
    DetectorInfo {
        name: "parabolic",
        stage: "detect.parabolic",
        description: "laser line per row by a 3-point parabola (threshold)",
        params: &[],
        construct: |coarse, _| Ok(Box::new(RowDetector::new(coarse, Parabolic))),
    },
    DetectorInfo {
        name: "gaussian",
        stage: "detect.gaussian",
        description: "laser line per row by a 3-point Gaussian (log-parabola) fit (threshold)",
        params: &[],
        construct: |coarse, _| Ok(Box::new(RowDetector::new(coarse, Gaussian))),
    },
    DetectorInfo {
        name: "blais-rioux",
        stage: "detect.blais-rioux",
        description: "laser line per row by the Blais-Rioux 4th-order derivative zero crossing (threshold)",
        params: &[],
        construct: |coarse, _| Ok(Box::new(RowDetector::new(coarse, BlaisRioux))),
    },
    DetectorInfo {
        name: "steger",
        stage: "detect.steger",
        description: "laser line per row by the Gaussian-derivative zero crossing (threshold, sigma)",
        params: &["sigma"],
        construct: |coarse, p| {
            let s = p.sigma.unwrap_or(1.5);
            if !(0.5..=10.0).contains(&s) {
                return Err(DetectError::Param(format!(
                    "sigma = {s}: valid range is 0.5..10 px"
                )));
            }
            Ok(Box::new(RowDetector::new(coarse, Steger::new(s))))
        },
    },
];

/// Every detector name, in the order tables list them (the names of [`DETECTORS`]).
pub const NAMES: [&str; DETECTORS.len()] = {
    let mut names = [""; DETECTORS.len()];
    let mut i = 0;
    while i < DETECTORS.len() {
        names[i] = DETECTORS[i].name;
        i += 1;
    }
    names
};

/// The entry of detector `name`.
pub fn info(name: &str) -> Result<&'static DetectorInfo, DetectError> {
    DETECTORS
        .iter()
        .find(|d| d.name == name)
        .ok_or_else(|| DetectError::UnknownDetector {
            name: name.into(),
            valid: NAMES.join(", "),
        })
}

/// Parameters of any detector (`detect.<name>` stage table, `footscan detect` options).
/// Keys a detector does not use are rejected by [`build`].
#[derive(Clone, Debug, Default, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DetectParams {
    /// Minimum peak: `"auto"` (default; relative to each row's background level and noise) or
    /// DN of an 8-bit frame (x257 for Gray16).
    pub threshold: Option<ThresholdParam>,
    /// The grey channel of colour frames (luma, red, green, blue, red-minus-others,
    /// green-minus-others). Unset: grey frames only.
    pub channel: Option<Channel>,
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

/// Build the detector `name` with `p`, for grey frames (a colour `channel` is refused: the
/// camera stages see Gray8/Gray16 frames; [`build_with_prep`] takes colour input).
pub fn build(name: &str, p: &DetectParams) -> Result<Box<dyn Detector>, DetectError> {
    if let Some(c) = p.channel.filter(|&c| c != Channel::Luma) {
        return Err(DetectError::Param(format!(
            "channel = {}: this detector sees grey frames (Gray8/Gray16); only luma applies (a V4L2 camera converts colour itself: set hardware.camera.channel)",
            c.as_str()
        )));
    }
    build_detector(name, p)
}

/// The detector `name` and the [`Prep`] (channel conversion, background) its input goes
/// through: for colour frames and laser-off subtraction.
pub fn build_with_prep(
    name: &str,
    p: &DetectParams,
) -> Result<(Box<dyn Detector>, Prep), DetectError> {
    Ok((build_detector(name, p)?, Prep::new(p.channel)))
}

fn build_detector(name: &str, p: &DetectParams) -> Result<Box<dyn Detector>, DetectError> {
    let coarse = CoarseConfig {
        threshold: p.threshold.map_or(Threshold::Auto, |t| t.0),
        ambiguity: p.ambiguity.unwrap_or(0.8),
        max_saturated_px: p.max_saturated_px.unwrap_or(12),
        skip_spikes: p.skip_spikes.unwrap_or(true),
    };
    coarse.validate()?;
    let d = info(name)?;
    let given = [
        ("window", p.window.is_some()),
        ("window_sigmas", p.window_sigmas.is_some()),
        ("smooth_rows", p.smooth_rows.is_some()),
        ("jump_px", p.jump_px.is_some()),
        ("bias_correction", p.bias_correction.is_some()),
        ("sigma", p.sigma.is_some()),
    ];
    for (key, set) in given {
        if set && !d.params.contains(&key) {
            return Err(DetectError::UnusedParam {
                detector: d.name,
                key,
            });
        }
    }
    (d.construct)(coarse, p)
}
