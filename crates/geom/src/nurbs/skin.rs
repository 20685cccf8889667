//! Compatible curves (common degree and knots), skinning (lofting) a surface through section
//! curves at given parameters, and interpolation of a grid of points into a surface.

use super::basis::{basis_funs, find_span};
use super::fit::{averaged_knots, periodic_full_knots, SparseRows};
use super::hcurve::H;
use super::{NurbsCurve, NurbsError, NurbsSurface, Result};
use crate::P3;

/// Knots equal within this (relative to the domain) are treated as one.
const KNOT_TOL: f64 = 1e-9;

/// The knots that define the spline space: strictly interior knots of an open vector, or one
/// period (domain start included) of a periodic one.
pub(crate) fn inner_knots(knots: &[f64], p: usize, n: usize, periodic: bool) -> Vec<f64> {
    if periodic {
        knots[p..n].to_vec()
    } else {
        knots[p + 1..n].to_vec()
    }
}

/// Union of several inner knot lists, each value with its largest multiplicity (values
/// within the tolerance merged; the value kept is the one of the earliest list). Sorting the
/// runs of all lists keeps this O(N log N) in the total number of knots.
pub(crate) fn merged_knots<'a>(
    it: impl Iterator<Item = (&'a [f64], usize, usize, bool)>,
) -> Vec<f64> {
    // (value, multiplicity, list index) of every run of equal knots.
    let mut runs: Vec<(f64, usize, usize)> = Vec::new();
    for (list, (knots, p, n, periodic)) in it.enumerate() {
        let inner = inner_knots(knots, p, n, periodic);
        let mut i = 0;
        while i < inner.len() {
            let v = inner[i];
            let mut j = i;
            while j < inner.len() && (inner[j] - v).abs() <= KNOT_TOL {
                j += 1;
            }
            runs.push((v, j - i, list));
            i = j;
        }
    }
    runs.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.2.cmp(&b.2)));
    let mut out = Vec::new();
    let mut i = 0;
    while i < runs.len() {
        let first = runs[i].0;
        let mut j = i;
        let (mut mult, mut rep) = (0, runs[i]);
        while j < runs.len() && runs[j].0 - first <= KNOT_TOL {
            mult = mult.max(runs[j].1);
            if runs[j].2 < rep.2 {
                rep = runs[j];
            }
            j += 1;
        }
        out.extend(std::iter::repeat_n(rep.0, mult));
        i = j;
    }
    out
}

/// Knots of `merged` missing from `own` (by value within the tolerance, with multiplicity).
/// Both are sorted, so each value's count in `own` is found by bisection.
pub(crate) fn missing_knots(own: &[f64], merged: &[f64]) -> Vec<f64> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < merged.len() {
        let v = merged[i];
        let mut j = i;
        while j < merged.len() && merged[j] == v {
            j += 1;
        }
        let lo = own.partition_point(|&x| x < v - KNOT_TOL);
        let hi = own.partition_point(|&x| x <= v + KNOT_TOL);
        let have = hi - lo;
        for _ in have..(j - i) {
            out.push(v);
        }
        i = j;
    }
    out
}

/// Bring curves to one degree (by elevation), one domain [0, 1] and one knot vector (by
/// refinement). All must be open or all periodic. Shapes are unchanged.
pub fn make_compatible(curves: &[NurbsCurve]) -> Result<Vec<NurbsCurve>> {
    if curves.is_empty() {
        return Ok(vec![]);
    }
    let periodic = curves[0].periodic;
    if let Some(i) = curves.iter().position(|c| c.periodic != periodic) {
        return Err(NurbsError::Incompatible {
            what: "curves",
            reason: format!(
                "curve {i} is {} but curve 0 is not",
                if periodic { "open" } else { "periodic" }
            ),
        });
    }
    let p = curves.iter().map(|c| c.degree).max().unwrap();
    let mut v: Vec<NurbsCurve> = curves
        .iter()
        .map(|c| c.reparametrized_unit().elevate_degree(p - c.degree))
        .collect();
    let merged = merged_knots(
        v.iter()
            .map(|c| (&c.knots[..], c.degree, c.points.len(), periodic)),
    );
    for c in v.iter_mut() {
        let own = inner_knots(&c.knots, c.degree, c.points.len(), periodic);
        let x = missing_knots(&own, &merged);
        *c = c.refine_knots(&x)?;
    }
    // Snap to one knot vector (values that matched within the tolerance).
    let k0 = v[0].knots.clone();
    for (i, c) in v.iter_mut().enumerate() {
        if c.knots.len() != k0.len() {
            return Err(NurbsError::Incompatible {
                what: "curves",
                reason: format!(
                    "curve {i} ended with {} knots, curve 0 with {}",
                    c.knots.len(),
                    k0.len()
                ),
            });
        }
        c.knots.clone_from(&k0);
    }
    Ok(v)
}

/// Chord-length skinning parameters: the mean distance between corresponding control
/// points of consecutive sections, normalised to [0, 1].
pub fn skinning_params(sections: &[NurbsCurve]) -> Result<Vec<f64>> {
    let k = sections.len();
    let mut d = vec![0.0; k];
    for s in 1..k {
        let (a, b) = (&sections[s - 1].points, &sections[s].points);
        let step: f64 = a.iter().zip(b).map(|(x, y)| (y - x).norm()).sum::<f64>() / a.len() as f64;
        d[s] = d[s - 1] + step;
    }
    let total = d[k - 1];
    if total.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(NurbsError::Invalid {
            what: "skinning",
            reason: "all sections coincide".into(),
        });
    }
    Ok(d.iter().map(|x| x / total).collect())
}

/// Solve one interpolation system for many right-hand sides in homogeneous form: rows are
/// data sites, `rhs[k]` the values at site k (one H per column). Returns control values.
fn interp_many(
    params: &[f64],
    p: usize,
    knots: &[f64],
    rhs: &[Vec<H>],
    what: &'static str,
) -> Result<Vec<Vec<H>>> {
    let n = params.len();
    let ncol = rhs[0].len();
    let mut a = SparseRows::new(n);
    let mut nb = vec![0.0; p + 1];
    for (k, &u) in params.iter().enumerate() {
        let span = find_span(n - 1, p, u, knots);
        basis_funs(span, u, p, knots, &mut nb);
        for j in 0..=p {
            a.add(k, span - p + j, nb[j]);
        }
    }
    let b: Vec<f64> = rhs
        .iter()
        .flat_map(|row| row.iter().flat_map(|h| [h.x, h.y, h.z, h.w]))
        .collect();
    let x = a.solve(b, 4 * ncol, what)?;
    Ok(x.chunks(4 * ncol)
        .map(|r| {
            r.chunks(4)
                .map(|c| H::new(c[0], c[1], c[2], c[3]))
                .collect()
        })
        .collect())
}

/// Periodic version of [`interp_many`]: sites in [t0, t0 + 1), period 1.
fn interp_many_periodic(
    params: &[f64],
    p: usize,
    rhs: &[Vec<H>],
    what: &'static str,
) -> Result<(Vec<f64>, Vec<Vec<H>>)> {
    let m = params.len();
    let ncol = rhs[0].len();
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
    let mut a = SparseRows::new(m);
    let mut nb = vec![0.0; p + 1];
    let (lo, hi) = (knots[p], knots[m + p]);
    for (k, &u) in params.iter().enumerate() {
        let u = super::norm_param(u, (lo, hi), true);
        let span = find_span(m + p - 1, p, u, &knots);
        basis_funs(span, u, p, &knots, &mut nb);
        for j in 0..=p {
            a.add(k, (span - p + j) % m, nb[j]);
        }
    }
    let b: Vec<f64> = rhs
        .iter()
        .flat_map(|row| row.iter().flat_map(|h| [h.x, h.y, h.z, h.w]))
        .collect();
    let x = a.solve(b, 4 * ncol, what)?;
    let mut rows: Vec<Vec<H>> = x
        .chunks(4 * ncol)
        .map(|r| {
            r.chunks(4)
                .map(|c| H::new(c[0], c[1], c[2], c[3]))
                .collect()
        })
        .collect();
    for k in 0..p {
        let r = rows[k].clone();
        rows.push(r);
    }
    Ok((knots, rows))
}

fn check_increasing(t: &[f64], what: &'static str) -> Result<()> {
    for i in 1..t.len() {
        if t[i].partial_cmp(&t[i - 1]) != Some(std::cmp::Ordering::Greater) {
            return Err(NurbsError::Invalid {
                what,
                reason: format!(
                    "parameters must increase strictly: {} after {}",
                    t[i],
                    t[i - 1]
                ),
            });
        }
    }
    Ok(())
}

/// Skin (loft) a surface through section curves: S(u, v_k) = C_k(u). Sections are made
/// compatible first (their u domain becomes [0, 1]); closed (periodic) sections give a
/// periodic u direction. `v` gives the section parameters (increasing), or `None` for
/// chord-length ones on [0, 1]. `degree_v` is lowered when there are few sections.
pub fn skin(sections: &[NurbsCurve], v: Option<&[f64]>, degree_v: usize) -> Result<NurbsSurface> {
    let k = sections.len();
    if k < 2 {
        return Err(NurbsError::Invalid {
            what: "skinning",
            reason: format!("{k} sections; need at least 2"),
        });
    }
    let secs = make_compatible(sections)?;
    let vp = match v {
        Some(v) => {
            if v.len() != k {
                return Err(NurbsError::Invalid {
                    what: "skinning",
                    reason: format!("{} v parameters for {k} sections", v.len()),
                });
            }
            v.to_vec()
        }
        None => skinning_params(&secs)?,
    };
    check_increasing(&vp, "skinning")?;
    let q = degree_v.min(k - 1).max(1);
    let knots_v = averaged_knots(&vp, q);
    let nu = secs[0].points.len();
    // rhs[k][i] = homogeneous control point i of section k.
    let rhs: Vec<Vec<H>> = secs.iter().map(|c| c.to_h().pw).collect();
    let ctrl = interp_many(&vp, q, &knots_v, &rhs, "skinning")?; // ctrl[j][i]
    let rational = secs.iter().any(|c| c.weights.is_some());
    let mut points = Vec::with_capacity(nu * k);
    let mut weights = Vec::with_capacity(nu * k);
    for i in 0..nu {
        for row in &ctrl {
            let h = row[i];
            points.push(P3::new(h.x / h.w, h.y / h.w, h.z / h.w));
            weights.push(h.w);
        }
    }
    let s = NurbsSurface {
        degree_u: secs[0].degree,
        degree_v: q,
        knots_u: secs[0].knots.clone(),
        knots_v,
        nu,
        nv: k,
        points,
        weights: rational.then_some(weights),
        periodic_u: secs[0].periodic,
        periodic_v: false,
    };
    s.validate()?;
    Ok(s)
}

/// Interpolate a grid of points: `grid[k * nl + l]` is reached at (u_k, v_l). With
/// `periodic_u` the rows k form closed loops (u in [u_0, u_0 + 1), first not repeated).
/// Each direction is interpolated in turn with knots by averaging (or the periodic rule).
pub fn interpolate_grid(
    grid: &[P3],
    u: &[f64],
    v: &[f64],
    degree_u: usize,
    degree_v: usize,
    periodic_u: bool,
) -> Result<NurbsSurface> {
    let (nk, nl) = (u.len(), v.len());
    if grid.len() != nk * nl {
        return Err(NurbsError::GridSize {
            what: "grid interpolation",
            nu: nk,
            nv: nl,
            expected: nk * nl,
            got: grid.len(),
        });
    }
    if nk < 2 || nl < 2 {
        return Err(NurbsError::Invalid {
            what: "grid interpolation",
            reason: format!("{nk} x {nl} grid; need 2 x 2"),
        });
    }
    check_increasing(u, "grid interpolation u")?;
    check_increasing(v, "grid interpolation v")?;
    let p = degree_u.min(nk - 1).max(1);
    let q = degree_v.min(nl - 1).max(1);
    // Along u first: one system for every column l.
    let rhs: Vec<Vec<H>> = (0..nk)
        .map(|k| {
            (0..nl)
                .map(|l| {
                    let g = grid[k * nl + l];
                    H::new(g.x, g.y, g.z, 1.0)
                })
                .collect()
        })
        .collect();
    let (knots_u, r) = if periodic_u {
        if u[nk - 1] - u[0] >= 1.0 {
            return Err(NurbsError::Invalid {
                what: "grid interpolation",
                reason: "periodic u must span less than 1".into(),
            });
        }
        interp_many_periodic(u, p, &rhs, "grid interpolation u")?
    } else {
        let ku = averaged_knots(u, p);
        let r = interp_many(u, p, &ku, &rhs, "grid interpolation u")?;
        (ku, r)
    };
    let nu = r.len();
    // Then along v: sites v_l, one column per control row i.
    let knots_v = averaged_knots(v, q);
    let rhs_v: Vec<Vec<H>> = (0..nl)
        .map(|l| (0..nu).map(|i| r[i][l]).collect())
        .collect();
    let c = interp_many(v, q, &knots_v, &rhs_v, "grid interpolation v")?; // c[j][i]
    let mut points = Vec::with_capacity(nu * nl);
    for i in 0..nu {
        for row in &c {
            points.push(P3::from(row[i].xyz()));
        }
    }
    let s = NurbsSurface {
        degree_u: p,
        degree_v: q,
        knots_u,
        knots_v,
        nu,
        nv: nl,
        points,
        weights: None,
        periodic_u,
        periodic_v: false,
    };
    s.validate()?;
    Ok(s)
}

/// Skin through sections that form a closed sequence (the last section is followed by the
/// first again): S(u, v_k) = C_k(u) with v periodic of period 1; `v` in [v_0, v_0 + 1).
/// Used for the guide-curve term of a Gordon surface over closed sections.
pub fn skin_closed(sections: &[NurbsCurve], v: &[f64], degree_v: usize) -> Result<NurbsSurface> {
    let k = sections.len();
    if k < 3 {
        return Err(NurbsError::Invalid {
            what: "closed skinning",
            reason: format!("{k} sections; need at least 3"),
        });
    }
    if v.len() != k {
        return Err(NurbsError::Invalid {
            what: "closed skinning",
            reason: format!("{} v parameters for {k} sections", v.len()),
        });
    }
    check_increasing(v, "closed skinning")?;
    if v[k - 1] - v[0] >= 1.0 {
        return Err(NurbsError::Invalid {
            what: "closed skinning",
            reason: "v must span less than the period 1".into(),
        });
    }
    let secs = make_compatible(sections)?;
    let q = degree_v.min(k - 1).max(1);
    let rhs: Vec<Vec<H>> = secs.iter().map(|c| c.to_h().pw).collect();
    let (knots_v, ctrl) = interp_many_periodic(v, q, &rhs, "closed skinning")?;
    let nu = secs[0].points.len();
    let nv = ctrl.len();
    let rational = secs.iter().any(|c| c.weights.is_some());
    let mut points = Vec::with_capacity(nu * nv);
    let mut weights = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        for row in &ctrl {
            let h = row[i];
            points.push(P3::new(h.x / h.w, h.y / h.w, h.z / h.w));
            weights.push(h.w);
        }
    }
    let s = NurbsSurface {
        degree_u: secs[0].degree,
        degree_v: q,
        knots_u: secs[0].knots.clone(),
        knots_v,
        nu,
        nv,
        points,
        weights: rational.then_some(weights),
        periodic_u: secs[0].periodic,
        periodic_v: true,
    };
    s.validate()?;
    Ok(s)
}
