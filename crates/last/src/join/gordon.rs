//! Gordon surface through a compatible curve network, closed around the sections.
//!
//! The network is a set of closed section curves C_k(u) and open guide curves G_i(v) that
//! cross at common parameters: C_k(u_i) = G_i(v_k) for every pair. Gordon's Boolean sum
//!
//!   S = S_sections + S_guides - T
//!
//! interpolates every curve of the network: S_sections skins the sections at the v_k (a
//! spline interpolation in v), S_guides skins the guides at the u_i (a periodic spline
//! interpolation in u), and T interpolates the grid of crossing points with the same two
//! interpolations, so it cancels what each skin adds along the other family. The three are
//! brought to common degrees and knots and summed control point by control point.
//!
//! footscan-geom skins open families only; the periodic skin across the guides (the guides'
//! control points interpolated around u with the knots of T) is written here.

use footscan_geom::nurbs::basis::{basis_funs, find_span};
use footscan_geom::nurbs::fit::interpolate_with;
use footscan_geom::nurbs::skin::skin;
use footscan_geom::nurbs::{make_surfaces_compatible, NurbsCurve, NurbsError, NurbsSurface};
use footscan_geom::P3;

/// A compatible curve network.
#[derive(Debug, Clone)]
pub struct Network {
    /// Closed (periodic) sections with one degree and knot vector, u domain [0, 1].
    pub sections: Vec<NurbsCurve>,
    /// Guide parameters on the sections: increasing in [0, 1).
    pub u_cross: Vec<f64>,
    /// Open guides with one degree and knot vector, v domain [0, 1].
    pub guides: Vec<NurbsCurve>,
    /// Section parameters on the guides: increasing, 0 first and 1 last.
    pub v_cross: Vec<f64>,
}

/// The Gordon surface and its three parts (all on common knots).
#[derive(Debug, Clone)]
pub struct Gordon {
    pub surface: NurbsSurface,
    pub s_sections: NurbsSurface,
    pub s_guides: NurbsSurface,
    pub tensor: NurbsSurface,
    /// Largest distance between C_k(u_i) and G_i(v_k) over the network, mm.
    pub network_mismatch: f64,
}

/// Build the Gordon surface of a compatible network. Fails when the curves do not meet at
/// their common parameters (by more than `tol` mm) or a construction step fails.
pub fn gordon(net: &Network, tol: f64) -> Result<Gordon, NurbsError> {
    let (m, k) = (net.guides.len(), net.sections.len());
    if m < 3 || k < 2 {
        return Err(NurbsError::Invalid {
            what: "Gordon network",
            reason: format!("{k} sections and {m} guides; need at least 2 and 3"),
        });
    }
    if net.u_cross.len() != m || net.v_cross.len() != k {
        return Err(NurbsError::Invalid {
            what: "Gordon network",
            reason: format!(
                "{} u parameters for {m} guides, {} v parameters for {k} sections",
                net.u_cross.len(),
                net.v_cross.len()
            ),
        });
    }
    // Crossing grid, row i = guide i (periodic direction u), column k = section k.
    let mut grid = Vec::with_capacity(m * k);
    let mut mismatch = 0.0f64;
    for (i, g) in net.guides.iter().enumerate() {
        for (s, c) in net.sections.iter().enumerate() {
            let a = c.point(net.u_cross[i]);
            let b = g.point(net.v_cross[s]);
            mismatch = mismatch.max((a - b).norm());
            grid.push(P3::from((a.coords + b.coords) * 0.5));
        }
    }
    if mismatch > tol {
        return Err(NurbsError::Incompatible {
            what: "Gordon network",
            reason: format!(
                "sections and guides miss each other by up to {mismatch:.3e} mm at their \
                 common parameters (tolerance {tol:.1e} mm)"
            ),
        });
    }
    let s1 = skin(&net.sections, Some(&net.v_cross), 3)?;
    // T = the periodic u interpolation of the v interpolants of the grid's rows: the same
    // two operators as the skins use.
    let p = 3;
    let knots_u = periodic_knots(&net.u_cross, p);
    let rows: Vec<NurbsCurve> = (0..m)
        .map(|i| interpolate_with(&grid[i * k..(i + 1) * k], &net.v_cross, 3, None))
        .collect::<Result<_, _>>()?;
    let t = skin_periodic_u(&rows, &net.u_cross, &knots_u, p)?;
    let s2 = skin_periodic_u(&net.guides, &net.u_cross, &knots_u, p)?;
    let v = make_surfaces_compatible(&[s1, s2, t])?;
    let surface = v[0].try_add(&v[1])?.try_sub(&v[2])?;
    let mut it = v.into_iter();
    Ok(Gordon {
        surface,
        s_sections: it.next().unwrap(),
        s_guides: it.next().unwrap(),
        tensor: it.next().unwrap(),
        network_mismatch: mismatch,
    })
}

/// Full unclamped periodic knot vector (period 1) for interpolation at `u` with odd degree
/// `p`: the knots are the sites themselves, extended by the period on both sides.
pub fn periodic_knots(u: &[f64], p: usize) -> Vec<f64> {
    let m = u.len() as isize;
    (0..(u.len() + 2 * p + 1) as isize)
        .map(|i| {
            let j = i - p as isize;
            u[j.rem_euclid(m) as usize] + j.div_euclid(m) as f64
        })
        .collect()
}

/// Skin compatible open curves around a periodic u direction: S(u_i, v) = G_i(v), with the
/// given periodic u knot vector (full, unclamped, period 1) of degree `p`.
pub fn skin_periodic_u(
    guides: &[NurbsCurve],
    u: &[f64],
    knots_u: &[f64],
    p: usize,
) -> Result<NurbsSurface, NurbsError> {
    let m = guides.len();
    let nu = m + p;
    if knots_u.len() != nu + p + 1 {
        return Err(NurbsError::Invalid {
            what: "periodic skin",
            reason: format!("{} knots for {m} curves of degree {p}", knots_u.len()),
        });
    }
    let g0 = &guides[0];
    if let Some(i) = guides
        .iter()
        .position(|g| g.knots != g0.knots || g.degree != g0.degree || g.weights.is_some())
    {
        return Err(NurbsError::Incompatible {
            what: "periodic skin",
            reason: format!("guide {i} differs from guide 0 in degree or knots, or is rational"),
        });
    }
    let nv = g0.points.len();
    let mut a = nalgebra::DMatrix::<f64>::zeros(m, m);
    let mut nb = vec![0.0; p + 1];
    let (lo, hi) = (knots_u[p], knots_u[m + p]);
    for (i, &ui) in u.iter().enumerate() {
        let ui = lo + (ui - lo).rem_euclid(hi - lo);
        let span = find_span(nu - 1, p, ui, knots_u);
        basis_funs(span, ui, p, knots_u, &mut nb);
        for (j, &b) in nb.iter().enumerate() {
            a[(i, (span - p + j) % m)] += b;
        }
    }
    let mut rhs = nalgebra::DMatrix::<f64>::zeros(m, 3 * nv);
    for (i, g) in guides.iter().enumerate() {
        for (j, q) in g.points.iter().enumerate() {
            for c in 0..3 {
                rhs[(i, 3 * j + c)] = q[c];
            }
        }
    }
    let lu = a.lu();
    let x = lu.solve(&rhs).ok_or_else(|| NurbsError::Singular {
        what: "periodic skin",
        reason: "collocation matrix".into(),
    })?;
    let mut points = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        let r = i % m;
        for j in 0..nv {
            points.push(P3::new(x[(r, 3 * j)], x[(r, 3 * j + 1)], x[(r, 3 * j + 2)]));
        }
    }
    NurbsSurface::new(
        p,
        g0.degree,
        knots_u.to_vec(),
        g0.knots.clone(),
        nu,
        nv,
        points,
        None,
    )?
    .with_periodic(true, false)
}

/// The iso-curve S(u, v0) of a non-rational surface as a curve in u (exact).
pub fn iso_v(s: &NurbsSurface, v0: f64) -> NurbsCurve {
    let q = s.degree_v;
    let (a, b) = s.domain_v();
    let v0 = v0.clamp(a, b);
    let span = find_span(s.nv - 1, q, v0, &s.knots_v);
    let mut nb = vec![0.0; q + 1];
    basis_funs(span, v0, q, &s.knots_v, &mut nb);
    let points = (0..s.nu)
        .map(|i| {
            let mut acc = nalgebra::Vector3::zeros();
            for (j, &w) in nb.iter().enumerate() {
                acc += w * s.point_ij(i, span - q + j).coords;
            }
            P3::from(acc)
        })
        .collect();
    NurbsCurve {
        degree: s.degree_u,
        knots: s.knots_u.clone(),
        points,
        weights: None,
        periodic: s.periodic_u,
    }
}

/// The iso-curve S(u0, v) of a non-rational surface as a curve in v (exact).
pub fn iso_u(s: &NurbsSurface, u0: f64) -> NurbsCurve {
    let p = s.degree_u;
    let (a, b) = s.domain_u();
    let u0 = if s.periodic_u {
        a + (u0 - a).rem_euclid(b - a)
    } else {
        u0.clamp(a, b)
    };
    let span = find_span(s.nu - 1, p, u0, &s.knots_u);
    let mut nb = vec![0.0; p + 1];
    basis_funs(span, u0, p, &s.knots_u, &mut nb);
    let points = (0..s.nv)
        .map(|j| {
            let mut acc = nalgebra::Vector3::zeros();
            for (i, &w) in nb.iter().enumerate() {
                acc += w * s.point_ij(span - p + i, j).coords;
            }
            P3::from(acc)
        })
        .collect();
    NurbsCurve {
        degree: s.degree_v,
        knots: s.knots_v.clone(),
        points,
        weights: None,
        periodic: s.periodic_v,
    }
}

/// Split a non-rational surface open in v at `v0` (strictly inside the domain) into the part
/// below and the part above, each clamped at the cut (exact: knot insertion to full
/// multiplicity, then the control net divided).
pub fn split_v(s: &NurbsSurface, v0: f64) -> Result<(NurbsSurface, NurbsSurface), NurbsError> {
    let q = s.degree_v;
    let have = s.knots_v.iter().filter(|&&x| x == v0).count();
    let r = s.insert_knot_v(v0, q.saturating_sub(have));
    // Snap knots within round-off of v0 to v0.
    let a = r
        .knots_v
        .iter()
        .position(|&x| (x - v0).abs() <= 1e-12)
        .ok_or_else(|| NurbsError::Invalid {
            what: "surface split",
            reason: format!("v = {v0} not found after insertion"),
        })?;
    let mut kl: Vec<f64> = r.knots_v[..a + q].to_vec();
    kl.push(v0);
    for x in kl.iter_mut().skip(a) {
        *x = v0;
    }
    let mut kr = vec![v0];
    kr.extend_from_slice(&r.knots_v[a..]);
    for x in kr.iter_mut().take(q + 1) {
        *x = v0;
    }
    let (nl, nr) = (a, r.nv - a + 1);
    let mut pl = Vec::with_capacity(r.nu * nl);
    let mut pr = Vec::with_capacity(r.nu * nr);
    for i in 0..r.nu {
        for j in 0..nl {
            pl.push(r.point_ij(i, j));
        }
        for j in a - 1..r.nv {
            pr.push(r.point_ij(i, j));
        }
    }
    let mk = |kv: Vec<f64>, nv: usize, pts: Vec<P3>| {
        NurbsSurface::new(r.degree_u, q, r.knots_u.clone(), kv, r.nu, nv, pts, None)?
            .with_periodic(r.periodic_u, false)
    };
    Ok((mk(kl, nl, pl)?, mk(kr, nr, pr)?))
}

/// The network of consecutive sections `range` alone: those sections, and guides
/// re-interpolated (cubic, as in the join) through their crossings on them at the section
/// parameters rescaled to [0, 1]. This is the main and auxiliary sections' network of the
/// paper when `range` covers them; a reference implementation can build it too.
pub fn sub_network(net: &Network, range: std::ops::Range<usize>) -> Result<Network, NurbsError> {
    if range.len() < 2 || range.end > net.sections.len() {
        return Err(NurbsError::Invalid {
            what: "sub-network",
            reason: format!(
                "sections {range:?} of {}; need at least 2 inside",
                net.sections.len()
            ),
        });
    }
    let sections: Vec<NurbsCurve> = net.sections[range.clone()].to_vec();
    let (v0, v1) = (net.v_cross[range.start], net.v_cross[range.end - 1]);
    let v_cross: Vec<f64> = net.v_cross[range]
        .iter()
        .map(|v| (v - v0) / (v1 - v0))
        .collect();
    let guides = net
        .u_cross
        .iter()
        .map(|&u| {
            let pts: Vec<P3> = sections.iter().map(|c| c.point(u)).collect();
            interpolate_with(&pts, &v_cross, 3, None)
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Network {
        sections,
        u_cross: net.u_cross.clone(),
        guides,
        v_cross,
    })
}
