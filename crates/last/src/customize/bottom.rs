//! A last's or a foot's bottom curve in the side view, and laying a mesh flat by it.

use footscan_geom::mesh::TriMesh;
use footscan_geom::P2;

/// A bottom that rises less than this anywhere (mm) is taken as flat.
pub(crate) const FLAT_TOL_MM: f64 = 0.5;
/// The part of the length whose sections' lowest points are the bottom curve (fractions from
/// the heel end): behind and in front of it the lowest point is the heel's and the toe's
/// rounding, so the curve is carried on along its end slopes there.
const BOTTOM_SPAN: (f64, f64) = (0.15, 0.9);

/// Half-width of the lowest-point and mean windows of [`BottomCurve::under_arch`] (mm).
const ARCH_SMOOTH_MM: usize = 8;

/// The lowest point of a mesh's section at every millimetre along x, from its rear end.
/// Returns the rear end, the extent along x and the lowest heights.
fn lowest_per_mm(m: &TriMesh) -> (f64, f64, Vec<Option<f64>>) {
    let bb = m.bbox();
    let n = (bb.max.x - bb.min.x).floor() as usize + 1;
    let xs: Vec<f64> = (0..n).map(|i| bb.min.x + i as f64).collect();
    let low = super::shape::station_points(m, &xs, f64::MAX)
        .iter()
        .map(|q| q.iter().map(|p| p.y).reduce(f64::min))
        .collect();
    (bb.min.x, bb.max.x - bb.min.x, low)
}

/// The lowest heights `low` (one a millimetre) averaged over +-`half` mm within [a, b] and
/// carried on beyond along the slopes of the span's last 10 mm: a last's bottom curve, and
/// the insole's spring under it. None when the span is under 20 mm or a station in it has
/// no height within reach.
pub fn smoothed_lowest(low: &[Option<f64>], a: usize, b: usize, half: usize) -> Option<Vec<f64>> {
    let n = low.len();
    if b < a + 20 || b >= n {
        return None;
    }
    let mut z = vec![0.0; n];
    for (i, zi) in z.iter_mut().enumerate().take(b + 1).skip(a) {
        let near: Vec<f64> = (i.saturating_sub(half).max(a)..=(i + half).min(b))
            .filter_map(|j| low[j])
            .collect();
        if near.is_empty() {
            return None;
        }
        *zi = near.iter().sum::<f64>() / near.len() as f64;
    }
    let back = (z[a + 10] - z[a]) / 10.0;
    let front = (z[b] - z[b - 10]) / 10.0;
    for i in 0..a {
        z[i] = z[a] - back * (a - i) as f64;
    }
    for i in b + 1..n {
        z[i] = z[b] + front * (i - b) as f64;
    }
    Some(z)
}

/// A last's bottom curve in its frame: the height of the lowest point of its section at
/// every millimetre along x, smoothed over +-5 mm.
pub(crate) struct BottomCurve {
    x0: f64,
    z: Vec<f64>,
}

impl BottomCurve {
    /// A last's: the sections' lowest points over [`BOTTOM_SPAN`], carried on beyond.
    pub(crate) fn of(m: &TriMesh) -> Option<BottomCurve> {
        let (x0, len, low) = lowest_per_mm(m);
        let n = low.len();
        let (a, b) = (
            (BOTTOM_SPAN.0 * len) as usize,
            ((BOTTOM_SPAN.1 * len) as usize).min(n.saturating_sub(1)),
        );
        let z = smoothed_lowest(&low, a, b, 5)?;
        Some(BottomCurve { x0, z })
    }

    /// A foot's bottom under its arch: zero where the foot stands on the glass (behind its
    /// heel's lowest point in the rear 30 % and in front of its forefoot's lowest point
    /// between 0.5 and 0.85 of the length), and between them a smooth curve under the
    /// sections' lowest points (the lowest within ARCH_SMOOTH_MM, averaged over as much
    /// again, never above the section's own lowest point; this lags a 6 mm arch by 1.1 mm
    /// at its top, the mean alone by much less, but the solve then did not converge on the
    /// lifted simulated foot: the heel offset and heel width traded for 40 steps). A foot
    /// scanned without weight on it (the real feet in the benchmark) has its whole midfoot
    /// 2-9 mm above the plane through heel and ball; laid flat by this curve it stands like a
    /// foot on the glass.
    pub(crate) fn under_arch(m: &TriMesh) -> Option<BottomCurve> {
        let (x0, len, low) = lowest_per_mm(m);
        let n = low.len();
        if n < 100 {
            return None;
        }
        // A station the mesh does not cross (a gap in a broken scan) raises nothing.
        let low: Vec<f64> = low.iter().map(|z| z.unwrap_or(0.0).max(0.0)).collect();
        let argmin = |a: f64, b: f64| {
            let (a, b) = ((a * len) as usize, ((b * len) as usize).min(n - 1));
            (a..=b).min_by(|&i, &j| low[i].total_cmp(&low[j]))
        };
        let (h, f) = (argmin(0.0, 0.3)?, argmin(0.5, 0.85)?);
        let w = ARCH_SMOOTH_MM;
        let floor: Vec<f64> = (0..n)
            .map(|i| {
                if i <= h || i >= f {
                    return 0.0;
                }
                low[i.saturating_sub(w)..=(i + w).min(n - 1)]
                    .iter()
                    .copied()
                    .fold(f64::MAX, f64::min)
            })
            .collect();
        let z: Vec<f64> = (0..n)
            .map(|i| {
                if i <= h || i >= f {
                    return 0.0;
                }
                let near = &floor[i.saturating_sub(w)..=(i + w).min(n - 1)];
                let mean = near.iter().sum::<f64>() / near.len() as f64;
                mean.min(low[i]).max(0.0)
            })
            .collect();
        Some(BottomCurve { x0, z })
    }

    pub(crate) fn at(&self, x: f64) -> f64 {
        let t = (x - self.x0).clamp(0.0, (self.z.len() - 1) as f64);
        let i = (t.floor() as usize).min(self.z.len() - 2);
        let f = t - i as f64;
        self.z[i] * (1.0 - f) + self.z[i + 1] * f
    }

    /// How far the bottom rises above its lowest point.
    pub(crate) fn rise(&self) -> f64 {
        let lo = self.z.iter().copied().fold(f64::MAX, f64::min);
        let hi = self.z.iter().copied().fold(f64::MIN, f64::max);
        hi - lo
    }

    /// The curve's own samples (every millimetre: linear interpolation between them is
    /// [`BottomCurve::at`], so a reader lays the last flat exactly as it was raised).
    pub(crate) fn samples(&self) -> Vec<P2> {
        self.z
            .iter()
            .enumerate()
            .map(|(i, z)| P2::new(self.x0 + i as f64, *z))
            .collect()
    }
}

/// Move every point up by `dz(x)`.
pub(crate) fn raise(pts: &mut [footscan_geom::P3], dz: impl Fn(f64) -> f64) {
    for p in pts {
        p.z += dz(p.x);
    }
}

/// Move every vertex up by `dz(x)`.
pub(crate) fn shear(m: &mut TriMesh, dz: impl Fn(f64) -> f64) {
    for v in &mut m.vertices {
        v.z += dz(v.x);
    }
}
