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
    /// Corners of the data given a knot of multiplicity 3 (C0 joints).
    pub corners: usize,
    /// Simple knots added to the starting ones, over `refits` least-squares solves.
    pub knots_inserted: usize,
    pub refits: usize,
    /// Stretches between corners interpolated on their own (no span there left to split).
    pub stretches_interpolated: usize,
    /// Whether the whole loop had to be interpolated.
    pub interpolated: bool,
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
    let (r, s) = fit_closed_split(&data, &opts).map_err(|e| CustomizeError::Curve {
        curve: name.into(),
        why: format!("fit: {e}", e = footscan_util::Chain(&e)),
    })?;
    let rec = FitRecord {
        curve: name,
        data_points: data.len(),
        control_points: r.control_points,
        max_error_mm: r.max_error,
        rms_error_mm: r.rms_error,
        corners: s.corners,
        knots_inserted: s.inserted,
        refits: r.iterations + 1,
        stretches_interpolated: s.stretches,
        interpolated: s.interpolated,
        met: r.met,
    };
    Ok((r.curve, rec))
}

/// Algorithm I for a closed loop with every span over the tolerance split at once (at the
/// middle of its data) per round, instead of one knot per refit as
/// [`fit::fit_closed_adaptive`] does: the same periodic least squares with chord-length
/// parameters, in a handful of refits rather than one per control point (a girth took 9 ms,
/// the side profile 60-150 ms).
///
/// Corners of the data (a turn of more than [`CORNER_DEG`] at one point: where a cut leaves
/// the glass, where the leg is cut off, the toe pads' creases in the side profile) get a knot
/// of multiplicity p, so the curve may turn there with C0 continuity; a cubic forced round
/// them needs a control point per data point nearby (the 260 mm foot's side profile ended in
/// interpolation through all 595 points). A bad span too sparse to split has its nearest
/// splittable neighbours within p spans split instead (their basis functions reach into
/// it); when none is left, the stretch between its corners is interpolated on its own, and
/// only a loop without corners is interpolated whole (docs/method.md 10.2).
pub fn fit_closed_split(
    points: &[P3],
    opts: &FitOptions,
) -> footscan_geom::nurbs::Result<(fit::FitReport, SplitStats)> {
    let m = points.len();
    let p = opts.degree.max(1);
    if m < p + 3 {
        let r = fit::fit_closed_adaptive(points, opts)?;
        let st = SplitStats {
            corners: 0,
            inserted: r.iterations,
            stretches: 0,
            interpolated: r.control_points == m,
        };
        return Ok((r, st));
    }
    let params = fit::parameters(points, opts.param, true)?;
    let corners = if p > 1 {
        corner_indices(points, p)
    } else {
        Vec::new()
    };
    let mut period: Vec<f64> = Vec::new();
    for &i in &corners {
        period.extend(std::iter::repeat_n(params[i], p));
    }
    // Starting knots spread over the data, one per ten points (every foot curve here needs
    // at least that many, and the first refits would only find so), away from the corners'
    // knots.
    let n0 = (m / 10).max(p + 3).min(m);
    for j in 0..n0 {
        let i = j * m / n0;
        let near = corners.iter().any(|&c| {
            let d = c.abs_diff(i);
            d.min(m - d) <= p
        });
        if !near {
            period.push(params[i]);
        }
    }
    period.sort_by(f64::total_cmp);
    let corner_u: Vec<f64> = corners.iter().map(|&i| params[i]).collect();
    // The period starts at parameter 0 (a corner there already holds it).
    if period.first() != Some(&0.0) {
        period.insert(0, 0.0);
    }
    let start = period.len() - p * corners.len();
    let mut stats = SplitStats {
        corners: corners.len(),
        inserted: 0,
        stretches: 0,
        interpolated: false,
    };
    let mut rounds = 0;
    let mut exact: Vec<usize> = Vec::new();
    loop {
        if period.len() > m {
            stats.interpolated = true;
            stats.inserted = m.saturating_sub(start);
            let r = interpolate_report(points, params, p, rounds, opts.tolerance)?;
            return Ok((r, stats));
        }
        let (c, e) = fit::least_squares_closed_residuals(points, &params, p, &period)?;
        let (max, rms) = fit::error_stats(&e);
        if max <= opts.tolerance {
            stats.inserted = period.len() - p * corners.len() - start;
            let r = fit::FitReport {
                control_points: period.len(),
                curve: c,
                params,
                max_error: max,
                rms_error: rms,
                iterations: rounds,
                met: true,
            };
            return Ok((r, stats));
        }
        // Spans between distinct knots: the worst error and the data strictly inside each.
        let mut bounds = period.clone();
        bounds.dedup();
        bounds.push(1.0);
        let ns = bounds.len() - 1;
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
        // Pieces per span: a cubic's error falls as the fourth power of the span, so a span
        // e times over the tolerance is cut in e^(1/4) pieces at once (at least two, at most
        // one per data point); a bad span too sparse to cut has its nearest cuttable
        // neighbours within p spans halved (their basis functions reach into it).
        let mut pieces = vec![1usize; ns];
        for s in 0..ns {
            if worst[s] <= opts.tolerance {
                continue;
            }
            let want = ((worst[s] / opts.tolerance)
                .powf(1.0 / (p + 1) as f64)
                .ceil() as usize)
                .max(2);
            if inside[s].len() >= 2 {
                pieces[s] = pieces[s].max(want.min(inside[s].len()));
                continue;
            }
            // Only spans within p of it carry basis functions that reach into it.
            for reach in 1..=p.min(ns / 2) {
                let mut found = false;
                for t in [(s + ns - reach % ns) % ns, (s + reach) % ns] {
                    if inside[t].len() >= 2 {
                        pieces[t] = pieces[t].max(2);
                        found = true;
                    }
                }
                if found {
                    break;
                }
            }
        }
        let mut cand: Vec<(f64, f64)> = Vec::new();
        for s in 0..ns {
            let (d, k) = (inside[s].len(), pieces[s]);
            for j in 1..k {
                let i = j * d / k;
                cand.push((0.5 * (inside[s][i - 1] + inside[s][i]), worst[s]));
            }
        }
        // Between two corners with d data points inside, k simple knots leave p + k - 1
        // basis functions that see only those points: k may not pass d + 1 - p (beyond it
        // the system is singular). The worst spans' knots go in first.
        cand.sort_by(|a, b| b.1.total_cmp(&a.1));
        let mut room = segment_room(&corner_u, &params, &period, p);
        let mut new: Vec<f64> = Vec::new();
        for (x, _) in cand {
            let g = segment_of(&corner_u, x);
            if room[g] > 0 {
                room[g] -= 1;
                new.push(x);
            }
        }
        new.truncate(m.saturating_sub(period.len()));
        if new.is_empty() {
            // Stuck: every bad span has a point or none inside and no room near it. A
            // stretch between corners is then interpolated on its own (its knots replaced
            // by the averages of its data's parameters, corners as clamped ends: exact
            // there, the rest untouched); a loop without corners, or a stretch already so
            // treated, is interpolated whole.
            let mut segs: Vec<usize> = (0..m)
                .filter(|&k| e[k] > opts.tolerance)
                .map(|k| segment_of(&corner_u, params[k]))
                .collect();
            segs.sort_unstable();
            segs.dedup();
            if corner_u.is_empty() || segs.iter().any(|g| exact.contains(g)) {
                stats.interpolated = true;
                stats.inserted = m.saturating_sub(start);
                let r = interpolate_report(points, params, p, rounds, opts.tolerance)?;
                return Ok((r, stats));
            }
            for g in segs {
                period = interpolate_stretch(&period, &corner_u, &params, p, g);
                exact.push(g);
                stats.stretches += 1;
            }
            rounds += 1;
            continue;
        }
        period.extend(new);
        period.sort_by(f64::total_cmp);
        rounds += 1;
    }
}

/// How [`fit_closed_split`] got there.
#[derive(Clone, Copy, Debug)]
pub struct SplitStats {
    pub corners: usize,
    /// Simple knots added to the starting ones.
    pub inserted: usize,
    /// Stretches between corners interpolated on their own.
    pub stretches: usize,
    pub interpolated: bool,
}

/// Smallest turn (degrees) between the chords into and out of a data point that makes it a
/// corner of the fit (knot of multiplicity p). A flat bottom's edge turns 90 degrees; a
/// girth's roundest turn on points 1 mm apart is a few degrees.
pub const CORNER_DEG: f64 = 30.0;

/// Data points where the loop turns by more than [`CORNER_DEG`], each the sharpest within
/// p + 1 points either way (corner knots closer than that would leave a basis function with
/// no data under it).
fn corner_indices(points: &[P3], p: usize) -> Vec<usize> {
    let m = points.len();
    let cos_min = CORNER_DEG.to_radians().cos();
    let turn: Vec<f64> = (0..m)
        .map(|i| {
            let a = points[i] - points[(i + m - 1) % m];
            let b = points[(i + 1) % m] - points[i];
            let d = a.norm() * b.norm();
            if d < 1e-12 {
                1.0
            } else {
                a.dot(&b) / d
            }
        })
        .collect();
    let w = p + 1;
    let mut out: Vec<usize> = (0..m)
        .filter(|&i| turn[i] < cos_min)
        .filter(|&i| {
            (1..=w).all(|k| {
                let (l, r) = (turn[(i + m - k) % m], turn[(i + k) % m]);
                // Sharpest wins; a tie goes to the earlier point.
                turn[i] < l && turn[i] <= r
            })
        })
        .collect();
    // Never so many that the corners' knots alone would take half the data.
    out.truncate(m / (2 * p));
    out
}

/// Which stretch between corners (parameters `corner_u`, ascending) holds `u`; the one
/// before the first corner and the one after the last are the same on the loop.
fn segment_of(corner_u: &[f64], u: f64) -> usize {
    match corner_u.partition_point(|&c| c < u) {
        i if i == corner_u.len() => 0,
        i => i,
    }
}

/// How many simple knots each stretch between corners may still take (see
/// [`fit_closed_split`]); without corners, the whole loop may take one per data point.
fn segment_room(corner_u: &[f64], params: &[f64], period: &[f64], p: usize) -> Vec<usize> {
    if corner_u.is_empty() {
        return vec![params.len().saturating_sub(period.len())];
    }
    let n = corner_u.len();
    let is_corner = |u: f64| corner_u.contains(&u);
    let mut data = vec![0usize; n];
    for &u in params.iter().filter(|&&u| !is_corner(u)) {
        data[segment_of(corner_u, u)] += 1;
    }
    let mut knots = vec![0usize; n];
    for &u in period.iter().filter(|&&u| !is_corner(u)) {
        knots[segment_of(corner_u, u)] += 1;
    }
    (0..n)
        .map(|g| (data[g] + 1).saturating_sub(p + knots[g]))
        .collect()
}

/// `period` with the simple knots of stretch `g` (between two corners) replaced by the
/// knots that interpolate its data: with the corners as clamped ends, d points inside give
/// d + 1 - p knots, each the mean of p consecutive parameters (de Boor's averaging, which
/// keeps the system nonsingular).
fn interpolate_stretch(
    period: &[f64],
    corner_u: &[f64],
    params: &[f64],
    p: usize,
    g: usize,
) -> Vec<f64> {
    let n = corner_u.len();
    // The stretch from corner g - 1 to corner g (stretch 0 wraps through the period's end).
    let lo = corner_u[(g + n - 1) % n];
    let hi = if g == 0 {
        corner_u[0] + 1.0
    } else {
        corner_u[g]
    };
    let unwrap = |u: f64| if u < lo { u + 1.0 } else { u };
    let mut us: Vec<f64> = params
        .iter()
        .map(|&u| unwrap(u))
        .filter(|&u| u > lo && u < hi)
        .collect();
    us.sort_by(f64::total_cmp);
    let mut all = vec![lo];
    all.extend(us);
    all.push(hi);
    let inner = (all.len() - 1).saturating_sub(p);
    let new = (1..=inner).map(|j| (all[j..j + p].iter().sum::<f64>() / p as f64).rem_euclid(1.0));
    let is_corner = |u: f64| corner_u.contains(&u);
    let mut out: Vec<f64> = period
        .iter()
        .copied()
        .filter(|&u| is_corner(u) || segment_of(corner_u, u) != g)
        .chain(new)
        .collect();
    out.sort_by(f64::total_cmp);
    out
}

/// The fit's last resort: the loop interpolated (error nil, a control point per point).
fn interpolate_report(
    points: &[P3],
    params: Vec<f64>,
    p: usize,
    rounds: usize,
    tol: f64,
) -> footscan_geom::nurbs::Result<fit::FitReport> {
    let c = fit::interpolate_closed_with(points, &params, p)?;
    let (max, rms) = fit::error_stats(&fit::errors(&c, points, &params));
    Ok(fit::FitReport {
        control_points: points.len(),
        curve: c,
        params,
        max_error: max,
        rms_error: rms,
        iterations: rounds,
        met: max <= tol,
    })
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
    // R's non-zeros (row, unique control point, value): p + 1 per constraint.
    let mut entries: Vec<(usize, usize, f64)> = Vec::with_capacity(m * (p + 1));
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
            entries.push((k, (span - p + j) % nu, *v));
        }
    }
    // The change of each unique control point (row i of `delta`), given to its wrapped copies.
    let moved = |delta: &dyn Fn(usize) -> V3| {
        let mut out = c.clone();
        for i in 0..n {
            out.points[i] += delta(i % nu);
        }
        out
    };
    // As many constraints as free control points (the collocation the frame uses): R is
    // square, R^T (R R^T)^-1 = R^-1, and R is a cyclic band, so eq. 9 is one sparse solve
    // in time linear in the size. Should R be singular, the dense path below names the
    // constraint.
    if m == nu {
        let mut sr = footscan_geom::nurbs::fit::SparseRows::new(nu);
        for &(k, j, v) in &entries {
            sr.add(k, j, v);
        }
        let rhs: Vec<f64> = cons
            .iter()
            .flat_map(|c| [c.delta.x, c.delta.y, c.delta.z])
            .collect();
        if let Ok(x) = sr.solve(rhs, 3, "least change") {
            return Ok(moved(&|j| V3::new(x[3 * j], x[3 * j + 1], x[3 * j + 2])));
        }
    }
    let mut r = DMatrix::<f64>::zeros(m, nu);
    for &(k, j, v) in &entries {
        r[(k, j)] += v;
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
    Ok(moved(&|j| {
        V3::new(delta[(j, 0)], delta[(j, 1)], delta[(j, 2)])
    }))
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed polyline through `corners`, sampled every `step` mm along each side.
    fn polygon(corners: &[(f64, f64)], step: f64) -> Vec<P3> {
        let mut out = Vec::new();
        for i in 0..corners.len() {
            let (a, b) = (corners[i], corners[(i + 1) % corners.len()]);
            let len = ((b.0 - a.0).powi(2) + (b.1 - a.1).powi(2)).sqrt();
            let n = (len / step).round() as usize;
            for k in 0..n {
                let t = k as f64 / n as f64;
                out.push(P3::new(a.0 + (b.0 - a.0) * t, 0.0, a.1 + (b.1 - a.1) * t));
            }
        }
        out
    }

    /// A section with right-angled corners (a flat bottom's): each corner gets a knot of
    /// multiplicity 3, the fit meets the tolerance with a few control points per side and
    /// runs through the corners; before, the corners drove the fit to interpolate every point.
    #[test]
    fn corners_get_c0_knots_not_interpolation() {
        let rect = polygon(&[(0.0, 0.0), (80.0, 0.0), (80.0, 30.0), (0.0, 30.0)], 1.0);
        let (c, r) = fit_loop("rectangle", &rect, 1.0, 0.05).unwrap();
        assert!(r.met && r.max_error_mm <= 0.05, "{r:?}");
        assert_eq!(r.corners, 4, "{r:?}");
        assert!(!r.interpolated, "{r:?}");
        assert!(
            r.control_points < 40,
            "{} control points for 220 points",
            r.control_points
        );
        for q in [(80.0, 0.0), (80.0, 30.0), (0.0, 30.0)] {
            let q = P3::new(q.0, 0.0, q.1);
            let d = (c.point(c.closest_point(&q).u) - q).norm();
            assert!(d < 0.05, "corner {q:?} missed by {d} mm");
        }
    }

    /// A stretch between corners whose spans are too sparse to split is interpolated on
    /// its own: with its knots from [`interpolate_stretch`] the least squares is exact on
    /// that stretch's points (noise of +-0.1 mm along one side here, under the corner angle) and nonsingular.
    #[test]
    fn a_stretch_between_corners_interpolates_its_points() {
        let mut pts = polygon(&[(0.0, 0.0), (80.0, 0.0), (80.0, 30.0), (0.0, 30.0)], 1.0);
        let mut s = 7u64;
        for q in pts.iter_mut() {
            if q.z == 30.0 && q.x > 0.5 && q.x < 79.5 {
                s = s
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                q.z += 0.2 * ((s >> 11) as f64 / (1u64 << 53) as f64) - 0.1;
            }
        }
        let p = 3;
        let params = fit::parameters(&pts, footscan_geom::nurbs::Param::ChordLength, true).unwrap();
        let corners = corner_indices(&pts, p);
        let corner_u: Vec<f64> = corners.iter().map(|&i| params[i]).collect();
        // The top side's corners (80, 30) and (0, 30) are found among the turns.
        let top = |u: f64| {
            let k = params.iter().position(|&x| x == u).unwrap();
            pts[k]
        };
        let g = (0..corner_u.len())
            .find(|&g| {
                let (a, b) = (
                    top(corner_u[(g + corner_u.len() - 1) % corner_u.len()]),
                    top(corner_u[g]),
                );
                (a.x - 80.0).abs() < 1e-9
                    && (a.z - 30.0).abs() < 1e-9
                    && b.x.abs() < 1e-9
                    && (b.z - 30.0).abs() < 1e-9
            })
            .expect("the top side between two corners");
        let mut period: Vec<f64> = corner_u.iter().flat_map(|&u| [u; 3]).collect();
        period.extend((1..12).map(|j| params[j * pts.len() / 12]));
        period.retain(|u| corner_u.contains(u) || corner_u.iter().all(|c| (c - u).abs() > 0.02));
        period.sort_by(f64::total_cmp);
        let period = interpolate_stretch(&period, &corner_u, &params, p, g);
        let (_, res) = fit::least_squares_closed_residuals(&pts, &params, p, &period).unwrap();
        let worst_top = pts
            .iter()
            .zip(&res)
            .filter(|(q, _)| q.z > 29.0 && q.x > 0.5 && q.x < 79.5)
            .map(|(_, r)| *r)
            .fold(0.0, f64::max);
        assert!(worst_top < 1e-6, "top stretch residual {worst_top} mm");
    }

    /// Eq. 9 with as many constraints as control points goes through the sparse square solve;
    /// the curve then meets every constraint.
    #[test]
    fn least_change_square_meets_every_constraint() {
        let pts: Vec<P3> = (0..200)
            .map(|i| {
                let t = i as f64 / 200.0 * std::f64::consts::TAU;
                P3::new(50.0 * t.cos(), 30.0 * t.sin(), 3.0 * (3.0 * t).sin())
            })
            .collect();
        let (c, _) = fit_loop("ellipse", &pts, 1.0, 0.05).unwrap();
        let nu = c.points.len() - c.degree;
        let (a, b) = c.domain();
        let cons: Vec<Constraint> = (0..nu)
            .map(|i| {
                let g = c.knots[i + 1..=i + c.degree].iter().sum::<f64>() / c.degree as f64;
                let u = a + (g - a).rem_euclid(b - a);
                Constraint {
                    name: "node",
                    u,
                    order: 0,
                    delta: V3::new(0.5 * (i as f64 * 0.7).sin(), 0.3, -0.2),
                }
            })
            .collect();
        let d = least_change("ellipse", &c, &cons).unwrap();
        for k in &cons {
            let moved = d.point(k.u) - c.point(k.u);
            assert!(
                (moved - k.delta).norm() < 1e-9,
                "{}: {moved:?} vs {:?}",
                k.u,
                k.delta
            );
        }
    }
}
