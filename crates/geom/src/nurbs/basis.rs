//! B-spline basis functions: knot span search, non-zero basis values and their derivatives
//! (the triangular-table recurrences of Cox and de Boor).

/// Index `k` of the knot span holding `u`, with `knots[k] <= u < knots[k + 1]` and
/// `degree <= k <= n` where `n + 1` is the control point count. `u` at or beyond the right end
/// of the domain falls in the last non-empty span, so the curve end is reachable.
pub fn find_span(n: usize, degree: usize, u: f64, knots: &[f64]) -> usize {
    if u >= knots[n + 1] {
        // Last non-empty span.
        let mut k = n;
        while k > degree && knots[k] >= knots[n + 1] {
            k -= 1;
        }
        return k;
    }
    if u <= knots[degree] {
        let mut k = degree;
        while k < n && knots[k + 1] <= u {
            k += 1;
        }
        return k;
    }
    let (mut lo, mut hi) = (degree, n + 1);
    // Invariant: knots[lo] <= u < knots[hi].
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if u < knots[mid] {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    lo
}

/// The `degree + 1` non-zero basis values N_{span-p..=span, p}(u), written to `out`.
pub fn basis_funs(span: usize, u: f64, degree: usize, knots: &[f64], out: &mut [f64]) {
    let p = degree;
    let mut left = [0.0f64; 32];
    let mut right = [0.0f64; 32];
    let (left, right) = if p < 32 {
        (&mut left[..=p], &mut right[..=p])
    } else {
        // Very high degrees: fall back to the heap (never used in practice).
        return basis_funs_heap(span, u, p, knots, out);
    };
    out[0] = 1.0;
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            let den = right[r + 1] + left[j - r];
            let temp = if den != 0.0 { out[r] / den } else { 0.0 };
            out[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        out[j] = saved;
    }
}

fn basis_funs_heap(span: usize, u: f64, p: usize, knots: &[f64], out: &mut [f64]) {
    let mut left = vec![0.0; p + 1];
    let mut right = vec![0.0; p + 1];
    out[0] = 1.0;
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            let den = right[r + 1] + left[j - r];
            let temp = if den != 0.0 { out[r] / den } else { 0.0 };
            out[r] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        out[j] = saved;
    }
}

/// Basis values and derivatives up to order `n`: `ders[k][j]` is the k-th derivative of
/// N_{span-p+j, p} at `u` (zero for k > p).
pub fn ders_basis_funs(span: usize, u: f64, p: usize, n: usize, knots: &[f64]) -> Vec<Vec<f64>> {
    let mut ndu = vec![vec![0.0; p + 1]; p + 1];
    let mut left = vec![0.0; p + 1];
    let mut right = vec![0.0; p + 1];
    ndu[0][0] = 1.0;
    for j in 1..=p {
        left[j] = u - knots[span + 1 - j];
        right[j] = knots[span + j] - u;
        let mut saved = 0.0;
        for r in 0..j {
            // Lower triangle: knot differences; upper triangle: basis values.
            ndu[j][r] = right[r + 1] + left[j - r];
            let temp = if ndu[j][r] != 0.0 {
                ndu[r][j - 1] / ndu[j][r]
            } else {
                0.0
            };
            ndu[r][j] = saved + right[r + 1] * temp;
            saved = left[j - r] * temp;
        }
        ndu[j][j] = saved;
    }
    let mut ders = vec![vec![0.0; p + 1]; n + 1];
    for j in 0..=p {
        ders[0][j] = ndu[j][p];
    }
    let mut a = vec![vec![0.0; p + 1]; 2];
    for r in 0..=p {
        let (mut s1, mut s2) = (0usize, 1usize);
        a[0][0] = 1.0;
        for k in 1..=n.min(p) {
            let mut d = 0.0;
            let rk = r as isize - k as isize;
            let pk = p - k;
            if r >= k {
                let den = ndu[pk + 1][rk as usize];
                a[s2][0] = if den != 0.0 { a[s1][0] / den } else { 0.0 };
                d = a[s2][0] * ndu[rk as usize][pk];
            }
            let j1 = if rk >= -1 { 1 } else { (-rk) as usize };
            let j2 = if r as isize - 1 <= pk as isize {
                k - 1
            } else {
                p - r
            };
            for j in j1..=j2 {
                let idx = (rk + j as isize) as usize;
                let den = ndu[pk + 1][idx];
                a[s2][j] = if den != 0.0 {
                    (a[s1][j] - a[s1][j - 1]) / den
                } else {
                    0.0
                };
                d += a[s2][j] * ndu[idx][pk];
            }
            if r <= pk {
                let den = ndu[pk + 1][r];
                a[s2][k] = if den != 0.0 { -a[s1][k - 1] / den } else { 0.0 };
                d += a[s2][k] * ndu[r][pk];
            }
            ders[k][r] = d;
            std::mem::swap(&mut s1, &mut s2);
        }
    }
    let mut fac = p as f64;
    for (k, row) in ders.iter_mut().enumerate().take(n.min(p) + 1).skip(1) {
        for v in row.iter_mut() {
            *v *= fac;
        }
        fac *= p.saturating_sub(k) as f64;
    }
    ders
}

/// Binomial coefficient as f64 (small arguments).
#[allow(dead_code)]
pub(crate) fn binomial(n: usize, k: usize) -> f64 {
    if k > n {
        return 0.0;
    }
    let k = k.min(n - k);
    let mut r = 1.0;
    for i in 0..k {
        r = r * (n - i) as f64 / (i + 1) as f64;
    }
    r.round()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn partition_of_unity_and_derivative_sum() {
        let knots = [0.0, 0.0, 0.0, 0.0, 0.3, 0.5, 0.5, 0.9, 1.0, 1.0, 1.0, 1.0];
        let n = knots.len() - 3 - 2;
        for i in 0..=100 {
            let u = i as f64 / 100.0;
            let s = find_span(n, 3, u, &knots);
            assert!(knots[s] <= u && (u < knots[s + 1] || u == 1.0));
            let mut b = [0.0; 4];
            basis_funs(s, u, 3, &knots, &mut b);
            assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-14);
            let d = ders_basis_funs(s, u, 3, 3, &knots);
            for (k, row) in d.iter().enumerate() {
                let sum: f64 = row.iter().sum();
                let want = if k == 0 { 1.0 } else { 0.0 };
                assert!((sum - want).abs() < 1e-9, "k={k} sum={sum}");
            }
            for j in 0..4 {
                assert!((d[0][j] - b[j]).abs() < 1e-14);
            }
        }
    }
}
