//! `bezier-plus`: the paper's Bezier estimator made accurate, robust and fast.
//!
//! Per frame, one pass over the rows (steps 1-3, each row while it is in the L1 cache), then
//! one over the row results (step 4); scratch is kept between frames, nothing is allocated:
//! 1. Coarse search (shared with every detector): peak, run, width, rejects, spikes skipped.
//! 2. Line width: a running mean of the rows' widths at half height (weight 1/8 per row), so
//!    the window follows the line, not per-row speckle.
//! 3. Bezier estimate per row, the paper's curves x(t), I(t) and the root of I'(t), with:
//!    - control points sized to the line: bins of b = round(sigma) pixels (b = 1 up to
//!      sigma 1.5 px), n + 1 of them spanning about +-`window_sigmas` line sigmas, so the
//!      Bernstein curve's smoothing (a binomial kernel of variance (n - 1) / 4 control points)
//!      grows with the line instead of staying a few pixels wide;
//!    - re-centring: a first estimate (5-pixel centre of gravity; over the whole run above the
//!      threshold for a line of sigma 3.5 px or more), then the window placed so
//!      its centre is as near it as the pixel grid allows (n even or odd, whichever is nearer);
//!    - the root by bracketed Newton on the factorised Bernstein derivative ([`root_near`]);
//!    - bias correction: the residual pull toward the window centre removed with a table built
//!      once from noise-free pixel-integrated Gaussian profiles (line sigma in bins x window
//!      parity x offset from the centre), linear interpolation in sigma and offset.
//! 4. Continuity along the line: a local linear fit over neighbouring rows with Gaussian
//!    weights (sigma `smooth_rows` rows), following the line only while consecutive rows
//!    differ by less than `jump_px`; the local quadratic fit instead where its curvature term is
//!    significant at the frame's measured column noise (line ends, walls); an isolated row that
//!    breaks continuity with both of its agreeing neighbours is replaced by their fit. Speckle
//!    is independent from row to row, so this averages it out; linear trends pass unchanged.
//!    Cost along y: the impulse response of the default (sigma 1.5 rows) has a FWHM of
//!    3.5 rows = 0.44 mm at the glass (rows are (D + h) / F = 0.125 mm apart at h = 0).

use super::bernstein::{root_near, root_near_on, Binomials, MAX_N};
use super::coarse::{
    prefetch_ahead, reject_isolated, CoarseConfig, CoarseScratch, Near, Peak, Px, NEAR_ROWS,
};
use super::estimators::{accepted, binomials};
use super::simd::Isa;
use super::{Detector, LinePeak, Reject};
use footscan_hal::{Frame, Pixels};

/// Settings of [`BezierPlus`].
#[derive(Clone, Debug, PartialEq)]
pub struct BezierPlusConfig {
    pub coarse: CoarseConfig,
    /// Half the window in line sigmas (the window holds about 2 * this * sigma + 1 pixels).
    pub window_sigmas: f64,
    /// Fixed even n instead (0 = sized from the measured width).
    pub window: usize,
    /// Gaussian sigma of the smoothing along the line, rows (0 = off).
    pub smooth_rows: f64,
    /// Largest column step between consecutive rows that still counts as the same line (px).
    pub jump_px: f64,
    /// Remove the residual bias with the table.
    pub bias_correction: bool,
}

impl Default for BezierPlusConfig {
    fn default() -> Self {
        BezierPlusConfig {
            coarse: CoarseConfig::default(),
            window_sigmas: 6.0,
            window: 0,
            smooth_rows: 1.5,
            jump_px: 1.0,
            bias_correction: true,
        }
    }
}

impl BezierPlusConfig {
    pub fn validate(&self) -> Result<(), super::DetectError> {
        self.coarse.validate()?;
        if !(0.5..=10.0).contains(&self.window_sigmas) {
            return Err(super::DetectError::Param(format!(
                "window_sigmas = {}: valid range is 0.5..10",
                self.window_sigmas
            )));
        }
        if self.window != 0 && !(4..MAX_N - 2).contains(&self.window) {
            return Err(super::DetectError::Param(format!(
                "window = {}: 0 (auto) or 4..{}",
                self.window,
                MAX_N - 3
            )));
        }
        if !(0.0..=10.0).contains(&self.smooth_rows) {
            return Err(super::DetectError::Param(format!(
                "smooth_rows = {}: valid range is 0..10",
                self.smooth_rows
            )));
        }
        if !(self.jump_px > 0.0 && self.jump_px <= 20.0) {
            return Err(super::DetectError::Param(format!(
                "jump_px = {}: valid range is (0, 20]",
                self.jump_px
            )));
        }
        Ok(())
    }
}

/// Bias of the re-centred estimate, by line sigma, window parity and offset.
#[derive(Debug, Clone)]
struct BiasTable {
    /// Sigma grid: SIG0 + k * SIG_STEP.
    /// table[(k * 3 + slot) * 2 + parity][d], slot 0/1/2 = n_even - 2 / n_even / n_even + 2 of
    /// the grid sigma, d over DELTA grid.
    table: Vec<[f32; ND]>,
    /// n_even at each grid sigma.
    n_at: Vec<usize>,
}

const SIG0: f64 = 0.5;
const SIG_STEP: f64 = 0.05;
const NSIG: usize = 111; // 0.5 ..= 6.0
const ND: usize = 49; // delta -0.75 ..= 0.75
const D_STEP: f64 = 1.5 / (ND - 1) as f64;

/// n_even for a line sigma.
fn n_even_for(sigma: f64, cfg: &BezierPlusConfig) -> usize {
    if cfg.window != 0 {
        return cfg.window & !1;
    }
    let n = 2 * ((cfg.window_sigmas * sigma).max(0.0) + 0.5) as usize;
    n.clamp(4, MAX_N - 3 - ((MAX_N - 3) & 1))
}

/// Pixel-integrated Gaussian sample, effective sigma `sigma` (box of 1 px included).
fn profile_sample(x: f64, c: f64, sigma_eff: f64) -> f32 {
    let s2 = (sigma_eff * sigma_eff - 1.0 / 12.0).max(0.01);
    let s = s2.sqrt();
    let k = 1.0 / (s * std::f64::consts::SQRT_2);
    let e = libm::erf((x + 0.5 - c) * k) - libm::erf((x - 0.5 - c) * k);
    (8.0 + 180.0 * 0.5 * e / (0.5 * (libm::erf(0.5 * k) - libm::erf(-0.5 * k)))) as f32
}

impl BiasTable {
    fn build(cfg: &BezierPlusConfig, binom: &Binomials) -> Self {
        let mut table = vec![[0.0f32; ND]; NSIG * 3 * 2];
        let mut n_at = vec![0; NSIG];
        let mut buf = [0.0f32; MAX_N];
        for (k, n_slot) in n_at.iter_mut().enumerate() {
            let sigma = SIG0 + k as f64 * SIG_STEP;
            let ne = n_even_for(sigma, cfg);
            *n_slot = ne;
            for slot in 0..3 {
                let n_even = (ne + 2 * slot).saturating_sub(2).clamp(4, MAX_N - 4);
                for parity in 0..2 {
                    let n = n_even + parity;
                    // Window x_0 = 0; its centre is n / 2.
                    let centre = n as f64 / 2.0;
                    let row = &mut table[(k * 3 + slot) * 2 + parity];
                    for (d, b) in row.iter_mut().enumerate() {
                        let delta = -0.75 + d as f64 * D_STEP;
                        for (i, v) in buf[..=n].iter_mut().enumerate() {
                            *v = profile_sample(i as f64, centre + delta, sigma);
                        }
                        let t0 = 0.5 + delta / n as f64;
                        *b = match root_near(&buf[..=n], binom, t0) {
                            Some(t) => (n as f64 * t - centre - delta) as f32,
                            None => 0.0,
                        };
                    }
                }
            }
        }
        BiasTable { table, n_at }
    }

    /// Bias at line sigma `sigma`, window n (`n_even` + `parity`), measured offset `delta`.
    fn bias(&self, sigma: f64, n_even: usize, parity: usize, delta: f64) -> f64 {
        let fs = ((sigma - SIG0) / SIG_STEP).clamp(0.0, (NSIG - 1) as f64);
        let k0 = (fs as usize).min(NSIG - 2); // fs >= 0: truncation is floor
        let ws = fs - k0 as f64;
        let fd = ((delta + 0.75) / D_STEP).clamp(0.0, (ND - 1) as f64);
        let d0 = (fd as usize).min(ND - 2);
        let wd = fd - d0 as f64;
        let mut acc = 0.0;
        let mut wsum = 0.0;
        for (k, wk) in [(k0, 1.0 - ws), (k0 + 1, ws)] {
            let slot = n_even as i64 - self.n_at[k] as i64;
            if !(-2..=2).contains(&slot) || slot % 2 != 0 {
                continue;
            }
            let slot = (slot / 2 + 1) as usize;
            let row = &self.table[(k * 3 + slot) * 2 + parity];
            let v = row[d0] as f64 * (1.0 - wd) + row[d0 + 1] as f64 * wd;
            acc += wk * v;
            wsum += wk;
        }
        if wsum > 0.0 {
            acc / wsum
        } else {
            0.0
        }
    }
}

/// The improved Bezier detector (see the module documentation).
pub struct BezierPlus {
    cfg: BezierPlusConfig,
    bias: Option<BiasTable>,
    raw: Vec<f64>,
    d2: Vec<f64>,
    s8: CoarseScratch<u8>,
    s16: CoarseScratch<u16>,
}

impl BezierPlus {
    pub fn new(cfg: BezierPlusConfig) -> Result<Self, super::DetectError> {
        cfg.validate()?;
        let bias = cfg
            .bias_correction
            .then(|| BiasTable::build(&cfg, binomials()));
        Ok(BezierPlus {
            cfg,
            bias,
            raw: Vec::new(),
            d2: Vec::with_capacity(4096),
            s8: CoarseScratch::default(),
            s16: CoarseScratch::default(),
        })
    }

    pub fn config(&self) -> &BezierPlusConfig {
        &self.cfg
    }

    fn run<T: Px>(
        &mut self,
        px: &[T],
        w: usize,
        h: usize,
        scratch: &mut CoarseScratch<T>,
        out: &mut [LinePeak],
    ) {
        self.raw.resize(h, f64::NAN);
        let cfg = self.cfg.coarse;
        let binom = binomials();
        // 1-3 in one pass, each row while it is in the L1 cache. The line width is a running
        // mean over the preceding valid rows (weight 1/8 per row), started by the first one.
        let mut width = f64::NAN;
        scratch.for_width(w);
        let isa = super::simd::current();
        for (r, row) in px.chunks_exact(w).enumerate() {
            prefetch_ahead(px, r, w);
            let thr = scratch.threshold_on(isa, &cfg, r, row);
            let blocks = scratch.for_width(w);
            T::block_max_on(isa, row, blocks);
            let near = (1..=NEAR_ROWS.min(r))
                .map(|k| self.raw[r - k])
                .find(|c| c.is_finite())
                .map(|col| Near {
                    col,
                    width: if width.is_finite() { width as f32 } else { 3.0 },
                });
            out[r] = match scratch.row_near_on(isa, row, &cfg, thr, near) {
                Err((why, v)) => {
                    self.raw[r] = f64::NAN;
                    LinePeak::rejected(why, v)
                }
                Ok(pk) => {
                    if pk.saturated == 0 {
                        let wd = pk.width as f64;
                        width = if width.is_finite() {
                            width + (wd - width) * 0.125
                        } else {
                            wd
                        };
                    }
                    let sigma = if width.is_finite() {
                        width
                    } else {
                        pk.width as f64
                    } / 2.3548;
                    match estimate_row(isa, row, &pk, sigma, &self.cfg, self.bias.as_ref(), binom) {
                        Some(c) => {
                            self.raw[r] = c;
                            accepted(c, &pk, T::FULL as f32)
                        }
                        None => {
                            self.raw[r] = f64::NAN;
                            LinePeak::rejected(Reject::Border, pk.peak)
                        }
                    }
                }
            };
        }
        // 4. Along the line.
        if self.cfg.smooth_rows > 0.0 {
            let noise = column_noise(&self.raw, self.cfg.jump_px, &mut self.d2);
            smooth_along(
                &self.raw,
                self.cfg.smooth_rows,
                self.cfg.jump_px,
                noise,
                out,
            );
        }
        reject_isolated(out);
    }
}

/// Pixels per Bezier control point for a line of (pixel-integrated) sigma `sigma` px: wide
/// lines are binned so the Bernstein curve's smoothing keeps pace with the line's width.
#[inline]
pub(crate) fn bin_for(sigma: f64) -> usize {
    ((sigma + 0.5) as usize).clamp(1, 8)
}

/// Bins of this many pixels or more (a line sigma of 3.5 px or more) start the estimate from
/// the centre of gravity of the whole run above the threshold ([`estimate_row`]).
const WIDE_BIN: usize = 4;

/// Flanks of the window for [`textured`]: beyond this many line sigmas of the first estimate
/// (the line's own tails are under 1 % of its peak there).
const FLANK_SIGMAS: f64 = 3.0;
/// A textured flank varies by more than this fraction of the line's height over its lowest
/// pixel ([`textured`]).
const TEXTURE_FRAC: f32 = 0.1;
/// ... and by more than this, 8-bit DN (x257 for Gray16): a dim line's JPEG ripple or a noisy
/// row's spread is not texture.
const TEXTURE_MIN_DN: f32 = 20.0;

/// The level to clip the window at when the board beside the line is textured, or None: the
/// highest pixel of the window's flanks (beyond [`FLANK_SIGMAS`] of `c1` and outside the run
/// above the threshold), at most the row's threshold, when the flanks vary by more than
/// [`TEXTURE_FRAC`] of the line's height and [`TEXTURE_MIN_DN`]. Across a chessboard's edges
/// (Ciclop, the `chessboard-jpeg` kind) the Bernstein curve over +-6 sigmas is pulled toward
/// the brighter square and the overshoot of the squares' edges; clipped at the flanks'
/// highest pixel, only the line above the board is left.
fn textured<T: Px>(row: &[T], pk: &Peak, c1: f64, sigma: f64, x0: usize, x1: usize) -> Option<f32> {
    let cl = (c1 - FLANK_SIGMAS * sigma).max(0.0) as usize;
    let cr = (c1 + FLANK_SIGMAS * sigma) as usize;
    let (a, z) = (pk.lo.min(cl), pk.hi.max(cr));
    let (mut lo, mut hi) = (f32::MAX, f32::MIN);
    for (c, v) in row.iter().enumerate().take(x1).skip(x0) {
        if c < a || c > z {
            lo = lo.min(v.f());
            hi = hi.max(v.f());
        }
    }
    let var = hi - lo;
    (hi >= lo && var > TEXTURE_FRAC * (pk.peak - lo).max(1.0) && var > TEXTURE_MIN_DN * T::SCALE)
        .then_some(hi.min(pk.thr))
}

/// Steps 3 of the module doc for one row: None if no window fits. Where the board beside the
/// line is textured ([`textured`]) the window's samples are clipped at the flanks' level and
/// the bias table (built for a whole Gaussian over a flat background) is not applied.
fn estimate_row<T: Px>(
    isa: Isa,
    row: &[T],
    pk: &Peak,
    sigma: f64,
    cfg: &BezierPlusConfig,
    bias: Option<&BiasTable>,
    binom: &Binomials,
) -> Option<f64> {
    let w = row.len();
    // Control points: bins of b pixels; the line's sigma in bins (pixel integration included).
    let sig_t2 = (sigma * sigma - 1.0 / 12.0).max(0.04);
    let room = pk.m.min(w - 1 - pk.m);
    let mut b = if cfg.window != 0 { 1 } else { bin_for(sigma) };
    let (mut sb, mut n_even);
    loop {
        let bf = b as f64;
        sb = (sig_t2 / (bf * bf) + 1.0 / 12.0).sqrt();
        n_even = n_even_for(sb, cfg);
        // Shrink the window at the image border (keep it on the line), unbinned if need be.
        while n_even >= 4 && ((n_even + 2) * b).div_ceil(2) + 1 > room {
            n_even -= 2;
        }
        if n_even >= 4 {
            break;
        }
        if b == 1 {
            return None;
        }
        b = 1;
    }
    let bf = b as f64;
    // First estimate: centre of gravity of the 5 pixels around the maximum over the background
    // (centre of a flat top).
    let c1 = if b >= WIDE_BIN {
        // A wide line (sigma 3.5 px or more): speckle moves its maximum by up to half its
        // width, and the root of I'(t) nearest a start there can be a speckle's. The centre
        // of gravity over the run above the threshold starts from the whole line.
        let (mut s0, mut s1) = (0.0f64, 0.0f64);
        for (k, v) in row[pk.lo..=pk.hi].iter().enumerate() {
            let v = (v.f() - pk.thr).max(0.0) as f64;
            s0 += v;
            s1 += v * k as f64;
        }
        if s0 > 0.0 {
            pk.lo as f64 + s1 / s0
        } else {
            pk.m as f64
        }
    } else if pk.top_hi > pk.top_lo {
        0.5 * (pk.top_lo + pk.top_hi) as f64
    } else {
        let m = pk.m;
        let (a, z) = (m.saturating_sub(2), (m + 2).min(w - 1));
        let (mut s0, mut s1) = (0.0f32, 0.0f32);
        for (k, v) in row[a..=z].iter().enumerate() {
            let v = (v.f() - pk.bg).max(0.0);
            s0 += v;
            s1 += v * k as f32;
        }
        a as f64
            + if s0 > 0.0 {
                (s1 / s0) as f64
            } else {
                (m - a) as f64
            }
    };
    // Window of n + 1 bins starting at pixel x0, centred as near c1 as the grid allows:
    // n even or odd (n_even + 1), whichever puts the centre nearer.
    let place = |n: usize| -> (f64, f64) {
        let half = ((n + 1) as f64 * bf - 1.0) / 2.0; // centre - x0
                                                      // Round half up without a libm call (SSE2 has no rounding instruction).
        let x0 = ((c1 - half + 0.5 + 1e6) as i64 - 1_000_000) as f64;
        (x0, x0 + half)
    };
    let (x0e, ce) = place(n_even);
    let (x0o, co) = place(n_even + 1);
    let (x0, centre, n, parity) = if (c1 - ce).abs() <= (c1 - co).abs() {
        (x0e, ce, n_even, 0)
    } else {
        (x0o, co, n_even + 1, 1)
    };
    if x0 < 0.0 || x0 as usize + (n + 1) * b > w {
        return None;
    }
    let x0 = x0 as usize;
    let mut smp = [0.0f32; MAX_N];
    if pk.spike_count > 0 && pk.spike_in(x0, x0 + (n + 1) * b - 1) {
        // A skipped spike inside the window: its pixels count as background.
        for (i, d) in smp[..=n].iter_mut().enumerate() {
            *d = (0..b)
                .map(|k| {
                    let c = x0 + i * b + k;
                    if pk.spike_in(c, c) {
                        pk.bg
                    } else {
                        row[c].f()
                    }
                })
                .sum();
        }
    } else if b == 1 {
        for (d, v) in smp[..=n].iter_mut().zip(&row[x0..=x0 + n]) {
            *d = v.f();
        }
    } else {
        for (d, bin) in smp[..=n]
            .iter_mut()
            .zip(row[x0..x0 + (n + 1) * b].chunks_exact(b))
        {
            *d = bin.iter().map(|v| v.f()).sum();
        }
    }
    // A wide line (bins of WIDE_BIN or more) is left as it is: speckle on its flanks would
    // read as texture (wide-speckled: 15 -> 12 regions of 20 within 5 % of cog).
    let clip = if b < WIDE_BIN {
        textured(row, pk, c1, sigma, x0, x0 + (n + 1) * b)
    } else {
        None
    };
    let mut raw = [0.0f32; MAX_N];
    if let Some(level) = clip {
        raw[..=n].copy_from_slice(&smp[..=n]);
        let floor = level * bf as f32;
        for v in &mut smp[..=n] {
            *v = (*v - floor).max(0.0);
        }
    }
    // Bin i's centre is at pixel x0 + (b - 1) / 2 + b i; x(t) = that at i = n t.
    let first = x0 as f64 + (bf - 1.0) / 2.0;
    let t0 = ((c1 - first) / (bf * n as f64)).clamp(0.0, 1.0);
    // A clipped window without a root near the start (a flat zero stretch) is read unclipped.
    let (t, clipped) = match root_near_on(isa, &smp[..=n], binom, t0) {
        Some(t) => (t, clip.is_some()),
        None if clip.is_some() => (root_near_on(isa, &raw[..=n], binom, t0)?, false),
        None => return None,
    };
    let c2 = first + bf * n as f64 * t;
    let delta = (c2 - centre) / bf;
    let corr = match bias {
        Some(tb) if pk.saturated == 0 && !clipped => bf * tb.bias(sb, n_even, parity, delta),
        _ => 0.0,
    };
    Some(c2 - corr)
}

/// Noise of the per-row columns: robust (MAD) sigma of the second differences / sqrt(6) over
/// rows where three consecutive columns are continuous. `scratch` is reused.
fn column_noise(raw: &[f64], jump: f64, scratch: &mut Vec<f64>) -> f64 {
    scratch.clear();
    for w in raw.windows(3) {
        let (a, b, c) = (w[0], w[1], w[2]);
        // Continuous: the step between rows changes by at most `jump` (any slope).
        if a.is_finite() && b.is_finite() && c.is_finite() && ((c - b) - (b - a)).abs() <= jump {
            scratch.push((a - 2.0 * b + c).abs());
        }
    }
    if scratch.len() < 8 {
        return 0.0;
    }
    let mid = scratch.len() / 2;
    let (_, med, _) = scratch.select_nth_unstable_by(mid, |x, y| x.total_cmp(y));
    1.4826 * *med / 6f64.sqrt()
}

/// Slope of the line at row `r` (px per row): the median of the steps to the rows up to 3
/// away whose columns are present, among steps that agree with each other within `jump`; 0 if
/// no neighbour is present. The estimate uses the unsmoothed columns: its noise only moves the
/// continuity test, not the fit.
fn local_slope(raw: &[f64], r: usize, jump: f64) -> f64 {
    let mut st = [0.0f64; 6];
    let mut n = 0;
    for d in 1..=3usize {
        for (a, b) in [(r.checked_sub(d), Some(r)), (Some(r), r.checked_add(d))] {
            if let (Some(a), Some(b)) = (a, b) {
                if b < raw.len() && raw[a].is_finite() && raw[b].is_finite() {
                    st[n] = (raw[b] - raw[a]) / d as f64;
                    n += 1;
                }
            }
        }
    }
    if n == 0 {
        return 0.0;
    }
    let s = &mut st[..n];
    s.sort_unstable_by(|x, y| x.total_cmp(y));
    let m = s[n / 2];
    // Steps of another line (a wall, a jump) do not set the slope.
    if s.iter().filter(|&&v| (v - m).abs() <= jump).count() * 2 > n {
        m
    } else {
        0.0
    }
}

/// Solve the symmetric 3x3 system `m x = t` (None if singular).
fn solve3(m: [[f64; 3]; 3], t: [f64; 3]) -> Option<([f64; 3], [[f64; 3]; 3])> {
    let c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
    let c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
    let c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    let det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
    if det.abs() < 1e-12 * m[0][0].powi(3).max(1e-300) {
        return None;
    }
    let inv = [
        [
            c00,
            m[0][2] * m[2][1] - m[0][1] * m[2][2],
            m[0][1] * m[1][2] - m[0][2] * m[1][1],
        ],
        [
            c01,
            m[0][0] * m[2][2] - m[0][2] * m[2][0],
            m[0][2] * m[1][0] - m[0][0] * m[1][2],
        ],
        [
            c02,
            m[0][1] * m[2][0] - m[0][0] * m[2][1],
            m[0][0] * m[1][1] - m[0][1] * m[1][0],
        ],
    ]
    .map(|r| r.map(|v| v / det));
    let x = [0, 1, 2].map(|i| inv[i][0] * t[0] + inv[i][1] * t[1] + inv[i][2] * t[2]);
    Some((x, inv))
}

/// Step 4 of the module doc: `raw` per-row columns (NaN = none) into `out[r].col`.
/// Local linear fit with Gaussian weights along the continuous stretch of the line; where the
/// local quadratic term is significant (|b2| > 3 standard errors at the frame's column noise)
/// the local quadratic fit is used instead, so bends of the line are not flattened.
fn smooth_along(raw: &[f64], sigma_r: f64, jump: f64, noise: f64, out: &mut [LinePeak]) {
    let h = raw.len();
    let mut wt = [0.0f64; 32];
    let radius = ((3.0 * sigma_r).ceil() as usize).min(wt.len() - 1);
    for (j, v) in wt.iter_mut().enumerate().take(radius + 1) {
        *v = (-((j * j) as f64) / (2.0 * sigma_r * sigma_r)).exp();
    }
    // The complete neighbourhood (2 radius + 1 rows) is the common case: its normal matrix,
    // inverse and quadratic-term variance are the same for every such row.
    let full = {
        let mut sw = [0.0f64; 5];
        let mut sww = [0.0f64; 5];
        for j in -(radius as i64)..=radius as i64 {
            let w = wt[j.unsigned_abs() as usize];
            let mut p = 1.0;
            for k in 0..5 {
                sw[k] += w * p;
                sww[k] += w * w * p;
                p *= j as f64;
            }
        }
        let m = [
            [sw[0], sw[1], sw[2]],
            [sw[1], sw[2], sw[3]],
            [sw[2], sw[3], sw[4]],
        ];
        solve3(m, [0.0; 3]).map(|(_, inv)| {
            let u = [
                [sww[0], sww[1], sww[2]],
                [sww[1], sww[2], sww[3]],
                [sww[2], sww[3], sww[4]],
            ];
            let mut v22 = 0.0;
            for i in 0..3 {
                for k in 0..3 {
                    v22 += inv[2][i] * u[i][k] * inv[2][k];
                }
            }
            (inv, v22.max(0.0).sqrt() * noise, sw)
        })
    };
    let valid = |i: usize| raw[i].is_finite();
    for r in 0..h {
        if !valid(r) {
            continue;
        }
        let c = raw[r];
        // The line's local slope (px per row) from the neighbouring rows: continuity is judged
        // on the step between rows minus this slope, so a line crossing rows at 2.5 px per row
        // is followed as one line, as a vertical one is.
        let slope = local_slope(raw, r, jump);
        // Fast path: all 2 radius + 1 rows present and continuous.
        if let Some((inv, se, sw)) = &full {
            if r >= radius && r + radius < h {
                let win = &raw[r - radius..=r + radius];
                let cont = win.iter().all(|v| v.is_finite())
                    && win.windows(2).all(|p| (p[1] - p[0] - slope).abs() <= jump);
                if cont {
                    let mut st = [0.0f64; 3];
                    for (k, &v) in win.iter().enumerate() {
                        let j = k as f64 - radius as f64;
                        let wv = wt[(k as i64 - radius as i64).unsigned_abs() as usize] * (v - c);
                        st[0] += wv;
                        st[1] += wv * j;
                        st[2] += wv * j * j;
                    }
                    let b2 = inv[2][0] * st[0] + inv[2][1] * st[1] + inv[2][2] * st[2];
                    let fit = if b2.abs() > 3.0 * se {
                        inv[0][0] * st[0] + inv[0][1] * st[1] + inv[0][2] * st[2]
                    } else {
                        // Symmetric weights: the linear fit's value is the weighted mean.
                        st[0] / sw[0]
                    };
                    out[r].col = c + fit;
                    continue;
                }
            }
        }
        // An isolated break: both neighbours agree with each other but not with this row.
        let isolated = r > 0
            && r + 1 < h
            && valid(r - 1)
            && valid(r + 1)
            && (raw[r + 1] - raw[r - 1] - 2.0 * slope).abs() <= 2.0 * jump
            && (c - raw[r - 1] - slope).abs() > jump
            && (raw[r + 1] - c - slope).abs() > jump;
        // Sums of w j^k (k = 0..4), w^2 j^k, w j^k c (k = 0..2); columns relative to c.
        let mut sw = [0.0f64; 5];
        let mut sww = [0.0f64; 5];
        let mut st = [0.0f64; 3];
        let mut npts = 0usize;
        let mut add = |j: f64, w: f64, v: f64| {
            let mut p = 1.0;
            for k in 0..5 {
                sw[k] += w * p;
                sww[k] += w * w * p;
                if k < 3 {
                    st[k] += w * p * (v - c);
                }
                p *= j;
            }
            npts += 1;
        };
        if !isolated {
            add(0.0, wt[0], c);
        }
        for dir in [-1i64, 1] {
            let mut last = if isolated { f64::NAN } else { c };
            for (j, &w) in wt.iter().enumerate().take(radius + 1).skip(1) {
                let i = r as i64 + dir * j as i64;
                if i < 0 || i >= h as i64 {
                    break;
                }
                let v = raw[i as usize];
                if !v.is_finite()
                    || (last.is_finite() && (v - last - dir as f64 * slope).abs() > jump)
                {
                    break;
                }
                last = v;
                add((dir * j as i64) as f64, w, v);
            }
        }
        let det = sw[0] * sw[2] - sw[1] * sw[1];
        let linear = if sw[0] <= 0.0 {
            0.0
        } else if det > 1e-9 * sw[0] * sw[0] {
            (sw[2] * st[0] - sw[1] * st[1]) / det
        } else {
            st[0] / sw[0]
        };
        let mut fit = linear;
        if npts >= 5 {
            let m = [
                [sw[0], sw[1], sw[2]],
                [sw[1], sw[2], sw[3]],
                [sw[2], sw[3], sw[4]],
            ];
            if let Some((b, inv)) = solve3(m, st) {
                // var(b2) = (M^-1 U M^-1)_22 noise^2, U = sum w^2 x x^T.
                let u = [
                    [sww[0], sww[1], sww[2]],
                    [sww[1], sww[2], sww[3]],
                    [sww[2], sww[3], sww[4]],
                ];
                let mut v22 = 0.0;
                for i in 0..3 {
                    for k in 0..3 {
                        v22 += inv[2][i] * u[i][k] * inv[2][k];
                    }
                }
                let se = v22.max(0.0).sqrt() * noise;
                if b[2].abs() > 3.0 * se {
                    fit = b[0];
                }
            }
        }
        out[r].col = c + fit;
        if isolated {
            out[r].quality *= 0.25;
        }
    }
}

impl Detector for BezierPlus {
    fn name(&self) -> &'static str {
        "bezier-plus"
    }

    fn detect(&mut self, frame: &Frame, out: &mut [LinePeak]) {
        let (w, h) = (frame.width as usize, frame.height as usize);
        assert_eq!(out.len(), h, "one result per row");
        match &frame.pixels {
            Pixels::Gray8(px) => {
                let mut s = std::mem::take(&mut self.s8);
                self.run(px, w, h, &mut s, out);
                self.s8 = s;
            }
            Pixels::Gray16(px) => {
                let mut s = std::mem::take(&mut self.s16);
                self.run(px, w, h, &mut s, out);
                self.s16 = s;
            }
        }
    }
}
