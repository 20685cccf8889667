/// Heights on a regular (x, y) grid in world millimetres: what the plantar model evaluates to
/// and what measurement works on. Cell (i, j) is centred at (x0 + i·cell, y0 + j·cell);
/// NaN marks cells outside the footprint.
///
/// Index order: row-major by y, x fastest: cell (i, j) is `z[j * nx + i]` ([`Self::index`],
/// [`Self::cell`] for the way back). This is an image's order (a row of the height-map PNG is
/// one y), unlike the scanner's `surface::PointGrid`, which keeps the scan's order (frame outer,
/// `points[i * nv + j]`). Use [`Self::get`], [`Self::set`], [`Self::index`] and
/// [`Self::cell`] rather than indexing `z` by hand, so the two orders are never confused.
#[derive(Clone, Debug, PartialEq)]
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

    pub fn x(&self, i: usize) -> f64 {
        self.x0 + i as f64 * self.cell_mm
    }

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

    pub fn get(&self, i: usize, j: usize) -> f64 {
        self.z[self.index(i, j)]
    }

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
}
