//! From in-system data to the [`Calibration`] a scan loads: the calibration detector, the
//! acquisition through a rig, the fit of the chosen method and the checks before saving.
//! Opening the devices is the orchestrator's job (`scan::calibrate`).

use super::acquire::InsystemData;
use super::bezier_depth::BezierDepth;
use super::insystem::{fit_insystem, InsystemFit, InsystemOptions};
use super::{CalibError, Calibration, CalibrationPlan};
use crate::detect::Detector;

/// How the scanner is calibrated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Method {
    /// The general model fitted to the plate and staircase seen through the scanner itself.
    Insystem,
    /// Heights from the Bezier depth network (x and y from the in-system model).
    Bezier,
    /// OpenCV checkerboard calibration and a laser plane fitted on the board.
    Opencv,
}

impl Method {
    pub const ALL: [Method; 3] = [Method::Insystem, Method::Bezier, Method::Opencv];

    pub fn name(self) -> &'static str {
        match self {
            Method::Insystem => "insystem",
            Method::Bezier => "bezier",
            Method::Opencv => "opencv",
        }
    }
}

/// A calibration method's name that is none of [`Method::ALL`].
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("unknown method `{0}`: one of insystem, bezier, opencv")]
pub struct UnknownMethod(pub String);

impl std::str::FromStr for Method {
    type Err = UnknownMethod;
    fn from_str(s: &str) -> Result<Self, UnknownMethod> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| UnknownMethod(s.to_string()))
    }
}

/// The detector calibration uses: the most accurate of [`crate::detect::NAMES`] on the
/// simulated line (see `footscan bench detect`).
pub const DETECTOR: &str = "bezier-plus";

/// A detector by name with its default parameters.
pub fn detector(name: &str) -> Result<Box<dyn Detector>, CalibError> {
    crate::detect::build(name, &Default::default())
        .map_err(|e| CalibError::Plan(format!("calibration detector: {e}")))
}

/// A calibration and what was learnt making it.
#[derive(Clone, Debug)]
pub struct Calibrated {
    pub calibration: Calibration,
    /// The in-system fit (methods insystem and bezier).
    pub insystem: Option<InsystemFit>,
    /// What each step of the guided procedure saw (in-system methods).
    pub steps: Vec<super::guided::StepRecord>,
}

/// Fit `method` (insystem or bezier) to in-system data.
pub fn from_insystem(
    data: &InsystemData,
    method: Method,
    plan: &CalibrationPlan,
) -> Result<Calibrated, CalibError> {
    let fit = fit_insystem(data, &InsystemOptions::default())?;
    let mut calibration = Calibration {
        method: Method::Insystem.name().into(),
        date: footscan_util::now_rfc3339(),
        model: fit.model.clone(),
        stddev: fit.stddev.clone(),
        residuals: fit.residuals.clone(),
        bezier: None,
    };
    match method {
        Method::Insystem => {}
        Method::Bezier => {
            let net = BezierDepth::fit(
                &data.plates,
                plan.bezier_degree_v,
                plan.bezier_smooth_degree,
            )?;
            calibration.method = Method::Bezier.name().into();
            let r = &mut calibration.residuals;
            r.insert("bezier_condition".into(), net.condition);
            r.insert("bezier_blocks".into(), net.blocks.len() as f64);
            r.insert(
                "bezier_u_h_detection_mm".into(),
                net.detection_uncertainty(fit.detection_noise_px),
            );
            calibration.bezier = Some(net);
        }
        Method::Opencv => {
            return Err(CalibError::Plan(
                "method opencv does not use in-system data".into(),
            ))
        }
    }
    check_before_saving(&calibration)?;
    Ok(Calibrated {
        calibration,
        insystem: Some(fit),
        steps: Vec::new(),
    })
}

/// The last line of defence before a file is written: a valid model and finite figures.
pub fn check_before_saving(c: &Calibration) -> Result<(), CalibError> {
    c.model
        .validate()
        .map_err(|e| CalibError::Implausible(format!("model: {e}")))?;
    if let Some((k, v)) = c.stddev.iter().find(|(_, v)| !v.is_finite()) {
        return Err(CalibError::Implausible(format!(
            "standard deviation of {k} is {v}: the data do not determine it"
        )));
    }
    let m = &c.model;
    if !(m.cx > 0.0 && m.cx < m.width as f64 && m.cy > 0.0 && m.cy < m.height as f64) {
        return Err(CalibError::Implausible(format!(
            "principal point ({:.1}, {:.1}) outside the {}x{} image",
            m.cx, m.cy, m.width, m.height
        )));
    }
    Ok(())
}

/// The configured limits a calibration must meet before it is written: every fit residual
/// `*_rms_px` within `max_residual_px`, the height uncertainty `u_h_mm` within `max_u_h_mm`.
/// The error names each limit exceeded and by how much.
pub fn check_limits(
    c: &Calibration,
    max_residual_px: f64,
    max_u_h_mm: f64,
) -> Result<(), CalibError> {
    let mut over = Vec::new();
    for (k, &v) in &c.residuals {
        if k.ends_with("_rms_px") && (v.is_nan() || v > max_residual_px) {
            over.push(format!(
                "{k} = {v:.4} px exceeds calibration.max_residual_px = {max_residual_px} px by {:.4} px",
                v - max_residual_px
            ));
        }
    }
    if let Some(&u) = c.residuals.get("u_h_mm") {
        if u.is_nan() || u > max_u_h_mm {
            over.push(format!(
                "the height uncertainty u_h_mm = {u:.4} mm exceeds calibration.max_u_h_mm = {max_u_h_mm} mm by {:.4} mm",
                u - max_u_h_mm
            ));
        }
    }
    if over.is_empty() {
        Ok(())
    } else {
        Err(CalibError::Limits(over.join("; ")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn methods_parse_by_name_and_an_unknown_one_is_named_with_the_valid_ones() {
        for m in Method::ALL {
            assert_eq!(m.name().parse::<Method>(), Ok(m));
        }
        let e = "checkerboard".parse::<Method>().unwrap_err();
        assert_eq!(e, UnknownMethod("checkerboard".into()));
        assert_eq!(
            e.to_string(),
            "unknown method `checkerboard`: one of insystem, bezier, opencv"
        );
    }
}
