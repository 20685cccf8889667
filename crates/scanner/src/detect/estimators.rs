//! Per-row subpixel estimators behind the shared coarse search: the paper's Bezier method as
//! written, and the baselines of docs/method.md section 4.4.

use super::bernstein::{bisect_literal, Binomials, MAX_N};
use super::coarse::{
    prefetch_ahead, reject_isolated, CoarseConfig, CoarseScratch, Near, Peak, Px, NEAR_ROWS,
};
use super::{Detector, LinePeak, Reject};
use footscan_hal::{Frame, Pixels};

/// A subpixel estimator of one row, given the coarse peak.
pub trait Estimate: Send + Sync {
    /// Detector name (`detect.<name>` as a stage).
    fn name(&self) -> &'static str;
    /// The line's column, or why the row has none.
    fn estimate<T: Px>(&self, row: &[T], pk: &Peak, cfg: &CoarseConfig) -> Result<f64, Reject>;
}

/// A detector that runs the coarse search and one [`Estimate`] on every row independently.
pub struct RowDetector<E> {
    pub coarse: CoarseConfig,
    pub est: E,
    s8: CoarseScratch<u8>,
    s16: CoarseScratch<u16>,
}

impl<E: Estimate> RowDetector<E> {
    pub fn new(coarse: CoarseConfig, est: E) -> Self {
        RowDetector {
            coarse,
            est,
            s8: CoarseScratch::default(),
            s16: CoarseScratch::default(),
        }
    }
}

fn run_rows<T: Px, E: Estimate>(
    px: &[T],
    w: usize,
    cfg: &CoarseConfig,
    est: &E,
    scratch: &mut CoarseScratch<T>,
    out: &mut [LinePeak],
) {
    scratch.for_width(w);
    let isa = super::simd::current();
    for (r, row) in px.chunks_exact(w).enumerate() {
        prefetch_ahead(px, r, w);
        let thr = scratch.threshold_on(isa, cfg, r, row);
        let blocks = scratch.for_width(w);
        T::block_max_on(isa, row, blocks);
        let near = (1..=NEAR_ROWS.min(r))
            .map(|k| &out[r - k])
            .find(|p| p.is_valid())
            .map(|p| Near {
                col: p.col,
                width: p.width,
            });
        out[r] = match scratch.row_near_on(isa, row, cfg, thr, near) {
            Err((r, v)) => LinePeak::rejected(r, v),
            Ok(pk) => match est.estimate(row, &pk, cfg) {
                Ok(col) => accepted(col, &pk, T::FULL as f32),
                Err(r) => LinePeak::rejected(r, pk.peak),
            },
        };
    }
    reject_isolated(&mut out[..px.len() / w.max(1)]);
}

pub(crate) fn accepted(col: f64, pk: &Peak, full: f32) -> LinePeak {
    LinePeak {
        col,
        intensity: pk.peak,
        width: pk.width,
        quality: pk.quality(pk.thr, full),
        reject: None,
    }
}

impl<E: Estimate> Detector for RowDetector<E> {
    fn name(&self) -> &'static str {
        self.est.name()
    }

    fn detect(&mut self, frame: &Frame, out: &mut [LinePeak]) {
        let w = frame.width as usize;
        assert_eq!(out.len(), frame.height as usize, "one result per row");
        match &frame.pixels {
            Pixels::Gray8(px) => run_rows(px, w, &self.coarse, &self.est, &mut self.s8, out),
            Pixels::Gray16(px) => run_rows(px, w, &self.coarse, &self.est, &mut self.s16, out),
        }
    }
}

/// Centre of the flat (saturated) top, the only honest answer of a 3-point fit there.
fn flat_top(pk: &Peak) -> Option<f64> {
    (pk.top_hi > pk.top_lo).then(|| 0.5 * (pk.top_lo + pk.top_hi) as f64)
}

/// Centre of gravity over the run above the threshold, weights `I - threshold` (unbiased for a
/// symmetric profile cut at a level).
#[derive(Clone, Debug)]
pub struct Cog;

impl Estimate for Cog {
    fn name(&self) -> &'static str {
        "cog"
    }
    fn estimate<T: Px>(&self, row: &[T], pk: &Peak, _: &CoarseConfig) -> Result<f64, Reject> {
        let t = pk.thr;
        let (mut s, mut sx) = (0.0f64, 0.0f64);
        for (i, v) in row.iter().enumerate().take(pk.hi + 1).skip(pk.lo) {
            let wgt = (v.f() - t) as f64;
            s += wgt;
            sx += wgt * i as f64;
        }
        if s <= 0.0 {
            return Err(Reject::BelowThreshold);
        }
        Ok(sx / s)
    }
}

/// 3-point parabola through the maximum and its neighbours.
#[derive(Clone, Debug)]
pub struct Parabolic;

impl Estimate for Parabolic {
    fn name(&self) -> &'static str {
        "parabolic"
    }
    fn estimate<T: Px>(&self, row: &[T], pk: &Peak, _: &CoarseConfig) -> Result<f64, Reject> {
        if let Some(c) = flat_top(pk) {
            return Ok(c);
        }
        let m = pk.m;
        let (a, b, c) = (row[m - 1].f(), row[m].f(), row[m + 1].f());
        Ok(m as f64 + three_point(a, b, c))
    }
}

/// Vertex offset of the parabola through (-1, a), (0, b), (1, c), within +-0.5.
#[inline]
fn three_point(a: f32, b: f32, c: f32) -> f64 {
    let den = a - 2.0 * b + c;
    if den >= 0.0 {
        return 0.0;
    }
    (0.5 * (a - c) / den).clamp(-0.5, 0.5) as f64
}

/// 3-point Gaussian fit: the parabola through the logarithms.
#[derive(Clone, Debug)]
pub struct Gaussian;

impl Estimate for Gaussian {
    fn name(&self) -> &'static str {
        "gaussian"
    }
    fn estimate<T: Px>(&self, row: &[T], pk: &Peak, _: &CoarseConfig) -> Result<f64, Reject> {
        if let Some(c) = flat_top(pk) {
            return Ok(c);
        }
        let m = pk.m;
        let l = |v: T| v.f().max(1.0).ln();
        Ok(m as f64 + three_point(l(row[m - 1]), l(row[m]), l(row[m + 1])))
    }
}

/// Blais and Rioux (1986): zero crossing of g(i) = I(i-2) + I(i-1) - I(i+1) - I(i+2), linearly
/// interpolated.
#[derive(Clone, Debug)]
pub struct BlaisRioux;

impl Estimate for BlaisRioux {
    fn name(&self) -> &'static str {
        "blais-rioux"
    }
    fn estimate<T: Px>(&self, row: &[T], pk: &Peak, _: &CoarseConfig) -> Result<f64, Reject> {
        let m = pk.m;
        if m < 3 || m + 3 >= row.len() {
            return Err(Reject::Border);
        }
        let g = |i: usize| row[i - 2].f() + row[i - 1].f() - row[i + 1].f() - row[i + 2].f();
        // g rises through zero at the line (left of it the lower pixels come first).
        let (gm1, g0, gp1) = (g(m - 1), g(m), g(m + 1));
        let col = if g0 <= 0.0 && gp1 > 0.0 {
            m as f64 + (g0 / (g0 - gp1)) as f64
        } else if gm1 < 0.0 && g0 >= 0.0 {
            (m - 1) as f64 + (gm1 / (gm1 - g0)) as f64
        } else {
            m as f64
        };
        Ok(col)
    }
}

/// Steger-style: zero of the first Gaussian-derivative response, one Newton step
/// x = m - r'(m) / r''(m) from the pixel of the maximum (moved once if the step leaves it).
#[derive(Clone, Debug)]
pub struct Steger {
    pub sigma: f64,
    radius: usize,
    /// G'(k) and G''(k), k = -radius..=radius.
    k1: Vec<f32>,
    k2: Vec<f32>,
}

impl Steger {
    pub fn new(sigma: f64) -> Self {
        let radius = (3.0 * sigma).ceil().max(1.0) as usize;
        let s2 = sigma * sigma;
        let (mut k1, mut k2) = (Vec::new(), Vec::new());
        for k in -(radius as i64)..=radius as i64 {
            let x = k as f64;
            let g = (-x * x / (2.0 * s2)).exp();
            k1.push((-x / s2 * g) as f32);
            k2.push(((x * x / s2 - 1.0) / s2 * g) as f32);
        }
        // A truncated second derivative does not sum to zero: make it, so the background drops.
        let mean = k2.iter().sum::<f32>() / k2.len() as f32;
        k2.iter_mut().for_each(|v| *v -= mean);
        Steger {
            sigma,
            radius,
            k1,
            k2,
        }
    }

    /// Newton offset from pixel `m` (None if the kernel leaves the row).
    fn step<T: Px>(&self, row: &[T], m: usize, bg: f32) -> Option<f64> {
        let r = self.radius;
        if m < r || m + r >= row.len() {
            return None;
        }
        // Convolution (f * G')(m) = sum_j f(j) G'(m - j): kernel index k = m - j + r.
        let (mut d1, mut d2) = (0.0f32, 0.0f32);
        for (k, (a, b)) in self.k1.iter().zip(&self.k2).enumerate() {
            let v = row[m + r - k].f() - bg;
            d1 += a * v;
            d2 += b * v;
        }
        if d2 >= 0.0 {
            return Some(0.0);
        }
        Some(-(d1 / d2) as f64)
    }
}

impl Estimate for Steger {
    fn name(&self) -> &'static str {
        "steger"
    }
    fn estimate<T: Px>(&self, row: &[T], pk: &Peak, _: &CoarseConfig) -> Result<f64, Reject> {
        let mut m = pk.m;
        let mut d = self.step(row, m, pk.bg).ok_or(Reject::Border)?;
        if d.abs() > 0.5 {
            m = if d > 0.0 { m + 1 } else { m - 1 };
            d = self.step(row, m, pk.bg).ok_or(Reject::Border)?;
        }
        Ok(m as f64 + d.clamp(-1.0, 1.0))
    }
}

/// The plantar scanner paper's method as written (its eq. 11-12, docs/method.md section 4.1):
/// a window of n + 1 pixels centred on the integer maximum, the Bernstein curves x(t) and
/// I(t), bisection on I'(t), the column x(t*).
#[derive(Clone, Debug)]
pub struct BezierLiteral {
    pub n: usize,
}

impl BezierLiteral {
    pub fn new(n: usize) -> Result<Self, super::DetectError> {
        if !(2..MAX_N).contains(&n) {
            return Err(super::DetectError::Param(format!(
                "window = {n}: valid range is 2..{}",
                MAX_N - 1
            )));
        }
        Ok(BezierLiteral { n })
    }
}

impl Estimate for BezierLiteral {
    fn name(&self) -> &'static str {
        "bezier"
    }
    fn estimate<T: Px>(&self, row: &[T], pk: &Peak, _: &CoarseConfig) -> Result<f64, Reject> {
        let n = self.n;
        let x0 = pk.m as i64 - (n / 2) as i64;
        if x0 < 0 || x0 as usize + n >= row.len() {
            return Err(Reject::Border);
        }
        let x0 = x0 as usize;
        let mut s = [0.0f64; MAX_N];
        for (i, v) in row[x0..=x0 + n].iter().enumerate() {
            s[i] = v.f() as f64;
        }
        let t = bisect_literal(&s[..=n]);
        Ok(x0 as f64 + n as f64 * t)
    }
}

/// Shared binomial table.
pub(crate) fn binomials() -> &'static Binomials {
    static B: std::sync::OnceLock<Binomials> = std::sync::OnceLock::new();
    B.get_or_init(Binomials::new)
}
