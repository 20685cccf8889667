//! Kept parts that stay the lasts they came from (issue 36).
//!
//! Resurfacing a kept part through its planar sections moves it off its mesh by up to 0.9 mm
//! (the sharp top rim, the toe tip, long facets): the back a last maker chose is then not the
//! back he gets. So each kept part is refitted by least squares to points spread over its
//! own facets (not only the sections), starting from the section surface's parameters and
//! a fifth of its u knots ([`SPANS_U`]), and knots are added in u and v in the spans where
//! the surface still strays more than [`TOL_MM`] from the mesh until none does. The join patch is then bent to meet the fitted
//! parts ([`meet`]): by default their position and tangent plane along the whole seam, the
//! change to the patch confined to a band next to each seam ([`Continuity::G1`]). The closed STL keeps the original meshes
//! themselves outside the join region, trimmed at the planes ([`trim`]) and stitched to the
//! patch ([`zip`]).

// Tensor-product index loops read closer to the formulas.
#![allow(clippy::needless_range_loop)]

use super::JoinError;
use footscan_geom::mesh::{Bvh, TriMesh};
use footscan_geom::nurbs::basis::{basis_funs, ders_basis_funs, find_span};
use footscan_geom::nurbs::{make_surfaces_compatible, NurbsSurface};
use footscan_geom::plane::Plane;
use footscan_geom::{P3, V3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::time::Instant;

/// Largest distance of a fitted kept part from its mesh, mm.
pub const TOL_MM: f64 = 0.1;
/// Spacing of the points sampled on the facets, mm.
const SAMPLE_MM: f64 = 1.0;
/// Fits at most (the first on the coarse knots, then one per refinement).
const ROUNDS: usize = 6;
/// Weight of the control net's second differences against the mean diagonal of the
/// normal matrix.
const SMOOTH: f64 = 1e-2;
/// The conjugate gradients stop when each coordinate's residual is below this fraction of
/// its right-hand side. (1e-5 halved the solves' time, but the RoundTip back's seam then
/// left the original last by 0.056 mm instead of 0.048: the pinned end curves are the
/// stiffest part of the system and the last to converge.)
const CG_TOL: f64 = 1e-7;
/// Weight of a point of the pinned end curves against a facet point.
const END_WEIGHT: f64 = 20.0;
/// Weight of the second differences around of the fitted part's first control row
/// differences at the cut against their fit ([`fair_cut`]). At 10 the parts within 3 v spans
/// of the cut stay as near their meshes as before on a dense grid (2000 x 31: 0.070 -> 0.065,
/// 0.080 -> 0.080, 0.098 -> 0.098, 0.076 -> 0.076 mm); at 30 the RoundTip back went to
/// 0.104 mm there, at 100 to 0.111 (docs/method.md 11.7.4).
const CUT_SMOOTH: f64 = 10.0;

/// The fit's constants, hashed into its cache key ([`super::fit_cache::key`]).
pub fn rules() -> [f64; 8] {
    [
        TOL_MM,
        SAMPLE_MM,
        ROUNDS as f64,
        SMOOTH,
        END_WEIGHT,
        SPANS_U as f64,
        CG_TOL,
        CUT_SMOOTH,
    ]
}

/// How a kept part was fitted and how far it is from its mesh.
#[derive(Debug, Clone, Copy, Default, Serialize, Deserialize)]
pub struct PartFit {
    /// Read from the fit cache ([`super::fit_cache`]): the figures are the stored fit's, `ms`
    /// its time when it was made.
    #[serde(default)]
    pub cached: bool,
    /// Points on the facets fitted.
    pub samples: usize,
    /// Fits made (the first on the section surface's knots, then one per refinement).
    pub rounds: usize,
    /// Knot spans around and along.
    pub spans_u: usize,
    pub spans_v: usize,
    /// Surface to mesh on a grid of 2 x 4 points per knot span of the section surface, mm: max, rms, and where the
    /// max lies (and its distance from the cutting plane, negative inside the part).
    pub max_mm: f64,
    pub rms_mm: f64,
    pub max_at: P3,
    pub max_from_plane_mm: f64,
    /// Largest distance of a fitted facet point from the surface, mm.
    pub points_max_mm: f64,
    /// Time of the fit, ms, and where it went: the facet points, the mesh's tree and the
    /// points' parameters (`setup_ms`), the least-squares solves and the checks against the
    /// mesh.
    pub ms: f64,
    pub setup_ms: f64,
    pub solve_ms: f64,
    pub check_ms: f64,
}

/// Points every [`SAMPLE_MM`] over the facets that `keep` accepts.
fn facet_points(mesh: &TriMesh, keep: &dyn Fn(&P3) -> bool) -> Vec<P3> {
    let mut out = Vec::new();
    for t in 0..mesh.triangles.len() {
        let [a, b, c] = mesh.corners(t);
        if !(keep(&a) || keep(&b) || keep(&c)) {
            continue;
        }
        if keep(&a) {
            out.push(a);
        }
        // Points spread by area (a long thin facet gets few): k per side for about one point
        // per SAMPLE_MM^2.
        let area = 0.5 * (b - a).cross(&(c - a)).norm();
        let k = ((2.0 * area).sqrt() / SAMPLE_MM).ceil() as usize;
        for i in 1..k {
            for j in 1..k - i {
                let (s, r) = (i as f64 / k as f64, j as f64 / k as f64);
                let p = a + (b - a) * s + (c - a) * r;
                if keep(&p) {
                    out.push(p);
                }
            }
        }
    }
    out
}

/// Finds the parameters of the nearest surface point: a tessellation's nearest triangle
/// gives the start, Gauss-Newton the rest.
struct Locator {
    bvh: Bvh,
    params: Vec<[(f64, f64); 3]>,
    corners: Vec<[P3; 3]>,
}

impl Locator {
    fn new(s: &NurbsSurface, nu: usize, nv: usize) -> Locator {
        let (u0, u1) = s.domain_u();
        let (v0, v1) = s.domain_v();
        let uu = |i: usize| u0 + (u1 - u0) * i as f64 / nu as f64;
        let vv = |j: usize| v0 + (v1 - v0) * j as f64 / nv as f64;
        let mut verts = Vec::with_capacity(nu * (nv + 1));
        for i in 0..nu {
            for j in 0..=nv {
                verts.push(s.point(uu(i), vv(j)));
            }
        }
        let id = |i: usize, j: usize| ((i % nu) * (nv + 1) + j) as u32;
        let mut tris = Vec::new();
        let mut params = Vec::new();
        for i in 0..nu {
            for j in 0..nv {
                let (a, b) = ((uu(i), vv(j)), (uu(i + 1), vv(j)));
                let (c, d) = ((uu(i + 1), vv(j + 1)), (uu(i), vv(j + 1)));
                tris.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                params.push([a, b, c]);
                tris.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
                params.push([a, c, d]);
            }
        }
        let m = TriMesh::new(verts, tris);
        let corners = (0..m.triangles.len()).map(|t| m.corners(t)).collect();
        Locator {
            bvh: Bvh::new(&m),
            params,
            corners,
        }
    }

    fn locate(&self, s: &NurbsSurface, p: &P3) -> (f64, f64) {
        let c = self
            .bvh
            .closest_point(p)
            .expect("a tessellation has triangles");
        let [a, b, d] = self.corners[c.triangle];
        let (e0, e1, e2) = (b - a, d - a, c.point - a);
        let (d00, d01, d11) = (e0.dot(&e0), e0.dot(&e1), e1.dot(&e1));
        let (d20, d21) = (e2.dot(&e0), e2.dot(&e1));
        let den = (d00 * d11 - d01 * d01).max(1e-300);
        let wb = ((d11 * d20 - d01 * d21) / den).clamp(0.0, 1.0);
        let wd = ((d00 * d21 - d01 * d20) / den).clamp(0.0, 1.0 - wb);
        let q = self.params[c.triangle];
        let mut u = q[0].0 + wb * (q[1].0 - q[0].0) + wd * (q[2].0 - q[0].0);
        let mut v = q[0].1 + wb * (q[1].1 - q[0].1) + wd * (q[2].1 - q[0].1);
        project(s, p, &mut u, &mut v, 5);
        (u, v)
    }
}

/// Gauss-Newton steps toward the foot point of `p` on `s` from (u, v), at most `steps` (v
/// clamped to the domain, u wrapped around it), ending once a step is under 1e-10.
pub fn project(s: &NurbsSurface, p: &P3, u: &mut f64, v: &mut f64, steps: usize) {
    let (u0, u1) = s.domain_u();
    let (v0, v1) = s.domain_v();
    for _ in 0..steps {
        let d = s.derivatives(*u, *v, 1);
        let r = p - P3::from(d[0][0]);
        let (su, sv) = (d[1][0], d[0][1]);
        let (a, b, c) = (su.dot(&su), su.dot(&sv), sv.dot(&sv));
        let (ru, rv) = (su.dot(&r), sv.dot(&r));
        let det = a * c - b * b;
        if det.abs() < 1e-300 {
            break;
        }
        let du = (c * ru - b * rv) / det;
        let dv = (a * rv - b * ru) / det;
        *u += du;
        *v = (*v + dv).clamp(v0, v1);
        *u = u0 + (*u - u0).rem_euclid(u1 - u0);
        if du.abs() < 1e-10 && dv.abs() < 1e-10 {
            break;
        }
    }
}

/// The non-zero basis products of one point: the first control index of each of the four
/// columns around (independent columns, wrapped) and the basis values around and along. The
/// 16 weights are the products `bu[a] * bv[b]`, at control `col[a] + b`; computed when used,
/// a row is 64 bytes where the 16 indices and weights were 256, and the conjugate gradients
/// stream every row once per product.
struct Row {
    col: [u32; 4],
    bu: [f64; 4],
    bv: [f64; 4],
}

impl Row {
    #[inline]
    fn each(&self, mut f: impl FnMut(usize, f64)) {
        for a in 0..4 {
            let c = self.col[a] as usize;
            for b in 0..4 {
                f(c + b, self.bu[a] * self.bv[b]);
            }
        }
    }
}

fn basis_row(s: &NurbsSurface, u: f64, v: f64) -> Row {
    let (p, q) = (s.degree_u, s.degree_v);
    debug_assert!(p == 3 && q == 3);
    let m = s.nu - p;
    let su = find_span(s.nu - 1, p, u, &s.knots_u);
    let sv = find_span(s.nv - 1, q, v, &s.knots_v);
    let mut r = Row {
        col: [0; 4],
        bu: [0.0; 4],
        bv: [0.0; 4],
    };
    basis_funs(su, u, p, &s.knots_u, &mut r.bu);
    basis_funs(sv, v, q, &s.knots_v, &mut r.bv);
    for a in 0..4 {
        r.col[a] = (((su - p + a) % m) * s.nv + sv - q) as u32;
    }
    r
}

/// Least squares of the control points to the facet points at their parameters, with a small
/// pull towards the current control points (it holds spans that few points reach), solved by
/// conjugate gradients from the current points. The normal matrix is never formed: each
/// product goes through the points' basis rows and the net's second differences, which read
/// a few MB where the assembled 7 x 7 neighbour blocks were 72 MB per product on a LastScan
/// back (500 x 371 spans) and the solve spent its time streaming them.
fn solve(s: &NurbsSurface, pts: &[P3], uv: &[(f64, f64)], wt: &[f64], tol: f64) -> NurbsSurface {
    let m = s.nu - s.degree_u;
    let n = m * s.nv;
    let nv = s.nv;
    let rows: Vec<Row> = uv.iter().map(|&(u, v)| basis_row(s, u, v)).collect();
    let mut diag = vec![0.0f64; n];
    let mut rhs = vec![V3::zeros(); n];
    for ((r, p), &g) in rows.iter().zip(pts).zip(wt) {
        r.each(|i, w| {
            rhs[i] += g * w * p.coords;
            diag[i] += g * w * w;
        });
    }
    let mean_diag = diag.iter().sum::<f64>() / n as f64;
    let mu = 1e-3 * mean_diag.max(1e-12);
    // Second differences of the control net around and along, a little: they keep the net
    // from rippling between the facet points where knots are denser than the points.
    let lam = SMOOTH * mean_diag.max(1e-12);
    // Every second-difference stencil once (the two neighbours and the centre), around and
    // along, visited in place rather than listed (a list was 5 MB read once per product).
    let stencils = |f: &mut dyn FnMut([usize; 3])| {
        for i in 0..m {
            let (im, ip) = ((i + m - 1) % m, (i + 1) % m);
            for j in 0..nv {
                f([im * nv + j, i * nv + j, ip * nv + j]);
                if j >= 1 && j + 1 < nv {
                    f([i * nv + j - 1, i * nv + j, i * nv + j + 1]);
                }
            }
        }
    };
    stencils(&mut |st| {
        diag[st[0]] += lam;
        diag[st[1]] += 4.0 * lam;
        diag[st[2]] += lam;
    });
    let x0: Vec<V3> = (0..n).map(|i| s.points[i].coords).collect();
    for i in 0..n {
        diag[i] += mu;
        rhs[i] += mu * x0[i];
    }
    // (Two threads, each over half the points, made the solves 1.1-3 times slower on this
    // shared two-core machine: each product waits for the slower half.)
    let matvec = |x: &[V3], y: &mut [V3]| {
        for (yi, xi) in y.iter_mut().zip(x) {
            *yi = mu * xi;
        }
        for (r, &g) in rows.iter().zip(wt) {
            let mut sum = V3::zeros();
            r.each(|i, w| sum += w * x[i]);
            sum *= g;
            r.each(|i, w| y[i] += w * sum);
        }
        stencils(&mut |st| {
            let d = lam * (x[st[0]] - 2.0 * x[st[1]] + x[st[2]]);
            y[st[0]] += d;
            y[st[1]] -= 2.0 * d;
            y[st[2]] += d;
        });
    };
    // Jacobi-preconditioned conjugate gradients, the three coordinates side by side.
    let mut x = x0.clone();
    let mut ax = vec![V3::zeros(); n];
    matvec(&x, &mut ax);
    let mut r: Vec<V3> = rhs.iter().zip(&ax).map(|(b, q)| b - q).collect();
    let mut z: Vec<V3> = r.iter().zip(&diag).map(|(r, d)| r / *d).collect();
    let mut d = z.clone();
    let dot3 = |a: &[V3], b: &[V3]| -> V3 {
        a.iter()
            .zip(b)
            .fold(V3::zeros(), |s, (x, y)| s + x.component_mul(y))
    };
    let mut rz = dot3(&r, &z);
    let b_norm = dot3(&rhs, &rhs).map(|x| x.sqrt().max(1e-300));
    let mut ad = vec![V3::zeros(); n];
    for _ in 0..80 {
        matvec(&d, &mut ad);
        let dad = dot3(&d, &ad);
        let alpha = rz.zip_map(&dad, |a, b| if b > 0.0 { a / b } else { 0.0 });
        for i in 0..n {
            x[i] += d[i].component_mul(&alpha);
            r[i] -= ad[i].component_mul(&alpha);
        }
        let rn = dot3(&r, &r).map(f64::sqrt);
        if (0..3).all(|c| rn[c] <= tol * b_norm[c]) {
            break;
        }
        for i in 0..n {
            z[i] = r[i] / diag[i];
        }
        let rz1 = dot3(&r, &z);
        let beta = rz1.zip_map(&rz, |a, b| if b > 0.0 { a / b } else { 0.0 });
        rz = rz1;
        for i in 0..n {
            d[i] = z[i] + d[i].component_mul(&beta);
        }
    }
    let mut out = s.clone();
    for i in 0..s.nu {
        for j in 0..s.nv {
            out.points[i * s.nv + j] = P3::from(x[(i % m) * s.nv + j]);
        }
    }
    out
}

/// Knot spans around of the fit before refinement: the section surface has one per section
/// point (500), more than the facet points can hold (a net that needs heavy smoothing, a big
/// solve, and normals that wiggle along the cut).
const SPANS_U: usize = 100;

/// `s0` on every `step`-th of its own u knots (so the union with the patch's knots, taken in
/// [`meet`], stays the patch's): each row of control points along u, a periodic curve, fitted
/// by least squares at 4 points per fine span. The v knots and rows stay.
fn coarse_u(s0: &NurbsSurface, step: usize) -> NurbsSurface {
    let p = s0.degree_u;
    let (u0, u1) = s0.domain_u();
    let period = u1 - u0;
    let fine = distinct(&s0.knots_u, u0, u1);
    let nf = fine.len() - 1;
    let mut dom: Vec<f64> = (0..nf).step_by(step.max(1)).map(|i| fine[i]).collect();
    dom.push(u1);
    let mc = dom.len() - 1;
    let mut knots: Vec<f64> = (0..p).map(|i| dom[mc - p + i] - period).collect();
    knots.extend(&dom);
    knots.extend((0..p).map(|k| dom[1 + k] + period));
    let nu = mc + p;
    let nv = s0.nv;
    let mut ata = nalgebra::DMatrix::<f64>::zeros(mc, mc);
    let mut atb = nalgebra::DMatrix::<f64>::zeros(mc, 3 * nv);
    let mut b = [0.0; 4];
    let mut bf = [0.0; 4];
    let mf = s0.nu - p;
    for w in fine.windows(2) {
        for f in [0.125, 0.375, 0.625, 0.875] {
            let u = w[0] + f * (w[1] - w[0]);
            let sp = find_span(nu - 1, p, u, &knots);
            basis_funs(sp, u, p, &knots, &mut b);
            let spf = find_span(s0.nu - 1, p, u, &s0.knots_u);
            basis_funs(spf, u, p, &s0.knots_u, &mut bf);
            let idx: Vec<usize> = (0..=p).map(|a| (sp - p + a) % mc).collect();
            for a in 0..=p {
                for c in 0..=p {
                    ata[(idx[a], idx[c])] += b[a] * b[c];
                }
            }
            for j in 0..nv {
                let mut q = V3::zeros();
                for a in 0..=p {
                    q += bf[a] * s0.points[((spf - p + a) % mf) * nv + j].coords;
                }
                for a in 0..=p {
                    for k in 0..3 {
                        atb[(idx[a], 3 * j + k)] += b[a] * q[k];
                    }
                }
            }
        }
    }
    let x = nalgebra::Cholesky::new(ata)
        .expect("a periodic B-spline fit with points in every span is positive definite")
        .solve(&atb);
    let mut pts = Vec::with_capacity(nu * nv);
    for i in 0..nu {
        for j in 0..nv {
            let r = i % mc;
            pts.push(P3::new(x[(r, 3 * j)], x[(r, 3 * j + 1)], x[(r, 3 * j + 2)]));
        }
    }
    NurbsSurface::new(p, s0.degree_v, knots, s0.knots_v.clone(), nu, nv, pts, None)
        .and_then(|s| s.with_periodic(true, false))
        .expect("the coarse surface keeps the section surface's form")
}

/// A knot in each u span of `s` that holds a point of `bad` (a u parameter): the knot of
/// `fine` (the section surface's) nearest the middle, or the middle where the span has none
/// inside (the sharp top rim needs spans finer than one per section point: 0.167 mm on the
/// LastScan back without them, 0.089 with).
fn split_u(s: &NurbsSurface, fine: &[f64], bad: &[f64]) -> Vec<f64> {
    let ku = distinct(&s.knots_u, s.domain_u().0, s.domain_u().1);
    let mut hit = vec![false; ku.len() - 1];
    for &u in bad {
        let j = ku.partition_point(|&k| k <= u).clamp(1, ku.len() - 1) - 1;
        hit[j] = true;
    }
    let mut out = Vec::new();
    for (j, _) in hit.iter().enumerate().filter(|(_, &h)| h) {
        let (a, b) = (ku[j], ku[j + 1]);
        let mid = 0.5 * (a + b);
        if let Some(&k) = fine
            .iter()
            .filter(|&&k| k > a + 1e-12 && k < b - 1e-12)
            .min_by(|x, y| (*x - mid).abs().total_cmp(&(*y - mid).abs()))
        {
            out.push(k);
        } else {
            out.push(mid);
        }
    }
    out
}

/// Distance of `s` from the mesh on 2 points per knot span around and 4 per span of the
/// section surface along (a distance over 5 mm counts as 5 mm).
struct Check {
    /// Grid points further than half the tolerance: parameters and the mesh's nearest point.
    far: Vec<((f64, f64), P3)>,
    max: f64,
    rms: f64,
    at: P3,
    /// The surface at each grid point and its distance from the mesh (an upper bound where
    /// the check was bounded, see [`check`]).
    pts: Vec<P3>,
    dist: Vec<f64>,
}

impl Check {
    /// No point checked yet, room for `cap`.
    fn empty(cap: usize) -> Check {
        Check {
            far: Vec::new(),
            max: 0.0,
            rms: 0.0,
            at: P3::origin(),
            pts: Vec::with_capacity(cap),
            dist: Vec::with_capacity(cap),
        }
    }
}

fn distinct(k: &[f64], lo: f64, hi: f64) -> Vec<f64> {
    let mut v: Vec<f64> = k.iter().copied().filter(|&x| x >= lo && x <= hi).collect();
    v.dedup();
    v
}

/// The check of `s` against the mesh on its grid. With `prev` (the check of the previous
/// fit, on the same grid), a grid point whose previous distance plus how far the surface
/// moved there stays within half the tolerance is not searched: it is not far, and that sum
/// stands for its distance (an upper bound). The far points and every decision the fit takes
/// from them (`far`, and `max` wherever it is over half the tolerance) are then the same as a
/// full check's; only `rms` and a `max` under half the tolerance are bounds, so the last
/// check of a fit is a full one.
fn check(
    s: &NurbsSurface,
    bvh: &Bvh,
    knots_u: &[f64],
    knots_v: &[f64],
    prev: Option<&Check>,
) -> Check {
    let (u0, u1) = s.domain_u();
    let (v0, v1) = s.domain_v();
    let ku = distinct(knots_u, u0, u1);
    let kv = distinct(knots_v, v0, v1);
    let mut us = Vec::new();
    for w in ku.windows(2) {
        for f in [0.0, 0.5] {
            us.push(w[0] + f * (w[1] - w[0]));
        }
    }
    let mut vs = Vec::new();
    for w in kv.windows(2) {
        for f in [0.0, 0.25, 0.5, 0.75] {
            vs.push(w[0] + f * (w[1] - w[0]));
        }
    }
    vs.push(v1);
    let n = us.len() * vs.len();
    let prev = prev.filter(|c| c.pts.len() == n);
    let nv = vs.len();
    // The grid's basis values once per row and column (a point is then 16 products, where
    // `NurbsSurface::point` searched both spans and allocated for every point).
    debug_assert!(s.degree_u == 3 && s.degree_v == 3 && s.weights.is_none());
    let basis = |n: usize, k: &[f64], t: f64| {
        let sp = find_span(n - 1, 3, t, k);
        let mut b = [0.0; 4];
        basis_funs(sp, t, 3, k, &mut b);
        (sp - 3, b)
    };
    let bv: Vec<(usize, [f64; 4])> = vs.iter().map(|&v| basis(s.nv, &s.knots_v, v)).collect();
    // Columns of the grid in chunks over the cores (results merged in grid order, so the
    // check is the same whatever the threads).
    let chunk = 16;
    let chunks = us.len().div_ceil(chunk);
    let parts = crate::par::map(chunks, crate::par::cores(2), |ck| {
        let mut c = Check::empty(chunk * nv);
        let mut sum = 0.0;
        for iu in ck * chunk..((ck + 1) * chunk).min(us.len()) {
            let u = us[iu];
            let (cu, bu) = basis(s.nu, &s.knots_u, u);
            for (iv, &v) in vs.iter().enumerate() {
                let k = iu * nv + iv;
                let (cv, bvv) = bv[iv];
                let mut acc = V3::zeros();
                for a in 0..4 {
                    let row = (cu + a) * s.nv + cv;
                    let mut col = V3::zeros();
                    for b in 0..4 {
                        col += bvv[b] * s.points[row + b].coords;
                    }
                    acc += bu[a] * col;
                }
                let p = P3::from(acc);
                c.pts.push(p);
                if let Some(b) = prev.map(|q| q.dist[k] + (p - q.pts[k]).norm()) {
                    if b <= 0.5 * TOL_MM {
                        c.dist.push(b);
                        sum += b * b;
                        if b > c.max {
                            c.max = b;
                            c.at = p;
                        }
                        continue;
                    }
                }
                // Most grid points lie within half the tolerance, and a search bounded by
                // it visits fewer boxes; the rest search again out to 5 mm.
                let near = bvh
                    .closest_within(&p, 0.5 * TOL_MM)
                    .or_else(|| bvh.closest_within(&p, 50.0 * TOL_MM));
                let d = near.as_ref().map_or(50.0 * TOL_MM, |c| c.distance);
                if let Some(n) = near {
                    if d > 0.5 * TOL_MM {
                        c.far.push(((u, v), n.point));
                    }
                }
                c.dist.push(d);
                sum += d * d;
                if d > c.max {
                    c.max = d;
                    c.at = p;
                }
            }
        }
        c.rms = sum;
        c
    });
    let mut c = Check::empty(n);
    let mut sum = 0.0;
    for p in parts {
        c.far.extend(p.far);
        c.pts.extend(p.pts);
        c.dist.extend(p.dist);
        sum += p.rms;
        if p.max > c.max {
            c.max = p.max;
            c.at = p.at;
        }
    }
    c.rms = (sum / n as f64).sqrt();
    c
}

/// Fit the kept part `s0` (the section surface, v across [0, 1] from its far end to the cut
/// when `cut_at_end`, else from the cut) to the facets of `mesh` between the cutting plane
/// and the part's last section (`within`: distance from the plane into the part, positive).
pub fn fit_part(
    s0: &NurbsSurface,
    mesh: &TriMesh,
    plane: &Plane,
    into_part: f64,
    within: f64,
) -> Result<(NurbsSurface, PartFit), JoinError> {
    let t0 = Instant::now();
    let depth = |p: &P3| into_part * plane.signed_distance(p);
    let keep = |p: &P3| {
        let d = depth(p);
        (-1e-9..=within).contains(&d)
    };
    let pts = facet_points(mesh, &keep);
    let bvh = Bvh::new(mesh);
    let mut s = s0.clone();
    let mut fit = PartFit::default();
    // One tessellation row per section span and 300 columns around: Gauss-Newton takes the
    // points the rest of the way (600 x 2 per span found the same feet in twice the time).
    let loc = Locator::new(&s, 300, s.nv - s.degree_v);
    let located: Vec<(P3, (f64, f64))> = {
        let chunk = 1024;
        crate::par::map(pts.len().div_ceil(chunk), crate::par::cores(2), |k| {
            pts[k * chunk..((k + 1) * chunk).min(pts.len())]
                .iter()
                .map(|p| (*p, loc.locate(&s, p)))
                .collect::<Vec<_>>()
        })
        .into_iter()
        .flatten()
        .collect()
    };

    // Points whose foot lies on an end curve are past the part's end (the heel or toe cap,
    // which the section surface does not reach) and would drag the end; points more than
    // 3 mm from the section surface were placed on the wrong span.
    let (v0, v1) = s.domain_v();
    let (pts, mut uv): (Vec<P3>, Vec<(f64, f64)>) = located
        .into_iter()
        .filter(|(p, (u, v))| {
            *v > v0 + 1e-9 && *v < v1 - 1e-9 && (s.point(*u, *v) - p).norm() < 3.0
        })
        .unzip();
    // The two end curves stay where the sections put them (the cut and the part's last
    // section, both on the mesh): pinned at their parameters, so the seam stays in the
    // cutting plane and the far end does not swing past the last facet points. (Moved to
    // their nearest mesh points they took the facets' kinks, and the G1Tangent patch, meeting
    // them, went from 2.7e7 to 2.9e9 in curvature variation.)
    let nfacet = pts.len();
    fit.samples = nfacet;
    let mut pts = pts;
    let (u0, u1) = s.domain_u();
    let ne = 2000;
    for v in [v0, v1] {
        for k in 0..ne {
            let u = u0 + (u1 - u0) * k as f64 / ne as f64;
            pts.push(s0.point(u, v));
            uv.push((u, v));
        }
    }
    let mut wt = vec![1.0; nfacet];
    wt.extend(std::iter::repeat_n(END_WEIGHT, 2 * ne));
    // The fit starts on SPANS_U spans around and gains knots only where the surface strays.
    let fine_u = distinct(&s0.knots_u, u0, u1);
    s = coarse_u(s0, (fine_u.len() - 1).div_ceil(SPANS_U));
    fit.setup_ms = t0.elapsed().as_secs_f64() * 1e3;
    let mut c: Option<Check> = None;
    for round in 0..ROUNDS {
        let ts = Instant::now();
        // The parameters stay those found on the section surface: knot insertion keeps the
        // surface, and re-projecting onto a half-fitted surface let points on the flat top
        // jump to far spans (a RoundTip back swung 30 mm off); re-projecting with the feet
        // kept within 2 mm left the LastScan back at 0.24 mm.
        s = solve(&s, &pts, &uv, &wt, CG_TOL);
        fit.solve_ms += ts.elapsed().as_secs_f64() * 1e3;
        fit.rounds = round + 1;
        let kv = distinct(&s.knots_v, s.domain_v().0, s.domain_v().1);
        let mut worst = vec![0.0f64; kv.len() - 1];
        let mut bad_u = Vec::new();
        for (p, &(u, v)) in pts[..nfacet].iter().zip(&uv) {
            let j = kv.partition_point(|&k| k <= v).clamp(1, kv.len() - 1) - 1;
            // The error that decides the knots is the distance to the foot found from there
            // (not kept for the fit): at the fixed parameters a point on a sharp rim reads
            // its parameter's drift as error, and v knots doubled everywhere.
            let mut e = (s.point(u, v) - p).norm();
            if e > 0.5 * TOL_MM {
                let (mut a, mut b) = (u, v);
                project(&s, p, &mut a, &mut b, 5);
                let f = (s.point(a, b) - p).norm();
                if (s.point(a, b) - s.point(u, v)).norm() < 2.0 {
                    e = e.min(f);
                }
            }
            worst[j] = worst[j].max(e);
            if e > TOL_MM {
                bad_u.push(u);
            }
        }
        let over_v: Vec<f64> = worst
            .iter()
            .enumerate()
            .filter(|(_, &d)| d > 0.5 * TOL_MM)
            .map(|(j, _)| 0.5 * (kv[j] + kv[j + 1]))
            .collect();
        let tc = Instant::now();
        // Bounded by the previous check (its decisions are a full check's); the fit's figures
        // come from the full check after the cut is faired, below.
        let ck = check(&s, &bvh, &s0.knots_u, &s0.knots_v, c.as_ref());
        fit.check_ms += tc.elapsed().as_secs_f64() * 1e3;
        // u spans are halved where a facet point or a check point is over the tolerance.
        bad_u.extend(
            ck.far
                .iter()
                .filter(|f| (s.point(f.0 .0, f.0 .1) - f.1).norm() > TOL_MM)
                .map(|f| f.0 .0),
        );
        let done = round + 1 == ROUNDS || (over_v.is_empty() && ck.max <= TOL_MM);
        // Where the surface bulges away from the facets no facet point pulls it back (their
        // feet are elsewhere): the grid points that stray pull towards their nearest mesh
        // point in the next fit.
        for &(q, p) in &ck.far {
            pts.push(p);
            uv.push(q);
            wt.push(1.0);
        }
        c = Some(ck);
        if done {
            break;
        }
        s = s.refine_v(&over_v).refine_u(&split_u(&s, &fine_u, &bad_u));
    }
    // The cut is the end of the section surface that lies on the plane.
    let at = |v: f64| {
        (0..8)
            .map(|k| depth(&s0.point(k as f64 / 8.0, v)).abs())
            .sum::<f64>()
    };
    fair_cut(&mut s, at(v0) < at(v1));
    let tc = Instant::now();
    let c = check(&s, &bvh, &s0.knots_u, &s0.knots_v, None);
    fit.check_ms += tc.elapsed().as_secs_f64() * 1e3;
    fit.points_max_mm = pts[..nfacet]
        .iter()
        .zip(&uv)
        .map(|(p, &(u, v))| (s.point(u, v) - p).norm())
        .fold(0.0, f64::max);
    fit.spans_u = distinct(&s.knots_u, s.domain_u().0, s.domain_u().1).len() - 1;
    fit.spans_v = distinct(&s.knots_v, s.domain_v().0, s.domain_v().1).len() - 1;
    fit.max_mm = c.max;
    fit.rms_mm = c.rms;
    fit.max_at = c.at;
    fit.max_from_plane_mm = -depth(&c.at);
    fit.ms = t0.elapsed().as_secs_f64() * 1e3;
    Ok((s, fit))
}

/// The fitted part's tangent field across the cut made fair: the differences between the
/// first control row in from the cut and the cut's own row (`at_start`: the cut at v = 0,
/// else at v = 1), which give the part's v derivative along the cut, replaced by their
/// smoothing around (periodic second differences over the control columns, weight
/// [`CUT_SMOOTH`]). The fit leaves that field wiggling column to column (the rows next to
/// the cut hold few facet points, and the pinned cut beside them), so the part's normal
/// wiggles along the cut, and a patch that meets it G1 had to carry the wiggles (curvature
/// variation 3.1e7 / 3.2e8 for `G1Tangent`, docs/method.md 11.7.4). The cut's row stays, so
/// the seam does not move; the surface within the first v spans moves by up to 0.06-0.12
/// mm, which leaves the part as near its mesh as it was (on the check grid and on a dense
/// grid next to the cut), and its normal at the cut nearer the original last's.
fn fair_cut(s: &mut NurbsSurface, at_start: bool) {
    let nv = s.nv;
    let m = s.nu - s.degree_u;
    let (r0, r1) = if at_start { (0, 1) } else { (nv - 1, nv - 2) };
    // (I + w D^T D) x = d with D the periodic second differences: a dense Cholesky of m x m
    // (m is a few hundred columns).
    let mut a = nalgebra::DMatrix::<f64>::identity(m, m);
    let mut b = nalgebra::DMatrix::<f64>::zeros(m, 3);
    for i in 0..m {
        let idx = [(i + m - 1) % m, i, (i + 1) % m];
        let w = [1.0, -2.0, 1.0];
        for p in 0..3 {
            for q in 0..3 {
                a[(idx[p], idx[q])] += CUT_SMOOTH * w[p] * w[q];
            }
        }
        let d = s.points[i * nv + r1] - s.points[i * nv + r0];
        for k in 0..3 {
            b[(i, k)] = d[k];
        }
    }
    let x = nalgebra::Cholesky::new(a)
        .expect("identity plus a positive semi-definite matrix")
        .solve(&b);
    // Columns past m wrap onto the first ones (periodic in u).
    for i in 0..s.nu {
        let k = i % m;
        let q0 = s.points[i * nv + r0];
        s.points[i * nv + r1] = q0 + V3::new(x[(k, 0)], x[(k, 1)], x[(k, 2)]);
    }
}

/// The v derivatives of order 0..=2 of `s` at v as control points along u (the u basis is
/// untouched by taking them).
fn iso_ders(s: &NurbsSurface, v: f64) -> [Vec<V3>; 3] {
    let q = s.degree_v;
    let sv = find_span(s.nv - 1, q, v, &s.knots_v);
    let d = ders_basis_funs(sv, v, q, 2, &s.knots_v);
    let mut out = [
        vec![V3::zeros(); s.nu],
        vec![V3::zeros(); s.nu],
        vec![V3::zeros(); s.nu],
    ];
    for (k, o) in out.iter_mut().enumerate() {
        for (i, x) in o.iter_mut().enumerate() {
            for b in 0..=q {
                *x += d[k][b] * s.points[i * s.nv + sv - q + b].coords;
            }
        }
    }
    out
}

/// Half-width, in control columns, of the window that smooths the G1 scale around the seam.
const SCALE_WINDOW: usize = 10;

/// `part`'s derivative control points scaled to the lengths of `own`'s: the scale is the ratio
/// of the lengths, its logarithm averaged over a periodic window of columns (`part` and `own`
/// share their u knots; the columns past `nu - degree` wrap onto the first ones).
fn scaled(part: &[V3], own: &[V3]) -> Vec<V3> {
    let n = part.len();
    let m = n - 3;
    let ln: Vec<f64> = (0..m)
        .map(|i| (own[i].norm().max(1e-12) / part[i].norm().max(1e-12)).ln())
        .collect();
    let w = SCALE_WINDOW.min(m / 2);
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut acc = 0.0;
        for k in 0..=2 * w {
            acc += ln[(i + m + k - w) % m];
        }
        out.push(part[i] * (acc / (2 * w + 1) as f64).exp());
    }
    out
}

/// Seam continuity asked of the patch against the fitted parts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub enum Continuity {
    /// Position and tangent plane along the whole seam, the tangent's change confined to a
    /// band next to each seam ([`G1_BAND`] of the patch's v): the patch leaves each seam along
    /// the fitted part's own v tangent at the length of the patch's (as [`Self::G1Tangent`]),
    /// but the change from the patch's own tangent fades out within the band instead of
    /// across the whole gap, so the fitted parts' normals, which wiggle along the cut, bend
    /// only a strip next to the part that has them and the rest of the patch stays the
    /// section patch. Normal jump 0.004 / 0.001 deg (LastScan back / toe) and 0.002 / 0.005
    /// deg (RoundTip) at most against the parts faired at the cut ([`fair_cut`]; 0.035 /
    /// 0.009 and 0.053 / 0.021 against the parts before); curvature variation 1.8e2 / 3.4e5
    /// against 1.4e2 / 3.7e5 for the section patch (docs/method.md 11.7.4).
    #[default]
    G1,
    /// Position and, at each control column's Greville point, the tangent plane: the patch's
    /// own v tangent turned into the fitted part's tangent plane there, by a Hermite
    /// correction across the whole gap (the default until 11.7.4). Between the points, where
    /// the normal turns fast at the rim, the normal jumps up to 0.45 deg (LastScan) and 1.3
    /// deg (RoundTip) against the parts faired at the cut (2.3 and 6.0 deg before; curvature
    /// variation 9.7e1 / 2.2e4, before 2.1e3 / 8.7e5).
    G1Greville,
    /// Position and tangent plane along the whole seam: the fitted part's own v tangent at
    /// the length of the patch's, by a Hermite correction across the whole gap. The normal
    /// jumps as [`Self::G1`]'s, but the fitted parts' normals wiggle along the cut and the
    /// patch carries what is left of the wiggles across the gap: curvature variation 3.1e7
    /// on the LastScan pair and 3.2e8 on the RoundTip pair before the parts were faired at the
    /// cut ([`fair_cut`]; ripples in the zebra pictures, docs/method.md 11.7.1), 1.0e2 / 3.2e6
    /// after, and 5.2e1 / 2.5e5 with a fairing ten times stronger, which takes the parts
    /// further from their meshes next to the cut (11.7.4).
    G1Tangent,
    /// Position, first and second v derivatives of the fitted parts: exact G2, but the
    /// fitted parts' derivatives carry their parametrisation, and the patch bulged (8.7 mm
    /// on the LastScan pair, 64 mm on the RoundTip pair); only where asked.
    G2,
}

/// Width of the band next to each seam, as a fraction of the patch's v, within which
/// [`Continuity::G1`] changes the patch's tangent: about 3 mm on the LastScan pair and 7 mm
/// on the RoundTip pair (the patch is 20 / 47 mm across). Curvature variation of the LastScan
/// patch against the band, measured before the parts were faired at the cut (RoundTip: 3.4e5
/// from 0.1 to 0.3): 2.8e2 at 0.1, 1.9e2 at 0.15, 2.3e2 at 0.2, 4.7e2 at 0.25 and 0.3, 4.4e4
/// at 0.45; the whole gap was 3.1e7.
pub const G1_BAND: f64 = 0.15;

/// The patch bent to meet `back` at its v = 1 and `toe` at its v = 0: a quintic (G2) or cubic
/// (G1) Hermite correction in v whose end values are the differences of position and of the
/// v derivatives, these scaled by the parameter lengths (`lens`: back, patch, toe on the
/// whole surface before each piece was mapped to [0, 1]); for [`Continuity::G1`] the
/// derivatives' part is a cubic B-spline that vanishes past [`G1_BAND`] from each end. All
/// three share their u knots.
pub fn meet(
    patch: &NurbsSurface,
    back: &NurbsSurface,
    toe: &NurbsSurface,
    lens: [f64; 3],
    c: Continuity,
) -> Result<NurbsSurface, JoinError> {
    // Bring the u knots together: the fitted parts may have gained knots around.
    let mut parts = vec![back.clone(), patch.clone(), toe.clone()];
    let ku: Vec<f64> = {
        let mut k: Vec<f64> = Vec::new();
        for s in &parts {
            for &x in &s.knots_u[s.degree_u..=s.nu] {
                if !k.iter().any(|&y| (y - x).abs() < 1e-12) {
                    k.push(x);
                }
            }
        }
        k
    };
    for s in parts.iter_mut() {
        let have = &s.knots_u[s.degree_u..=s.nu];
        let add: Vec<f64> = ku
            .iter()
            .copied()
            .filter(|x| !have.iter().any(|y| (y - x).abs() < 1e-12))
            .collect();
        *s = s.refine_u(&add);
    }
    let (b, p, t) = (&parts[0], &parts[1], &parts[2]);
    let (fb, ft) = (lens[1] / lens[0], lens[1] / lens[2]);
    let bd = iso_ders(b, 1.0);
    let pd0 = iso_ders(p, 0.0);
    let pd1 = iso_ders(p, 1.0);
    let td = iso_ders(t, 0.0);
    let nu = p.nu;
    let diff = |a: &[V3], s: f64, bb: &[V3]| -> Vec<V3> {
        a.iter().zip(bb).map(|(x, y)| x * s - y).collect::<Vec<_>>()
    };
    let d0 = diff(&bd[0], 1.0, &pd0[0]);
    let d1 = diff(&bd[1], fb, &pd0[1]);
    let d2 = diff(&bd[2], fb * fb, &pd0[2]);
    let e0 = diff(&td[0], 1.0, &pd1[0]);
    let e1 = diff(&td[1], ft, &pd1[1]);
    let e2 = diff(&td[2], ft * ft, &pd1[2]);
    // Bezier control values in v of the correction.
    let cols: Vec<Vec<V3>> = match c {
        Continuity::G2 => (0..nu)
            .map(|i| {
                vec![
                    d0[i],
                    d0[i] + d1[i] / 5.0,
                    d0[i] + d1[i] * 0.4 + d2[i] / 20.0,
                    e0[i] - e1[i] * 0.4 + e2[i] / 20.0,
                    e0[i] - e1[i] / 5.0,
                    e0[i],
                ]
            })
            .collect(),
        Continuity::G1 => return band(p, [&d0, &e0], [&bd[1], &td[1]], [&pd0[1], &pd1[1]]),
        Continuity::G1Greville => {
            // The patch's own v tangent turned into the fitted part's tangent plane at the
            // Greville point of each control column: the fitted parts' v derivatives carry
            // their parametrisation (short spans near the cut after refinement), and taking
            // them whole bulged the patch by 1.5-12 mm (64 mm for G2 on the RoundTip pair).
            let gr = |i: usize| {
                let k = &p.knots_u;
                (1..=p.degree_u).map(|a| k[i + a]).sum::<f64>() / p.degree_u as f64
            };
            let turn = |surf: &NurbsSurface, v: f64, pv: &[V3]| -> Vec<V3> {
                (0..nu)
                    .map(|i| {
                        let n = surf.normal(gr(i), v);
                        -n * n.dot(&pv[i])
                    })
                    .collect()
            };
            let t1 = turn(b, 1.0, &pd0[1]);
            let u1 = turn(t, 0.0, &pd1[1]);
            (0..nu)
                .map(|i| vec![d0[i], d0[i] + t1[i] / 3.0, e0[i] - u1[i] / 3.0, e0[i]])
                .collect()
        }
        Continuity::G1Tangent => {
            // The fitted part's own v derivative, scaled column by column to the length of
            // the patch's own: the direction is the fitted part's, so the patch leaves the
            // seam in its tangent plane, and the length the patch's, so it does not bulge (the
            // fitted parts' derivatives carry their parametrisation: short spans near the cut
            // after refinement, and taking them whole bulged the patch by 1.5-12 mm). The
            // scale is exact G1 where it is constant; it is smoothed around the seam so its
            // variation tilts the tangent plane by far less than 0.1 deg. (Turning the
            // patch's own tangent into the part's tangent plane at each column's Greville
            // point left 1.3-7.7 deg between the points where the normal turns fast.)
            let t1 = scaled(&bd[1], &pd0[1]);
            let u1 = scaled(&td[1], &pd1[1]);
            let d1: Vec<V3> = t1.iter().zip(&pd0[1]).map(|(a, b)| a - b).collect();
            let e1: Vec<V3> = u1.iter().zip(&pd1[1]).map(|(a, b)| a - b).collect();
            (0..nu)
                .map(|i| vec![d0[i], d0[i] + d1[i] / 3.0, e0[i] - e1[i] / 3.0, e0[i]])
                .collect()
        }
    };
    let deg = cols[0].len() - 1;
    let mut kv = vec![0.0; deg + 1];
    kv.extend(vec![1.0; deg + 1]);
    let pts: Vec<P3> = cols.iter().flatten().map(|x| P3::from(*x)).collect();
    let corr = NurbsSurface::new(
        p.degree_u,
        deg,
        p.knots_u.clone(),
        kv,
        nu,
        deg + 1,
        pts,
        None,
    )?
    .with_periodic(p.periodic_u, false)?;
    let both = make_surfaces_compatible(&[p.clone(), corr])?;
    Ok(both[0].try_add(&both[1])?)
}

/// [`Continuity::G1`]'s patch: `p` plus a cubic Hermite correction of position (end values
/// `pos`, zero end tangents) and one of tangent on the knots 0, 0, 0, 0, b/2, b, 1 - b,
/// 1 - b/2, 1, 1, 1, 1 in v (b = [`G1_BAND`]), whose control values are zero but next to each
/// end: its first basis function is zero past b, so the tangent's change, the fitted part's
/// v derivative (`part`, back then toe) scaled to the length of the patch's own (`own`) less
/// that, acts only in the band. Both are C2 in v and exact at the ends: position and tangent
/// plane of the fitted parts along the whole seam.
fn band(
    p: &NurbsSurface,
    pos: [&[V3]; 2],
    part: [&[V3]; 2],
    own: [&[V3]; 2],
) -> Result<NurbsSurface, JoinError> {
    let nu = p.nu;
    let t0 = scaled(part[0], own[0]);
    let t1 = scaled(part[1], own[1]);
    let a = 0.5 * G1_BAND;
    // The first basis function's derivative at 0 is 3 / a (and the last's at 1, negated).
    let z = V3::zeros();
    let pts_pos: Vec<P3> = (0..nu)
        .flat_map(|i| [pos[0][i], pos[0][i], pos[1][i], pos[1][i]])
        .map(P3::from)
        .collect();
    let pts_tan: Vec<P3> = (0..nu)
        .flat_map(|i| {
            let (d, e) = (t0[i] - own[0][i], t1[i] - own[1][i]);
            [z, d * a / 3.0, z, z, z, z, -e * a / 3.0, z]
        })
        .map(P3::from)
        .collect();
    let kv_pos = vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
    let b = G1_BAND;
    let kv_tan = vec![
        0.0,
        0.0,
        0.0,
        0.0,
        a,
        b,
        1.0 - b,
        1.0 - a,
        1.0,
        1.0,
        1.0,
        1.0,
    ];
    let corr = |kv: Vec<f64>, pts: Vec<P3>| {
        let n = kv.len() - 4;
        NurbsSurface::new(p.degree_u, 3, p.knots_u.clone(), kv, nu, n, pts, None)
            .and_then(|s| s.with_periodic(p.periodic_u, false))
    };
    let all =
        make_surfaces_compatible(&[p.clone(), corr(kv_pos, pts_pos)?, corr(kv_tan, pts_tan)?])?;
    Ok(all[0].try_add(&all[1])?.try_add(&all[2])?)
}

/// The part of `mesh` on the kept side of `plane` (`into_part` = +1 keeps the side the normal
/// points to, -1 the other), triangles crossing the plane cut at it, and the boundary loop
/// left on the plane, in the order of the kept triangles' edges.
pub fn trim(mesh: &TriMesh, plane: &Plane, into_part: f64) -> (TriMesh, Vec<u32>) {
    let d: Vec<f64> = mesh
        .vertices
        .iter()
        .map(|v| {
            let x = into_part * plane.signed_distance(v);
            if x.abs() < 1e-9 {
                0.0
            } else {
                x
            }
        })
        .collect();
    let mut verts: Vec<P3> = Vec::new();
    let mut map: HashMap<u32, u32> = HashMap::new();
    let mut cut: HashMap<(u32, u32), u32> = HashMap::new();
    let mut on_plane: Vec<bool> = Vec::new();
    let mut tris: Vec<[u32; 3]> = Vec::new();
    let mut keep_v = |i: u32, verts: &mut Vec<P3>, on: &mut Vec<bool>| -> u32 {
        *map.entry(i).or_insert_with(|| {
            verts.push(mesh.vertices[i as usize]);
            on.push(d[i as usize] == 0.0);
            (verts.len() - 1) as u32
        })
    };
    for tri in &mesh.triangles {
        let inside: Vec<bool> = tri.iter().map(|&i| d[i as usize] >= 0.0).collect();
        let n_in = inside.iter().filter(|&&x| x).count();
        if n_in == 0 {
            continue;
        }
        // Vertices of the kept polygon in order.
        let mut poly: Vec<u32> = Vec::with_capacity(4);
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let (da, db) = (d[a as usize], d[b as usize]);
            if da >= 0.0 {
                poly.push(keep_v(a, &mut verts, &mut on_plane));
            }
            if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
                let key = (a.min(b), a.max(b));
                let id = *cut.entry(key).or_insert_with(|| {
                    let (pa, pb) = (mesh.vertices[a as usize], mesh.vertices[b as usize]);
                    let t = da / (da - db);
                    verts.push(pa + (pb - pa) * t);
                    on_plane.push(true);
                    (verts.len() - 1) as u32
                });
                poly.push(id);
            }
        }
        for k in 1..poly.len().saturating_sub(1) {
            let t = [poly[0], poly[k], poly[k + 1]];
            if t[0] != t[1] && t[1] != t[2] && t[0] != t[2] {
                tris.push(t);
            }
        }
    }
    let m = TriMesh::new(verts, tris);
    // Boundary: directed edges used once, whose ends both lie on the plane.
    let mut count: HashMap<(u32, u32), i32> = HashMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut next: HashMap<u32, u32> = HashMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if count[&(a.min(b), a.max(b))] == 1 && on_plane[a as usize] && on_plane[b as usize] {
                next.insert(a, b);
            }
        }
    }
    let mut loop_ = Vec::new();
    if let Some((&start, _)) = next.iter().min_by_key(|(k, _)| **k) {
        let mut c = start;
        loop {
            loop_.push(c);
            match next.get(&c) {
                Some(&n) if n != start && loop_.len() <= next.len() => c = n,
                _ => break,
            }
        }
    }
    (m, loop_)
}

/// Triangles joining two closed loops of vertex ids `a` and `b` (in `verts`) that run the
/// same way round: from the nearest pair, each step advances the loop whose next point makes
/// the shorter diagonal.
pub fn zip(verts: &[P3], a: &[u32], b: &[u32]) -> Vec<[u32; 3]> {
    let (na, nb) = (a.len(), b.len());
    let p = |i: u32| verts[i as usize];
    let b0 = (0..nb)
        .min_by(|&i, &j| {
            (p(b[i]) - p(a[0]))
                .norm()
                .total_cmp(&(p(b[j]) - p(a[0])).norm())
        })
        .unwrap_or(0);
    let bb = |j: usize| b[(b0 + j) % nb];
    let aa = |i: usize| a[i % na];
    let (mut i, mut j) = (0, 0);
    let mut out = Vec::with_capacity(na + nb);
    while i < na || j < nb {
        let adv_a = if i == na {
            false
        } else if j == nb {
            true
        } else {
            (p(aa(i + 1)) - p(bb(j))).norm() <= (p(bb(j + 1)) - p(aa(i))).norm()
        };
        if adv_a {
            out.push([aa(i), aa(i + 1), bb(j)]);
            i += 1;
        } else {
            out.push([aa(i), bb(j + 1), bb(j)]);
            j += 1;
        }
    }
    out
}

/// Which way a loop turns about `axis`: +1 counterclockwise looking against it.
pub fn turn(verts: &[P3], l: &[u32], axis: &V3) -> f64 {
    let c = l
        .iter()
        .fold(V3::zeros(), |s, &i| s + verts[i as usize].coords)
        / l.len().max(1) as f64;
    let mut a = V3::zeros();
    for k in 0..l.len() {
        let (p, q) = (
            verts[l[k] as usize].coords - c,
            verts[l[(k + 1) % l.len()] as usize].coords - c,
        );
        a += p.cross(&q);
    }
    a.dot(axis).signum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A closed tube around z: `m` control columns (periodic cubic, uniform knots) and one
    /// control row per `(z, radius)` (clamped cubic along), each control point's radius
    /// moved by `bump(column, row)`.
    fn tube(m: usize, rows: &[(f64, f64)], bump: impl Fn(usize, usize) -> f64) -> NurbsSurface {
        let p = 3;
        let nv = rows.len();
        let knots_u: Vec<f64> = (0..m + 2 * p + 1)
            .map(|i| (i as f64 - p as f64) / m as f64)
            .collect();
        let mut knots_v = vec![0.0; 4];
        for k in 1..nv - 3 {
            knots_v.push(k as f64 / (nv - 3) as f64);
        }
        knots_v.extend([1.0; 4]);
        let mut pts = Vec::new();
        for i in 0..m + p {
            let a = std::f64::consts::TAU * (i % m) as f64 / m as f64;
            for (j, &(z, r)) in rows.iter().enumerate() {
                let r = r + bump(i % m, j);
                pts.push(P3::new(r * a.cos(), r * a.sin(), z));
            }
        }
        NurbsSurface::new(p, 3, knots_u, knots_v, m + p, nv, pts, None)
            .and_then(|s| s.with_periodic(true, false))
            .unwrap()
    }

    fn angle_deg(a: V3, b: V3) -> f64 {
        a.normalize()
            .dot(&b.normalize())
            .abs()
            .min(1.0)
            .acos()
            .to_degrees()
    }

    /// The default G1 meets both parts' tangent planes along the whole seam, even where the
    /// part's tangent wiggles column to column, and leaves the patch as it was past the band.
    #[test]
    fn g1_meets_the_tangent_planes_and_keeps_the_middle() {
        let m = 64;
        // A cone in to the cut at z = 0 whose row next to the cut wiggles, a straight tube as
        // the patch, a wider cone out of the toe cut at z = 10.
        let back = tube(
            m,
            &[(-10.0, 12.0), (-6.0, 11.2), (-3.0, 10.6), (0.0, 10.0)],
            |i, j| {
                if j == 2 {
                    0.05 * (-1f64).powi(i as i32)
                } else {
                    0.0
                }
            },
        );
        let patch = tube(
            m,
            &[
                (0.0, 10.0),
                (10.0 / 3.0, 10.0),
                (20.0 / 3.0, 10.0),
                (10.0, 10.0),
            ],
            |_, _| 0.0,
        );
        let toe = tube(
            m,
            &[(10.0, 10.0), (13.0, 10.3), (16.0, 10.6), (20.0, 11.0)],
            |_, _| 0.0,
        );
        let met = meet(&patch, &back, &toe, [1.0, 1.0, 1.0], Continuity::G1).unwrap();
        for k in 0..500 {
            let u = (k as f64 + 0.5) / 500.0;
            assert!((met.point(u, 0.0) - back.point(u, 1.0)).norm() < 1e-12);
            assert!((met.point(u, 1.0) - toe.point(u, 0.0)).norm() < 1e-12);
            let jb = angle_deg(met.normal(u, 0.0), back.normal(u, 1.0));
            let jt = angle_deg(met.normal(u, 1.0), toe.normal(u, 0.0));
            // Exact but for the scale's variation around (its window, [`scaled`]): the part's
            // alternating row changes the ratio of lengths column to column (1.2e-4 deg).
            assert!(jb < 1e-3 && jt < 1e-3, "u {u}: {jb} / {jt} deg");
            // Past the band the patch is its own (the positions met already).
            for v in [G1_BAND + 1e-9, 0.5, 1.0 - G1_BAND - 1e-9] {
                assert!(
                    (met.point(u, v) - patch.point(u, v)).norm() < 1e-12,
                    "{u} {v}"
                );
            }
        }
        // The Greville turn, on the same parts, misses the wiggling part's tangent plane
        // between its points (0.22 deg here).
        let grev = meet(&patch, &back, &toe, [1.0; 3], Continuity::G1Greville).unwrap();
        let worst = (0..500)
            .map(|k| {
                let u = (k as f64 + 0.5) / 500.0;
                angle_deg(grev.normal(u, 0.0), back.normal(u, 1.0))
            })
            .fold(0.0, f64::max);
        assert!(worst > 0.01, "{worst}");
        // Inside the band it bends (the cone's tangent is not the tube's).
        assert!((met.point(0.3, 0.5 * G1_BAND) - patch.point(0.3, 0.5 * G1_BAND)).norm() > 1e-3);
    }

    /// The row next to the cut loses its column-to-column wiggle; the cut's row stays.
    #[test]
    fn fair_cut_smooths_the_tangent_field_and_keeps_the_cut() {
        let m = 64;
        let rows = [(-10.0, 12.0), (-6.0, 11.2), (-3.0, 10.6), (0.0, 10.0)];
        let wiggle = |i: usize, j: usize| {
            if j == 2 {
                0.05 * (-1f64).powi(i as i32)
            } else {
                0.0
            }
        };
        let alternation = |s: &NurbsSurface| {
            (0..m)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / m as f64;
                    let d = s.points[i * s.nv + 2] - s.points[i * s.nv + 3];
                    (-1f64).powi(i as i32) * d.dot(&V3::new(a.cos(), a.sin(), 0.0))
                })
                .sum::<f64>()
                / m as f64
        };
        let mut s = tube(m, &rows, wiggle);
        let before = s.clone();
        assert!((alternation(&s) - 0.05).abs() < 1e-12);
        fair_cut(&mut s, false);
        // The highest frequency around shrinks by about 1 + 16 CUT_SMOOTH (161: 3.1e-4 mm
        // left).
        assert!(alternation(&s).abs() < 0.05 / 100.0, "{}", alternation(&s));
        for i in 0..s.nu {
            assert_eq!(s.points[i * s.nv + 3], before.points[i * s.nv + 3]);
            assert_eq!(s.points[i * s.nv], before.points[i * s.nv]);
            // The wrapped columns stay copies of the first ones.
            let k = i % m;
            assert_eq!(s.points[i * s.nv + 2], s.points[k * s.nv + 2]);
        }
        // The smooth part of the field (the cone's slope) stays within 1 %.
        let smooth = tube(m, &rows, |_, _| 0.0);
        let d0 = (smooth.points[2] - smooth.points[3]).norm();
        let d1 = (s.points[2] - s.points[3]).norm();
        assert!((d1 - d0).abs() < 0.01 * d0, "{d0} {d1}");
    }
}
