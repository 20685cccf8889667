//! The least-squares comparator of Table 1: one global polynomial surface for the whole sole,
//! x, y and z each a polynomial of total degree `d` in the grid parameters (s, t) (scaled to
//! [-1, 1], Chebyshev basis for conditioning), fitted to the valid points only.

use super::ops::{Counted, OpCount, Scalar};
use super::point_grid::{is_point, PointGrid};
use super::SurfaceError;
use footscan_geom::P3;
use nalgebra::{DMatrix, DVector};

#[derive(Clone, Debug)]
pub struct PolySurface {
    degree: usize,
    max: [f64; 2],
    /// Per coordinate, the coefficients c_ab for a + b <= d in the order a = 0.., b = 0..d-a.
    coef: [Vec<f64>; 3],
}

/// Chebyshev T_0..T_d at x.
#[inline]
fn cheb<T: Scalar>(x: T, d: usize, out: &mut [T]) {
    out[0] = T::from_f64(1.0);
    if d >= 1 {
        out[1] = x;
    }
    let x2 = x + x;
    for k in 2..=d {
        out[k] = x2 * out[k - 1] - out[k - 2];
    }
}

fn cheb_d1(x: f64, d: usize, t: &[f64], out: &mut [f64]) {
    // T_k' = 2 T_(k-1) + 2x T_(k-1)' - T_(k-2)' (differentiating the recurrence).
    out[0] = 0.0;
    if d >= 1 {
        out[1] = 1.0;
    }
    for k in 2..=d {
        out[k] = 2.0 * t[k - 1] + 2.0 * x * out[k - 1] - out[k - 2];
    }
}

pub fn terms(degree: usize) -> usize {
    (degree + 1) * (degree + 2) / 2
}

impl PolySurface {
    /// Least squares over the valid points of `g` (normal equations, Cholesky).
    pub fn fit(g: &PointGrid, degree: usize) -> Result<Self, SurfaceError> {
        if g.nu < 2 || g.nv < 2 {
            return Err(SurfaceError::GridTooSmall { nu: g.nu, nv: g.nv });
        }
        let m = terms(degree);
        let max = [(g.nu - 1) as f64, (g.nv - 1) as f64];
        let mut ata = DMatrix::<f64>::zeros(m, m);
        let mut atb = [DVector::zeros(m), DVector::zeros(m), DVector::zeros(m)];
        let (mut tu, mut tv) = (vec![0.0; degree + 1], vec![0.0; degree + 1]);
        let mut row = vec![0.0; m];
        let mut n = 0usize;
        for i in 0..g.nu {
            cheb(2.0 * i as f64 / max[0] - 1.0, degree, &mut tu);
            for j in 0..g.nv {
                let p = g.get(i, j);
                if !is_point(&p) {
                    continue;
                }
                n += 1;
                cheb(2.0 * j as f64 / max[1] - 1.0, degree, &mut tv);
                let mut q = 0;
                for a in 0..=degree {
                    for b in 0..=degree - a {
                        row[q] = tu[a] * tv[b];
                        q += 1;
                    }
                }
                // Upper triangle only; mirrored below.
                for r in 0..m {
                    let fr = row[r];
                    for c in r..m {
                        ata[(r, c)] += fr * row[c];
                    }
                    for k in 0..3 {
                        atb[k][r] += fr * p[k];
                    }
                }
            }
        }
        if n < m {
            return Err(SurfaceError::Empty);
        }
        for r in 0..m {
            for c in 0..r {
                ata[(r, c)] = ata[(c, r)];
            }
        }
        let ch = ata.cholesky().ok_or(SurfaceError::Singular)?;
        let coef = atb.map(|b| ch.solve(&b).iter().copied().collect());
        Ok(PolySurface { degree, max, coef })
    }

    pub fn degree(&self) -> usize {
        self.degree
    }

    pub fn bytes(&self) -> usize {
        3 * self.coef[0].len() * 8 + 2 * 8
    }

    pub fn domain(&self) -> [f64; 2] {
        self.max
    }

    pub fn eval_coord_generic<T: Scalar>(&self, k: usize, s: f64, t: f64) -> T {
        let d = self.degree;
        let two = T::from_f64(2.0);
        let one = T::from_f64(1.0);
        let x = two * T::from_f64(s) / T::from_f64(self.max[0]) - one;
        let y = two * T::from_f64(t) / T::from_f64(self.max[1]) - one;
        let mut tu = vec![T::from_f64(0.0); d + 1];
        let mut tv = vec![T::from_f64(0.0); d + 1];
        cheb(x, d, &mut tu);
        cheb(y, d, &mut tv);
        let c = &self.coef[k];
        let mut q = 0;
        let mut total = T::from_f64(0.0);
        for a in 0..=d {
            let mut inner = T::from_f64(c[q]);
            q += 1;
            for b in 1..=d - a {
                inner = inner + T::from_f64(c[q]) * tv[b];
                q += 1;
            }
            total = if a == 0 { inner } else { total + tu[a] * inner };
        }
        total
    }

    pub fn eval(&self, s: f64, t: f64) -> P3 {
        P3::from([0, 1, 2].map(|k| self.eval_coord_generic::<f64>(k, s, t)))
    }

    pub fn eval_d1(&self, s: f64, t: f64) -> super::Jet {
        let d = self.degree;
        let (x, y) = (2.0 * s / self.max[0] - 1.0, 2.0 * t / self.max[1] - 1.0);
        let (mut tu, mut tv) = (vec![0.0; d + 1], vec![0.0; d + 1]);
        let (mut du, mut dv) = (vec![0.0; d + 1], vec![0.0; d + 1]);
        cheb(x, d, &mut tu);
        cheb(y, d, &mut tv);
        cheb_d1(x, d, &tu, &mut du);
        cheb_d1(y, d, &tv, &mut dv);
        let mut out = [[0.0; 3]; 3];
        for k in 0..3 {
            let c = &self.coef[k];
            let mut q = 0;
            for a in 0..=d {
                for b in 0..=d - a {
                    out[0][k] += c[q] * tu[a] * tv[b];
                    out[1][k] += c[q] * du[a] * tv[b];
                    out[2][k] += c[q] * tu[a] * dv[b];
                    q += 1;
                }
            }
            out[1][k] *= 2.0 / self.max[0];
            out[2][k] *= 2.0 / self.max[1];
        }
        out.into()
    }

    pub fn z_ops(&self, s: f64, t: f64) -> OpCount {
        Counted::take();
        let _ = self.eval_coord_generic::<Counted>(2, s, t);
        Counted::take()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reproduces_a_polynomial_and_its_derivatives() {
        let mut pts = Vec::new();
        for i in 0..15 {
            for j in 0..12 {
                let (s, t) = (i as f64, j as f64);
                let z = 1.0 + 0.3 * s - 0.02 * s * t + 0.001 * s * s * s;
                pts.push(if (i + j) % 7 == 0 {
                    [f64::NAN; 3]
                } else {
                    [s * 0.5, t * 0.25, z]
                });
            }
        }
        let g = PointGrid::new(15, 12, pts.into_iter().map(P3::from).collect());
        let p = PolySurface::fit(&g, 4).unwrap();
        let (s, t) = (3.7, 8.2);
        let z = 1.0 + 0.3 * s - 0.02 * s * t + 0.001 * s * s * s;
        let e = p.eval(s, t);
        assert!((e[2] - z).abs() < 1e-9 && (e[0] - s * 0.5).abs() < 1e-9);
        let d = p.eval_d1(s, t);
        assert!((d.du.z - (0.3 - 0.02 * t + 0.003 * s * s)).abs() < 1e-8);
        assert!((d.dv.z + 0.02 * s).abs() < 1e-8 && (d.dv.y - 0.25).abs() < 1e-9);
        assert!(p.z_ops(s, t).total() > terms(4) as u64);
    }
}
