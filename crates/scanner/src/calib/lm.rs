//! Levenberg-Marquardt through the `levenberg-marquardt` crate (MINPACK's trust region on
//! nalgebra), with a central-difference Jacobian, and the covariance of the solution.

use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra::{storage::Owned, DMatrix, DVector, Dyn};

/// Residuals of a parameter vector, written into `out` (same length on every call).
pub type ResidualFn<'a> = dyn Fn(&[f64], &mut Vec<f64>) + 'a;

struct Problem<'a> {
    f: &'a ResidualFn<'a>,
    x: DVector<f64>,
    step: Vec<f64>,
    m: usize,
}

impl Problem<'_> {
    fn eval(&self, x: &[f64]) -> Option<DVector<f64>> {
        let mut out = Vec::with_capacity(self.m);
        (self.f)(x, &mut out);
        (out.len() == self.m && out.iter().all(|v| v.is_finite())).then(|| DVector::from_vec(out))
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for Problem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.x.copy_from(x);
    }

    fn params(&self) -> DVector<f64> {
        self.x.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        self.eval(self.x.as_slice())
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        jacobian(self, self.x.as_slice())
    }
}

fn jacobian(p: &Problem, x: &[f64]) -> Option<DMatrix<f64>> {
    let n = x.len();
    let mut j = DMatrix::zeros(p.m, n);
    let mut xx = x.to_vec();
    for k in 0..n {
        let h = p.step[k];
        xx[k] = x[k] + h;
        let plus = p.eval(&xx)?;
        xx[k] = x[k] - h;
        let minus = p.eval(&xx)?;
        xx[k] = x[k];
        j.set_column(k, &((plus - minus) / (2.0 * h)));
    }
    Some(j)
}

/// The solution of a least-squares fit.
#[derive(Clone, Debug)]
pub struct Solution {
    pub x: Vec<f64>,
    /// Residuals at the solution.
    pub residuals: Vec<f64>,
    /// Covariance of `x`: `s^2 (J^T J)^-1` with `s^2` the residual variance per degree of
    /// freedom (residuals are expected in units of their own standard deviation).
    pub covariance: DMatrix<f64>,
    /// `s^2` (about 1 when the residual weights match the noise).
    pub reduced_chi2: f64,
    /// Condition number of `J^T J` after scaling its columns to unit norm.
    pub condition: f64,
    pub evaluations: usize,
    pub termination: String,
}

/// Why the solver gave no solution.
#[derive(Debug, thiserror::Error)]
pub enum LmError {
    #[error("no residuals")]
    NoResiduals,
    #[error("the starting point gives non-finite residuals")]
    NonFiniteStart,
    /// The solver stopped without success: its termination reason, as it names it.
    #[error("{termination} after {evaluations} evaluations")]
    Stopped {
        termination: String,
        evaluations: usize,
    },
    #[error("non-finite residuals at the solution")]
    NonFiniteResiduals,
    #[error("non-finite Jacobian at the solution")]
    NonFiniteJacobian,
    #[error("covariance: {0}")]
    Covariance(&'static str),
}

/// Minimise the sum of squared residuals from `x0`. `step[k]` is the finite-difference step of
/// parameter k. Err with the termination reason when the solver fails.
pub fn solve(
    f: &ResidualFn,
    x0: &[f64],
    step: &[f64],
    patience: usize,
) -> Result<Solution, LmError> {
    assert_eq!(x0.len(), step.len());
    let mut first = Vec::new();
    f(x0, &mut first);
    if first.is_empty() {
        return Err(LmError::NoResiduals);
    }
    if first.iter().any(|v| !v.is_finite()) {
        return Err(LmError::NonFiniteStart);
    }
    let problem = Problem {
        f,
        x: DVector::from_column_slice(x0),
        step: step.to_vec(),
        m: first.len(),
    };
    let (problem, report) = LevenbergMarquardt::new()
        .with_patience(patience)
        .minimize(problem);
    let termination = format!("{:?}", report.termination);
    if !report.termination.was_successful() {
        return Err(LmError::Stopped {
            termination,
            evaluations: report.number_of_evaluations,
        });
    }
    let x = problem.x.as_slice().to_vec();
    let residuals = problem.eval(&x).ok_or(LmError::NonFiniteResiduals)?;
    let j = jacobian(&problem, &x).ok_or(LmError::NonFiniteJacobian)?;
    let (m, n) = (j.nrows(), j.ncols());
    let dof = (m as f64 - n as f64).max(1.0);
    let reduced_chi2 = residuals.norm_squared() / dof;
    // Scale columns to unit norm for a meaningful condition number and a stable inverse.
    let norms: Vec<f64> = (0..n).map(|k| j.column(k).norm().max(1e-300)).collect();
    let mut js = j.clone();
    for (k, nk) in norms.iter().enumerate() {
        js.column_mut(k).scale_mut(1.0 / nk);
    }
    let jtj = js.transpose() * &js;
    let svd = jtj.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    let condition = if smin > 0.0 {
        smax / smin
    } else {
        f64::INFINITY
    };
    let inv = svd
        .pseudo_inverse(smax * 1e-15)
        .map_err(LmError::Covariance)?;
    let mut covariance = inv * reduced_chi2;
    for a in 0..n {
        for b in 0..n {
            covariance[(a, b)] /= norms[a] * norms[b];
        }
    }
    Ok(Solution {
        x,
        residuals: residuals.as_slice().to_vec(),
        covariance,
        reduced_chi2,
        condition,
        evaluations: report.number_of_evaluations,
        termination,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The solver's reason is a typed source of the calibration error, said once in the chain.
    #[test]
    fn a_failed_fit_is_a_typed_source_said_once() {
        let none = |_: &[f64], _: &mut Vec<f64>| {};
        let e = solve(&none, &[1.0], &[1e-3], 10).unwrap_err();
        assert!(matches!(e, LmError::NoResiduals), "{e:?}");
        let nan = |_: &[f64], out: &mut Vec<f64>| out.push(f64::NAN);
        let e = solve(&nan, &[1.0], &[1e-3], 10).unwrap_err();
        assert!(matches!(e, LmError::NonFiniteStart), "{e:?}");
        let calib = crate::calib::CalibError::NotConverged {
            what: "the fit".into(),
            source: e,
        };
        assert_eq!(
            footscan_util::chain(&calib),
            "the fit did not converge: the starting point gives non-finite residuals"
        );
    }

    #[test]
    fn fits_an_exponential_with_its_uncertainty() {
        // y = a exp(-b t) + noise of sd 0.01, residuals weighted by 1 / 0.01.
        let (a, b) = (2.5, 0.7);
        let ts: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let noise: Vec<f64> = (0..50)
            .map(|i| 0.01 * ((i * 7919 % 101) as f64 / 50.0 - 1.0) * 1.7)
            .collect();
        let ys: Vec<f64> = ts
            .iter()
            .zip(&noise)
            .map(|(t, n)| a * (-b * t).exp() + n)
            .collect();
        let f = |x: &[f64], out: &mut Vec<f64>| {
            out.clear();
            out.extend(
                ts.iter()
                    .zip(&ys)
                    .map(|(t, y)| (x[0] * (-x[1] * t).exp() - y) / 0.01),
            );
        };
        let s = solve(&f, &[1.0, 0.1], &[1e-6, 1e-6], 100).unwrap();
        assert!(
            (s.x[0] - a).abs() < 0.02 && (s.x[1] - b).abs() < 0.02,
            "{:?}",
            s.x
        );
        let sd_a = s.covariance[(0, 0)].sqrt();
        assert!(sd_a > 1e-4 && sd_a < 0.02, "sd(a) {sd_a}");
        assert!(
            s.reduced_chi2 > 0.1 && s.reduced_chi2 < 3.0,
            "{}",
            s.reduced_chi2
        );
        // A residual function that turns non-finite is a failure, not a result.
        let bad = |_: &[f64], out: &mut Vec<f64>| {
            out.clear();
            out.push(f64::NAN);
        };
        assert!(solve(&bad, &[1.0], &[1e-6], 10).is_err());
    }
}
