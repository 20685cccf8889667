//! The Bezier depth network of the plantar scanner paper (eq. 13-16) as a second height mapping
//! (docs/method.md section 5.2): `h = C(u, v) = sum_i sum_l C_il B_i^n(u) B_l^m(v)` with
//! `u = a0 + a1 s` the line shift `s = c_0(r) - c` from the reference (glass) line normalised
//! over the calibrated range (eq. 14) and `v = b0 + b1 r` the row (eq. 15), the control values
//! `C_il = w_il h_il` solved so that the network passes through every calibration sample.
//!
//! The paper's single network over all rows would have a degree near 1000 in v: its Bernstein
//! collocation matrix is numerically singular (see [`bernstein_condition`]). Here the rows are
//! cut into blocks of `degree_v + 1` consecutive rows (neighbouring blocks share their edge row)
//! and each block has its own network of degree `degree_v` <= 8 in v and `K - 1` <= 8 in u for K
//! plate heights; every sample row of the block is a node (v = l / degree_v), so the network
//! interpolates every plate sample exactly and each block's system is square and well
//! conditioned. [`BezierDepth::condition`] is the largest 2-norm condition number over the
//! blocks: with 6 heights about 3.5e2 at degree 4 in v (the default), 1.4e4 at degree 8. The
//! one-dimensional Bernstein collocation matrix alone has condition 4.6e2 at degree 8, 9.8e5 at
//! 16, 2.4e9 at 24 and is numerically singular from about 40 on.

use super::data::PlateObservation;
use super::CalibError;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// Largest degree in either direction.
pub const MAX_DEGREE: usize = 8;

#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BezierDepth {
    /// Height of the reference line (the lowest plate), mm.
    pub base_height_mm: f64,
    /// The reference line c_0(r): column of the lowest plate per row (NaN: no data).
    pub reference_col: Vec<f64>,
    /// Shift s (px) mapped to u = 0 and u = 1 (eq. 14).
    pub shift_range_px: [f64; 2],
    pub degree_u: usize,
    pub degree_v: usize,
    pub blocks: Vec<DepthBlock>,
    /// Largest condition number of a block's interpolation system.
    pub condition: f64,
}

/// One row block: rows `first..=last`, v = (r - first) / (last - first).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct DepthBlock {
    pub first: usize,
    pub last: usize,
    /// C_il at `i * (last - first + 1) + l`.
    pub control: Vec<f64>,
}

/// Bernstein basis B_i^n(t), i = 0..=n: the shared basis, under the name this module's
/// equations use.
pub use footscan_geom::bernstein::basis as bernstein;

/// 2-norm condition number of the degree-n Bernstein collocation matrix at n + 1 equispaced
/// nodes: what a single network of that degree in one direction must solve.
pub fn bernstein_condition(n: usize) -> f64 {
    let mut m = DMatrix::zeros(n + 1, n + 1);
    let mut b = vec![0.0; n + 1];
    for k in 0..=n {
        bernstein(n, if n == 0 { 0.0 } else { k as f64 / n as f64 }, &mut b);
        for i in 0..=n {
            m[(k, i)] = b[i];
        }
    }
    condition(&m)
}

fn condition(m: &DMatrix<f64>) -> f64 {
    let sv = m.clone().svd(false, false).singular_values;
    let (max, min) = (sv.max(), sv.min());
    if min > 0.0 {
        max / min
    } else {
        f64::INFINITY
    }
}

/// Least-squares polynomial of `degree` (Chebyshev basis on the row range) through the finite
/// values of `col`, evaluated where `col` is finite; `degree` 0 returns `col` unchanged.
pub fn smooth_along_rows(col: &[f64], degree: usize) -> Vec<f64> {
    let pts: Vec<(usize, f64)> = col
        .iter()
        .enumerate()
        .filter(|(_, c)| c.is_finite())
        .map(|(r, &c)| (r, c))
        .collect();
    if degree == 0 || pts.len() <= 2 * (degree + 1) {
        return col.to_vec();
    }
    let n = col.len().max(2) as f64;
    let basis = |r: usize, out: &mut [f64]| {
        let t = 2.0 * r as f64 / (n - 1.0) - 1.0;
        out[0] = 1.0;
        if out.len() > 1 {
            out[1] = t;
        }
        for k in 2..out.len() {
            out[k] = 2.0 * t * out[k - 1] - out[k - 2];
        }
    };
    let mut a = DMatrix::zeros(pts.len(), degree + 1);
    let mut row = vec![0.0; degree + 1];
    for (i, &(r, _)) in pts.iter().enumerate() {
        basis(r, &mut row);
        for (k, v) in row.iter().enumerate() {
            a[(i, k)] = *v;
        }
    }
    let b = nalgebra::DVector::from_iterator(pts.len(), pts.iter().map(|p| p.1));
    let Ok(coef) = a.svd(true, true).solve(&b, 1e-12) else {
        return col.to_vec();
    };
    col.iter()
        .enumerate()
        .map(|(r, &c)| {
            if c.is_finite() {
                basis(r, &mut row);
                row.iter().zip(coef.iter()).map(|(x, y)| x * y).sum()
            } else {
                c
            }
        })
        .collect()
}

impl BezierDepth {
    /// Fit the network to the plate observations (at least 2 heights; the lowest is the
    /// reference line). With `smooth_degree` > 0 each plate's line is first replaced by its
    /// least-squares polynomial of that degree along the rows (a flat plate's line is a smooth
    /// curve; this removes the detection noise that interpolation would otherwise carry into
    /// every row's mapping); the network then passes through these samples exactly.
    pub fn fit(
        plates: &[PlateObservation],
        degree_v: usize,
        smooth_degree: usize,
    ) -> Result<Self, CalibError> {
        let degree_v = degree_v.clamp(1, MAX_DEGREE);
        let smoothed: Vec<PlateObservation> = plates
            .iter()
            .map(|p| PlateObservation {
                col: smooth_along_rows(&p.col, smooth_degree),
                ..p.clone()
            })
            .collect();
        let mut plates: Vec<&PlateObservation> = smoothed.iter().collect();
        plates.sort_by(|a, b| a.height_mm.total_cmp(&b.height_mm));
        plates.dedup_by(|a, b| (a.height_mm - b.height_mm).abs() < 1e-9);
        if plates.len() < 2 {
            return Err(CalibError::TooFewHeights {
                got: plates.len(),
                need: 2,
                heights: format!(
                    "{:?} mm",
                    plates.iter().map(|p| p.height_mm).collect::<Vec<_>>()
                ),
            });
        }
        let base = plates[0];
        let rows = base.col.len();
        let k = plates.len();
        let degree_u = (k - 1).min(MAX_DEGREE);
        let shift = |p: &PlateObservation, r: usize| base.col[r] - p.col[r];
        let s1 = plates
            .iter()
            .flat_map(|p| (0..rows).map(move |r| shift(p, r)))
            .filter(|s| s.is_finite())
            .fold(0.0, f64::max);
        if s1 <= 0.0 {
            return Err(CalibError::NoUsableRows {
                target: "the plate".into(),
                detail: "the line does not move between the plate heights".into(),
            });
        }
        let range = [0.0, s1];
        let mut blocks = Vec::new();
        let mut worst: f64 = 1.0;
        let mut first = 0;
        let mut bu = vec![0.0; degree_u + 1];
        let mut bv = vec![0.0; degree_v + 1];
        while first + 1 < rows {
            let last = (first + degree_v).min(rows - 1);
            let m = last - first;
            let complete = (first..=last).all(|r| plates.iter().all(|p| p.col[r].is_finite()));
            if complete {
                let unknowns = (degree_u + 1) * (m + 1);
                let mut a = DMatrix::zeros(k * (m + 1), unknowns);
                let mut rhs = nalgebra::DVector::zeros(k * (m + 1));
                for (ki, p) in plates.iter().enumerate() {
                    for l in 0..=m {
                        let r = first + l;
                        let u = (shift(p, r) - range[0]) / (range[1] - range[0]);
                        bernstein(degree_u, u, &mut bu);
                        bernstein(m, l as f64 / m as f64, &mut bv);
                        let eq = ki * (m + 1) + l;
                        for i in 0..=degree_u {
                            for j in 0..=m {
                                a[(eq, i * (m + 1) + j)] = bu[i] * bv[j];
                            }
                        }
                        rhs[eq] = p.height_mm;
                    }
                }
                worst = worst.max(condition(&a));
                // Square when K - 1 <= MAX_DEGREE: exact interpolation; least squares otherwise.
                let svd = a.svd(true, true);
                let c = svd
                    .solve(&rhs, 1e-14)
                    .map_err(|e| CalibError::Implausible(format!("Bezier block {first}: {e}")))?;
                blocks.push(DepthBlock {
                    first,
                    last,
                    control: c.as_slice().to_vec(),
                });
            }
            first = last;
        }
        if blocks.is_empty() {
            return Err(CalibError::NoUsableRows {
                target: "the plate".into(),
                detail: "no block of rows has the line at every height".into(),
            });
        }
        Ok(BezierDepth {
            base_height_mm: base.height_mm,
            reference_col: base.col.clone(),
            shift_range_px: range,
            degree_u,
            degree_v,
            blocks,
            condition: worst,
        })
    }

    /// Height of the line seen at (row, col), None outside the calibrated rows.
    pub fn height(&self, row: f64, col: f64) -> Option<f64> {
        let r0 = row.floor();
        if !(r0 >= 0.0 && row <= (self.reference_col.len() - 1) as f64) {
            return None;
        }
        let i0 = r0 as usize;
        let f = row - r0;
        let c0 = if f > 0.0 {
            let a = self.reference_col[i0];
            let b = *self.reference_col.get(i0 + 1)?;
            a + (b - a) * f
        } else {
            self.reference_col[i0]
        };
        if !c0.is_finite() {
            return None;
        }
        // Blocks share edge rows; partition_point finds the first block ending at or after row.
        let bi = self.blocks.partition_point(|b| (b.last as f64) < row);
        let b = self.blocks.get(bi)?;
        if row < b.first as f64 {
            return None;
        }
        let m = b.last - b.first;
        let n = self.degree_u;
        let u =
            (c0 - col - self.shift_range_px[0]) / (self.shift_range_px[1] - self.shift_range_px[0]);
        let v = (row - b.first as f64) / m as f64;
        let mut bu = [0.0; MAX_DEGREE + 1];
        let mut bv = [0.0; MAX_DEGREE + 1];
        bernstein(n, u, &mut bu);
        bernstein(m, v, &mut bv);
        let h = b
            .control
            .chunks_exact(m + 1)
            .zip(&bu[..=n])
            .map(|(row_c, wu)| wu * row_c.iter().zip(&bv).map(|(c, w)| c * w).sum::<f64>())
            .sum();
        Some(h)
    }

    /// Eq. 30 for the network: one frame's detection noise `noise_px` through dh/du, RMS over
    /// u in [0, 1] at the middle row (mm).
    pub fn detection_uncertainty(&self, noise_px: f64) -> f64 {
        let rows = self.reference_col.len();
        let r = (rows / 2) as f64;
        let c0 = self.reference_col[rows / 2];
        let span = self.shift_range_px[1] - self.shift_range_px[0];
        let mut sum = 0.0;
        let mut n = 0;
        for k in 0..=20 {
            let s = self.shift_range_px[0] + span * k as f64 / 20.0;
            let (Some(a), Some(b)) = (self.height(r, c0 - s + 0.5), self.height(r, c0 - s - 0.5))
            else {
                continue;
            };
            sum += ((b - a) * noise_px).powi(2);
            n += 1;
        }
        if n == 0 {
            f64::NAN
        } else {
            (sum / n as f64).sqrt()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plate(h: f64, rows: usize) -> PlateObservation {
        // An ideal scanner with a row-dependent principal column (a curved line).
        let col = (0..rows)
            .map(|r| {
                let cx = 640.0 + 1e-5 * (r as f64 - 500.0).powi(2);
                cx + 2000.0 * 70.0 / (250.0 + h)
            })
            .collect();
        PlateObservation {
            height_mm: h,
            frames: 1,
            col,
            std: vec![0.0; rows],
        }
    }

    #[test]
    fn interpolates_samples_and_holds_between_heights() {
        let heights = [0.0, 7.0, 14.0, 21.0, 28.0, 35.0];
        let plates: Vec<_> = heights.iter().map(|&h| plate(h, 100)).collect();
        let net = BezierDepth::fit(&plates, 4, 0).unwrap();
        assert_eq!(net.degree_u, 5);
        assert!(net.condition < 1e3, "condition {}", net.condition);
        // Degree 8 in v is still usable; the condition grows fast with the degree.
        let c8 = BezierDepth::fit(&plates, 8, 0).unwrap().condition;
        assert!(c8 > net.condition && c8 < 1e5, "{c8}");
        for p in &plates {
            for r in [0usize, 7, 8, 50, 99] {
                let h = net.height(r as f64, p.col[r]).unwrap();
                assert!(
                    (h - p.height_mm).abs() < 1e-8,
                    "row {r}: {h} vs {}",
                    p.height_mm
                );
            }
        }
        // Held out: heights between the calibration heights.
        for h in [3.5, 17.5, 31.5] {
            let p = plate(h, 100);
            for r in [3usize, 44, 95] {
                let e = net.height(r as f64, p.col[r]).unwrap() - h;
                assert!(e.abs() < 2e-3, "h {h} row {r}: error {e}");
            }
        }
        assert!(net.height(100.0, 1200.0).is_none());
        let u = net.detection_uncertainty(0.1);
        assert!(u > 0.03 && u < 0.07, "u_h {u}");
        assert!(BezierDepth::fit(&plates[..1], 8, 0).is_err());
        // Smoothing keeps a smooth line as it is.
        let s = smooth_along_rows(&plates[2].col, 8);
        assert!(s
            .iter()
            .zip(&plates[2].col)
            .all(|(a, b)| (a - b).abs() < 1e-6));
    }

    #[test]
    fn one_network_over_all_rows_would_be_singular() {
        assert!(bernstein_condition(8) < 1e3);
        assert!(bernstein_condition(40) > 1e9);
        let mut b = [0.0; 9];
        bernstein(8, 0.3, &mut b);
        assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-14);
    }
}
