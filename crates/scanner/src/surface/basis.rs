//! The network's basis (docs/method.md section 7.1) and the per-period interpolation matrices.
//!
//! b0 = (1 + 4t)(1 - t)^4, b1 = 10 t^2 (1 - t)^3, b2 = 10 t^3 (1 - t)^2, b3 = (5 - 4t) t^4:
//! the quintic Bernstein basis with doubled end control points (b0 = B0 + B1, b3 = B4 + B5),
//! so every b_i has zero derivative at t = 0 and t = 1. The basis itself is
//! `footscan_geom::bernstein::flat_end_quintic` (one Bernstein implementation for the detector,
//! the calibration and this model); the interpolation matrices are the network's own.

use super::ops::Scalar;
use footscan_geom::bernstein::{flat_end_quintic, flat_end_quintic_d1, flat_end_quintic_d2};

/// b0..b3 at `t`, generic so the operation counter can run the same code: the shared
/// [`flat_end_quintic`], under the name the network's equations use.
#[inline(always)]
pub fn basis<T: Scalar>(t: T) -> [T; 4] {
    flat_end_quintic(t)
}

/// First derivatives b0'..b3' at `t`.
#[inline]
pub fn basis_d1(t: f64) -> [f64; 4] {
    flat_end_quintic_d1(t)
}

/// Second derivatives b0''..b3'' at `t`.
#[inline]
pub fn basis_d2(t: f64) -> [f64; 4] {
    flat_end_quintic_d2(t)
}

/// The 4 x (k + 1) matrix E_k taking the k + 1 grid points of a segment side with period k
/// to its 4 coefficients, C = E_u P E_v^T.
///
/// - k = 3: E = M^-1 with M[a][b] = b_b(a/3), in exact rationals: the corners pass through,
///   the inner pair solves the 2x2 system of eq. 6-7 (the 4x4 system of eq. 8 is its tensor
///   product).
/// - k = 2 (edge segment with 3 points): nodes at t = 0, 1/2, 1, corners pass through and the
///   two inner coefficients are equal: C1 = C2 = (16 P1 - 3 P0 - 3 P2) / 10.
/// - k = 1 (edge segment with 2 points): C1 = (3 P0 + 2 P1) / 5, C2 = (2 P0 + 3 P1) / 5, the
///   coefficients a linear function would have if the ends were not doubled.
pub fn interpolation_matrix(k: usize) -> &'static [[f64; 4]] {
    const E3: [[f64; 4]; 4] = [
        [1.0, 0.0, 0.0, 0.0],
        [-71.0 / 40.0, 162.0 / 40.0, -81.0 / 40.0, 30.0 / 40.0],
        [30.0 / 40.0, -81.0 / 40.0, 162.0 / 40.0, -71.0 / 40.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    const E2: [[f64; 4]; 4] = [
        [1.0, 0.0, 0.0, 0.0],
        [-0.3, 1.6, -0.3, 0.0],
        [-0.3, 1.6, -0.3, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    const E1: [[f64; 4]; 4] = [
        [1.0, 0.0, 0.0, 0.0],
        [0.6, 0.4, 0.0, 0.0],
        [0.4, 0.6, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
    ];
    match k {
        3 => &E3,
        2 => &E2,
        1 => &E1,
        _ => panic!("segment period {k}: must be 1, 2 or 3"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // The basis and its derivatives are tested where they live (footscan_geom::bernstein).

    #[test]
    fn interpolation_matrices_reproduce_the_nodes() {
        for k in 1..=3 {
            let e = interpolation_matrix(k);
            for node in 0..=k {
                let b = basis(node as f64 / k as f64);
                for p in 0..=k {
                    // Value at node `node` of the curve through the unit vector e_p.
                    let v: f64 = (0..4).map(|i| b[i] * e[i][p]).sum();
                    let want = if p == node { 1.0 } else { 0.0 };
                    assert!((v - want).abs() < 1e-14, "k={k} node={node} p={p}: {v}");
                }
            }
        }
    }
}
