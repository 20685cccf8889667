//! The Bezier network of the plantar scanner paper (eq. 5, 25-29; docs/method.md section 7)
//! over a grid of 3D points.
//!
//! The grid is cut into segments of 4 x 4 points with stride 3 (neighbours share an edge row
//! or column); where fewer than 4 points remain at the grid's end the segment has the shorter
//! period (see [`interpolation_matrix`]). Each segment stores the products C_ij = W_ij P_ij
//! of x, y and z (never W_ij alone: P_ij = 0 is common), computed as C = E_u P E_v^T, and
//! interpolates its points exactly. A segment with a missing point (outside the footprint) is
//! left out and counted.
//!
//! Parameters: a global (s, t) in grid index units, s in [0, nu - 1] along frames and t in
//! [0, nv - 1] along rows; segment (a, b) covers s in [3a, 3a + k_u], local u = (s - 3a)/k_u.

use super::basis::{basis, basis_d1, basis_d2, interpolation_matrix};
use super::ops::{dot, Scalar};
use super::point_grid::{is_point, PointGrid};
use super::SurfaceError;
use crate::geom::HeightMap;
use footscan_geom::{P2, P3, V2, V3};
use std::sync::OnceLock;

const NONE: u32 = u32::MAX;

/// One segment: its lattice position and the 16 products C_ij of x, y and z.
#[derive(Clone, Debug, PartialEq)]
pub struct Segment {
    pub a: u32,
    pub b: u32,
    /// `c[coord][i * 4 + j]`, i along u, j along v; coord 0 = x, 1 = y, 2 = z.
    pub c: [[f64; 16]; 3],
}

#[derive(Debug)]
pub struct BezierNetwork {
    nu: usize,
    nv: usize,
    su: usize,
    sv: usize,
    /// Lattice cell (a * sv + b) to its index in `segs`, or NONE when left out.
    index: Vec<u32>,
    segs: Vec<Segment>,
    skipped: usize,
    locator: OnceLock<Locator>,
}

/// Normal-angle jumps across shared segment edges.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Continuity {
    /// Shared edges between two modelled segments.
    pub edges: usize,
    /// Points compared (samples per edge x edges).
    pub samples: usize,
    pub max_deg: f64,
    pub mean_deg: f64,
    /// 95th percentile.
    pub p95_deg: f64,
}

/// Number of segments along a side of `n` points, and the period of segment `a`.
pub(crate) fn segments_along(n: usize) -> usize {
    (n - 1).div_ceil(3)
}

pub(crate) fn period(n: usize, a: usize) -> usize {
    (n - 1 - 3 * a).min(3)
}

impl BezierNetwork {
    /// Build the network from a grid with at least 2 x 2 points.
    pub fn build(grid: &PointGrid) -> Result<Self, SurfaceError> {
        let (nu, nv) = (grid.nu, grid.nv);
        if nu < 2 || nv < 2 {
            return Err(SurfaceError::GridTooSmall { nu, nv });
        }
        let (su, sv) = (segments_along(nu), segments_along(nv));
        let mut index = vec![NONE; su * sv];
        let mut segs = Vec::with_capacity(su * sv);
        let mut skipped = 0;
        for a in 0..su {
            let ku = period(nu, a);
            for b in 0..sv {
                match Segment::interpolating(|i, j| grid.get(i, j), a, b, ku, period(nv, b)) {
                    Some(seg) => {
                        index[a * sv + b] = segs.len() as u32;
                        segs.push(seg);
                    }
                    None => skipped += 1,
                }
            }
        }
        Ok(BezierNetwork {
            nu,
            nv,
            su,
            sv,
            index,
            segs,
            skipped,
            locator: OnceLock::new(),
        })
    }

    /// Grid points along u and v.
    pub fn grid_size(&self) -> (usize, usize) {
        (self.nu, self.nv)
    }

    /// Segment lattice along u and v.
    pub fn lattice(&self) -> (usize, usize) {
        (self.su, self.sv)
    }

    /// The modelled segments.
    pub fn segments(&self) -> &[Segment] {
        &self.segs
    }

    /// Lattice segments left out because a point was missing.
    pub fn skipped(&self) -> usize {
        self.skipped
    }

    /// Bytes the model occupies: the coefficients plus the lattice index.
    pub fn bytes(&self) -> usize {
        self.segs.len() * std::mem::size_of::<Segment>() + self.index.len() * 4
    }

    /// The segment at lattice (a, b), if modelled.
    pub fn segment(&self, a: usize, b: usize) -> Option<&Segment> {
        if a >= self.su || b >= self.sv {
            return None;
        }
        let k = self.index[a * self.sv + b];
        (k != NONE).then(|| &self.segs[k as usize])
    }

    /// Global (s, t) to (segment, u, v); None outside the grid or where the segment is missing.
    pub fn locate_param(&self, s: f64, t: f64) -> Option<(&Segment, f64, f64)> {
        let (smax, tmax) = ((self.nu - 1) as f64, (self.nv - 1) as f64);
        if !(0.0..=smax).contains(&s) || !(0.0..=tmax).contains(&t) {
            return None;
        }
        let a = ((s / 3.0).floor() as usize).min(self.su - 1);
        let b = ((t / 3.0).floor() as usize).min(self.sv - 1);
        let seg = self.segment(a, b)?;
        let u = (s - 3.0 * a as f64) / period(self.nu, a) as f64;
        let v = (t - 3.0 * b as f64) / period(self.nv, b) as f64;
        Some((seg, u, v))
    }

    /// (x, y, z) at global parameters (s, t).
    pub fn eval(&self, s: f64, t: f64) -> Option<P3> {
        let (seg, u, v) = self.locate_param(s, t)?;
        Some(seg.eval(u, v))
    }

    /// Unit normal at (s, t), oriented as S_u x S_v (+z for a grid with x along frames and y
    /// along rows). On segment edges, where the first derivative across the edge vanishes,
    /// the one-sided limit of the tangent (the second derivative) is used.
    pub fn normal(&self, s: f64, t: f64) -> Option<V3> {
        let (seg, u, v) = self.locate_param(s, t)?;
        Some(seg.normal(u, v))
    }

    /// Height z at world (x, y): the (u, v) with x(u, v) = x, y(u, v) = y found by Newton's
    /// method in the segments whose bounding box holds (x, y). None outside the model.
    pub fn height_at(&self, x: f64, y: f64) -> Option<f64> {
        self.point_at(x, y).map(|(p, _, _)| p.z)
    }

    /// The model point over world (x, y) and its global parameters (s, t).
    pub fn point_at(&self, x: f64, y: f64) -> Option<(P3, f64, f64)> {
        let loc = self.locator.get_or_init(|| Locator::new(&self.segs));
        for &k in loc.candidates(x, y) {
            let seg = &self.segs[k as usize];
            if let Some((u, v)) = seg.invert(x, y) {
                let (a, b) = (seg.a as usize, seg.b as usize);
                let s = 3.0 * a as f64 + u * period(self.nu, a) as f64;
                let t = 3.0 * b as f64 + v * period(self.nv, b) as f64;
                return Some((seg.eval(u, v), s, t));
            }
        }
        None
    }

    /// Evaluate every segment at the local parameters `us x vs` (the same pattern in each,
    /// so the basis is computed once, as in the paper's Fig. 11), appending (x, y, z).
    pub fn eval_pattern(&self, us: &[f64], vs: &[f64], out: &mut Vec<P3>) {
        let bu: Vec<[f64; 4]> = us.iter().map(|&u| basis(u)).collect();
        let bv: Vec<[f64; 4]> = vs.iter().map(|&v| basis(v)).collect();
        out.reserve(self.segs.len() * us.len() * vs.len());
        for seg in &self.segs {
            for bu in &bu {
                // r[k][j] = sum_i bu_i C_ij, then the point is sum_j bv_j r[k][j].
                let mut r = [[0.0; 4]; 3];
                for (k, rk) in r.iter_mut().enumerate() {
                    for (j, rkj) in rk.iter_mut().enumerate() {
                        let c = &seg.c[k];
                        *rkj =
                            bu[0] * c[j] + bu[1] * c[4 + j] + bu[2] * c[8 + j] + bu[3] * c[12 + j];
                    }
                }
                for bv in &bv {
                    out.push(P3::new(dot(&r[0], bv), dot(&r[1], bv), dot(&r[2], bv)));
                }
            }
        }
    }

    /// Heights on a regular (x, y) grid with cells of `cell_mm`, NaN outside the model: each
    /// segment's cells (those in the bounding box of its coefficients, which holds the patch)
    /// are inverted to (u, v) by Newton's method and z evaluated there.
    pub fn eval_heightmap(&self, cell_mm: f64) -> HeightMap {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        self.eval_heightmap_on(cell_mm, cores.min(4))
    }

    /// [`Self::eval_heightmap`] on up to `threads` threads (bands of rows; the same map
    /// whatever the count).
    pub fn eval_heightmap_on(&self, cell_mm: f64, threads: usize) -> HeightMap {
        assert!(cell_mm > 0.0, "cell size must be positive");
        let Some(area) = Lattice::covering(&self.segs, cell_mm) else {
            return HeightMap::new(0.0, 0.0, cell_mm, 0, 0);
        };
        let mut map = area.map(cell_mm);
        let nx = map.nx;
        // Bands of rows on threads of their own: a cell depends only on the segments before
        // it in order and on its own row's neighbours, so every band computes exactly what
        // one pass over the map would (the measurements wait on this map after the last
        // frame, issue 34 item 2).
        let threads = threads.clamp(1, map.ny.div_ceil(64).max(1));
        let band = map.ny.div_ceil(threads);
        if threads <= 1 {
            fill_heights(&self.segs, cell_mm, &area, 0, &mut map.z);
        } else {
            std::thread::scope(|s| {
                for (k, z) in map.z.chunks_mut(band * nx).enumerate() {
                    let area = &area;
                    s.spawn(move || fill_heights(&self.segs, cell_mm, area, k * band, z));
                }
            });
        }
        map
    }

    /// Normal-angle jump across every edge shared by two modelled segments, sampled at
    /// `per_edge` points strictly inside the edge (the corners, where both tangents vanish,
    /// are excluded). Both sides share the edge curve (C0), but the cross-edge tangent of each
    /// side is its second derivative there, so the jump is not zero in general.
    pub fn continuity(&self, per_edge: usize) -> Continuity {
        let mut c = Continuity::default();
        let mut all = Vec::new();
        let mut add = |n1: V3, n2: V3| {
            let d = n1.dot(&n2).clamp(-1.0, 1.0);
            let ang = d.acos().to_degrees();
            if ang.is_finite() {
                all.push(ang);
            }
        };
        let ts: Vec<f64> = (0..per_edge)
            .map(|k| (k as f64 + 0.5) / per_edge as f64)
            .collect();
        for a in 0..self.su {
            for b in 0..self.sv {
                let Some(s0) = self.segment(a, b) else {
                    continue;
                };
                if let Some(s1) = self.segment(a + 1, b) {
                    c.edges += 1;
                    for &t in &ts {
                        add(s0.normal(1.0, t), s1.normal(0.0, t));
                    }
                }
                if let Some(s1) = self.segment(a, b + 1) {
                    c.edges += 1;
                    for &t in &ts {
                        add(s0.normal(t, 1.0), s1.normal(t, 0.0));
                    }
                }
            }
        }
        if !all.is_empty() {
            all.sort_by(f64::total_cmp);
            c.samples = all.len();
            c.mean_deg = all.iter().sum::<f64>() / all.len() as f64;
            c.max_deg = all[all.len() - 1];
            c.p95_deg = all[(all.len() - 1) * 95 / 100];
        }
        c
    }
}

impl Segment {
    /// Segment (a, b) interpolating the points `get(i, j)` of the grid's (a, b) block
    /// (periods `ku`, `kv`: 3, or fewer at the grid's end); None where one is missing.
    pub fn interpolating(
        get: impl Fn(usize, usize) -> P3,
        a: usize,
        b: usize,
        ku: usize,
        kv: usize,
    ) -> Option<Segment> {
        let (eu, ev) = (interpolation_matrix(ku), interpolation_matrix(kv));
        let (i0, j0) = (3 * a, 3 * b);
        let mut p = [[[0.0; 4]; 4]; 3]; // p[coord][i][j]
        for di in 0..=ku {
            for dj in 0..=kv {
                let q = get(i0 + di, j0 + dj);
                if !is_point(&q) {
                    return None;
                }
                for k in 0..3 {
                    p[k][di][dj] = q[k];
                }
            }
        }
        let mut c = [[0.0; 16]; 3];
        for k in 0..3 {
            // t = E_u P (4 x (kv+1)), then C = t E_v^T.
            let mut t = [[0.0; 4]; 4];
            for (i, row) in t.iter_mut().enumerate() {
                for (dj, r) in row.iter_mut().enumerate().take(kv + 1) {
                    *r = (0..=ku).map(|di| eu[i][di] * p[k][di][dj]).sum();
                }
            }
            for i in 0..4 {
                for j in 0..4 {
                    c[k][i * 4 + j] = (0..=kv).map(|dj| t[i][dj] * ev[j][dj]).sum();
                }
            }
        }
        Some(Segment {
            a: a as u32,
            b: b as u32,
            c,
        })
    }

    /// One coordinate at local (u, v): 16 products and the basis in both directions.
    #[inline]
    pub fn eval_coord_generic<T: Scalar>(&self, k: usize, u: T, v: T) -> T {
        let bu = basis(u);
        let bv = basis(v);
        let c = &self.c[k];
        let mut r = [T::from_f64(0.0); 4];
        for (j, rj) in r.iter_mut().enumerate() {
            let col = [
                T::from_f64(c[j]),
                T::from_f64(c[4 + j]),
                T::from_f64(c[8 + j]),
                T::from_f64(c[12 + j]),
            ];
            *rj = dot(&bu, &col);
        }
        dot(&r, &bv)
    }

    #[inline]
    pub fn eval_coord(&self, k: usize, u: f64, v: f64) -> f64 {
        self.eval_coord_generic(k, u, v)
    }

    pub fn eval(&self, u: f64, v: f64) -> P3 {
        P3::new(
            self.eval_coord(0, u, v),
            self.eval_coord(1, u, v),
            self.eval_coord(2, u, v),
        )
    }

    fn contract(&self, k: usize, bu: &[f64; 4], bv: &[f64; 4]) -> f64 {
        let c = &self.c[k];
        let mut s = 0.0;
        for i in 0..4 {
            for j in 0..4 {
                s += bu[i] * bv[j] * c[i * 4 + j];
            }
        }
        s
    }

    /// Value and first partial derivatives of x and y: ((x, y), (x_u, y_u), (x_v, y_v)).
    fn xy_d1(&self, u: f64, v: f64) -> (P2, V2, V2) {
        let (bu, bv, du, dv) = (basis(u), basis(v), basis_d1(u), basis_d1(v));
        let f = |k: usize| {
            // Contract along u first (value and derivative rows), then along v.
            let c = &self.c[k];
            let (mut r, mut d) = ([0.0; 4], [0.0; 4]);
            for j in 0..4 {
                let col = [c[j], c[4 + j], c[8 + j], c[12 + j]];
                r[j] = dot(&bu, &col);
                d[j] = dot(&du, &col);
            }
            (dot(&r, &bv), dot(&d, &bv), dot(&r, &dv))
        };
        let (x, xu, xv) = f(0);
        let (y, yu, yv) = f(1);
        (P2::new(x, y), V2::new(xu, yu), V2::new(xv, yv))
    }

    /// Tangent along u (or v) with the edge limit: where the first derivative vanishes the
    /// direction of the second derivative, signed toward increasing parameter.
    fn tangent(&self, u: f64, v: f64, along_u: bool) -> V3 {
        let (bu, bv) = (basis(u), basis(v));
        let (d1, d2, t) = if along_u {
            ((basis_d1(u), bv), (basis_d2(u), bv), u)
        } else {
            ((bu, basis_d1(v)), (bu, basis_d2(v)), v)
        };
        let first = V3::from([0, 1, 2].map(|k| self.contract(k, &d1.0, &d1.1)));
        let second = V3::from([0, 1, 2].map(|k| self.contract(k, &d2.0, &d2.1)));
        if first.norm() > 1e-12 * (1.0 + second.norm()) {
            first
        } else {
            let sign = if t < 0.5 { 1.0 } else { -1.0 };
            second * sign
        }
    }

    /// Unit normal S_u x S_v at local (u, v) (see [`BezierNetwork::normal`]).
    pub fn normal(&self, u: f64, v: f64) -> V3 {
        let n = self.tangent(u, v, true).cross(&self.tangent(u, v, false));
        n / n.norm()
    }

    /// Bounding box (x0, x1, y0, y1) of the x and y coefficients: the patch lies inside it
    /// (the quintic Bernstein form with doubled ends has control points C_ij).
    pub fn bbox(&self) -> [f64; 4] {
        let (mut b0, mut b1, mut b2, mut b3) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for i in 0..16 {
            b0 = b0.min(self.c[0][i]);
            b1 = b1.max(self.c[0][i]);
            b2 = b2.min(self.c[1][i]);
            b3 = b3.max(self.c[1][i]);
        }
        [b0, b1, b2, b3]
    }

    /// Local (u, v) in [0, 1]^2 with (x, y)(u, v) = (x, y) to 1e-9 mm, by Newton's method
    /// clamped to the unit square. Start: the affine map through three corners. Where the
    /// Jacobian is singular (on an edge, where the across-edge derivative vanishes) the
    /// iterate is nudged 1e-3 inward. None if it does not converge inside the square.
    pub fn invert(&self, x: f64, y: f64) -> Option<(f64, f64)> {
        self.invert_from(x, y, None)
    }

    /// [`Segment::invert`] starting from `start` (e.g. the solution of a neighbouring point)
    /// instead of the affine guess. A point outside the patch is given up on once the
    /// iterate has been clamped on the same side of the square three times running (the map
    /// is close to affine, and near an edge, where it flattens, Newton undershoots rather
    /// than overshoots, so repeated clamping means the point is outside).
    pub fn invert_from(&self, x: f64, y: f64, start: Option<(f64, f64)>) -> Option<(f64, f64)> {
        self.invert_tol(x, y, start, 1e-9)
    }

    /// Newton's method of [`Segment::invert_from`] to a residual of `tol` mm in x and y.
    fn invert_tol(
        &self,
        x: f64,
        y: f64,
        start: Option<(f64, f64)>,
        tol: f64,
    ) -> Option<(f64, f64)> {
        let (mut u, mut v) = match start {
            Some(s) => s,
            None => self.affine_guess(x, y),
        };
        let mut clamped = (0u8, 0u32); // (side code, consecutive count)
        let mut best = f64::INFINITY;
        let mut stuck = 0;
        for _ in 0..60 {
            let (p, du, dv) = self.xy_d1(u, v);
            let (rx, ry) = (p.x - x, p.y - y);
            let r = rx.abs().max(ry.abs());
            if r < tol {
                return Some((u, v));
            }
            if r >= best {
                stuck += 1;
                if stuck > 4 {
                    return None;
                }
            } else {
                best = r;
                stuck = 0;
            }
            let det = du.x * dv.y - dv.x * du.y;
            let scale = (du.x.abs() + du.y.abs() + dv.x.abs() + dv.y.abs()).powi(2);
            if det.abs() <= 1e-14 * scale.max(1e-300) {
                u += (0.5 - u).signum() * 1e-3;
                v += (0.5 - v).signum() * 1e-3;
                continue;
            }
            let su = (rx * dv.y - ry * dv.x) / det;
            let sv = (du.x * ry - du.y * rx) / det;
            let (nu, nv) = (u - su, v - sv);
            // Quadratic convergence: the residual after this step is about |x''| |step|^2,
            // with |x''| at most ~50 times the first derivatives' size here. Accept without
            // another evaluation when that is below the tolerance.
            let size = du.x.abs() + du.y.abs() + dv.x.abs() + dv.y.abs();
            let inside = (0.0..=1.0).contains(&nu) && (0.0..=1.0).contains(&nv);
            if inside && 50.0 * size * (su * su + sv * sv) < tol {
                return Some((nu, nv));
            }
            let side = (nu < 0.0) as u8
                | ((nu > 1.0) as u8) << 1
                | ((nv < 0.0) as u8) << 2
                | ((nv > 1.0) as u8) << 3;
            if side != 0 && side == clamped.0 {
                clamped.1 += 1;
                if clamped.1 >= 3 {
                    return None;
                }
            } else {
                clamped = (side, (side != 0) as u32);
            }
            u = nu.clamp(0.0, 1.0);
            v = nv.clamp(0.0, 1.0);
        }
        None
    }

    /// (u, v) of (x, y) under the affine map through corners (0,0), (1,0), (0,1).
    fn affine_guess(&self, x: f64, y: f64) -> (f64, f64) {
        let p00 = P2::new(self.c[0][0], self.c[1][0]);
        let p10 = P2::new(self.c[0][12], self.c[1][12]);
        let p01 = P2::new(self.c[0][3], self.c[1][3]);
        let (ex, ey) = (p10 - p00, p01 - p00);
        let det = ex.perp(&ey);
        let (dx, dy) = (x - p00.x, y - p00.y);
        if det.abs() > 1e-300 {
            (
                ((dx * ey.y - dy * ey.x) / det).clamp(0.0, 1.0),
                ((ex.x * dy - ex.y * dx) / det).clamp(0.0, 1.0),
            )
        } else {
            (0.5, 0.5)
        }
    }
}

/// Cells of a height map on the absolute lattice of a cell size: cell (i, j) of the map is
/// centred on ((x0 + i) c, (y0 + j) c). Every map of one cell size agrees on where its cells
/// are, so a map filled while a scan runs ([`HeightFill`]) holds the heights a map of the
/// whole network would, bit for bit.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Lattice {
    x0: i64,
    y0: i64,
    nx: usize,
    ny: usize,
}

impl Lattice {
    /// Lattice indices of the cells in `b` (x0, x1, y0, y1 in mm): first and last along x,
    /// first and last along y (empty where first > last).
    fn cells_in(b: &[f64; 4], cell: f64) -> [i64; 4] {
        [
            (b[0] / cell).ceil() as i64,
            (b[1] / cell).floor() as i64,
            (b[2] / cell).ceil() as i64,
            (b[3] / cell).floor() as i64,
        ]
    }

    /// The smallest lattice holding the boxes of `segs` (the cells at or below each box's
    /// lower edge included), or None without segments.
    fn covering(segs: &[Segment], cell: f64) -> Option<Lattice> {
        let mut it = segs.iter().map(|s| Lattice::around(&s.bbox(), cell));
        let first = it.next()?;
        Some(it.fold(first, |a, b| a.union(&b)))
    }

    fn around(b: &[f64; 4], cell: f64) -> Lattice {
        let (x0, y0) = ((b[0] / cell).floor() as i64, (b[2] / cell).floor() as i64);
        let (x1, y1) = ((b[1] / cell).floor() as i64, (b[3] / cell).floor() as i64);
        Lattice {
            x0,
            y0,
            nx: (x1 - x0).max(0) as usize + 1,
            ny: (y1 - y0).max(0) as usize + 1,
        }
    }

    fn union(&self, o: &Lattice) -> Lattice {
        let (x0, y0) = (self.x0.min(o.x0), self.y0.min(o.y0));
        let x1 = (self.x0 + self.nx as i64).max(o.x0 + o.nx as i64);
        let y1 = (self.y0 + self.ny as i64).max(o.y0 + o.ny as i64);
        Lattice {
            x0,
            y0,
            nx: (x1 - x0) as usize,
            ny: (y1 - y0) as usize,
        }
    }

    fn contains(&self, o: &Lattice) -> bool {
        self.union(o) == *self
    }

    /// An empty (NaN) map on this lattice.
    fn map(&self, cell: f64) -> HeightMap {
        self.map_of(cell, vec![f64::NAN; self.nx * self.ny])
    }

    /// The map on this lattice holding `z` (row-major, `nx * ny` cells).
    fn map_of(&self, cell: f64, z: Vec<f64>) -> HeightMap {
        debug_assert_eq!(z.len(), self.nx * self.ny);
        HeightMap {
            x0: self.x0 as f64 * cell,
            y0: self.y0 as f64 * cell,
            cell_mm: cell,
            nx: self.nx,
            ny: self.ny,
            z,
        }
    }
}

/// Heights of `segs`, in their order, into the rows `row0..` of a map on `area` (`z` holds
/// whole rows from row `row0` on). Each segment's cells (those in the bounding box of its
/// coefficients, which holds the patch) are inverted to (u, v) by Newton's method and z
/// evaluated there; a cell an earlier segment filled is kept.
fn fill_heights(segs: &[Segment], cell: f64, area: &Lattice, row0: usize, z: &mut [f64]) {
    let nx = area.nx;
    let rows = row0..row0 + z.len() / nx;
    for seg in segs {
        let [i0, i1, j0, j1] = Lattice::cells_in(&seg.bbox(), cell);
        let (i0, i1) = ((i0 - area.x0).max(0), (i1 - area.x0).min(nx as i64 - 1));
        let (j0, j1) = (
            (j0 - area.y0).max(0),
            (j1 - area.y0).min(area.ny as i64 - 1),
        );
        if i0 > i1 || j0 > j1 {
            continue;
        }
        let (i0, i1) = (i0 as usize, i1 as usize);
        for j in (j0 as usize).max(rows.start)..=(j1 as usize).min(rows.end.saturating_sub(1)) {
            let zr = &mut z[(j - row0) * nx..(j - row0 + 1) * nx];
            let y = (area.y0 + j as i64) as f64 * cell;
            // Start each cell from its left neighbours' solutions (extrapolated) when they
            // had one.
            let mut prev: Option<(f64, f64)> = None;
            let mut prev2: Option<(f64, f64)> = None;
            for (i, zc) in zr.iter_mut().enumerate().take(i1 + 1).skip(i0) {
                if zc.is_finite() {
                    (prev, prev2) = (None, None);
                    continue;
                }
                let guess = match (prev, prev2) {
                    (Some(a), Some(b)) => Some((
                        (2.0 * a.0 - b.0).clamp(0.0, 1.0),
                        (2.0 * a.1 - b.1).clamp(0.0, 1.0),
                    )),
                    (a, _) => a,
                };
                let x = (area.x0 + i as i64) as f64 * cell;
                // 1e-7 mm in (x, y) is far below any height the map can show.
                let found = match guess {
                    Some(p) => seg
                        .invert_tol(x, y, Some(p), 1e-7)
                        .or_else(|| seg.invert_tol(x, y, None, 1e-7)),
                    None => seg.invert_tol(x, y, None, 1e-7),
                };
                if let Some((u, v)) = found {
                    *zc = seg.eval_coord(2, u, v);
                }
                prev2 = if found.is_some() { prev } else { None };
                prev = found;
            }
        }
    }
}

/// A network's height map filled segment by segment while its grid grows (a scan's frames
/// arrive in order along u, and a column of segments is final once the three frames after
/// its first have come), so that after the last frame only the last columns are left.
/// [`HeightFill::finish`] checks the segments it was given against the finished network and
/// gives exactly [`BezierNetwork::eval_heightmap`]'s heights (on a lattice that may reach
/// further), or that map itself when they differ (frames bridged or changed after they were
/// given).
#[derive(Debug)]
pub struct HeightFill {
    cell: f64,
    area: Option<Lattice>,
    z: Vec<f64>,
    segs: Vec<Segment>,
}

impl HeightFill {
    pub fn new(cell_mm: f64) -> Self {
        assert!(cell_mm > 0.0, "cell size must be positive");
        HeightFill {
            cell: cell_mm,
            area: None,
            z: Vec::new(),
            segs: Vec::new(),
        }
    }

    /// Segments given so far.
    pub fn len(&self) -> usize {
        self.segs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.segs.is_empty()
    }

    /// Fill the cells of `segs`, the network's next segments in its order.
    pub fn add(&mut self, segs: &[Segment]) {
        let Some(need) = Lattice::covering(segs, self.cell) else {
            return;
        };
        let area = match self.area {
            Some(a) if a.contains(&need) => a,
            _ => self.grow(need),
        };
        fill_heights(segs, self.cell, &area, 0, &mut self.z);
        self.segs.extend_from_slice(segs);
    }

    /// A larger map holding `need`, with room to grow (half as wide again and an eighth as
    /// high each way, so a scan's map is copied a few times, not once a column).
    fn grow(&mut self, need: Lattice) -> Lattice {
        let u = self.area.map_or(need, |a| a.union(&need));
        let (mx, my) = (u.nx / 2 + 16, u.ny / 8 + 16);
        let grown = Lattice {
            x0: u.x0 - mx as i64,
            y0: u.y0 - my as i64,
            nx: u.nx + 2 * mx,
            ny: u.ny + 2 * my,
        };
        let mut z = vec![f64::NAN; grown.nx * grown.ny];
        if let Some(old) = self.area {
            copy_into(&self.z, &old, &mut z, &grown);
        }
        self.z = z;
        self.area = Some(grown);
        grown
    }

    /// The network's height map: the segments not given yet filled in. Each cell holds
    /// exactly what [`BezierNetwork::eval_heightmap`] gives for it, but the map may reach
    /// further (NaN there): the room it kept to grow, not cut off, since a copy of the map
    /// would cost more than the measurement that reads it by position. When the segments
    /// given are not the network's first ones, `eval_heightmap` itself.
    pub fn finish(mut self, net: &BezierNetwork) -> HeightMap {
        let k = self.segs.len();
        if net.segs.len() < k || net.segs[..k] != self.segs[..] {
            tracing::debug!(
                given = k,
                "height map: the segments given are not the network's; computed again"
            );
            return net.eval_heightmap(self.cell);
        }
        self.add(&net.segs[k..]);
        match self.area {
            Some(area) => area.map_of(self.cell, self.z),
            None => HeightMap::new(0.0, 0.0, self.cell, 0, 0),
        }
    }
}

/// Copy a map on `from` into a map on `to`, which holds it.
fn copy_into(src: &[f64], from: &Lattice, dst: &mut [f64], to: &Lattice) {
    let (di, dj) = ((from.x0 - to.x0) as usize, (from.y0 - to.y0) as usize);
    for (j, row) in src.chunks_exact(from.nx).enumerate() {
        let d0 = (j + dj) * to.nx + di;
        dst[d0..d0 + from.nx].copy_from_slice(row);
    }
}

/// Uniform buckets over the segments' bounding boxes, for point location.
#[derive(Debug)]
struct Locator {
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Locator {
    fn new(segs: &[Segment]) -> Self {
        let boxes: Vec<[f64; 4]> = segs.iter().map(Segment::bbox).collect();
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        let mut size = Vec::with_capacity(boxes.len());
        for b in &boxes {
            x0 = x0.min(b[0]);
            x1 = x1.max(b[1]);
            y0 = y0.min(b[2]);
            y1 = y1.max(b[3]);
            size.push((b[1] - b[0]).max(b[3] - b[2]));
        }
        if boxes.is_empty() {
            return Locator {
                x0: 0.0,
                y0: 0.0,
                cell: 1.0,
                nx: 0,
                ny: 0,
                start: vec![0],
                items: Vec::new(),
            };
        }
        size.sort_by(f64::total_cmp);
        let cell = (2.0 * size[size.len() / 2]).max(1e-6);
        let nx = (((x1 - x0) / cell).floor() as usize + 1).min(1 << 14);
        let ny = (((y1 - y0) / cell).floor() as usize + 1).min(1 << 14);
        let cell = cell.max((x1 - x0) / nx as f64).max((y1 - y0) / ny as f64) * (1.0 + 1e-12);
        let range = |b: &[f64; 4]| {
            let i0 = ((b[0] - x0) / cell) as usize;
            let i1 = (((b[1] - x0) / cell) as usize).min(nx - 1);
            let j0 = ((b[2] - y0) / cell) as usize;
            let j1 = (((b[3] - y0) / cell) as usize).min(ny - 1);
            (i0, i1, j0, j1)
        };
        let mut count = vec![0u32; nx * ny + 1];
        for b in &boxes {
            let (i0, i1, j0, j1) = range(b);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    count[j * nx + i + 1] += 1;
                }
            }
        }
        for k in 1..count.len() {
            count[k] += count[k - 1];
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; *count.last().unwrap() as usize];
        for (s, b) in boxes.iter().enumerate() {
            let (i0, i1, j0, j1) = range(b);
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let slot = &mut fill[j * nx + i];
                    items[*slot as usize] = s as u32;
                    *slot += 1;
                }
            }
        }
        Locator {
            x0,
            y0,
            cell,
            nx,
            ny,
            start: count,
            items,
        }
    }

    fn candidates(&self, x: f64, y: f64) -> &[u32] {
        let (fx, fy) = ((x - self.x0) / self.cell, (y - self.y0) / self.cell);
        if !(fx >= 0.0 && fy >= 0.0) {
            return &[];
        }
        let (i, j) = (fx as usize, fy as usize);
        if i >= self.nx || j >= self.ny {
            return &[];
        }
        let k = j * self.nx + i;
        &self.items[self.start[k] as usize..self.start[k + 1] as usize]
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A smooth surface on an irregular grid (x spacing varies, y depends on z).
    fn wavy(nu: usize, nv: usize) -> PointGrid {
        let mut pts = Vec::new();
        for i in 0..nu {
            let x = i as f64 * 0.5 + 0.02 * (i as f64 * 0.3).sin();
            for j in 0..nv {
                let y0 = j as f64 * 0.25;
                let z = 3.0 + (x * 0.2).sin() * (y0 * 0.3).cos();
                pts.push([x, y0 * (1.0 + z / 250.0), z]);
            }
        }
        PointGrid::new(nu, nv, pts.into_iter().map(P3::from).collect())
    }

    #[test]
    fn interpolates_every_point_with_short_edge_segments() {
        for (nu, nv) in [(10, 13), (11, 12), (12, 11), (2, 2), (3, 4)] {
            let g = wavy(nu, nv);
            let n = BezierNetwork::build(&g).unwrap();
            assert_eq!(n.skipped(), 0);
            for i in 0..nu {
                for j in 0..nv {
                    let p = n.eval(i as f64, j as f64).unwrap();
                    let q = g.get(i, j);
                    for k in 0..3 {
                        assert!(
                            (p[k] - q[k]).abs() < 1e-9,
                            "{nu}x{nv} ({i},{j}) {p:?} {q:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn missing_points_drop_their_segments() {
        let mut g = wavy(10, 10);
        g.set(4, 4, P3::from([f64::NAN; 3])); // inside segment (1, 1) only
        g.set(3, 5, P3::from([f64::NAN; 3])); // on the shared edge of (0, 1) and (1, 1)
        let n = BezierNetwork::build(&g).unwrap();
        assert_eq!(n.lattice(), (3, 3));
        assert_eq!(n.skipped(), 2);
        assert!(n.segment(1, 1).is_none() && n.segment(0, 1).is_none());
        assert!(n.eval(4.0, 4.0).is_none());
        assert!(n.eval(7.0, 7.0).is_some());
    }

    #[test]
    fn inversion_and_heightmap_agree_with_parametric_points() {
        let g = wavy(31, 40);
        let n = BezierNetwork::build(&g).unwrap();
        for &(s, t) in &[
            (1.3, 2.2),
            (3.0, 4.5),
            (17.25, 30.0),
            (29.9, 38.1),
            (6.0, 9.0),
        ] {
            let p = n.eval(s, t).unwrap();
            let (q, s2, t2) = n.point_at(p[0], p[1]).unwrap();
            assert!((q[2] - p[2]).abs() < 1e-8, "({s},{t}): {p:?} vs {q:?}");
            assert!(
                (s2 - s).abs() < 1e-3 && (t2 - t).abs() < 1e-3,
                "({s},{t}) -> ({s2},{t2})"
            );
        }
        let m = n.eval_heightmap(0.3);
        assert!(m.valid_count() > 1000);
        let mut checked = 0;
        for j in 0..m.ny {
            for i in 0..m.nx {
                let z = m.get(i, j);
                if z.is_finite() {
                    let h = n.height_at(m.x(i), m.y(j)).unwrap();
                    assert!((h - z).abs() < 1e-6);
                    checked += 1;
                }
            }
        }
        assert_eq!(checked, m.valid_count());
        // Interior cells are all covered.
        let (x, y) = (7.0, 5.0);
        let (i, j) = m.cell_of(x, y).unwrap();
        assert!(m.get(i, j).is_finite());
    }

    /// The map on bands of rows on several threads is the one-pass map, bit for bit (NaN
    /// where it is NaN): the measurements must not change with the core count.
    #[test]
    fn the_height_map_is_the_same_on_any_number_of_threads() {
        let n = BezierNetwork::build(&wavy(61, 80)).unwrap();
        let one = n.eval_heightmap_on(0.05, 1);
        assert!(one.ny > 3 * 64, "enough rows for several bands: {}", one.ny);
        for threads in [2, 3, 4] {
            let many = n.eval_heightmap_on(0.05, threads);
            assert_eq!(
                (many.nx, many.ny, many.x0, many.y0),
                (one.nx, one.ny, one.x0, one.y0)
            );
            let same = one
                .z
                .iter()
                .zip(&many.z)
                .all(|(a, b)| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
            assert!(same, "{threads} threads");
        }
    }

    fn same_map(a: &HeightMap, b: &HeightMap) -> bool {
        (a.nx, a.ny, a.x0, a.y0, a.cell_mm) == (b.nx, b.ny, b.x0, b.y0, b.cell_mm)
            && a.z
                .iter()
                .zip(&b.z)
                .all(|(p, q)| p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()))
    }

    /// `got` holds `want`'s heights bit for bit at `want`'s cells and nothing elsewhere.
    pub(crate) fn same_heights(got: &HeightMap, want: &HeightMap) -> bool {
        let mut n = 0;
        for j in 0..want.ny {
            for i in 0..want.nx {
                let w = want.get(i, j);
                let g = got
                    .cell_of(want.x(i), want.y(j))
                    .map_or(f64::NAN, |(a, b)| got.get(a, b));
                if !(w.to_bits() == g.to_bits() || (w.is_nan() && g.is_nan())) {
                    return false;
                }
                n += w.is_finite() as usize;
            }
        }
        got.cell_mm == want.cell_mm && got.valid_count() == n
    }

    /// Filled column by column as a scan's frames come, the map holds the whole network's
    /// heights bit for bit, and so does a fill given segments of another grid (computed
    /// again).
    #[test]
    fn a_map_filled_column_by_column_is_the_whole_map() {
        let mut g = wavy(61, 80);
        // A hole, so some segments are left out and the order has gaps.
        for (i, j) in [(20, 30), (21, 31), (40, 5)] {
            g.set(i, j, P3::from([f64::NAN; 3]));
        }
        let n = BezierNetwork::build(&g).unwrap();
        assert!(n.skipped() > 0);
        let whole = n.eval_heightmap_on(0.05, 1);
        assert!(whole.valid_count() > 10_000, "{}", whole.valid_count());
        let mut fill = HeightFill::new(0.05);
        let last = n.segments().last().unwrap().a;
        for a in 0..last {
            let col: Vec<Segment> = n.segments().iter().filter(|s| s.a == a).cloned().collect();
            fill.add(&col);
        }
        assert!(fill.len() > n.segments().len() * 9 / 10);
        assert!(same_heights(&fill.finish(&n), &whole));

        let mut other = g.clone();
        other.set(3, 3, P3::new(1.0, 0.8, 3.5));
        let o = BezierNetwork::build(&other).unwrap();
        let mut fill = HeightFill::new(0.05);
        fill.add(&o.segments()[..o.segments().len() / 2]);
        assert!(same_map(&fill.finish(&n), &whole));
    }

    #[test]
    fn normals_point_up_and_edges_show_a_jump() {
        let g = wavy(31, 40);
        let n = BezierNetwork::build(&g).unwrap();
        let nn = n.normal(4.0, 5.5).unwrap();
        assert!(nn[2] > 0.9);
        assert!(((nn[0].powi(2) + nn[1].powi(2) + nn[2].powi(2)).sqrt() - 1.0).abs() < 1e-12);
        let c = n.continuity(8);
        assert_eq!(c.edges, 9 * 13 + 10 * 12);
        assert!(c.max_deg > 0.0 && c.max_deg < 10.0, "{c:?}");
        // A plane z = 0.1 x + 0.2 y on a uniform grid has no jump.
        let mut pts = Vec::new();
        for i in 0..10 {
            for j in 0..10 {
                let (x, y) = (i as f64, j as f64 * 0.5);
                pts.push([x, y, 0.1 * x + 0.2 * y]);
            }
        }
        let p = BezierNetwork::build(&PointGrid::new(
            10,
            10,
            pts.into_iter().map(P3::from).collect(),
        ))
        .unwrap();
        let c = p.continuity(8);
        assert!(c.max_deg < 1e-5, "{c:?}"); // acos near 1 resolves ~1e-6 deg
    }
}
