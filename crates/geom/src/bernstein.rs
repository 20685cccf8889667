//! Bernstein polynomials B_i^n(t) = C(n, i) t^i (1 - t)^(n - i): the one basis the detector's
//! Bezier curves (docs/method.md section 4.1), the calibration's Bezier depth network (section
//! 5.2) and the plantar model's network (section 7.1) are written in.
//!
//! Each caller needs the basis in a different shape, so the shapes live here side by side and
//! the tests hold them to one another:
//! - [`basis`]: every B_i^n(t) of one degree (the calibration network builds its systems from
//!   these);
//! - [`de_casteljau`]: the value of a Bezier polynomial sum B_i^n(t) c_i, stable on [0, 1]
//!   (the paper's detector);
//! - [`Binomials`], [`to_power_form`] and [`horner`]: the same value as
//!   (1 - t)^n p(s) with p(s) = sum C(n, i) c_i s^i and s = t / (1 - t), so its sign costs one
//!   Horner pass (the fast detector's root search);
//! - [`flat_end_quintic`] and its derivatives: the quintic basis with doubled end control
//!   points, in closed form because it runs per evaluated point of the plantar model and its
//!   operation count is a reported figure (README, docs/method.md section 7.3).
//!
//! Everything works on caller-provided or fixed-size stack storage: the per-pixel and
//! per-point paths allocate nothing.

use std::ops::{Add, Mul, Sub};

/// Most control values (degree + 1) the fixed-size functions here take: [`Binomials`] holds
/// C(k, i) for k < `MAX_TERMS`, and [`de_casteljau`] works in a stack array of this length.
pub const MAX_TERMS: usize = 48;

/// Binomial coefficients C(k, i) for k < [`MAX_TERMS`], built once (Pascal's triangle, exact
/// in f64 at these sizes) so a per-pixel evaluation only looks them up.
pub struct Binomials {
    rows: Vec<[f64; MAX_TERMS]>,
}

impl Binomials {
    pub fn new() -> Self {
        let mut rows = vec![[0.0; MAX_TERMS]; MAX_TERMS];
        for k in 0..MAX_TERMS {
            rows[k][0] = 1.0;
            for i in 1..=k {
                rows[k][i] = rows[k - 1][i - 1] + if i < k { rows[k - 1][i] } else { 0.0 };
            }
        }
        Binomials { rows }
    }

    /// C(k, 0..=k), zero beyond.
    #[inline]
    pub fn row(&self, k: usize) -> &[f64; MAX_TERMS] {
        &self.rows[k]
    }
}

impl Default for Binomials {
    fn default() -> Self {
        Self::new()
    }
}

/// Every B_i^n(t), i = 0..=n, into `out[..=n]` (`out` at least n + 1 long).
///
/// Built up degree by degree (the de Casteljau recurrence on the unit vectors), which stays
/// stable for t in and near [0, 1] where the power form would cancel.
pub fn basis(n: usize, t: f64, out: &mut [f64]) {
    out[..=n].fill(0.0);
    out[0] = 1.0;
    for j in 1..=n {
        let mut prev = 0.0;
        for b in out.iter_mut().take(j + 1) {
            let cur = *b;
            *b = (1.0 - t) * cur + t * prev;
            prev = cur;
        }
    }
}

/// sum B_i^n(t) c_i for the n + 1 control values `c` (at most [`MAX_TERMS`]), by de
/// Casteljau's algorithm: repeated convex combinations, no powers, so it is the reference the
/// faster forms are checked against.
#[inline]
pub fn de_casteljau(c: &[f64], t: f64) -> f64 {
    let len = c.len();
    let mut b = [0.0f64; MAX_TERMS];
    b[..len].copy_from_slice(c);
    for k in (1..len).rev() {
        for i in 0..k {
            b[i] = (1.0 - t) * b[i] + t * b[i + 1];
        }
    }
    b[0]
}

/// Turn the n + 1 Bernstein control values in `c` into the coefficients a_i = C(n, i) c_i of
/// p(s), where sum B_i^n(t) c_i = (1 - t)^n p(t / (1 - t)) for t < 1. On [0, 1) the factor
/// (1 - t)^n is positive, so the sign of the Bezier polynomial is the sign of p, which
/// [`horner`] evaluates in n steps (de Casteljau takes n^2 / 2).
#[inline(always)]
pub fn to_power_form(c: &mut [f64], binom: &Binomials) {
    let row = binom.row(c.len() - 1);
    for (a, &k) in c.iter_mut().zip(row) {
        *a *= k;
    }
}

/// p(s) and p'(s) for p(s) = sum a_i s^i, by Horner's rule.
#[inline(always)]
pub fn horner(a: &[f64], s: f64) -> (f64, f64) {
    let mut p = 0.0;
    let mut dp = 0.0;
    for &c in a.iter().rev() {
        dp = dp * s + p;
        p = p * s + c;
    }
    (p, dp)
}

/// The quintic Bernstein basis with doubled end control points, b0..b3 at `t`:
/// b0 = B_0^5 + B_1^5 = (1 + 4t)(1 - t)^4, b1 = B_2^5 = 10 t^2 (1 - t)^3,
/// b2 = B_3^5 = 10 t^3 (1 - t)^2, b3 = B_4^5 + B_5^5 = (5 - 4t) t^4.
/// Every b_i has zero derivative at t = 0 and t = 1, which is what lets the plantar model's
/// patches meet with a continuous tangent plane.
///
/// Generic over the number type so an operation-counting scalar can run the very code the
/// model evaluates with; the closed form is written for few operations (the count is a
/// reported figure), so any change here changes that figure.
#[inline(always)]
pub fn flat_end_quintic<T>(t: T) -> [T; 4]
where
    T: Copy + From<f64> + Add<Output = T> + Sub<Output = T> + Mul<Output = T>,
{
    let one = T::from(1.0);
    let s = one - t;
    let t2 = t * t;
    let s2 = s * s;
    let ten = T::from(10.0);
    let four = T::from(4.0);
    [
        (one + four * t) * (s2 * s2),
        ten * t2 * (s2 * s),
        ten * (t2 * t) * s2,
        (T::from(5.0) - four * t) * (t2 * t2),
    ]
}

/// First derivatives of [`flat_end_quintic`], b0'..b3' at `t`.
#[inline]
pub fn flat_end_quintic_d1(t: f64) -> [f64; 4] {
    let s = 1.0 - t;
    [
        -20.0 * t * s * s * s,
        10.0 * t * s * s * (2.0 - 5.0 * t),
        10.0 * t * t * s * (3.0 - 5.0 * t),
        20.0 * t * t * t * s,
    ]
}

/// Second derivatives of [`flat_end_quintic`], b0''..b3'' at `t`.
#[inline]
pub fn flat_end_quintic_d2(t: f64) -> [f64; 4] {
    let s = 1.0 - t;
    [
        -20.0 * s * s * (1.0 - 4.0 * t),
        10.0 * s * (2.0 - 16.0 * t + 20.0 * t * t),
        10.0 * t * (6.0 - 24.0 * t + 20.0 * t * t),
        20.0 * t * t * (3.0 - 4.0 * t),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn binomials_are_pascals_triangle() {
        let b = Binomials::new();
        assert_eq!(b.row(0)[0], 1.0);
        assert_eq!(&b.row(5)[..7], &[1.0, 5.0, 10.0, 10.0, 5.0, 1.0, 0.0]);
        for k in 0..MAX_TERMS {
            assert_eq!(b.row(k)[k], 1.0);
            let sum: f64 = b.row(k).iter().sum();
            assert_eq!(sum, 2f64.powi(k as i32), "row {k}");
        }
    }

    #[test]
    fn basis_is_a_partition_of_unity_and_matches_the_closed_form() {
        let binom = Binomials::new();
        let mut out = [0.0; 12];
        for n in 0..=11 {
            for k in 0..=20 {
                let t = k as f64 / 20.0;
                basis(n, t, &mut out);
                assert!((out[..=n].iter().sum::<f64>() - 1.0).abs() < 1e-14);
                for (i, b) in out[..=n].iter().enumerate() {
                    let want = binom.row(n)[i] * t.powi(i as i32) * (1.0 - t).powi((n - i) as i32);
                    assert!((b - want).abs() < 1e-14, "B_{i}^{n}({t})");
                }
            }
        }
    }

    #[test]
    fn de_casteljau_and_power_form_agree_with_the_basis() {
        let binom = Binomials::new();
        let c = [3.0, -1.0, 4.0, -1.5, 5.0, -9.0, 2.0];
        let mut b = [0.0; 7];
        for k in 0..20 {
            let t = k as f64 / 20.0;
            basis(6, t, &mut b);
            let want: f64 = b.iter().zip(&c).map(|(b, c)| b * c).sum();
            assert!((de_casteljau(&c, t) - want).abs() < 1e-13, "t {t}");
            let mut a = c;
            to_power_form(&mut a, &binom);
            let (p, _) = horner(&a, t / (1.0 - t));
            assert!(((1.0 - t).powi(6) * p - want).abs() < 1e-12, "t {t}");
        }
    }

    #[test]
    fn flat_end_quintic_is_the_quintic_basis_with_doubled_ends() {
        let mut b5 = [0.0; 6];
        for k in 0..=20 {
            let t = k as f64 / 20.0;
            basis(5, t, &mut b5);
            let want = [b5[0] + b5[1], b5[2], b5[3], b5[4] + b5[5]];
            let got = flat_end_quintic(t);
            for i in 0..4 {
                assert!((got[i] - want[i]).abs() < 1e-14, "b{i}({t})");
            }
            // Derivatives against central differences.
            let h = 1e-6;
            let (bp, bm) = (flat_end_quintic(t + h), flat_end_quintic(t - h));
            let d1 = flat_end_quintic_d1(t);
            let (dp, dm) = (flat_end_quintic_d1(t + h), flat_end_quintic_d1(t - h));
            let d2 = flat_end_quintic_d2(t);
            for i in 0..4 {
                assert!(
                    (d1[i] - (bp[i] - bm[i]) / (2.0 * h)).abs() < 1e-7,
                    "b{i}' at {t}"
                );
                assert!(
                    (d2[i] - (dp[i] - dm[i]) / (2.0 * h)).abs() < 1e-6,
                    "b{i}'' at {t}"
                );
            }
        }
        for t in [0.0, 1.0] {
            assert!(flat_end_quintic_d1(t).iter().all(|d| *d == 0.0));
        }
    }
}
