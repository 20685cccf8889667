//! The adjusted bottom as a B-spline surface: a cubic tensor-product least-squares fit of
//! the adjusted height grid, parametrised by x and y in mm, and the outline lifted onto it
//! as a closed B-spline curve.

use super::{AdjustError, Adjustment};
use footscan_geom::nurbs::basis::{basis_funs, find_span};
use footscan_geom::nurbs::fit::{fit_closed_adaptive, FitOptions};
use footscan_geom::nurbs::{NurbsCurve, NurbsSurface};
use footscan_geom::P3;
use nalgebra::DMatrix;

/// The fitted bottom and how well it fits the adjusted heights.
#[derive(Clone, Debug)]
pub struct BottomSurface {
    pub surface: NurbsSurface,
    /// The adjusted outline on the surface (None when the curve fit failed; see `notes`).
    pub outline: Option<NurbsCurve>,
    /// Fit error over the cells inside the outline (mm).
    pub rms_mm: f64,
    pub max_mm: f64,
    pub notes: Vec<String>,
}

fn clamped_uniform(a: f64, b: f64, n_ctrl: usize, p: usize) -> Vec<f64> {
    let inner = n_ctrl - p - 1;
    let mut k = vec![a; p + 1];
    for i in 1..=inner {
        k.push(a + (b - a) * i as f64 / (inner + 1) as f64);
    }
    k.extend(std::iter::repeat_n(b, p + 1));
    k
}

/// Collocation matrix of `n_ctrl` B-splines of degree `p` at `xs`.
fn collocation(xs: &[f64], knots: &[f64], n_ctrl: usize, p: usize) -> DMatrix<f64> {
    let mut m = DMatrix::zeros(xs.len(), n_ctrl);
    let mut nb = vec![0.0; p + 1];
    for (r, &x) in xs.iter().enumerate() {
        let span = find_span(n_ctrl - 1, p, x, knots);
        basis_funs(span, x, p, knots, &mut nb);
        for (j, &b) in nb.iter().enumerate() {
            m[(r, span - p + j)] = b;
        }
    }
    m
}

/// Greville abscissae: where a linear function's control points sit.
fn greville(knots: &[f64], n_ctrl: usize, p: usize) -> Vec<f64> {
    (0..n_ctrl)
        .map(|i| knots[i + 1..=i + p].iter().sum::<f64>() / p as f64)
        .collect()
}

/// Fits the adjusted bottom with control points about `spacing_mm` apart.
pub fn fit_bottom(adj: &Adjustment, spacing_mm: f64) -> Result<BottomSurface, AdjustError> {
    let g = &adj.heights;
    let p = 3;
    let (xa, xb) = (g.x0, g.x(g.nx - 1));
    let (ya, yb) = (g.y0, g.y(g.ny - 1));
    let mu = (((xb - xa) / spacing_mm).round() as usize + p).clamp(p + 1, g.nx);
    let mv = (((yb - ya) / spacing_mm).round() as usize + p).clamp(p + 1, g.ny);
    let ku = clamped_uniform(xa, xb, mu, p);
    let kv = clamped_uniform(ya, yb, mv, p);
    let xs: Vec<f64> = (0..g.nx).map(|i| g.x(i)).collect();
    let ys: Vec<f64> = (0..g.ny).map(|j| g.y(j)).collect();
    let nu = collocation(&xs, &ku, mu, p);
    let nv = collocation(&ys, &kv, mv, p);
    let z = DMatrix::from_fn(g.nx, g.ny, |i, j| g.get(i, j));
    if z.iter().any(|v| !v.is_finite()) {
        return Err(AdjustError::Output {
            path: "bottom surface".into(),
            why: "the adjusted height grid has holes".into(),
        });
    }
    // Separable least squares: along x for every row, then along y.
    let solve = |n: &DMatrix<f64>, rhs: &DMatrix<f64>| {
        let ntn = n.transpose() * n;
        let ntr = n.transpose() * rhs;
        ntn.cholesky().map(|c| c.solve(&ntr))
    };
    let fail = |what: &str| AdjustError::Output {
        path: "bottom surface".into(),
        why: format!("the least-squares system along {what} is singular"),
    };
    let c1 = solve(&nu, &z).ok_or_else(|| fail("x"))?; // mu x ny
    let c2 = solve(&nv, &c1.transpose()).ok_or_else(|| fail("y"))?; // mv x mu
    let gu = greville(&ku, mu, p);
    let gv = greville(&kv, mv, p);
    let mut points = Vec::with_capacity(mu * mv);
    for (i, &x) in gu.iter().enumerate() {
        for (j, &y) in gv.iter().enumerate() {
            points.push(P3::new(x, y, c2[(j, i)]));
        }
    }
    let surface =
        NurbsSurface::new(p, p, ku, kv, mu, mv, points, None).map_err(|e| AdjustError::Output {
            path: "bottom surface".into(),
            why: footscan_util::chain(&e),
        })?;
    let fitted = &nu * c2.transpose() * nv.transpose(); // nx x ny
    let (mut s2, mut n, mut mx) = (0.0, 0usize, 0.0f64);
    for j in 0..g.ny {
        for i in 0..g.nx {
            if adj.inside[j * g.nx + i] {
                let e = fitted[(i, j)] - z[(i, j)];
                s2 += e * e;
                n += 1;
                mx = mx.max(e.abs());
            }
        }
    }
    let mut notes = Vec::new();
    let lifted: Vec<P3> = super::outline::resample_closed(&adj.outline, 256)
        .iter()
        .map(|q| P3::new(q.x, q.y, surface.point(q.x, q.y).z))
        .collect();
    let outline = match fit_closed_adaptive(
        &lifted,
        &FitOptions {
            tolerance: 0.05,
            ..FitOptions::default()
        },
    ) {
        Ok(r) => Some(r.curve),
        Err(e) => {
            notes.push(format!(
                "outline curve not fitted: {e}",
                e = footscan_util::Chain(&e)
            ));
            None
        }
    };
    Ok(BottomSurface {
        surface,
        outline,
        rms_mm: (s2 / n.max(1) as f64).sqrt(),
        max_mm: mx,
        notes,
    })
}
