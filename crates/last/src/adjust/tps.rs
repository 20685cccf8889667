//! A 2D thin-plate spline: the smoothest (least bending energy) map of the plane that takes
//! given points exactly to given targets, an affine part plus radial terms r^2 log r.

use super::outline::Pt;
use nalgebra::DMatrix;

/// A fitted thin-plate map. Coordinates are shifted and scaled to about unit size before
/// solving, which keeps the system well conditioned for millimetre inputs.
#[derive(Clone, Debug)]
pub struct Tps {
    centres: Vec<Pt>,
    /// Radial weights per centre, for x and y.
    w: Vec<[f64; 2]>,
    /// Affine part: a0 + a1 x + a2 y, for x and y.
    a: [[f64; 2]; 3],
    origin: Pt,
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
    pub fn fit(from: &[Pt], to: &[Pt]) -> Option<Tps> {
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
        let origin = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        let unit = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-9) / 2.0;
        let centres: Vec<Pt> = from
            .iter()
            .map(|p| [(p[0] - origin[0]) / unit, (p[1] - origin[1]) / unit])
            .collect();
        let m = n + 3;
        let mut k = DMatrix::<f64>::zeros(m, m);
        for i in 0..n {
            for j in 0..i {
                let (dx, dy) = (centres[i][0] - centres[j][0], centres[i][1] - centres[j][1]);
                let v = kernel(dx * dx + dy * dy);
                k[(i, j)] = v;
                k[(j, i)] = v;
            }
            let row = [1.0, centres[i][0], centres[i][1]];
            for (c, v) in row.iter().enumerate() {
                k[(i, n + c)] = *v;
                k[(n + c, i)] = *v;
            }
        }
        let mut rhs = DMatrix::<f64>::zeros(m, 2);
        for i in 0..n {
            rhs[(i, 0)] = (to[i][0] - from[i][0]) / unit;
            rhs[(i, 1)] = (to[i][1] - from[i][1]) / unit;
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
    pub fn apply(&self, p: Pt) -> Pt {
        let d = self.displacement(p);
        [p[0] + d[0], p[1] + d[1]]
    }

    /// The map's displacement at `p` (mm).
    pub fn displacement(&self, p: Pt) -> Pt {
        let (x, y) = (
            (p[0] - self.origin[0]) / self.unit,
            (p[1] - self.origin[1]) / self.unit,
        );
        let mut d = [
            self.a[0][0] + self.a[1][0] * x + self.a[2][0] * y,
            self.a[0][1] + self.a[1][1] * x + self.a[2][1] * y,
        ];
        for (c, w) in self.centres.iter().zip(&self.w) {
            let (dx, dy) = (x - c[0], y - c[1]);
            let k = kernel(dx * dx + dy * dy);
            d[0] += w[0] * k;
            d[1] += w[1] * k;
        }
        [d[0] * self.unit, d[1] * self.unit]
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
    d: Vec<Pt>,
}

impl Tabulated {
    /// Tabulates `tps` over [x0, x1] x [y0, y1] at nodes `step` apart.
    pub fn new(tps: &Tps, lo: Pt, hi: Pt, step: f64) -> Tabulated {
        let nx = ((hi[0] - lo[0]) / step).ceil() as usize + 2;
        let ny = ((hi[1] - lo[1]) / step).ceil() as usize + 2;
        let mut d = Vec::with_capacity(nx * ny);
        for j in 0..ny {
            for i in 0..nx {
                d.push(tps.displacement([lo[0] + i as f64 * step, lo[1] + j as f64 * step]));
            }
        }
        Tabulated {
            x0: lo[0],
            y0: lo[1],
            step,
            nx,
            ny,
            d,
        }
    }

    /// Where the tabulated map takes `p` (clamped to the table's edge outside it).
    pub fn apply(&self, p: Pt) -> Pt {
        let fx = ((p[0] - self.x0) / self.step).clamp(0.0, (self.nx - 1) as f64);
        let fy = ((p[1] - self.y0) / self.step).clamp(0.0, (self.ny - 1) as f64);
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
        let mut out = p;
        for q in 0..2 {
            out[q] +=
                (1.0 - ty) * ((1.0 - tx) * a[q] + tx * b[q]) + ty * ((1.0 - tx) * c[q] + tx * e[q]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_exactly_and_reproduces_affine_maps() {
        let from: Vec<Pt> = (0..40)
            .map(|k| {
                let a = k as f64 * 0.7;
                [100.0 * a.cos() + 3.0 * k as f64, 40.0 * a.sin()]
            })
            .collect();
        let affine = |p: Pt| {
            [
                1.02 * p[0] - 0.1 * p[1] + 5.0,
                0.05 * p[0] + 0.97 * p[1] - 2.0,
            ]
        };
        let to: Vec<Pt> = from.iter().map(|&p| affine(p)).collect();
        let t = Tps::fit(&from, &to).unwrap();
        for (p, q) in from.iter().zip(&to) {
            let r = t.apply(*p);
            assert!((r[0] - q[0]).abs() < 1e-8 && (r[1] - q[1]).abs() < 1e-8);
        }
        let p = [12.3, -4.5];
        let (r, e) = (t.apply(p), affine(p));
        assert!((r[0] - e[0]).abs() < 1e-8 && (r[1] - e[1]).abs() < 1e-8);
        // A bump at one point: still exact there.
        let mut to2 = to.clone();
        to2[7][1] += 1.5;
        let t2 = Tps::fit(&from, &to2).unwrap();
        let r = t2.apply(from[7]);
        assert!((r[1] - to2[7][1]).abs() < 1e-8);
        let tab = Tabulated::new(&t2, [-120.0, -60.0], [240.0, 60.0], 2.0);
        let (a, b) = (tab.apply([30.0, 10.0]), t2.apply([30.0, 10.0]));
        assert!((a[0] - b[0]).abs() < 0.01 && (a[1] - b[1]).abs() < 0.01);
    }
}
