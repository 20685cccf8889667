//! A 2D thin-plate spline: the smoothest (least bending energy) map of the plane that takes
//! given points exactly to given targets, an affine part plus radial terms r^2 log r.

use footscan_geom::{P2, V2};
use nalgebra::DMatrix;

/// A fitted thin-plate map. Coordinates are shifted and scaled to about unit size before
/// solving, which keeps the system well conditioned for millimetre inputs.
#[derive(Clone, Debug)]
pub struct Tps {
    /// The centres, shifted and scaled (`(p - origin) / unit`).
    centres: Vec<P2>,
    /// Radial weights per centre, for x and y.
    w: Vec<[f64; 2]>,
    /// Affine part: a0 + a1 x + a2 y, for x and y.
    a: [[f64; 2]; 3],
    origin: P2,
    unit: f64,
}

fn kernel(r2: f64) -> f64 {
    if r2 <= 0.0 {
        0.0
    } else {
        0.5 * r2 * r2.ln()
    }
}

impl Tps {
    /// The map taking `from[k]` to `to[k]` exactly (None when the points are degenerate,
    /// e.g. all on a line).
    pub fn fit(from: &[P2], to: &[P2]) -> Option<Tps> {
        let n = from.len();
        if n < 3 || to.len() != n {
            return None;
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in from {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let origin = P2::new((lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0);
        let unit = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-9) / 2.0;
        let centres: Vec<P2> = from.iter().map(|p| P2::from((p - origin) / unit)).collect();
        let m = n + 3;
        let mut k = DMatrix::<f64>::zeros(m, m);
        for i in 0..n {
            for j in 0..i {
                let d = centres[i] - centres[j];
                let v = kernel(d.x * d.x + d.y * d.y);
                k[(i, j)] = v;
                k[(j, i)] = v;
            }
            let row = [1.0, centres[i].x, centres[i].y];
            for (c, v) in row.iter().enumerate() {
                k[(i, n + c)] = *v;
                k[(n + c, i)] = *v;
            }
        }
        let mut rhs = DMatrix::<f64>::zeros(m, 2);
        for i in 0..n {
            let d = (to[i] - from[i]) / unit;
            rhs[(i, 0)] = d.x;
            rhs[(i, 1)] = d.y;
        }
        let sol = k.lu().solve(&rhs)?;
        if sol.iter().any(|v| !v.is_finite()) {
            return None;
        }
        let w = (0..n).map(|i| [sol[(i, 0)], sol[(i, 1)]]).collect();
        let a = [
            [sol[(n, 0)], sol[(n, 1)]],
            [sol[(n + 1, 0)], sol[(n + 1, 1)]],
            [sol[(n + 2, 0)], sol[(n + 2, 1)]],
        ];
        Some(Tps {
            centres,
            w,
            a,
            origin,
            unit,
        })
    }

    /// Where the map takes `p`.
    pub fn apply(&self, p: P2) -> P2 {
        p + self.displacement(p)
    }

    /// The map's displacement at `p` (mm).
    pub fn displacement(&self, p: P2) -> V2 {
        let q = (p - self.origin) / self.unit;
        let mut d = V2::new(
            self.a[0][0] + self.a[1][0] * q.x + self.a[2][0] * q.y,
            self.a[0][1] + self.a[1][1] * q.x + self.a[2][1] * q.y,
        );
        for (c, w) in self.centres.iter().zip(&self.w) {
            let r = q - c.coords;
            let k = kernel(r.x * r.x + r.y * r.y);
            d.x += w[0] * k;
            d.y += w[1] * k;
        }
        d * self.unit
    }

    pub fn len(&self) -> usize {
        self.centres.len()
    }
    pub fn is_empty(&self) -> bool {
        self.centres.is_empty()
    }
}

/// A displacement field tabulated on a coarse grid and interpolated bilinearly: a thin-plate
/// map is smooth, and tabulating it turns thousands of evaluations over hundreds of centres
/// into a few hundred.
#[derive(Clone, Debug)]
pub struct Tabulated {
    x0: f64,
    y0: f64,
    step: f64,
    nx: usize,
    ny: usize,
    d: Vec<V2>,
}

impl Tabulated {
    /// Tabulates `tps` over [x0, x1] x [y0, y1] at nodes `step` apart.
    pub fn new(tps: &Tps, lo: P2, hi: P2, step: f64) -> Tabulated {
        let nx = ((hi.x - lo.x) / step).ceil() as usize + 2;
        let ny = ((hi.y - lo.y) / step).ceil() as usize + 2;
        let mut d = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                d.push(tps.displacement(P2::new(lo.x + i as f64 * step, lo.y + j as f64 * step)));
            }
        }
        Tabulated {
            x0: lo.x,
            y0: lo.y,
            step,
            nx,
            ny,
            d,
        }
    }

    /// Where the tabulated map takes `p` (clamped to the table's edge outside it).
    pub fn apply(&self, p: P2) -> P2 {
        let fx = ((p.x - self.x0) / self.step).clamp(0.0, (self.nx - 1) as f64);
        let fy = ((p.y - self.y0) / self.step).clamp(0.0, (self.ny - 1) as f64);
        let i = (fx as usize).min(self.nx - 2);
        let j = (fy as usize).min(self.ny - 2);
        let (tx, ty) = (fx - i as f64, fy - j as f64);
        let k = j * self.nx + i;
        let (a, b, c, e) = (
            self.d[k],
            self.d[k + 1],
            self.d[k + self.nx],
            self.d[k + self.nx + 1],
        );
        p + ((a * (1.0 - tx) + b * tx) * (1.0 - ty) + (c * (1.0 - tx) + e * tx) * ty)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_exactly_and_reproduces_affine_maps() {
        let from: Vec<P2> = (0..40)
            .map(|k| {
                let a = k as f64 * 0.7;
                P2::new(100.0 * a.cos() + 3.0 * k as f64, 40.0 * a.sin())
            })
            .collect();
        let affine = |p: P2| P2::new(1.02 * p.x - 0.1 * p.y + 5.0, 0.05 * p.x + 0.97 * p.y - 2.0);
        let to: Vec<P2> = from.iter().map(|&p| affine(p)).collect();
        let t = Tps::fit(&from, &to).unwrap();
        for (p, q) in from.iter().zip(&to) {
            let r = t.apply(*p);
            assert!((r - q).amax() < 1e-8);
        }
        let p = P2::new(12.3, -4.5);
        let (r, e) = (t.apply(p), affine(p));
        assert!((r - e).amax() < 1e-8);
        // A bump at one point: still exact there.
        let mut to2 = to.clone();
        to2[7].y += 1.5;
        let t2 = Tps::fit(&from, &to2).unwrap();
        let r = t2.apply(from[7]);
        assert!((r.y - to2[7].y).abs() < 1e-8);
        let tab = Tabulated::new(&t2, P2::new(-120.0, -60.0), P2::new(240.0, 60.0), 2.0);
        let q = P2::new(30.0, 10.0);
        let (a, b) = (tab.apply(q), t2.apply(q));
        assert!((a - b).amax() < 0.01);
    }
}
