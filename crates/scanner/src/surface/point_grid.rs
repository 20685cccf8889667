//! A structured grid of 3D points, u (frames) by v (rows), NaN where there is no point: what
//! every surface model here is built from.

use crate::scandata::ScanGrid;
use footscan_geom::P3;

/// Index order: u-major, v fastest: point (i, j) is `points[i * nv + j]` ([`Self::index`]).
/// This is the scan's order (a frame's rows arrive together and `grid.bin` stores them so, see
/// [`ScanGrid::point`]), which is why [`Self::from_scan`] copies without reordering; it is the
/// transpose of [`crate::geom::HeightMap`]'s image order (`z[j * nx + i]`). Use [`Self::get`],
/// [`Self::set`] and [`Self::index`] rather than indexing `points` by hand.
#[derive(Clone, Debug, PartialEq)]
pub struct PointGrid {
    /// Points along u (scan frames).
    pub nu: usize,
    /// Points along v (image rows).
    pub nv: usize,
    /// `nu * nv`, u-major (`points[i * nv + j]`); NaN marks a missing point.
    pub points: Vec<P3>,
}

/// Which scan frames and rows a sub-grid keeps.
#[derive(Clone, Debug, PartialEq)]
pub struct Subsample {
    pub frames: Vec<usize>,
    pub rows: Vec<usize>,
}

impl PointGrid {
    pub fn new(nu: usize, nv: usize, points: Vec<P3>) -> Self {
        assert_eq!(points.len(), nu * nv, "point count != nu * nv");
        PointGrid { nu, nv, points }
    }

    /// A height function sampled at `xs` (u) by `ys` (v); NaN where it has no value.
    pub fn sample(f: impl Fn(f64, f64) -> Option<f64>, xs: &[f64], ys: &[f64]) -> Self {
        let mut pts = Vec::with_capacity(xs.len() * ys.len());
        for &x in xs {
            for &y in ys {
                pts.push(f(x, y).map_or(P3::from([f64::NAN; 3]), |z| P3::new(x, y, z)));
            }
        }
        PointGrid::new(xs.len(), ys.len(), pts)
    }

    /// The whole scan grid: u = frame, v = row.
    pub fn from_scan(g: &ScanGrid) -> Self {
        PointGrid::new(g.frames.len(), g.rows, g.points.clone())
    }

    /// Position of point (i, j) in `points`: `i * nv + j`.
    #[inline]
    pub fn index(&self, i: usize, j: usize) -> usize {
        i * self.nv + j
    }

    #[inline]
    pub fn get(&self, i: usize, j: usize) -> P3 {
        self.points[self.index(i, j)]
    }

    #[inline]
    pub fn set(&mut self, i: usize, j: usize, p: P3) {
        let k = self.index(i, j);
        self.points[k] = p;
    }

    #[inline]
    pub fn is_valid(&self, i: usize, j: usize) -> bool {
        is_point(&self.get(i, j))
    }

    pub fn valid_count(&self) -> usize {
        self.points.iter().filter(|p| is_point(p)).count()
    }

    /// Index bounding box of the valid points: (first frame, last frame, first row, last row).
    pub fn valid_bounds(&self) -> Option<(usize, usize, usize, usize)> {
        let mut b: Option<(usize, usize, usize, usize)> = None;
        for i in 0..self.nu {
            for j in 0..self.nv {
                if self.is_valid(i, j) {
                    b = Some(match b {
                        None => (i, i, j, j),
                        Some((i0, i1, j0, j1)) => (i0.min(i), i1.max(i), j0.min(j), j1.max(j)),
                    });
                }
            }
        }
        b
    }

    /// `n_u` frames and `n_v` rows evenly spaced in index over the bounding box of the valid
    /// points (rounded to the nearest index): the Table-1 configuration is `even(88, 91)`.
    pub fn even_subsample(&self, n_u: usize, n_v: usize) -> Option<Subsample> {
        let (i0, i1, j0, j1) = self.valid_bounds()?;
        let pick = |a: usize, b: usize, n: usize| -> Vec<usize> {
            if n <= 1 || b == a {
                return vec![a];
            }
            let mut v: Vec<usize> = (0..n)
                .map(|k| a + ((b - a) as f64 * k as f64 / (n - 1) as f64).round() as usize)
                .collect();
            v.dedup();
            v
        };
        Some(Subsample {
            frames: pick(i0, i1, n_u),
            rows: pick(j0, j1, n_v),
        })
    }

    pub fn subsample(&self, s: &Subsample) -> PointGrid {
        let mut pts = Vec::with_capacity(s.frames.len() * s.rows.len());
        for &i in &s.frames {
            for &j in &s.rows {
                pts.push(self.get(i, j));
            }
        }
        PointGrid::new(s.frames.len(), s.rows.len(), pts)
    }

    /// The grid with every missing point filled, for the tensor-product comparators that need
    /// a complete rectangle (the Bezier network does not: it leaves such segments out).
    /// z: the nearest valid point along v in the same frame (constant extension); frames with
    /// no point copy the nearest frame that has one. x: the frame's mean valid x (offset from
    /// its neighbours for empty frames). y: the nearest valid y along v plus the grid's median
    /// row step times the index distance, so the fill stays a regular parametrisation.
    pub fn filled(&self) -> Option<PointGrid> {
        let (nu, nv) = (self.nu, self.nv);
        let mut out = self.points.clone();
        // Median y step per row over valid neighbours.
        let mut steps: Vec<f64> = Vec::new();
        for i in 0..nu {
            for j in 1..nv {
                let (a, b) = (self.get(i, j - 1), self.get(i, j));
                if is_point(&a) && is_point(&b) {
                    steps.push(b[1] - a[1]);
                }
            }
        }
        let dy = if steps.is_empty() {
            1.0
        } else {
            steps.sort_by(f64::total_cmp);
            steps[steps.len() / 2]
        };
        let mut has = vec![false; nu];
        let mut frame_x = vec![f64::NAN; nu];
        for i in 0..nu {
            let valid: Vec<usize> = (0..nv).filter(|&j| self.is_valid(i, j)).collect();
            if valid.is_empty() {
                continue;
            }
            has[i] = true;
            frame_x[i] = valid.iter().map(|&j| self.get(i, j)[0]).sum::<f64>() / valid.len() as f64;
            // Nearest valid index along v for each j (two sweeps).
            let mut near = vec![usize::MAX; nv];
            let mut last = usize::MAX;
            for (j, n) in near.iter_mut().enumerate() {
                if self.is_valid(i, j) {
                    last = j;
                }
                *n = last;
            }
            let mut next = usize::MAX;
            for j in (0..nv).rev() {
                if self.is_valid(i, j) {
                    next = j;
                }
                let prev = near[j];
                near[j] = match (prev, next) {
                    (usize::MAX, n) => n,
                    (p, usize::MAX) => p,
                    (p, n) => {
                        if j - p <= n - j {
                            p
                        } else {
                            n
                        }
                    }
                };
            }
            for j in 0..nv {
                if !self.is_valid(i, j) {
                    let s = self.get(i, near[j]);
                    out[i * nv + j] =
                        P3::new(frame_x[i], s.y + dy * (j as f64 - near[j] as f64), s.z);
                }
            }
        }
        let first = has.iter().position(|&h| h)?;
        let last = has.iter().rposition(|&h| h)?;
        // Mean x step between frames with points, to place empty frames.
        let dx = if last > first {
            (frame_x[last] - frame_x[first]) / (last - first) as f64
        } else {
            1.0
        };
        for i in 0..nu {
            if has[i] {
                continue;
            }
            // Nearest frame with points.
            let src = (0..nu)
                .filter(|&k| has[k])
                .min_by_key(|&k| k.abs_diff(i))
                .unwrap();
            for j in 0..nv {
                let s = out[src * nv + j];
                out[i * nv + j] = P3::new(s.x + dx * (i as f64 - src as f64), s.y, s.z);
            }
        }
        Some(PointGrid::new(nu, nv, out))
    }
}

#[inline]
pub(crate) fn is_point(p: &P3) -> bool {
    p.x.is_finite() && p.y.is_finite() && p.z.is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn subsample_and_fill() {
        let nan = P3::from([f64::NAN; 3]);
        let mut pts = vec![nan; 5 * 4];
        for i in 1..4 {
            for j in 1..3 {
                pts[i * 4 + j] = P3::new(i as f64, j as f64 * 0.5, (i + j) as f64);
            }
        }
        let g = PointGrid::new(5, 4, pts);
        assert_eq!(g.valid_bounds(), Some((1, 3, 1, 2)));
        let s = g.even_subsample(3, 2).unwrap();
        assert_eq!(s.frames, vec![1, 2, 3]);
        assert_eq!(s.rows, vec![1, 2]);
        assert_eq!(g.subsample(&s).valid_count(), 6);
        let f = g.filled().unwrap();
        assert_eq!(f.valid_count(), 20);
        assert_eq!(f.get(1, 0), P3::new(1.0, 0.0, 2.0));
        assert_eq!(f.get(2, 3), P3::new(2.0, 1.5, 4.0));
        assert_eq!(f.get(0, 1), P3::new(0.0, 0.5, 2.0));
        assert_eq!(f.get(4, 2), P3::new(4.0, 1.0, 5.0));
    }
}
