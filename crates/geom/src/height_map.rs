use std::collections::VecDeque;

/// Heights on a regular (x, y) grid in world millimetres: what the plantar model evaluates to
/// and what measurement works on. Cell (i, j) is centred at (x0 + i·cell, y0 + j·cell);
/// NaN marks cells outside the footprint.
///
/// Index order: row-major by y, x fastest: cell (i, j) is `z[j * nx + i]` ([`Self::index`],
/// [`Self::cell`] for the way back). This is an image's order (a row of the height-map PNG is
/// one y), unlike the scanner's `surface::PointGrid`, which keeps the scan's order (frame outer,
/// `points[i * nv + j]`). Use [`Self::get`], [`Self::set`], [`Self::index`] and
/// [`Self::cell`] rather than indexing `z` by hand, so the two orders are never confused.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HeightMap {
    pub x0: f64,
    pub y0: f64,
    pub cell_mm: f64,
    pub nx: usize,
    pub ny: usize,
    /// Row-major by y: `z[j * nx + i]`.
    pub z: Vec<f64>,
}

impl HeightMap {
    pub fn new(x0: f64, y0: f64, cell_mm: f64, nx: usize, ny: usize) -> Self {
        assert!(cell_mm > 0.0, "cell size must be positive");
        HeightMap {
            x0,
            y0,
            cell_mm,
            nx,
            ny,
            z: vec![f64::NAN; nx * ny],
        }
    }

    #[inline]
    pub fn x(&self, i: usize) -> f64 {
        self.x0 + i as f64 * self.cell_mm
    }

    #[inline]
    pub fn y(&self, j: usize) -> f64 {
        self.y0 + j as f64 * self.cell_mm
    }

    /// Position of cell (i, j) in `z`: `j * nx + i`.
    #[inline]
    pub fn index(&self, i: usize, j: usize) -> usize {
        j * self.nx + i
    }

    /// Cell (i, j) of position `k` in `z`: the inverse of [`Self::index`].
    #[inline]
    pub fn cell(&self, k: usize) -> (usize, usize) {
        (k % self.nx, k / self.nx)
    }

    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.z[self.index(i, j)]
    }

    #[inline]
    pub fn set(&mut self, i: usize, j: usize, z: f64) {
        let k = self.index(i, j);
        self.z[k] = z;
    }

    /// Nearest cell of a world point, if inside the map.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let i = ((x - self.x0) / self.cell_mm).round();
        let j = ((y - self.y0) / self.cell_mm).round();
        (i >= 0.0 && j >= 0.0 && (i as usize) < self.nx && (j as usize) < self.ny)
            .then_some((i as usize, j as usize))
    }

    /// A height field sampled at the cell centres of the box [x0, x1] x [y0, y1] (NaN where
    /// `h` has no height): how the simulator's analytic surfaces become maps for tests.
    pub fn sampled(
        [x0, y0]: [f64; 2],
        [x1, y1]: [f64; 2],
        cell_mm: f64,
        h: impl Fn(f64, f64) -> Option<f64>,
    ) -> Self {
        let nx = ((x1 - x0) / cell_mm) as usize;
        let ny = ((y1 - y0) / cell_mm) as usize;
        let mut m = HeightMap::new(x0, y0, cell_mm, nx, ny);
        for j in 0..ny {
            for i in 0..nx {
                if let Some(z) = h(m.x(i), m.y(j)) {
                    m.set(i, j, z);
                }
            }
        }
        m
    }

    /// Cells with a height.
    pub fn valid_count(&self) -> usize {
        self.z.iter().filter(|z| z.is_finite()).count()
    }

    /// Bilinear height at (x, y). Where some of the four surrounding cells are NaN the finite
    /// ones are blended by their bilinear weights (so the edge of a footprint keeps its
    /// heights); NaN when none is finite or (x, y) is outside the grid.
    pub fn sample(&self, x: f64, y: f64) -> f64 {
        let fx = (x - self.x0) / self.cell_mm;
        let fy = (y - self.y0) / self.cell_mm;
        if !(fx > -0.5 && fy > -0.5 && fx < self.nx as f64 - 0.5 && fy < self.ny as f64 - 0.5) {
            return f64::NAN;
        }
        let i0 = (fx.floor().max(0.0) as usize).min(self.nx.saturating_sub(2));
        let j0 = (fy.floor().max(0.0) as usize).min(self.ny.saturating_sub(2));
        let (tx, ty) = (
            (fx - i0 as f64).clamp(0.0, 1.0),
            (fy - j0 as f64).clamp(0.0, 1.0),
        );
        let (i1, j1) = ((i0 + 1).min(self.nx - 1), (j0 + 1).min(self.ny - 1));
        let corners = [
            (self.get(i0, j0), (1.0 - tx) * (1.0 - ty)),
            (self.get(i1, j0), tx * (1.0 - ty)),
            (self.get(i0, j1), (1.0 - tx) * ty),
            (self.get(i1, j1), tx * ty),
        ];
        let (mut s, mut w) = (0.0, 0.0);
        for (z, wt) in corners {
            if z.is_finite() {
                s += z * wt;
                w += wt;
            }
        }
        if w > 1e-9 {
            s / w
        } else {
            // Exactly on a NaN corner's side: the nearest finite corner.
            corners
                .iter()
                .find(|c| c.0.is_finite())
                .map_or(f64::NAN, |c| c.0)
        }
    }

    /// Bilinear height at (x, y) only where all four surrounding cells are finite.
    pub fn sample_full(&self, x: f64, y: f64) -> Option<f64> {
        let fx = (x - self.x0) / self.cell_mm;
        let fy = (y - self.y0) / self.cell_mm;
        if !(fx >= 0.0 && fy >= 0.0 && fx <= (self.nx - 1) as f64 && fy <= (self.ny - 1) as f64) {
            return None;
        }
        let i0 = (fx as usize).min(self.nx.saturating_sub(2));
        let j0 = (fy as usize).min(self.ny.saturating_sub(2));
        let (tx, ty) = (fx - i0 as f64, fy - j0 as f64);
        let k = j0 * self.nx + i0;
        let (a, b, c, d) = (
            self.z[k],
            self.z[k + 1],
            self.z[k + self.nx],
            self.z[k + self.nx + 1],
        );
        let v = (1.0 - ty) * ((1.0 - tx) * a + tx * b) + ty * ((1.0 - tx) * c + tx * d);
        v.is_finite().then_some(v)
    }

    /// [`HeightMap::sample`] with (x, y) clamped into the grid first.
    pub fn sample_clamped(&self, x: f64, y: f64) -> f64 {
        let xm = self.x(self.nx - 1);
        let ym = self.y(self.ny - 1);
        self.sample(x.clamp(self.x0, xm), y.clamp(self.y0, ym))
    }

    /// Fills every NaN cell from its finite neighbours, layer by layer outward (breadth first
    /// over 4-neighbours, each new cell the mean of its already known 8-neighbours): a cheap
    /// continuation that keeps the known cells and costs one visit per cell.
    pub fn fill(&mut self) {
        let (nx, ny) = (self.nx, self.ny);
        let mut known: Vec<bool> = self.z.iter().map(|z| z.is_finite()).collect();
        let mut queued = known.clone();
        let mut q = VecDeque::new();
        for j in 0..ny {
            for i in 0..nx {
                let k = j * nx + i;
                if known[k] {
                    continue;
                }
                if neighbours4(i, j, nx, ny).any(|n| known[n]) {
                    queued[k] = true;
                    q.push_back(k);
                }
            }
        }
        while let Some(k) = q.pop_front() {
            let (i, j) = (k % nx, k / nx);
            let (mut s, mut n) = (0.0, 0.0);
            for dj in -1i64..=1 {
                for di in -1i64..=1 {
                    let (ii, jj) = (i as i64 + di, j as i64 + dj);
                    if (di, dj) == (0, 0) || ii < 0 || jj < 0 || ii >= nx as i64 || jj >= ny as i64
                    {
                        continue;
                    }
                    let m = jj as usize * nx + ii as usize;
                    if known[m] {
                        let w = if di == 0 || dj == 0 { 1.0 } else { 0.5 };
                        s += w * self.z[m];
                        n += w;
                    }
                }
            }
            if n > 0.0 {
                self.z[k] = s / n;
                known[k] = true;
            }
            for m in neighbours4(i, j, nx, ny) {
                if !queued[m] {
                    queued[m] = true;
                    q.push_back(m);
                }
            }
        }
    }

    /// `passes` Jacobi passes of the 4-neighbour mean over the cells where `active` is true;
    /// `pinned` cells and cells missing a neighbour keep their heights.
    pub fn smooth4(&mut self, active: &[bool], pinned: &[bool], passes: usize) {
        let (nx, ny) = (self.nx, self.ny);
        let mut next = self.z.clone();
        for _ in 0..passes {
            for j in 1..ny.saturating_sub(1) {
                for i in 1..nx - 1 {
                    let k = j * nx + i;
                    if !active[k] || pinned[k] {
                        continue;
                    }
                    let s = self.z[k - 1] + self.z[k + 1] + self.z[k - nx] + self.z[k + nx];
                    if s.is_finite() {
                        next[k] = s / 4.0;
                    }
                }
            }
            std::mem::swap(&mut self.z, &mut next);
            next.copy_from_slice(&self.z);
        }
    }
}

fn neighbours4(i: usize, j: usize, nx: usize, ny: usize) -> impl Iterator<Item = usize> {
    let mut v = [usize::MAX; 4];
    if i > 0 {
        v[0] = j * nx + i - 1;
    }
    if i + 1 < nx {
        v[1] = j * nx + i + 1;
    }
    if j > 0 {
        v[2] = (j - 1) * nx + i;
    }
    if j + 1 < ny {
        v[3] = (j + 1) * nx + i;
    }
    v.into_iter().filter(|&k| k != usize::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_centres_and_lookup() {
        let mut m = HeightMap::new(10.0, -5.0, 0.5, 4, 3);
        assert_eq!(m.valid_count(), 0);
        m.set(3, 2, 1.5);
        assert_eq!(m.get(3, 2), 1.5);
        assert_eq!((m.x(3), m.y(2)), (11.5, -4.0));
        assert_eq!(m.cell_of(11.6, -4.1), Some((3, 2)));
        assert_eq!(m.cell_of(12.0, -4.0), None);
        assert_eq!(m.cell_of(9.7, -5.0), None);
        assert_eq!(m.valid_count(), 1);
    }

    #[test]
    fn bilinear_is_exact_on_planes_and_fill_continues_them() {
        let mut g = HeightMap::new(-1.0, 2.0, 0.5, 20, 10);
        for j in 0..10 {
            for i in 0..20 {
                if i < 12 {
                    g.set(i, j, 1.0 + 2.0 * g.x(i) - 0.5 * g.y(j));
                }
            }
        }
        let p = |x: f64, y: f64| 1.0 + 2.0 * x - 0.5 * y;
        assert!((g.sample(2.1, 3.3) - p(2.1, 3.3)).abs() < 1e-12);
        assert!(g.sample(8.9, 3.0).is_nan());
        g.fill();
        assert_eq!(g.valid_count(), 200);
        // The fill is a continuation, not exact: it stays within the known range.
        assert!(g.z.iter().all(|z| *z <= p(4.5, 2.0) + 1e-9));
    }

    #[test]
    fn smoothing_keeps_pinned_cells_and_linear_fields() {
        let mut g = HeightMap::new(0.0, 0.0, 1.0, 8, 8);
        for k in 0..64 {
            g.z[k] = (k % 8) as f64 + 3.0 * (k / 8) as f64;
        }
        let before = g.clone();
        let mut pinned = vec![false; 64];
        pinned[27] = true;
        g.z[27] = 100.0;
        g.smooth4(&[true; 64], &pinned, 3);
        assert_eq!(g.z[27], 100.0);
        // Away from the spike the linear field is a fixed point of the mean.
        assert!((g.z[9] - before.z[9]).abs() < 1e-12 || g.z[9] > before.z[9]);
        assert_eq!(g.z[0], before.z[0]);
    }
}
