//! Small least-squares fits used to place landmarks between outline vertices.

use footscan_geom::P2;
use nalgebra::{Const, DimMin, Matrix3, SMatrix, SVector, Vector3};

/// Least-squares circle through `pts`: algebraic (Kasa) start, then Gauss-Newton on the
/// geometric distances. Returns (centre, radius), or None for fewer than 3 usable points.
pub fn fit_circle(pts: &[P2]) -> Option<(P2, f64)> {
    if pts.len() < 3 {
        return None;
    }
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.x).sum::<f64>() / n,
        pts.iter().map(|p| p.y).sum::<f64>() / n,
    );
    // x^2 + y^2 + D x + E y + F = 0 on centred coordinates.
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    for p in pts {
        let (x, y) = (p.x - mx, p.y - my);
        let row = Vector3::new(x, y, 1.0);
        ata += row * row.transpose();
        atb += row * (-(x * x + y * y));
    }
    let s = ata.lu().solve(&atb)?;
    let (mut cx, mut cy) = (-s[0] / 2.0, -s[1] / 2.0);
    let mut r = (cx * cx + cy * cy - s[2]).max(0.0).sqrt();
    for _ in 0..20 {
        let mut jtj = Matrix3::zeros();
        let mut jtr = Vector3::zeros();
        for p in pts {
            let (dx, dy) = (p.x - mx - cx, p.y - my - cy);
            let d = (dx * dx + dy * dy).sqrt().max(1e-12);
            let res = d - r;
            let j = Vector3::new(-dx / d, -dy / d, -1.0);
            jtj += j * j.transpose();
            jtr += j * res;
        }
        let step = jtj.lu().solve(&(-jtr))?;
        cx += step[0];
        cy += step[1];
        r += step[2];
        if step.norm() < 1e-10 {
            break;
        }
    }
    (r.is_finite() && r > 0.0).then_some((P2::new(cx + mx, cy + my), r))
}

/// The top of a peak sampled as (t, s) pairs (s = height of the outline in the direction the
/// landmark is extreme in, t = position across it): the model is two half-curves with a
/// common vertex and zero slope there, s = a - k1 d^2 [- q1 d^4] for d = t - t0 < 0 and
/// a - k2 d^2 [- q2 d^4] for d > 0 (quartic terms with `quartic`, for wider windows), so a
/// peak whose flanks curve differently (a rounded front next to a long flat side) is located
/// without the pull toward the flat side a single parabola has. Returns (t0, a), or None
/// when there are too few samples.
pub fn peak_vertex(ts: &[f64], ss: &[f64], quartic: bool) -> Option<(f64, f64)> {
    // Fixed-size systems: a search does about 280 fits, and a heap matrix per fit was a large
    // share of the measurement's time (docs/method.md 8.4).
    if quartic {
        peak_vertex_n::<5>(ts, ss)
    } else {
        peak_vertex_n::<3>(ts, ss)
    }
}

/// [`peak_vertex`] with `N` = 3 (quadratic flanks) or 5 (with quartic terms) coefficients.
fn peak_vertex_n<const N: usize>(ts: &[f64], ss: &[f64]) -> Option<(f64, f64)>
where
    Const<N>: DimMin<Const<N>, Output = Const<N>>,
{
    if ts.len() < 7 {
        return None;
    }
    let lo = ts.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ts.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if hi - lo <= 0.0 {
        return None;
    }
    let row = |t: f64, t0: f64| -> [f64; N] {
        let d2 = (t - t0) * (t - t0);
        let d4 = d2 * d2;
        let full = if t < t0 {
            [1.0, -d2, 0.0, -d4, 0.0]
        } else {
            [1.0, 0.0, -d2, 0.0, -d4]
        };
        std::array::from_fn(|a| full[a])
    };
    // Residual and vertex height of the best linear coefficients for a given t0. The normal
    // equations from the powers of d summed per side (a row has 1, d^2 and d^4 on its own
    // side only): 8 sums a sample instead of N^2 + N products; a landmark search does about
    // 120 fits of up to 500 samples, and a scan's results wait on them (issue 34 item 2).
    let fit = |t0: f64| -> Option<(f64, f64)> {
        // Per side: count, d^2, d^4, d^6, d^8, s, s d^2, s d^4 (in locals: an array indexed
        // by the side kept every sum in memory).
        let (mut l, mut r) = ([0.0f64; 8], [0.0f64; 8]);
        for (&t, &s) in ts.iter().zip(ss) {
            let d2 = (t - t0) * (t - t0);
            let d4 = d2 * d2;
            let add = |q: &mut [f64; 8]| {
                q[0] += 1.0;
                q[1] += d2;
                q[2] += d4;
                q[5] += s;
                q[6] += s * d2;
                if N == 5 {
                    q[3] += d2 * d4;
                    q[4] += d4 * d4;
                    q[7] += s * d4;
                }
            };
            if t < t0 {
                add(&mut l);
            } else {
                add(&mut r);
            }
        }
        let (l, r) = (&l, &r);
        let mut ata = SMatrix::<f64, N, N>::zeros();
        let mut atb = SVector::<f64, N>::zeros();
        ata[(0, 0)] = l[0] + r[0];
        ata[(0, 1)] = -l[1];
        ata[(0, 2)] = -r[1];
        ata[(1, 1)] = l[2];
        ata[(2, 2)] = r[2];
        atb[0] = l[5] + r[5];
        atb[1] = -l[6];
        atb[2] = -r[6];
        if N == 5 {
            ata[(0, 3)] = -l[2];
            ata[(0, 4)] = -r[2];
            ata[(1, 3)] = l[3];
            ata[(2, 4)] = r[3];
            ata[(3, 3)] = l[4];
            ata[(4, 4)] = r[4];
            atb[3] = -l[7];
            atb[4] = -r[7];
        }
        for a in 0..N {
            for b in 0..a {
                ata[(a, b)] = ata[(b, a)];
            }
        }
        // Regularise a flank without samples (vertex at the window end).
        let scale = ata[(0, 0)].max(1.0) * 1e-12;
        for a in 1..N {
            ata[(a, a)] += scale;
        }
        let c = ata.lu().solve(&atb)?;
        let res: f64 = ts
            .iter()
            .zip(ss)
            .map(|(&t, &s)| {
                let r = row(t, t0);
                let m: f64 = (0..N).map(|a| r[a] * c[a]).sum();
                (s - m).powi(2)
            })
            .sum();
        Some((res, c[0]))
    };
    let n = 200;
    let mut best = (f64::INFINITY, lo, 0.0);
    for q in 0..=n {
        let t0 = lo + (hi - lo) * q as f64 / n as f64;
        if let Some((r, a)) = fit(t0) {
            if r < best.0 {
                best = (r, t0, a);
            }
        }
    }
    // Golden-section refinement around the best grid point, one new fit per step.
    let step = (hi - lo) / n as f64;
    let (mut a, mut b) = ((best.1 - step).max(lo), (best.1 + step).min(hi));
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let res = |t: f64| fit(t).map_or(f64::INFINITY, |f| f.0);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut rc, mut rd) = (res(c), res(d));
    for _ in 0..40 {
        if rc < rd {
            (b, d, rd) = (d, c, rc);
            c = b - g * (b - a);
            rc = res(c);
        } else {
            (a, c, rc) = (c, d, rd);
            d = a + g * (b - a);
            rd = res(d);
        }
    }
    let t0 = 0.5 * (a + b);
    let (_, s0) = fit(t0)?;
    Some((t0, s0))
}

/// Local quadratic regression of `ss` over `ts` at `t`, with samples within `half` of it
/// (tricube weights); the smoothed value, or None with fewer than 3 samples.
pub fn local_quadratic(ts: &[f64], ss: &[f64], t: f64, half: f64) -> Option<f64> {
    let mut ata = Matrix3::zeros();
    let mut atb = Vector3::zeros();
    let mut n = 0;
    for (&ti, &si) in ts.iter().zip(ss) {
        let u = (ti - t) / half;
        if u.abs() >= 1.0 {
            continue;
        }
        let w = (1.0 - u.abs().powi(3)).powi(3);
        let row = Vector3::new(1.0, u, u * u);
        ata += row * row.transpose() * w;
        atb += row * (si * w);
        n += 1;
    }
    if n < 3 {
        return None;
    }
    ata.lu().solve(&atb).map(|c| c[0])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn circle_through_an_arc() {
        let pts: Vec<P2> = (0..50)
            .map(|k| {
                let a = 2.0 + 1.5 * k as f64 / 49.0;
                P2::new(5.0 + 31.0 * a.cos(), -7.0 + 31.0 * a.sin())
            })
            .collect();
        let (c, r) = fit_circle(&pts).unwrap();
        assert!(
            (c.x - 5.0).abs() < 1e-6 && (c.y + 7.0).abs() < 1e-6,
            "{c:?}"
        );
        assert!((r - 31.0).abs() < 1e-6);
        assert!(fit_circle(&pts[..2]).is_none());
    }

    #[test]
    fn asymmetric_peak_vertex() {
        // A flat flank (k = 0.002) on the left, a sharp one (k = 0.06) on the right.
        let (t0, a) = (1.3, 7.0);
        let ts: Vec<f64> = (0..300).map(|k| -15.0 + 0.07 * k as f64).collect();
        let ss: Vec<f64> = ts
            .iter()
            .map(|&t| {
                let k = if t < t0 { 0.002 } else { 0.06 };
                a - k * (t - t0) * (t - t0)
            })
            .collect();
        let (t, s) = peak_vertex(&ts, &ss, false).unwrap();
        let (t4, s4) = peak_vertex(&ts, &ss, true).unwrap();
        assert!((t4 - t0).abs() < 1e-4 && (s4 - a).abs() < 1e-6, "{t4} {s4}");
        assert!((t - t0).abs() < 1e-4 && (s - a).abs() < 1e-6, "{t} {s}");
        let v = local_quadratic(&ts, &ss, -5.0, 2.0).unwrap();
        assert!((v - (a - 0.002 * 6.3 * 6.3)).abs() < 1e-9);
    }
}
