//! Algorithm I (fit each characteristic curve) and Algorithm II (move characteristic points
//! with the least change of control points).

use crate::customize::error::CustomizeError;
use footscan_geom::nurbs::basis::{ders_basis_funs, find_span};
use footscan_geom::nurbs::{fit, FitOptions, NurbsCurve};
use footscan_geom::{P3, V3};
use nalgebra::DMatrix;
use serde::Serialize;

/// Per-curve record of Algorithm I.
#[derive(Clone, Debug, Serialize)]
pub struct FitRecord {
    pub curve: &'static str,
    pub data_points: usize,
    pub control_points: usize,
    pub max_error_mm: f64,
    pub rms_error_mm: f64,
    pub knots_inserted: usize,
    pub met: bool,
}

/// Algorithm I on a closed loop: resampled by arc length to points `step` mm apart (cut
/// loops crowd points where the mesh is fine), then the periodic adaptive least-squares fit.
pub fn fit_loop(
    name: &'static str,
    pts: &[P3],
    step: f64,
    tol: f64,
) -> Result<(NurbsCurve, FitRecord), CustomizeError> {
    let pl = footscan_geom::polyline::Polyline::closed(pts.to_vec());
    let n = ((pl.length() / step).ceil() as usize).clamp(12, 2000);
    let rs = pl.resample(n);
    let mut data = rs.points;
    if data.len() > 1 && (data[0] - data[data.len() - 1]).norm() < 1e-9 {
        data.pop();
    }
    let opts = FitOptions {
        tolerance: tol,
        ..FitOptions::default()
    };
    let r = fit_closed_split(&data, &opts).map_err(|e| CustomizeError::Curve {
        curve: name.into(),
        why: format!("fit: {e}"),
    })?;
    let rec = FitRecord {
        curve: name,
        data_points: data.len(),
        control_points: r.control_points,
        max_error_mm: r.max_error,
        rms_error_mm: r.rms_error,
        knots_inserted: r.iterations,
        met: r.met,
    };
    Ok((r.curve, rec))
}

/// Algorithm I for a closed loop with every span over the tolerance split at once (at the
/// middle of its data) per round, instead of one knot per refit as
/// [`fit::fit_closed_adaptive`] does: the same periodic least squares with chord-length
/// parameters, in a handful of refits rather than one per control point (a girth took 9 ms,
/// the side profile 60-150 ms). It may end with a few more control points than inserting
/// one knot at a time. When no span can be split and the tolerance is not met, the one-at-a
/// -time fit decides.
pub fn fit_closed_split(
    points: &[P3],
    opts: &FitOptions,
) -> footscan_geom::nurbs::Result<fit::FitReport> {
    let m = points.len();
    let p = opts.degree.max(1);
    if m < p + 3 {
        return fit::fit_closed_adaptive(points, opts);
    }
    let params = fit::parameters(points, opts.param, true)?;
    let n0 = (p + 3).min(m);
    let mut period: Vec<f64> = (0..n0)
        .map(|j| if j == 0 { 0.0 } else { params[j * m / n0] })
        .collect();
    let mut rounds = 0;
    loop {
        let c = fit::least_squares_closed_with_knots(points, &params, p, &period)?;
        let e: Vec<f64> = points
            .iter()
            .zip(&params)
            .map(|(q, &u)| (c.point(u) - q).norm())
            .collect();
        let max = e.iter().fold(0.0f64, |a, &x| a.max(x));
        if max <= opts.tolerance {
            let rms = (e.iter().map(|x| x * x).sum::<f64>() / m as f64).sqrt();
            return Ok(fit::FitReport {
                control_points: period.len(),
                curve: c,
                params,
                max_error: max,
                rms_error: rms,
                iterations: rounds,
                met: true,
            });
        }
        // Split every span holding a point over the tolerance at the middle of its data; a
        // span too sparse to split has its neighbours split instead (their basis functions
        // reach into it).
        let mut bounds = period.clone();
        bounds.push(1.0);
        let ns = period.len();
        let mut worst = vec![0.0f64; ns];
        let mut inside: Vec<Vec<f64>> = vec![Vec::new(); ns];
        let mut s = 0;
        for k in 0..m {
            while s + 1 < ns && params[k] >= bounds[s + 1] {
                s += 1;
            }
            worst[s] = worst[s].max(e[k]);
            if params[k] > bounds[s] && params[k] < bounds[s + 1] {
                inside[s].push(params[k]);
            }
        }
        let mut split = vec![false; ns];
        for s in 0..ns {
            if worst[s] <= opts.tolerance {
                continue;
            }
            if inside[s].len() >= 2 {
                split[s] = true;
            } else {
                for t in [(s + ns - 1) % ns, (s + 1) % ns] {
                    split[t] |= inside[t].len() >= 2;
                }
            }
        }
        let mut new: Vec<f64> = (0..ns)
            .filter(|&s| split[s])
            .map(|s| {
                let h = inside[s].len() / 2;
                0.5 * (inside[s][h - 1] + inside[s][h])
            })
            .collect();
        new.truncate(m.saturating_sub(ns));
        if new.is_empty() {
            return fit::fit_closed_adaptive(points, opts);
        }
        period.extend(new);
        period.sort_by(f64::total_cmp);
        rounds += 1;
    }
}

/// One constraint of Algorithm II: at parameter `u`, the `order`-th derivative (0: the point)
/// changes by `delta`.
#[derive(Clone, Copy, Debug)]
pub struct Constraint {
    pub name: &'static str,
    pub u: f64,
    pub order: usize,
    pub delta: V3,
}

/// Algorithm II (the paper's eq. 9): the control-point change of least squared norm that
/// gives every constraint, delta^T = R^T (R R^T)^-1 DeltaP^T. Periodic curves move their
/// unique control points (the wrapped copies follow). A rank-deficient R is an error naming
/// the curve and the first constraint that depends on the ones before it.
pub fn least_change(
    curve_name: &str,
    c: &NurbsCurve,
    cons: &[Constraint],
) -> Result<NurbsCurve, CustomizeError> {
    if c.weights.is_some() {
        return Err(CustomizeError::Curve {
            curve: curve_name.into(),
            why: "rational curve: the least-change deformation here moves polynomial ones".into(),
        });
    }
    let p = c.degree;
    let n = c.points.len();
    let nu = if c.periodic { n - p } else { n };
    let (a, b) = c.domain();
    let m = cons.len();
    let mut r = DMatrix::<f64>::zeros(m, nu);
    for (k, cs) in cons.iter().enumerate() {
        let u = if c.periodic {
            a + (cs.u - a).rem_euclid(b - a)
        } else {
            cs.u.clamp(a, b)
        };
        let span = find_span(n - 1, p, u, &c.knots);
        let ders = ders_basis_funs(span, u, p, cs.order.min(p), &c.knots);
        if cs.order > p {
            continue;
        }
        for (j, v) in ders[cs.order].iter().enumerate() {
            r[(k, (span - p + j) % nu)] += v;
        }
    }
    // Rank check: a Cholesky factor whose pivots stay clear of zero; only when it fails is
    // the set searched (incrementally) for the constraint that depends on the ones before.
    let rrt = &r * r.transpose();
    let scale = (0..m)
        .map(|i| rrt[(i, i)])
        .fold(0.0f64, f64::max)
        .max(1e-300);
    let dp = DMatrix::from_fn(m, 3, |i, j| cons[i].delta[j]);
    let chol = rrt.clone().cholesky().filter(|ch| {
        let l = ch.l_dirty();
        (0..m).all(|i| l[(i, i)] * l[(i, i)] > 1e-10 * scale)
    });
    let Some(chol) = chol else {
        for k in 1..=m {
            let sub = rrt.view((0, 0), (k, k)).clone_owned();
            let sv = sub.singular_values();
            let smin = sv.iter().cloned().fold(f64::MAX, f64::min);
            if smin <= 1e-10 * scale {
                return Err(CustomizeError::RankDeficient {
                    curve: curve_name.into(),
                    constraint: cons[k - 1].name.into(),
                });
            }
        }
        return Err(CustomizeError::RankDeficient {
            curve: curve_name.into(),
            constraint: "(the set as a whole)".into(),
        });
    };
    let delta = r.transpose() * chol.solve(&dp);
    let mut out = c.clone();
    for i in 0..n {
        let d = delta.row(i % nu);
        out.points[i] += V3::new(d[0], d[1], d[2]);
    }
    Ok(out)
}

/// Parameter of the curve point closest to `q`.
pub fn param_of(c: &NurbsCurve, q: &P3) -> f64 {
    c.closest_point(q).u
}

/// Secant search for the scalar `t` where `f(t) = 0`, starting from 0 and `t1`.
pub fn secant(
    mut f: impl FnMut(f64) -> Result<f64, CustomizeError>,
    t1: f64,
) -> Result<f64, CustomizeError> {
    let (mut x0, mut x1) = (0.0, t1);
    let (mut f0, mut f1) = (f(x0)?, f(x1)?);
    for _ in 0..30 {
        if f1.abs() < 1e-4 || (f1 - f0).abs() < 1e-14 {
            break;
        }
        let x2 = x1 - f1 * (x1 - x0) / (f1 - f0);
        x0 = x1;
        f0 = f1;
        x1 = x2;
        f1 = f(x1)?;
    }
    Ok(x1)
}
