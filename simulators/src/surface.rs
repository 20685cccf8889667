//! What the laser can hit: a height field standing on the glass. Its own file so the scene
//! models (foot, last, mesh, targets) and the renderer each import it, not each other.

/// A height field standing on the glass: what the laser can hit.
pub trait Surface: Send + Sync + std::fmt::Debug {
    /// Height z >= 0 of the surface above world (x, y), None where there is nothing.
    fn height(&self, x: f64, y: f64) -> Option<f64>;
    /// An upper bound of every height (solver bracket).
    fn max_height(&self) -> f64;
    /// World y interval outside which `height` is None.
    fn y_bounds(&self) -> (f64, f64) {
        (f64::NEG_INFINITY, f64::INFINITY)
    }
    /// The z where the line `x = x0 + tan_b * z` (fixed y) meets the surface, if it does.
    fn plane_height(&self, x0: f64, tan_b: f64, y: f64) -> Option<f64> {
        solve_plane_height(self, x0, tan_b, y)
    }
}

/// Solve `z = height(x0 + tan_b z, y)` by secant iteration from the fixed point (to 1e-12 mm).
pub fn solve_plane_height<S: Surface + ?Sized>(s: &S, x0: f64, tan_b: f64, y: f64) -> Option<f64> {
    let g = |z: f64| s.height(x0 + tan_b * z, y).map(|h| z - h);
    let mut z0 = s.height(x0, y)?;
    let mut g0 = g(z0)?;
    if g0.abs() < 1e-13 {
        return Some(z0);
    }
    let mut z1 = z0 - g0;
    for _ in 0..60 {
        let g1 = g(z1)?;
        if g1.abs() < 1e-13 {
            return Some(z1);
        }
        let dg = g1 - g0;
        let next = if dg.abs() > 1e-300 {
            z1 - g1 * (z1 - z0) / dg
        } else {
            z1 - g1
        };
        z0 = z1;
        g0 = g1;
        z1 = next.clamp(0.0, s.max_height() * 2.0 + 1.0);
    }
    None
}
