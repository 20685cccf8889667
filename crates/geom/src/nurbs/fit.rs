//! Curve fitting: global interpolation (open, with optional end derivatives, and closed
//! periodic), least squares with fixed ends, and the adaptive least-squares fit that inserts
//! knots where the error is largest until a tolerance is met (closed curves: periodic).

use super::basis::{basis_funs, ders_basis_funs, find_span};
use super::{NurbsCurve, NurbsError, Result};
use crate::{P3, V3};

/// How data points are assigned curve parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Param {
    /// Proportional to the distance between consecutive points.
    #[default]
    ChordLength,
    /// Proportional to the square root of that distance (steadier at sharp turns).
    Centripetal,
    /// Equally spaced.
    Uniform,
}

/// Parameters in [0, 1] for open data (first 0, last 1). For a closed loop (`closed`, the
/// first point not repeated at the end) the parameters lie in [0, 1) and 1 closes the loop.
pub fn parameters(points: &[P3], method: Param, closed: bool) -> Result<Vec<f64>> {
    let n = points.len();
    if n < 2 {
        return Err(NurbsError::Invalid {
            what: "parameters",
            reason: format!("{n} points; need at least 2"),
        });
    }
    let seg = |a: &P3, b: &P3| -> f64 {
        let d = (b - a).norm();
        match method {
            Param::ChordLength => d,
            Param::Centripetal => d.sqrt(),
            Param::Uniform => 1.0,
        }
    };
    let mut cum = vec![0.0; if closed { n + 1 } else { n }];
    for i in 1..cum.len() {
        cum[i] = cum[i - 1] + seg(&points[i - 1], &points[i % n]);
    }
    let total = *cum.last().unwrap();
    if !(total > 0.0 && total.is_finite()) {
        return Err(NurbsError::Invalid {
            what: "parameters",
            reason: "all points coincide (zero total chord length)".into(),
        });
    }
    let mut t: Vec<f64> = cum.iter().map(|c| c / total).collect();
    if closed {
        t.pop();
    } else {
        *t.last_mut().unwrap() = 1.0;
    }
    for i in 1..t.len() {
        if t[i] <= t[i - 1] {
            return Err(NurbsError::Invalid {
                what: "parameters",
                reason: format!("points {} and {i} coincide (repeated data point)", i - 1),
            });
        }
    }
    Ok(t)
}

/// Clamped knot vector by averaging the parameters (every interior knot is the mean of p
/// consecutive parameters), giving a well-conditioned interpolation system.
pub fn averaged_knots(params: &[f64], degree: usize) -> Vec<f64> {
    let n = params.len() - 1;
    let p = degree;
    let (a, b) = (params[0], params[n]);
    let mut k = vec![a; p + 1];
    for j in 1..=(n - p) {
        let s: f64 = params[j..j + p].iter().sum();
        k.push(s / p as f64);
    }
    k.extend(std::iter::repeat_n(b, p + 1));
    k
}

/// Dense square system solved by Gaussian elimination that skips zeros (B-spline systems are
/// banded, or banded with corners when periodic), falling back to LU with partial pivoting
/// when a pivot is too small. `a` is row-major n x n; `b` holds `nrhs` right-hand sides per
/// row. Returns the solution in the layout of `b`.
pub(crate) fn solve(
    n: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    nrhs: usize,
    what: &'static str,
) -> Result<Vec<f64>> {
    let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if scale == 0.0 || !scale.is_finite() {
        return Err(NurbsError::Singular {
            what,
            reason: "zero or non-finite matrix".into(),
        });
    }
    // Put each row's largest entry on the diagonal when that is a permutation (periodic
    // collocation has its dominant entries off the diagonal), so elimination needs no pivots.
    let arg: Vec<usize> = (0..n)
        .map(|i| {
            (0..n).fold(0, |best, j| {
                if a[i * n + j].abs() > a[i * n + best].abs() {
                    j
                } else {
                    best
                }
            })
        })
        .collect();
    let mut seen = vec![usize::MAX; n];
    let mut perm_ok = true;
    for (i, &c) in arg.iter().enumerate() {
        if seen[c] != usize::MAX {
            perm_ok = false;
            break;
        }
        seen[c] = i;
    }
    let (mut a2, mut b2) = if perm_ok {
        let mut a2 = vec![0.0; n * n];
        let mut b2 = vec![0.0; n * nrhs];
        for (c, &i) in seen.iter().enumerate() {
            a2[c * n..(c + 1) * n].copy_from_slice(&a[i * n..(i + 1) * n]);
            b2[c * nrhs..(c + 1) * nrhs].copy_from_slice(&b[i * nrhs..(i + 1) * nrhs]);
        }
        (a2, b2)
    } else {
        (a.clone(), b.clone())
    };
    // Last non-zero column of each row.
    let mut row_end: Vec<usize> = (0..n)
        .map(|i| (0..n).rev().find(|&j| a2[i * n + j] != 0.0).unwrap_or(0))
        .collect();
    let mut ok = true;
    'elim: for k in 0..n {
        let piv = a2[k * n + k];
        let row_max = (k..=row_end[k]).fold(0.0f64, |m, j| m.max(a2[k * n + j].abs()));
        if piv.abs() <= 1e-3 * row_max || piv.abs() <= 1e-14 * scale {
            ok = false;
            break 'elim;
        }
        for i in (k + 1)..n {
            let f = a2[i * n + k];
            if f == 0.0 {
                continue;
            }
            let f = f / piv;
            a2[i * n + k] = 0.0;
            for j in (k + 1)..=row_end[k] {
                a2[i * n + j] -= f * a2[k * n + j];
            }
            row_end[i] = row_end[i].max(row_end[k]);
            for r in 0..nrhs {
                b2[i * nrhs + r] -= f * b2[k * nrhs + r];
            }
        }
    }
    if ok {
        for k in (0..n).rev() {
            for r in 0..nrhs {
                let mut s = b2[k * nrhs + r];
                for j in (k + 1)..=row_end[k].max(k) {
                    s -= a2[k * n + j] * b2[j * nrhs + r];
                }
                b2[k * nrhs + r] = s / a2[k * n + k];
            }
        }
        if b2.iter().all(|x| x.is_finite()) {
            return Ok(b2);
        }
    }
    let m = nalgebra::DMatrix::from_row_slice(n, n, &a);
    let rhs = nalgebra::DMatrix::from_row_slice(n, nrhs, &b);
    let lu = m.lu();
    let x = lu.solve(&rhs).ok_or_else(|| NurbsError::Singular {
        what,
        reason: format!(
            "{n} x {n} system has no unique solution (parameters and knots do not fit)"
        ),
    })?;
    let out: Vec<f64> = (0..n)
        .flat_map(|i| (0..nrhs).map(move |r| (i, r)))
        .map(|(i, r)| x[(i, r)])
        .collect();
    if out.iter().any(|v| !v.is_finite()) {
        return Err(NurbsError::Singular {
            what,
            reason: "solution is not finite".into(),
        });
    }
    Ok(out)
}

fn to_rows(points: &[P3]) -> Vec<f64> {
    points.iter().flat_map(|p| [p.x, p.y, p.z]).collect()
}

fn from_rows(x: &[f64]) -> Vec<P3> {
    x.chunks(3).map(|c| P3::new(c[0], c[1], c[2])).collect()
}

/// Global interpolation through `points` with chord-length (or other) parameters.
pub fn interpolate(points: &[P3], degree: usize, method: Param) -> Result<NurbsCurve> {
    let t = parameters(points, method, false)?;
    interpolate_with(points, &t, degree, None)
}

/// Global interpolation at given increasing parameters, optionally with first derivatives
/// at both ends (each adds one control point). The degree is lowered to fit few points.
pub fn interpolate_with(
    points: &[P3],
    params: &[f64],
    degree: usize,
    end_derivs: Option<(V3, V3)>,
) -> Result<NurbsCurve> {
    let m = points.len();
    check_params(m, params, "interpolation")?;
    if degree == 0 {
        return Err(NurbsError::Degree {
            what: "interpolation",
            degree,
        });
    }
    let extra = if end_derivs.is_some() { 2 } else { 0 };
    let p = degree
        .min(m - 1 + extra)
        .min(if extra > 0 { m } else { m - 1 });
    if end_derivs.is_some() && p < 2 {
        return Err(NurbsError::Invalid {
            what: "interpolation",
            reason: "end derivatives need degree >= 2 and at least 2 points".into(),
        });
    }
    let nc = m + extra;
    let knots = if end_derivs.is_some() {
        // Interior knots average p consecutive parameters (m - p + 1 of them).
        let mut k = vec![params[0]; p + 1];
        for j in 0..=(m - p) {
            k.push(params[j..j + p].iter().sum::<f64>() / p as f64);
        }
        k.extend(std::iter::repeat_n(params[m - 1], p + 1));
        k
    } else {
        averaged_knots(params, p)
    };
    let mut a = vec![0.0; nc * nc];
    let mut b = vec![0.0; nc * 3];
    let mut row = 0;
    let put_point_row = |row: usize, u: f64, q: &P3, a: &mut Vec<f64>, b: &mut Vec<f64>| {
        let span = find_span(nc - 1, p, u, &knots);
        let mut nb = vec![0.0; p + 1];
        basis_funs(span, u, p, &knots, &mut nb);
        for (j, v) in nb.iter().enumerate() {
            a[row * nc + span - p + j] = *v;
        }
        b[row * 3..row * 3 + 3].copy_from_slice(&[q.x, q.y, q.z]);
    };
    put_point_row(row, params[0], &points[0], &mut a, &mut b);
    row += 1;
    if let Some((d0, _)) = end_derivs {
        let span = find_span(nc - 1, p, params[0], &knots);
        let nd = ders_basis_funs(span, params[0], p, 1, &knots);
        for j in 0..=p {
            a[row * nc + span - p + j] = nd[1][j];
        }
        b[row * 3..row * 3 + 3].copy_from_slice(&[d0.x, d0.y, d0.z]);
        row += 1;
    }
    for k in 1..m - 1 {
        put_point_row(row, params[k], &points[k], &mut a, &mut b);
        row += 1;
    }
    if let Some((_, d1)) = end_derivs {
        let u = params[m - 1];
        let span = find_span(nc - 1, p, u, &knots);
        let nd = ders_basis_funs(span, u, p, 1, &knots);
        for j in 0..=p {
            a[row * nc + span - p + j] = nd[1][j];
        }
        b[row * 3..row * 3 + 3].copy_from_slice(&[d1.x, d1.y, d1.z]);
        row += 1;
    }
    put_point_row(row, params[m - 1], &points[m - 1], &mut a, &mut b);
    let x = solve(nc, a, b, 3, "interpolation")?;
    let mut pts = from_rows(&x);
    pts[0] = points[0];
    pts[nc - 1] = points[m - 1];
    NurbsCurve::new(p, knots, pts, None)
}

fn check_params(m: usize, params: &[f64], what: &'static str) -> Result<()> {
    if m < 2 {
        return Err(NurbsError::Invalid {
            what,
            reason: format!("{m} points; need at least 2"),
        });
    }
    if params.len() != m {
        return Err(NurbsError::Invalid {
            what,
            reason: format!("{} parameters for {m} points", params.len()),
        });
    }
    for i in 1..m {
        if params[i].partial_cmp(&params[i - 1]) != Some(std::cmp::Ordering::Greater)
            || !params[i].is_finite()
        {
            return Err(NurbsError::Invalid {
                what,
                reason: format!(
                    "parameters must increase strictly: t[{i}] = {} after {}",
                    params[i],
                    params[i - 1]
                ),
            });
        }
    }
    Ok(())
}

/// Full unclamped periodic knot vector from one period's knots (`period[0]` is the domain
/// start, period length `t`).
pub(crate) fn periodic_full_knots(period: &[f64], p: usize, t: f64) -> Vec<f64> {
    let nu = period.len() as isize;
    (0..(period.len() + 2 * p + 1) as isize)
        .map(|i| {
            let j = i - p as isize;
            period[j.rem_euclid(nu) as usize] + j.div_euclid(nu) as f64 * t
        })
        .collect()
}

/// Build the periodic curve from unique control points.
fn periodic_curve(p: usize, period: &[f64], t: f64, uniq: &[P3]) -> Result<NurbsCurve> {
    let knots = periodic_full_knots(period, p, t);
    let mut pts = uniq.to_vec();
    for k in 0..p {
        pts.push(uniq[k]);
    }
    NurbsCurve::new_periodic(p, knots, pts, None)
}

/// For parameter `u` of a periodic curve with `nu` unique points: the unique indices and
/// basis values of the p + 1 functions that do not vanish.
fn periodic_basis(
    u: f64,
    p: usize,
    knots: &[f64],
    nu: usize,
    out_idx: &mut [usize],
    out_b: &mut [f64],
) {
    let (a, b) = (knots[p], knots[nu + p]);
    let u = super::norm_param(u, (a, b), true);
    let span = find_span(nu + p - 1, p, u, knots);
    basis_funs(span, u, p, knots, out_b);
    for j in 0..=p {
        out_idx[j] = (span - p + j) % nu;
    }
}

/// Closed interpolation through a loop of points (first not repeated at the end): a
/// periodic curve of the given degree, C^(p-1) everywhere, through every point.
pub fn interpolate_closed(points: &[P3], degree: usize, method: Param) -> Result<NurbsCurve> {
    let t = parameters(points, method, true)?;
    interpolate_closed_with(points, &t, degree)
}

/// Closed interpolation at given parameters in [t0, t0 + 1) (period 1).
pub fn interpolate_closed_with(points: &[P3], params: &[f64], degree: usize) -> Result<NurbsCurve> {
    let m = points.len();
    check_params(m, params, "closed interpolation")?;
    if degree == 0 {
        return Err(NurbsError::Degree {
            what: "closed interpolation",
            degree,
        });
    }
    if params[m - 1] - params[0] >= 1.0 {
        return Err(NurbsError::Invalid {
            what: "closed interpolation",
            reason: "parameters must span less than the period 1".into(),
        });
    }
    let p = degree.min(m - 1);
    if m < p + 1 {
        return Err(NurbsError::TooFewPoints {
            what: "closed interpolation",
            degree: p,
            need: p + 1,
            got: m,
        });
    }
    // Odd degree: knots at the parameters; even degree: knots midway between them.
    let period: Vec<f64> = if p % 2 == 1 {
        params.to_vec()
    } else {
        (0..m)
            .map(|i| {
                if i + 1 < m {
                    0.5 * (params[i] + params[i + 1])
                } else {
                    0.5 * (params[i] + params[0] + 1.0)
                }
            })
            .collect()
    };
    let knots = periodic_full_knots(&period, p, 1.0);
    let mut a = vec![0.0; m * m];
    let mut idx = vec![0usize; p + 1];
    let mut nb = vec![0.0; p + 1];
    for k in 0..m {
        periodic_basis(params[k], p, &knots, m, &mut idx, &mut nb);
        for j in 0..=p {
            a[k * m + idx[j]] += nb[j];
        }
    }
    let x = solve(m, a, to_rows(points), 3, "closed interpolation")?;
    periodic_curve(p, &period, 1.0, &from_rows(&x))
}

/// Result of a least-squares fit.
#[derive(Debug, Clone)]
pub struct FitReport {
    pub curve: NurbsCurve,
    /// Parameter of each data point.
    pub params: Vec<f64>,
    /// Largest and root-mean-square distance from a data point to the curve point at its
    /// parameter (an upper bound of the distance to the curve), mm.
    pub max_error: f64,
    pub rms_error: f64,
    /// Unique control points (periodic curves: without the wrapped copies).
    pub control_points: usize,
    /// Knot insertions made by the adaptive loop.
    pub iterations: usize,
    /// Whether `max_error <= tolerance`.
    pub met: bool,
}

/// Options of the adaptive least-squares fit.
#[derive(Debug, Clone, Copy)]
pub struct FitOptions {
    pub degree: usize,
    /// Maximum error to reach, mm (default 0.05).
    pub tolerance: f64,
    pub param: Param,
    /// Cap on unique control points (default: the number of data points).
    pub max_control_points: Option<usize>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            degree: 3,
            tolerance: 0.05,
            param: Param::ChordLength,
            max_control_points: None,
        }
    }
}

/// Least squares with fixed ends: the curve starts at the first point and ends at the last
/// exactly; the interior control points minimise the squared distances at the parameters.
pub fn least_squares_with_knots(
    points: &[P3],
    params: &[f64],
    degree: usize,
    knots: &[f64],
) -> Result<NurbsCurve> {
    let m = points.len();
    check_params(m, params, "least squares")?;
    let p = degree;
    let nc = knots.len() - p - 1;
    if nc > m {
        return Err(NurbsError::Invalid {
            what: "least squares",
            reason: format!("{nc} control points for {m} data points"),
        });
    }
    let (q0, qm) = (points[0], points[m - 1]);
    let nun = nc.saturating_sub(2);
    let mut pts = vec![q0; nc];
    pts[nc - 1] = qm;
    if nun > 0 {
        let mut ata = vec![0.0; nun * nun];
        let mut atb = vec![0.0; nun * 3];
        let mut nb = vec![0.0; p + 1];
        for k in 1..m - 1 {
            let u = params[k];
            let span = find_span(nc - 1, p, u, knots);
            basis_funs(span, u, p, knots, &mut nb);
            let mut r = points[k].coords;
            for j in 0..=p {
                let i = span - p + j;
                if i == 0 {
                    r -= nb[j] * q0.coords;
                } else if i == nc - 1 {
                    r -= nb[j] * qm.coords;
                }
            }
            for j in 0..=p {
                let i = span - p + j;
                if i == 0 || i == nc - 1 {
                    continue;
                }
                let ii = i - 1;
                for l in 0..=p {
                    let i2 = span - p + l;
                    if i2 == 0 || i2 == nc - 1 {
                        continue;
                    }
                    ata[ii * nun + i2 - 1] += nb[j] * nb[l];
                }
                atb[ii * 3] += nb[j] * r.x;
                atb[ii * 3 + 1] += nb[j] * r.y;
                atb[ii * 3 + 2] += nb[j] * r.z;
            }
        }
        let x = solve(nun, ata, atb, 3, "least squares")?;
        pts[1..nc - 1].copy_from_slice(&from_rows(&x));
    }
    NurbsCurve::new(p, knots.to_vec(), pts, None)
}

/// Least squares with fixed ends and `n_ctrl` control points, knots placed so every span
/// holds data (the NURBS Book's spacing rule).
pub fn least_squares(
    points: &[P3],
    params: &[f64],
    degree: usize,
    n_ctrl: usize,
) -> Result<NurbsCurve> {
    let m = points.len();
    check_params(m, params, "least squares")?;
    let p = degree.min(n_ctrl.saturating_sub(1)).max(1);
    if n_ctrl < p + 1 || n_ctrl > m {
        return Err(NurbsError::Invalid {
            what: "least squares",
            reason: format!(
                "{n_ctrl} control points: need between {} and {m} (data points)",
                p + 1
            ),
        });
    }
    let mut knots = vec![params[0]; p + 1];
    let d = m as f64 / (n_ctrl - p) as f64;
    for j in 1..(n_ctrl - p) {
        let jd = j as f64 * d;
        let i = jd.floor() as usize;
        let alpha = jd - i as f64;
        knots.push((1.0 - alpha) * params[i - 1] + alpha * params[i.min(m - 1)]);
    }
    knots.extend(std::iter::repeat_n(params[m - 1], p + 1));
    least_squares_with_knots(points, params, p, &knots)
}

fn errors(c: &NurbsCurve, points: &[P3], params: &[f64]) -> Vec<f64> {
    points
        .iter()
        .zip(params)
        .map(|(q, &u)| (c.point(u) - q).norm())
        .collect()
}

fn stats(e: &[f64]) -> (f64, f64) {
    let max = e.iter().fold(0.0f64, |m, &x| m.max(x));
    let rms = (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
    (max, rms)
}

/// Pick a new knot in the span (of `distinct` breakpoints) holding the worst data point:
/// the mean parameter of the data in that span, so no span is left without data.
fn new_knot(distinct: &[f64], params: &[f64], err: &[f64], tried: &[f64]) -> Option<f64> {
    // Spans ordered by their worst error.
    let nspan = distinct.len() - 1;
    let mut worst = vec![(0.0f64, 0usize); nspan];
    for (s, w) in worst.iter_mut().enumerate() {
        w.1 = s;
    }
    for (k, &u) in params.iter().enumerate() {
        let s = match distinct.partition_point(|&b| b <= u) {
            0 => 0,
            i => (i - 1).min(nspan - 1),
        };
        worst[s].0 = worst[s].0.max(err[k]);
    }
    worst.sort_by(|a, b| b.0.total_cmp(&a.0));
    for &(_, s) in &worst {
        let (lo, hi) = (distinct[s], distinct[s + 1]);
        let inside: Vec<f64> = params
            .iter()
            .copied()
            .filter(|&u| u > lo && u < hi)
            .collect();
        if inside.len() < 2 {
            continue;
        }
        // Split the data of the span in two halves.
        let h = inside.len() / 2;
        let x = 0.5 * (inside[h - 1] + inside[h]);
        if x > lo && x < hi && !tried.contains(&x) {
            return Some(x);
        }
    }
    None
}

/// Algorithm I of the customised-last method: least squares with fixed ends and
/// chord-length parameters, starting from the fewest control points and inserting one knot
/// at a time in the span with the largest error until the maximum error is under the
/// tolerance (or no span can take another knot).
pub fn fit_adaptive(points: &[P3], opts: &FitOptions) -> Result<FitReport> {
    let m = points.len();
    let params = parameters(points, opts.param, false)?;
    let p = opts.degree.min(m - 1).max(1);
    let cap = opts.max_control_points.unwrap_or(m).min(m);
    let mut knots = vec![0.0; p + 1];
    knots.extend(std::iter::repeat_n(1.0, p + 1));
    let mut iterations = 0;
    loop {
        let c = least_squares_with_knots(points, &params, p, &knots)?;
        let e = errors(&c, points, &params);
        let (max, rms) = stats(&e);
        let nc = c.points.len();
        let done = max <= opts.tolerance || nc >= cap;
        let distinct: Vec<f64> = c.span_breaks();
        let next = if done {
            None
        } else {
            new_knot(&distinct, &params, &e, &[])
        };
        match next {
            Some(x) => {
                let pos = knots.partition_point(|&k| k <= x);
                knots.insert(pos, x);
                iterations += 1;
            }
            None if max > opts.tolerance && nc < cap && cap >= m => {
                // No span can take another knot with data on both sides: the data is too
                // sparse for the tolerance, so interpolate it (error zero at the points).
                let c = interpolate_with(points, &params, p, None)?;
                let (max, rms) = stats(&errors(&c, points, &params));
                return Ok(FitReport {
                    control_points: c.points.len(),
                    curve: c,
                    params,
                    max_error: max,
                    rms_error: rms,
                    iterations,
                    met: max <= opts.tolerance,
                });
            }
            None => {
                return Ok(FitReport {
                    control_points: nc,
                    curve: c,
                    params,
                    max_error: max,
                    rms_error: rms,
                    iterations,
                    met: max <= opts.tolerance,
                });
            }
        }
    }
}

/// Periodic least squares for a closed loop (first point not repeated) with the given
/// period knots in [0, 1) (`period[0] = 0`).
pub fn least_squares_closed_with_knots(
    points: &[P3],
    params: &[f64],
    degree: usize,
    period: &[f64],
) -> Result<NurbsCurve> {
    let m = points.len();
    let p = degree;
    let nu = period.len();
    if nu < p + 1 || nu > m {
        return Err(NurbsError::Invalid {
            what: "closed least squares",
            reason: format!(
                "{nu} control points: need between {} and {m} (data points)",
                p + 1
            ),
        });
    }
    let knots = periodic_full_knots(period, p, 1.0);
    let mut ata = vec![0.0; nu * nu];
    let mut atb = vec![0.0; nu * 3];
    let mut idx = vec![0usize; p + 1];
    let mut nb = vec![0.0; p + 1];
    for k in 0..m {
        periodic_basis(params[k], p, &knots, nu, &mut idx, &mut nb);
        let q = points[k];
        for j in 0..=p {
            for l in 0..=p {
                ata[idx[j] * nu + idx[l]] += nb[j] * nb[l];
            }
            atb[idx[j] * 3] += nb[j] * q.x;
            atb[idx[j] * 3 + 1] += nb[j] * q.y;
            atb[idx[j] * 3 + 2] += nb[j] * q.z;
        }
    }
    let x = solve(nu, ata, atb, 3, "closed least squares")?;
    periodic_curve(p, period, 1.0, &from_rows(&x))
}

/// Adaptive least-squares fit of a closed loop (girths, sections): a periodic curve with
/// chord-length parameters, knots inserted where the error is largest until the maximum
/// error is under the tolerance.
pub fn fit_closed_adaptive(points: &[P3], opts: &FitOptions) -> Result<FitReport> {
    let m = points.len();
    let params = parameters(points, opts.param, true)?;
    let p = opts.degree.max(1);
    if m < p + 3 {
        return Err(NurbsError::TooFewPoints {
            what: "closed fit",
            degree: p,
            need: p + 3,
            got: m,
        });
    }
    let cap = opts.max_control_points.unwrap_or(m).min(m);
    let n0 = (p + 3).min(m);
    // Start: n0 knots spread over the data.
    let mut period: Vec<f64> = (0..n0)
        .map(|j| if j == 0 { 0.0 } else { params[j * m / n0] })
        .collect();
    let mut iterations = 0;
    loop {
        let c = least_squares_closed_with_knots(points, &params, p, &period)?;
        let e = errors(&c, points, &params);
        let (max, rms) = stats(&e);
        let nu = period.len();
        let done = max <= opts.tolerance || nu >= cap;
        let mut distinct = period.clone();
        distinct.dedup();
        distinct.push(1.0);
        let next = if done {
            None
        } else {
            new_knot(&distinct, &params, &e, &[])
        };
        match next {
            Some(x) => {
                let pos = period.partition_point(|&k| k <= x);
                period.insert(pos, x);
                iterations += 1;
            }
            None if max > opts.tolerance && nu < cap && cap >= m => {
                // Too sparse for another knot with data on both sides: interpolate.
                let c = interpolate_closed_with(points, &params, p)?;
                let (max, rms) = stats(&errors(&c, points, &params));
                return Ok(FitReport {
                    control_points: c.points.len() - c.degree,
                    curve: c,
                    params,
                    max_error: max,
                    rms_error: rms,
                    iterations,
                    met: max <= opts.tolerance,
                });
            }
            None => {
                return Ok(FitReport {
                    control_points: nu,
                    curve: c,
                    params,
                    max_error: max,
                    rms_error: rms,
                    iterations,
                    met: max <= opts.tolerance,
                });
            }
        }
    }
}
