//! The plantar scanner paper's closed forms (eq. 20-21, docs/method.md section 6.2): per image
//! row, the image centre c_x and the distance D from the line columns at three plate heights,
//! under the ideal model of docs/method.md section 2.1 where `(c_k - c_x)(D + h_k) = F L` for
//! every height k.
//!
//! With K >= 3 heights the same relation is solved per row by linear least squares in
//! (F L + c_x D, D, c_x): `c_k h_k = A - D c_k + c_x h_k`; with exactly three heights this is
//! eq. 20-21. These per-row values are the starting point of the general fit; their spread
//! over the rows shows how far the real scanner is from the ideal model (distortion, tilts).

use super::data::PlateObservation;
use nalgebra::{Matrix3, Vector3};

/// Eq. 20 and 21 as printed: (c_x, D) from the columns `x` of one row at heights `h`.
pub fn eq20_21(h: [f64; 3], x: [f64; 3]) -> Option<(f64, f64)> {
    let [h1, h2, h3] = h;
    let [x1, x2, x3] = x;
    let den = (h1 - h2) * (x1 - x3) + (h3 - h1) * (x1 - x2);
    if den.abs() < 1e-12 || (x1 - x2).abs() < 1e-12 {
        return None;
    }
    let xc = ((h1 * x1 - h2 * x2) * (x1 - x3) + (h3 * x3 - h1 * x1) * (x1 - x2)) / den;
    let d = (h2 * (x2 - xc) - h1 * (x1 - xc)) / (x1 - x2);
    Some((xc, d))
}

/// One row's closed-form solution.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowSolution {
    pub row: usize,
    pub cx: f64,
    pub d_mm: f64,
    /// F L (px mm).
    pub fl: f64,
}

/// Per-row least squares over every height with a valid column (at least 3).
pub fn per_row(plates: &[PlateObservation]) -> Vec<RowSolution> {
    let rows = plates.iter().map(|p| p.col.len()).min().unwrap_or(0);
    let mut out = Vec::new();
    for r in 0..rows {
        let samples: Vec<(f64, f64)> = plates
            .iter()
            .filter(|p| p.col[r].is_finite())
            .map(|p| (p.height_mm, p.col[r]))
            .collect();
        if samples.len() < 3 {
            continue;
        }
        // c h = A - D c + cx h  ->  [1, -c, h] . (A, D, cx) = c h
        let mut ata = Matrix3::zeros();
        let mut atb = Vector3::zeros();
        for &(h, c) in &samples {
            let a = Vector3::new(1.0, -c, h);
            ata += a * a.transpose();
            atb += a * (c * h);
        }
        let Some(sol) = ata.lu().solve(&atb) else {
            continue;
        };
        let (a, d, cx) = (sol[0], sol[1], sol[2]);
        if !(d.is_finite() && d > 0.0 && cx.is_finite()) {
            continue;
        }
        out.push(RowSolution {
            row: r,
            cx,
            d_mm: d,
            fl: a - cx * d,
        });
    }
    out
}

/// Medians and robust spreads of the per-row solutions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Summary {
    pub rows: usize,
    pub cx: f64,
    pub d_mm: f64,
    pub fl: f64,
    /// 1.4826 x median absolute deviation over rows.
    pub cx_spread: f64,
    pub d_spread: f64,
}

pub fn summarize(rows: &[RowSolution]) -> Option<Summary> {
    if rows.is_empty() {
        return None;
    }
    let cx: Vec<f64> = rows.iter().map(|r| r.cx).collect();
    let d: Vec<f64> = rows.iter().map(|r| r.d_mm).collect();
    let fl: Vec<f64> = rows.iter().map(|r| r.fl).collect();
    Some(Summary {
        rows: rows.len(),
        cx: median(&cx),
        d_mm: median(&d),
        fl: median(&fl),
        cx_spread: mad(&cx),
        d_spread: mad(&d),
    })
}

pub fn median(v: &[f64]) -> f64 {
    let mut s: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    if s.is_empty() {
        return f64::NAN;
    }
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

pub fn mad(v: &[f64]) -> f64 {
    let m = median(v);
    let dev: Vec<f64> = v.iter().map(|x| (x - m).abs()).collect();
    1.4826 * median(&dev)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ideal_col(h: f64) -> f64 {
        643.7 + 2000.0 * 70.0 / (250.0 + h)
    }

    #[test]
    fn eq20_21_recover_the_ideal_scanner() {
        let h = [0.0, 10.0, 30.0];
        let (xc, d) = eq20_21(h, h.map(ideal_col)).unwrap();
        assert!(
            (xc - 643.7).abs() < 1e-6 && (d - 250.0).abs() < 1e-6,
            "{xc} {d}"
        );
        assert!(eq20_21([1.0, 1.0, 1.0], [5.0, 5.0, 5.0]).is_none());
    }

    #[test]
    fn least_squares_equals_eq20_21_with_three_heights() {
        let heights = [0.0, 12.0, 31.0];
        // A slightly non-ideal row: the least squares form is still the same solution.
        let cols = heights.map(|h| ideal_col(h) + 0.01 * h);
        let plates: Vec<PlateObservation> = heights
            .iter()
            .zip(cols)
            .map(|(&h, c)| PlateObservation {
                height_mm: h,
                frames: 1,
                col: vec![c; 3],
                std: vec![0.0; 3],
            })
            .collect();
        let rows = per_row(&plates);
        assert_eq!(rows.len(), 3);
        let (xc, d) = eq20_21(heights, cols).unwrap();
        assert!((rows[0].cx - xc).abs() < 1e-6 && (rows[0].d_mm - d).abs() < 1e-6);
        let s = summarize(&rows).unwrap();
        assert_eq!(s.rows, 3);
        assert!(s.cx_spread < 1e-9);
    }
}
