//! Bernstein (Bezier) curves of a window of pixel intensities (the plantar scanner paper's
//! eq. 11-12, docs/method.md section 4.1) and the root of their derivative.
//!
//! For a window of n + 1 samples I_0..I_n at uniform positions x_i = x_0 + i, the curve is
//! x(t) = x_0 + n t, I(t) = sum B_i^n(t) I_i, and I'(t) = n sum B_i^(n-1)(t) d_i with
//! d_i = I_(i+1) - I_i. Two ways to find I'(t*) = 0:
//! - [`bisect_literal`]: the paper's, de Casteljau evaluation of I'(t) and bisection on [0, 1];
//! - [`root_near`]: the same root, from the factorisation
//!   sum B_i^(n-1)(t) d_i = (1 - t)^(n-1) p(s), p(s) = sum C(n-1, i) d_i s^i, s = t / (1 - t),
//!   so the sign of I'(t) is the sign of a polynomial evaluated by Horner's rule in O(n);
//!   a bracket is found next to a starting t and closed by Newton steps kept inside it.
//!
//! The Bernstein evaluations themselves (de Casteljau, the binomial table, the power form)
//! are the shared ones of `footscan_geom::bernstein`; what is here is the detector's use of
//! them: which polynomial, which root, and how it is searched.

use super::simd::{self, Isa};
pub use footscan_geom::bernstein::Binomials;
use footscan_geom::bernstein::{de_casteljau, horner, to_power_form, MAX_TERMS};

/// Largest window (n + 1 samples) the Bezier detectors accept: the size of the shared
/// Bernstein tables and stack buffers, so a window never allocates.
pub const MAX_N: usize = MAX_TERMS;

/// The paper's method: I'(t) by de Casteljau on the difference control points `d`
/// (d_i = I_(i+1) - I_i, i < n), bisection on [0, 1] to |dt| < 1e-9. Without a sign change
/// the maximum of I(t) is at an end: the end with the larger I is returned.
pub fn bisect_literal(samples: &[f64]) -> f64 {
    let n = samples.len() - 1;
    let mut d = [0.0f64; MAX_N];
    for i in 0..n {
        d[i] = samples[i + 1] - samples[i];
    }
    let d = &d[..n];
    let dprime = |t: f64| -> f64 { de_casteljau(d, t) };
    let (mut a, mut b) = (0.0f64, 1.0f64);
    let fa = dprime(a);
    let fb = dprime(b);
    if fa <= 0.0 && fb <= 0.0 || fa >= 0.0 && fb >= 0.0 {
        return if samples[0] >= samples[n] { 0.0 } else { 1.0 };
    }
    let rising_at_a = fa > 0.0;
    while b - a > 1e-9 {
        let c = 0.5 * (a + b);
        let fc = dprime(c);
        if (fc > 0.0) == rising_at_a {
            a = c;
        } else {
            b = c;
        }
    }
    0.5 * (a + b)
}

/// Root t* of I'(t) (a maximum of I: + to - crossing) nearest `t0`, to about 1e-6 px.
/// `samples` are the n + 1 window values; `binom` from [`Binomials`]. None if I'(t) has no
/// + to - crossing in [0, 1]. The portable code (Horner's rule): the scalar path.
pub fn root_near(samples: &[f32], binom: &Binomials, t0: f64) -> Option<f64> {
    root_near_on(Isa::Scalar, samples, binom, t0)
}

/// [`root_near`] with p(s) and p'(s) evaluated on the instruction set `isa`
/// ([`simd::poly_and_derivative`]; Horner's rule on the scalar set).
pub fn root_near_on(isa: Isa, samples: &[f32], binom: &Binomials, t0: f64) -> Option<f64> {
    let n = samples.len() - 1;
    debug_assert!((2..MAX_N).contains(&n));
    // Zero-padded to a multiple of 4 terms for the packed evaluation (MAX_N + 3 >= n + 3).
    let mut a = [0.0f64; MAX_N + 4];
    for i in 0..n {
        a[i] = (samples[i + 1] - samples[i]) as f64;
    }
    to_power_form(&mut a[..n], binom);
    let padded = n.next_multiple_of(4);
    let mut da = [0.0f64; MAX_N + 4];
    if isa != Isa::Scalar {
        for i in 0..n - 1 {
            da[i] = (i + 1) as f64 * a[i + 1];
        }
    }
    let (a4, da4) = (&a[..padded], &da[..padded]);
    let a = &a[..n];
    let eval = |s: f64| -> (f64, f64) {
        simd::poly_and_derivative(isa, a4, da4, s).unwrap_or_else(|| horner(a, s))
    };
    // Fast path: Newton on p(s) from the starting point; a maximum has p' < 0 at the root.
    {
        let tc = t0.clamp(0.02, 0.98);
        let mut s = tc / (1.0 - tc);
        for _ in 0..8 {
            let (p, dp) = eval(s);
            if dp.is_nan() || dp >= 0.0 {
                break;
            }
            let ds = p / dp;
            s -= ds;
            if !(s > 0.0 && s < 1e6) {
                break;
            }
            // Quadratic convergence: after a step below 1e-3 px the error is ~1e-6 px, so the
            // step is taken without another evaluation.
            let scale = 1.0 + s;
            if ds.abs() < 1e-3 * scale * scale / n as f64 {
                return Some(s / scale);
            }
        }
    }
    // g(t) = p(t / (1 - t)), same sign as I'(t) on [0, 1).
    let g = |t: f64| -> (f64, f64) {
        if t >= 1.0 {
            // Sign at t = 1 is the sign of the leading coefficient.
            return (a[n - 1], 0.0);
        }
        let u = 1.0 - t;
        let (p, dp) = eval(t / u);
        (p, dp / (u * u))
    };
    // Bracket [lo, hi] with g(lo) > 0 >= g(hi), searched outward from t0 in steps of half a px.
    let step = 0.5 / n as f64;
    let t0 = t0.clamp(0.0, 1.0);
    let (g0, _) = g(t0);
    let (mut lo, mut hi);
    if g0 > 0.0 {
        lo = t0;
        hi = t0;
        loop {
            let t = (hi + step).min(1.0);
            if g(t).0 <= 0.0 {
                hi = t;
                break;
            }
            lo = t;
            hi = t;
            if t >= 1.0 {
                return None;
            }
        }
    } else {
        hi = t0;
        lo = t0;
        loop {
            let t = (lo - step).max(0.0);
            if g(t).0 > 0.0 {
                lo = t;
                break;
            }
            hi = t;
            lo = t;
            if t <= 0.0 {
                return None;
            }
        }
    }
    // Newton inside the bracket, bisection when a step leaves it.
    let mut t = 0.5 * (lo + hi);
    for _ in 0..40 {
        let (f, df) = g(t);
        if f > 0.0 {
            lo = t;
        } else {
            hi = t;
        }
        let mut next = if df < 0.0 { t - f / df } else { f64::NAN };
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        let done = (next - t).abs() < 1e-7 / n as f64 || hi - lo < 1e-9;
        t = next;
        if done {
            break;
        }
    }
    Some(t)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn window(c: f64, sigma: f64, n: usize, x0: f64) -> Vec<f64> {
        (0..=n)
            .map(|i| {
                let d = x0 + i as f64 - c;
                8.0 + 180.0 * (-d * d / (2.0 * sigma * sigma)).exp()
            })
            .collect()
    }

    #[test]
    fn literal_and_fast_roots_agree() {
        let b = Binomials::new();
        for n in [4usize, 6, 7, 10, 15] {
            for k in 0..20 {
                let c = 10.0 + k as f64 * 0.05;
                let x0 = (10.0 - n as f64 / 2.0).floor();
                let s = window(c, 1.6, n, x0);
                let s32: Vec<f32> = s.iter().map(|&v| v as f32).collect();
                let t1 = bisect_literal(&s);
                let t2 = root_near(&s32, &b, 0.5).unwrap();
                assert!((t1 - t2).abs() < 1e-5, "n {n} c {c}: {t1} vs {t2}");
            }
        }
    }

    #[test]
    fn symmetric_window_gives_its_centre() {
        let b = Binomials::new();
        let s: Vec<f32> = window(5.0, 1.6, 10, 0.0)
            .iter()
            .map(|&v| v as f32)
            .collect();
        let t = root_near(&s, &b, 0.3).unwrap();
        assert!((t - 0.5).abs() < 1e-7);
    }
}
