//! Height uncertainty (the plantar scanner paper's eq. 30-31, recast for the parametric model;
//! docs/method.md section 6.5): the detection noise of one frame, measured as the spread of
//! repeated frames, through the sensitivity dh/dc of the triangulation; and the calibration's
//! own uncertainty, the parameter covariance propagated through dh/dtheta at the calibration
//! samples.
//!
//! In the paper's eq. 30 the row coordinate also carries an uncertainty (u_v); here every row
//! is measured at its own integer row, so only the column is uncertain.

use super::data::PlateObservation;
use super::CameraModel;
use nalgebra::{DMatrix, DVector};

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeightUncertainty {
    /// One frame's detection noise at the lowest calibration height (mm).
    pub detection_mm: f64,
    /// The calibration parameters' uncertainty, RMS over the calibration samples (mm).
    pub model_mm: f64,
    /// Both (root sum of squares).
    pub total_mm: f64,
}

/// `cov` is the covariance of the model parameters `x` (the first `x.len()` of the fit),
/// `model_of` rebuilds the model from them, `step` are finite-difference steps.
pub fn height_uncertainty(
    model: &CameraModel,
    cov: &DMatrix<f64>,
    plates: &[PlateObservation],
    noise_px: f64,
    model_of: &dyn Fn(&[f64]) -> CameraModel,
    x: &[f64],
    step: &[f64],
) -> HeightUncertainty {
    let tri = model.triangulator();
    let row_mid = model.cy.round().clamp(0.0, model.height as f64 - 1.0) as usize;
    let detection_mm = plates
        .iter()
        .min_by(|a, b| a.height_mm.total_cmp(&b.height_mm))
        .and_then(|p| {
            let c = p.col.get(row_mid).copied().filter(|c| c.is_finite())?;
            let a = tri.point(0.0, c - 0.5, row_mid as f64)?[2];
            let b = tri.point(0.0, c + 0.5, row_mid as f64)?[2];
            Some((b - a).abs() * noise_px)
        })
        .unwrap_or(f64::NAN);
    // Samples: every 32nd row of every plate height.
    let samples: Vec<(f64, f64)> = plates
        .iter()
        .flat_map(|p| {
            p.col
                .iter()
                .enumerate()
                .step_by(32)
                .filter(|(_, c)| c.is_finite())
                .map(|(r, &c)| (r as f64, c))
        })
        .collect();
    let n = x.len();
    let plus_minus: Vec<(CameraModel, CameraModel)> = (0..n)
        .map(|k| {
            let mut a = x.to_vec();
            let mut b = x.to_vec();
            a[k] += step[k];
            b[k] -= step[k];
            (model_of(&a), model_of(&b))
        })
        .collect();
    let tris: Vec<_> = plus_minus
        .iter()
        .map(|(a, b)| (a.triangulator(), b.triangulator()))
        .collect();
    let mut sum = 0.0;
    let mut count = 0usize;
    for &(r, c) in &samples {
        let g: Option<Vec<f64>> = tris
            .iter()
            .zip(step)
            .map(|((a, b), s)| Some((a.point(0.0, c, r)?[2] - b.point(0.0, c, r)?[2]) / (2.0 * s)))
            .collect();
        let Some(g) = g else { continue };
        let g = DVector::from_vec(g);
        let var = (g.transpose() * cov * &g)[(0, 0)];
        if var.is_finite() && var >= 0.0 {
            sum += var;
            count += 1;
        }
    }
    let model_mm = if count > 0 {
        (sum / count as f64).sqrt()
    } else {
        f64::NAN
    };
    HeightUncertainty {
        detection_mm,
        model_mm,
        total_mm: (detection_mm.powi(2) + model_mm.powi(2)).sqrt(),
    }
}
