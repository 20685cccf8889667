//! Knot insertion and refinement, degree elevation, splitting, reversing, reparametrisation.

/// Clamped knot vector on [0, 1] with uniform interior knots for `n` control points.
pub(crate) fn clamped_uniform_knots(degree: usize, n: usize) -> Vec<f64> {
    let mut k = vec![0.0; degree + 1];
    let inner = n - degree - 1;
    for i in 1..=inner {
        k.push(i as f64 / (inner + 1) as f64);
    }
    k.extend(std::iter::repeat_n(1.0, degree + 1));
    k
}
