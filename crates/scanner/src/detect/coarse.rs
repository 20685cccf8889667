//! The coarse search every detector shares: per row, the line's integer peak, its extent, a
//! width, and the reasons to reject the row (below threshold, saturated, ambiguous, border),
//! with specular spikes skipped.
//!
//! Speed: the only pass over every pixel is [`block_max`], the maximum of each 64-pixel block,
//! written as fixed-size folds the compiler turns into packed max instructions. The row's
//! maximum, its position, and the second peak outside the line are then found from the block
//! maxima (20 per 1280-pixel row) and the pixels of one or two blocks.

use super::simd::{self, Isa};
use super::Reject;

/// A pixel type of a frame (Gray8 or Gray16).
pub trait Px: Copy + Ord + Default + Send + Sync + 'static {
    /// Full scale (saturation) value.
    const FULL: u32;
    /// 8-bit DN to this format's units.
    const SCALE: f32;
    fn f(self) -> f32;
    /// [`block_max`] on the instruction set `isa` (the explicit kernels of [`super::simd`]).
    #[inline]
    fn block_max_on(isa: Isa, row: &[Self], blocks: &mut [Self]) {
        let _ = isa;
        block_max_scalar(row, blocks)
    }
    /// [`row_background`] on the instruction set `isa`.
    #[inline]
    fn background_on(isa: Isa, row: &[Self]) -> (f32, f32, f32) {
        let _ = isa;
        row_background_scalar(row)
    }
    /// First index of `v` in `s`, `s.len()` if absent.
    #[inline]
    fn position(s: &[Self], v: Self) -> usize {
        s.iter().position(|&x| x == v).unwrap_or(s.len())
    }
    /// [`Self::position`] on the instruction set `isa`.
    #[inline]
    fn position_on(isa: Isa, s: &[Self], v: Self) -> usize {
        let _ = isa;
        Self::position(s, v)
    }
    /// The largest block maximum and the first block holding it, on `isa` (None: the
    /// portable scan of [`first_max`]).
    #[inline]
    fn first_block_on(isa: Isa, blocks: &[Self]) -> Option<(Self, usize)> {
        let _ = (isa, blocks);
        None
    }
    /// The first index in `from..to` whose value is not above `t` (not > `t` when `strict`,
    /// not >= `t` otherwise), `to` if every one is: where a run of the line ends going right.
    #[inline]
    fn run_fwd_on(isa: Isa, row: &[Self], from: usize, to: usize, t: f32, strict: bool) -> usize {
        let _ = isa;
        let above = |v: Self| if strict { v.f() > t } else { v.f() >= t };
        let mut k = from;
        while k < to && above(row[k]) {
            k += 1;
        }
        k
    }
    /// One past the last index in `from..to` whose value is not above `t` (as
    /// [`Self::run_fwd_on`]), `from` if every one is: where a run ends going left from `to`.
    #[inline]
    fn run_back_on(isa: Isa, row: &[Self], from: usize, to: usize, t: f32, strict: bool) -> usize {
        let _ = isa;
        let above = |v: Self| if strict { v.f() > t } else { v.f() >= t };
        let mut k = to;
        while k > from && above(row[k - 1]) {
            k -= 1;
        }
        k
    }
    /// The largest block maximum outside blocks `lo..=hi`, on `isa` (None: the portable fold).
    #[inline]
    fn blocks_outside_on(isa: Isa, blocks: &[Self], lo: usize, hi: usize) -> Option<Self> {
        let _ = (isa, blocks, lo, hi);
        None
    }
}

impl Px for u8 {
    const FULL: u32 = 255;
    const SCALE: f32 = 1.0;
    #[inline(always)]
    fn f(self) -> f32 {
        self as f32
    }
    #[inline]
    fn block_max_on(isa: Isa, row: &[u8], blocks: &mut [u8]) {
        super::simd::block_max_u8(isa, row, blocks)
    }
    #[inline]
    fn background_on(isa: Isa, row: &[u8]) -> (f32, f32, f32) {
        row_background_u8(isa, row)
    }
    #[inline]
    fn position_on(isa: Isa, s: &[u8], v: u8) -> usize {
        simd::position_u8(isa, s, v).unwrap_or_else(|| Self::position(s, v))
    }
    #[inline]
    fn first_block_on(isa: Isa, blocks: &[u8]) -> Option<(u8, usize)> {
        simd::first_max_u8(isa, blocks)
    }
    #[inline]
    fn blocks_outside_on(isa: Isa, blocks: &[u8], lo: usize, hi: usize) -> Option<u8> {
        simd::max_outside_u8(isa, blocks, lo, hi)
    }
    #[inline]
    fn run_fwd_on(isa: Isa, row: &[u8], from: usize, to: usize, t: f32, strict: bool) -> usize {
        match at_most_u8(t, strict) {
            Some(c) if isa != Isa::Scalar && from < to => {
                simd::first_at_most_u8(&row[from..to], c).map_or(to, |k| from + k)
            }
            _ => {
                let above = |v: u8| if strict { v.f() > t } else { v.f() >= t };
                let mut k = from;
                while k < to && above(row[k]) {
                    k += 1;
                }
                k
            }
        }
    }
    #[inline]
    fn run_back_on(isa: Isa, row: &[u8], from: usize, to: usize, t: f32, strict: bool) -> usize {
        match at_most_u8(t, strict) {
            Some(c) if isa != Isa::Scalar && from < to => {
                simd::last_at_most_u8(&row[from..to], c).map_or(from, |k| from + k + 1)
            }
            _ => {
                let above = |v: u8| if strict { v.f() > t } else { v.f() >= t };
                let mut k = to;
                while k > from && above(row[k - 1]) {
                    k -= 1;
                }
                k
            }
        }
    }
    /// Eight bytes per step: the classic "has a zero byte" test on `word ^ v..v`; its lowest
    /// set bit always marks the first match.
    #[inline]
    fn position(s: &[u8], v: u8) -> usize {
        const LO: u64 = 0x0101_0101_0101_0101;
        const HI: u64 = 0x8080_8080_8080_8080;
        let pat = LO.wrapping_mul(v as u64);
        let mut chunks = s.chunks_exact(8);
        let mut base = 0;
        for c in &mut chunks {
            let x = u64::from_le_bytes(c.try_into().expect("8 bytes")) ^ pat;
            let t = x.wrapping_sub(LO) & !x & HI;
            if t != 0 {
                return base + (t.trailing_zeros() / 8) as usize;
            }
            base += 8;
        }
        base + chunks
            .remainder()
            .iter()
            .position(|&x| x == v)
            .unwrap_or(s.len() - base)
    }
}

/// The byte c with "v is not above t" exactly when v <= c, for every byte v: "not above" is
/// v <= t (strict, v > t is above) or v < t; None when no byte or every byte is above (t out
/// of range), where the portable loop decides.
#[inline]
fn at_most_u8(t: f32, strict: bool) -> Option<u8> {
    if !(0.0..255.0).contains(&t) {
        return None;
    }
    // t in [0, 255): its floor fits a byte.
    let f = t as u32;
    if strict {
        // v <= t  <=>  v <= floor(t) for an integer v.
        Some(f as u8)
    } else if (f as f32) == t {
        // v < t = f  <=>  v <= f - 1.
        f.checked_sub(1).map(|c| c as u8)
    } else {
        // v < t, t not an integer  <=>  v <= floor(t).
        Some(f as u8)
    }
}

impl Px for u16 {
    const FULL: u32 = 65535;
    const SCALE: f32 = 257.0;
    #[inline(always)]
    fn f(self) -> f32 {
        self as f32
    }
    #[inline]
    fn block_max_on(isa: Isa, row: &[u16], blocks: &mut [u16]) {
        super::simd::block_max_u16(isa, row, blocks)
    }
    #[inline]
    fn position_on(isa: Isa, s: &[u16], v: u16) -> usize {
        simd::position_u16(isa, s, v).unwrap_or_else(|| Self::position(s, v))
    }
    #[inline]
    fn first_block_on(isa: Isa, blocks: &[u16]) -> Option<(u16, usize)> {
        simd::first_max_u16(isa, blocks)
    }
    #[inline]
    fn blocks_outside_on(isa: Isa, blocks: &[u16], lo: usize, hi: usize) -> Option<u16> {
        simd::max_outside_u16(isa, blocks, lo, hi)
    }
}

/// The level a row's peak must exceed to hold a line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Threshold {
    /// Relative to the row's own background: its bright level (upper quartile of a sample of
    /// the row) plus [`AUTO_SIGMAS`] times its noise (from neighbour differences), at least
    /// [`AUTO_MIN_NOISES`] noises above the level, within [`AUTO_FLOOR_DN`]..[`AUTO_MIN_DN`]
    /// ([`row_background`]). Ambient light, texture and the
    /// camera's noise set it, not the operator.
    Auto,
    /// A fixed level, 8-bit DN (x257 for Gray16).
    Dn(f32),
}

/// `Threshold::Auto`: robust standard deviations of the row's background above its level.
pub const AUTO_SIGMAS: f32 = 6.0;
/// `Threshold::Auto`: the most the least contrast over the row's level asks for, 8-bit DN
/// (reached at a noise of [`AUTO_MIN_DN`] / [`AUTO_MIN_NOISES`], 0.5 DN).
pub const AUTO_MIN_DN: f32 = 20.0;
/// `Threshold::Auto`: the least contrast over the row's level, in the row's noise. A fixed 20 DN
/// never let a dim line (11-15 DN over a JPEG's dark board, whose background quantises to
/// exactly 0) through. 40, not the 6 of [`AUTO_SIGMAS`]: the noise read from 64 samples of a
/// quantised row reads low, and a row whose median difference is 1 DN or more (noise of 1 DN)
/// keeps the 20 DN it always had; only nearly flat rows go lower.
pub const AUTO_MIN_NOISES: f32 = 40.0;
/// `Threshold::Auto`: the quantile, in sixteenths, of the neighbour differences that measures
/// a dark row's noise ([`row_background`]): the line itself spans at most a few of the 64.
const AUTO_TAIL: usize = 15;
/// `Threshold::Auto`: the least contrast on a row whose sampled noise is 0 (a blank board, a
/// JPEG's flattened dark blocks), 8-bit DN: many times rounding's own noise (0.29 DN), and
/// below the 11 DN peak of the dimmest line it is meant to let through.
pub const AUTO_FLOOR_DN: f32 = 6.0;
/// `Threshold::Auto`: the background statistics are refreshed every this many rows.
pub const AUTO_BAND_ROWS: usize = 8;
/// `Threshold::Auto`: pixels sampled (evenly spaced) for a row's statistics.
const AUTO_SAMPLES: usize = 64;

/// Settings of the coarse search, in 8-bit DN (scaled by 257 for Gray16).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoarseConfig {
    /// A row's peak must exceed this to hold a line.
    pub threshold: Threshold,
    /// A second peak outside the line of at least this fraction of the line's peak (above the
    /// background) makes the row ambiguous. > 1 disables the test.
    pub ambiguity: f32,
    /// Rows whose saturated run is longer than this (px) and than half the line's width at
    /// half height are rejected as saturated.
    pub max_saturated_px: usize,
    /// Skip specular spikes: saturated runs of at most 6 px whose neighbours are dark.
    pub skip_spikes: bool,
}

impl Default for CoarseConfig {
    fn default() -> Self {
        CoarseConfig {
            threshold: Threshold::Auto,
            ambiguity: 0.8,
            max_saturated_px: 12,
            skip_spikes: true,
        }
    }
}

impl CoarseConfig {
    pub fn validate(&self) -> Result<(), super::DetectError> {
        if let Threshold::Dn(t) = self.threshold {
            if !(t > 0.0 && t < 255.0) {
                return Err(super::DetectError::Param(format!(
                    "threshold = {t}: valid range is (0, 255) DN, or \"auto\""
                )));
            }
        }
        if self.ambiguity.is_nan() || self.ambiguity <= 0.0 {
            return Err(super::DetectError::Param(format!(
                "ambiguity = {}: must be > 0 (a fraction of the peak; > 1 disables the test)",
                self.ambiguity
            )));
        }
        if self.max_saturated_px == 0 {
            return Err(super::DetectError::Param(
                "max_saturated_px must be at least 1".into(),
            ));
        }
        Ok(())
    }
}

/// The line's peak in one row, as the coarse search found it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Peak {
    /// Integer column of the maximum (centre of a flat top).
    pub m: usize,
    /// The flat top (equal maximal values) around `m`, inclusive.
    pub top_lo: usize,
    pub top_hi: usize,
    /// Peak value (frame units).
    pub peak: f32,
    /// Run of pixels above the threshold around the peak, inclusive.
    pub lo: usize,
    pub hi: usize,
    /// Local background (frame units).
    pub bg: f32,
    /// The threshold this row was cut at (frame units).
    pub thr: f32,
    /// Width above half the peak (over the background), px, interpolated.
    pub width: f32,
    /// Saturated pixels at the peak (0 if none).
    pub saturated: u16,
    /// Highest value outside the line, relative to the peak (both over the background).
    pub second: f32,
    /// Specular spikes skipped in this row (columns, inclusive; `spike_count` of them), for
    /// estimators whose window reaches them.
    pub spikes: [(u32, u32); 2],
    pub spike_count: u8,
}

impl Peak {
    /// Whether a skipped spike overlaps columns [a, b].
    #[inline]
    pub fn spike_in(&self, a: usize, b: usize) -> bool {
        self.spikes[..self.spike_count as usize]
            .iter()
            .any(|&(x, y)| (x as usize) <= b && (y as usize) >= a)
    }

    /// Moves every column by `off`: a peak found in a slice of the row, in row columns.
    pub fn shift(&mut self, off: usize) {
        self.m += off;
        self.top_lo += off;
        self.top_hi += off;
        self.lo += off;
        self.hi += off;
        for s in &mut self.spikes[..self.spike_count as usize] {
            s.0 += off as u32;
            s.1 += off as u32;
        }
    }
}

impl Peak {
    /// 0..1: signal over threshold, uniqueness, saturation.
    pub fn quality(&self, threshold: f32, full: f32) -> f32 {
        let sig = ((self.peak - threshold) / (0.5 * full - threshold).max(1.0)).clamp(0.0, 1.0);
        let uniq = (1.0 - self.second).clamp(0.0, 1.0);
        let sat = if self.saturated > 0 { 0.5 } else { 1.0 };
        sig * uniq * sat
    }
}

/// Pixels per block of the block-maximum pass.
pub const BLOCK: usize = 64;

/// Scratch for the coarse search: the block maxima of one row, and the automatic threshold of
/// the current band of rows.
#[derive(Default, Debug, Clone)]
pub struct CoarseScratch<T> {
    blocks: Vec<T>,
    /// Block maxima of a window of the row ([`coarse_row_near`]).
    window_blocks: Vec<T>,
    auto_thr: f32,
    /// The automatic threshold over the band's level: the least contrast a line must have
    /// ([`coarse_row_local`]).
    auto_margin: f32,
}

/// Robust level and noise of a row from [`AUTO_SAMPLES`] evenly spaced pixels (frame units):
/// the level is their upper quartile, the noise 1.4826 x the median absolute difference of
/// each sample to its right neighbour, over sqrt 2. On a textured row (a checkerboard under
/// room light) the median and MAD of the row measure the texture: the threshold landed above
/// a laser that stood clear of the white squares. The upper quartile is the bright background
/// the line must beat, and neighbour differences see the noise, not the texture (its edges are
/// few). The third value is the 15/16 quantile of the same differences: on a dark row the
/// camera's rounding or a JPEG's block quantisation make most differences exactly 0, so the
/// median reads no noise at all while the tail still shows what noise or scene the row holds
/// ([`auto_threshold`]). On the stack: no allocation. On this thread's instruction set
/// ([`simd::current`]).
pub fn row_background<T: Px>(row: &[T]) -> (f32, f32, f32) {
    T::background_on(simd::current(), row)
}

/// [`row_background`] by the portable code (`select_nth_unstable`): the scalar path.
pub fn row_background_scalar<T: Px>(row: &[T]) -> (f32, f32, f32) {
    let n = row.len().min(AUTO_SAMPLES);
    if n == 0 {
        return (0.0, 0.0, 0.0);
    }
    let step = row.len() / n;
    let mut s = [0u32; AUTO_SAMPLES];
    let mut d = [0u32; AUTO_SAMPLES];
    for k in 0..n {
        let i = k * step + step / 2;
        let v = row[i].f() as u32;
        s[k] = v;
        d[k] = v.abs_diff(row[(i + 1).min(row.len() - 1)].f() as u32);
    }
    let q3 = *s[..n].select_nth_unstable(3 * n / 4).1;
    let mad = *d[..n].select_nth_unstable(n / 2).1;
    let tail = *d[..n].select_nth_unstable(AUTO_TAIL * n / 16).1;
    (
        q3 as f32,
        1.4826 * mad as f32 / std::f32::consts::SQRT_2,
        tail as f32,
    )
}

/// [`row_background`] of a Gray8 row: the same samples, the two order statistics by the
/// packed kernel of [`simd::kth_u8`] (rows of at least 64 pixels; shorter ones as before).
#[inline]
fn row_background_u8(isa: Isa, row: &[u8]) -> (f32, f32, f32) {
    if isa == Isa::Scalar || row.len() < AUTO_SAMPLES {
        return row_background_scalar(row);
    }
    let n = AUTO_SAMPLES;
    let step = row.len() / n;
    let mut s = [0u8; AUTO_SAMPLES];
    let mut d = [0u8; AUTO_SAMPLES];
    for k in 0..n {
        let i = k * step + step / 2;
        let v = row[i];
        s[k] = v;
        d[k] = v.abs_diff(row[(i + 1).min(row.len() - 1)]);
    }
    let (q3, mad, tail) = simd::kth3_u8(isa, &s, 3 * n / 4, &d, n / 2, AUTO_TAIL * n / 16);
    (
        q3 as f32,
        1.4826 * mad as f32 / std::f32::consts::SQRT_2,
        tail as f32,
    )
}

/// The automatic threshold of a row with background `(level, spread, tail)` (frame units,
/// [`row_background`]): [`AUTO_SIGMAS`] noises above the level, and at least
/// [`AUTO_MIN_NOISES`] noises, within [`AUTO_FLOOR_DN`]..[`AUTO_MIN_DN`]. The noise for the
/// least contrast is the larger of the median's and the tail's estimate (the 15/16 quantile of
/// |difference| is 2.63 standard deviations of Gaussian noise), so a row reads as quiet only
/// when nearly all of its differences are 0.
#[inline]
pub fn auto_threshold<T: Px>(level: f32, spread: f32, tail: f32) -> f32 {
    let noise = spread.max(tail / 2.63);
    let least = (AUTO_MIN_NOISES * noise).clamp(AUTO_FLOOR_DN * T::SCALE, AUTO_MIN_DN * T::SCALE);
    level + (AUTO_SIGMAS * spread).max(least)
}

impl<T: Px> CoarseScratch<T> {
    /// The threshold of row `r` (frame units): fixed, or automatic from the row's background,
    /// refreshed every [`AUTO_BAND_ROWS`] rows (the first row of each band stands for it).
    #[inline]
    pub fn threshold(&mut self, cfg: &CoarseConfig, r: usize, row: &[T]) -> f32 {
        self.threshold_on(simd::current(), cfg, r, row)
    }

    /// [`Self::threshold`] on the instruction set `isa`.
    #[inline]
    pub fn threshold_on(&mut self, isa: Isa, cfg: &CoarseConfig, r: usize, row: &[T]) -> f32 {
        match cfg.threshold {
            Threshold::Dn(t) => t * T::SCALE,
            Threshold::Auto => {
                if r.is_multiple_of(AUTO_BAND_ROWS) || self.auto_thr <= 0.0 {
                    let (level, spread, tail) = T::background_on(isa, row);
                    self.auto_thr = auto_threshold::<T>(level, spread, tail);
                    self.auto_margin = self.auto_thr - level;
                }
                self.auto_thr
            }
        }
    }

    /// The block buffer for rows of `w` pixels (allocates only when `w` changes).
    pub fn for_width(&mut self, w: usize) -> &mut [T] {
        let nb = w.div_ceil(BLOCK);
        if self.blocks.len() != nb {
            self.blocks.resize(nb, T::default());
            self.window_blocks.resize(nb, T::default());
        }
        &mut self.blocks
    }

    /// The coarse search of row `r` (its block maxima already in [`Self::for_width`]'s buffer)
    /// with the line's continuity as the tie-breaker ([`coarse_row_near`]).
    pub fn row_near(
        &mut self,
        row: &[T],
        cfg: &CoarseConfig,
        thr: f32,
        near: Option<Near>,
    ) -> Result<Peak, (Reject, f32)> {
        self.row_near_on(simd::current(), row, cfg, thr, near)
    }

    /// [`Self::row_near`] on the instruction set `isa`.
    pub fn row_near_on(
        &mut self,
        isa: Isa,
        row: &[T],
        cfg: &CoarseConfig,
        thr: f32,
        near: Option<Near>,
    ) -> Result<Peak, (Reject, f32)> {
        let first = coarse_row_on(isa, row, &self.blocks, cfg, thr);
        match (first, near) {
            (Err((Reject::Ambiguous, v)), Some(n)) => {
                coarse_row_near_on(isa, row, &mut self.window_blocks, cfg, thr, n)
                    .ok_or((Reject::Ambiguous, v))
            }
            // Nothing above the threshold once the spikes were skipped, but the line of the
            // rows above may be one of them: a saturated line a few pixels wide whose flanks
            // fall steeply (a colour difference clipped at full scale) looks like a specular
            // spike in one row. A spike is a disc of a few rows; a line continues.
            (Err((Reject::BelowThreshold, v)), Some(n)) => {
                if cfg.skip_spikes {
                    let kept = CoarseConfig {
                        skip_spikes: false,
                        ..*cfg
                    };
                    let pk = coarse_row_near_on(isa, row, &mut self.window_blocks, &kept, thr, n)
                        .filter(|pk| pk.saturated > 0);
                    if let Some(pk) = pk {
                        return Ok(pk);
                    }
                }
                if cfg.threshold != Threshold::Auto || self.auto_margin <= 0.0 {
                    return Err((Reject::BelowThreshold, v));
                }
                let margin = self.auto_margin;
                coarse_row_local_on(isa, row, &mut self.window_blocks, cfg, thr, margin, n)
                    .ok_or((Reject::BelowThreshold, v))
            }
            (r, _) => r,
        }
    }
}

/// How many rows ahead [`prefetch_row`] is used.
pub const PREFETCH_ROWS: usize = 4;

/// Ask the cache for a row ahead of its use (one hint per 64-byte line): the per-row work
/// between two rows otherwise leaves the hardware prefetcher behind at every page boundary.
#[inline(always)]
pub fn prefetch_row<T>(row: &[T]) {
    #[cfg(target_arch = "x86_64")]
    {
        let bytes = std::mem::size_of_val(row);
        let p = row.as_ptr() as *const i8;
        let mut off = 0;
        while off < bytes {
            // SAFETY: a prefetch hint has no effect on memory; the address is inside `row`.
            unsafe {
                std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(p.add(off))
            };
            off += 64;
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = row;
}

/// [`prefetch_row`] the row [`PREFETCH_ROWS`] after row `r` of a `w`-wide frame, if any.
#[inline(always)]
pub fn prefetch_ahead<T>(px: &[T], r: usize, w: usize) {
    if let Some(ahead) = px.get((r + PREFETCH_ROWS) * w..(r + PREFETCH_ROWS + 1) * w) {
        prefetch_row(ahead);
    }
}

/// Maximum of each 64-pixel block of `row` into `blocks` (`row.len().div_ceil(64)` of them),
/// on this thread's instruction set ([`simd::current`]).
#[inline]
pub fn block_max<T: Px>(row: &[T], blocks: &mut [T]) {
    T::block_max_on(simd::current(), row, blocks)
}

/// [`block_max`] by the portable code: the scalar path the SIMD kernels are compared with.
#[inline]
pub fn block_max_scalar<T: Copy + Ord + Default>(row: &[T], blocks: &mut [T]) {
    let full = row.len() / BLOCK;
    let (body, tail) = row.split_at(full * BLOCK);
    for (b, ch) in blocks.iter_mut().zip(body.chunks_exact(BLOCK)) {
        let ch: &[T; BLOCK] = ch.try_into().expect("block size");
        // A vertical max of the four 16-pixel quarters, then the reduction.
        let mut m = [T::default(); 16];
        for i in 0..16 {
            m[i] = ch[i].max(ch[i + 16]).max(ch[i + 32].max(ch[i + 48]));
        }
        *b = m.iter().copied().fold(T::default(), T::max);
    }
    if !tail.is_empty() {
        blocks[full] = tail.iter().copied().fold(T::default(), T::max);
    }
}

/// Sum of every byte of a frame: the memory-bandwidth floor a detector is compared with.
/// SSE2 `psadbw` on x86_64 (16 bytes per instruction into two u64 lanes), portable elsewhere.
pub fn sum_bytes(px: &[u8]) -> u64 {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        let mut chunks = px.chunks_exact(64);
        // SAFETY: SSE2 is part of the x86_64 baseline; loads are unaligned loads of in-bounds
        // 16-byte pieces of each 64-byte chunk.
        let total = unsafe {
            let zero = _mm_setzero_si128();
            let (mut a, mut b, mut c, mut d) = (zero, zero, zero, zero);
            for ch in &mut chunks {
                let p = ch.as_ptr() as *const __m128i;
                a = _mm_add_epi64(a, _mm_sad_epu8(_mm_loadu_si128(p), zero));
                b = _mm_add_epi64(b, _mm_sad_epu8(_mm_loadu_si128(p.add(1)), zero));
                c = _mm_add_epi64(c, _mm_sad_epu8(_mm_loadu_si128(p.add(2)), zero));
                d = _mm_add_epi64(d, _mm_sad_epu8(_mm_loadu_si128(p.add(3)), zero));
            }
            let s = _mm_add_epi64(_mm_add_epi64(a, b), _mm_add_epi64(c, d));
            let mut lanes = [0u64; 2];
            _mm_storeu_si128(lanes.as_mut_ptr() as *mut __m128i, s);
            lanes[0] + lanes[1]
        };
        total + chunks.remainder().iter().map(|&v| v as u64).sum::<u64>()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        px.iter().map(|&v| v as u64).sum()
    }
}

/// Excluded column ranges (spikes, the line itself) when looking for a maximum.
#[derive(Clone, Copy, Default)]
struct Ranges {
    r: [(usize, usize); 6],
    n: usize,
}

impl Ranges {
    fn push(&mut self, lo: usize, hi: usize) {
        if self.n < self.r.len() {
            self.r[self.n] = (lo, hi);
            self.n += 1;
            self.r[..self.n].sort_unstable();
        }
    }
}

/// Maximum of a short slice: 16 lanes, vectorised.
#[inline]
fn seg_max<T: Px>(s: &[T]) -> T {
    let mut acc = [T::default(); 16];
    let mut it = s.chunks_exact(16);
    for c in &mut it {
        for i in 0..16 {
            acc[i] = acc[i].max(c[i]);
        }
    }
    let m = acc.iter().copied().fold(T::default(), T::max);
    it.remainder().iter().copied().fold(m, T::max)
}

/// Maximum of the row outside `ex`, from the block maxima: the value and the first position of
/// it (the position only if `want_pos`; value 0 and position 0 if nothing is left).
fn max_outside<T: Px>(
    isa: Isa,
    row: &[T],
    blocks: &[T],
    ex: &Ranges,
    want_pos: bool,
) -> (T, usize) {
    let w = row.len();
    let mut best = T::default();
    // Where the best lies: [lo, hi] of a whole block or of a piece of one.
    let mut at: Option<(usize, usize)> = None;
    for (b, &bm) in blocks.iter().enumerate() {
        if at.is_some() && bm <= best {
            continue;
        }
        let (b0, b1) = (b * BLOCK, ((b + 1) * BLOCK).min(w) - 1);
        let hit = ex.r[..ex.n].iter().any(|&(a, z)| a <= b1 && z >= b0);
        if !hit {
            best = bm;
            at = Some((b0, b1));
            continue;
        }
        // The pieces of the block outside the (sorted) ranges.
        let mut start = b0;
        let piece = |a: usize, z: usize, best: &mut T, at: &mut Option<(usize, usize)>| {
            let m = seg_max(&row[a..=z]);
            if at.is_none() || m > *best {
                *best = m;
                *at = Some((a, z));
            }
        };
        for &(lo, hi) in &ex.r[..ex.n] {
            if hi < start {
                continue;
            }
            if lo > b1 {
                break;
            }
            if lo > start {
                piece(start, lo - 1, &mut best, &mut at);
            }
            start = hi + 1;
            if start > b1 {
                break;
            }
        }
        if start <= b1 {
            piece(start, b1, &mut best, &mut at);
        }
    }
    match at {
        Some((a, z)) if want_pos => (best, a + T::position_on(isa, &row[a..=z], best).min(z - a)),
        Some(_) => (best, 0),
        None => (T::default(), 0),
    }
}

/// The row's maximum and its first position, from the block maxima.
#[inline]
fn first_max<T: Px>(isa: Isa, row: &[T], blocks: &[T]) -> (T, usize) {
    let (m, b) = T::first_block_on(isa, blocks).unwrap_or_else(|| {
        let (mut m, mut b) = (T::default(), 0);
        for (i, &v) in blocks.iter().enumerate() {
            if v > m {
                m = v;
                b = i;
            }
        }
        (m, b)
    });
    let b0 = b * BLOCK;
    let end = (b0 + BLOCK).min(row.len());
    (
        m,
        b0 + T::position_on(isa, &row[b0..end], m).min(end - b0 - 1),
    )
}

/// The row's maximum outside [lo, hi] (0 if nothing is left), from the block maxima.
#[inline]
fn max_excluding<T: Px>(isa: Isa, row: &[T], blocks: &[T], lo: usize, hi: usize) -> T {
    let (bl, bh) = (lo / BLOCK, hi / BLOCK);
    let end = ((bh + 1) * BLOCK).min(row.len());
    let m = T::blocks_outside_on(isa, blocks, bl, bh).unwrap_or_else(|| {
        let m = blocks[..bl].iter().copied().fold(T::default(), T::max);
        blocks[bh + 1..].iter().copied().fold(m, T::max)
    });
    m.max(seg_max(&row[bl * BLOCK..lo]))
        .max(seg_max(&row[(hi + 1).min(end)..end]))
}

/// If a specular spike (a saturated run of at most 6 px, one or two overlapping spike discs,
/// whose neighbours are below a quarter of
/// full scale) is at `pos`, the columns to exclude.
fn spike_at<T: Px>(row: &[T], pos: usize, cfg: &CoarseConfig) -> Option<(usize, usize)> {
    let w = row.len();
    let v = row[pos];
    if !cfg.skip_spikes || (v.f() as u32) < T::FULL {
        return None;
    }
    let (mut a, mut b) = (pos, pos);
    while a > 0 && row[a - 1] == v {
        a -= 1;
    }
    while b + 1 < w && row[b + 1] == v {
        b += 1;
    }
    let dark = 0.25 * T::FULL as f32;
    let left = if a > 0 { row[a - 1].f() } else { 0.0 };
    let right = if b + 1 < w { row[b + 1].f() } else { 0.0 };
    (b - a < 6 && left < dark && right < dark).then(|| (a.saturating_sub(1), (b + 1).min(w - 1)))
}

/// The coarse search of one row whose block maxima ([`block_max`]) are `blocks`, cut at `thr`
/// (frame units, [`CoarseScratch::threshold`]). `Err((reason, intensity))` when no line is
/// accepted.
pub fn coarse_row<T: Px>(
    row: &[T],
    blocks: &[T],
    cfg: &CoarseConfig,
    thr: f32,
) -> Result<Peak, (Reject, f32)> {
    coarse_row_on(simd::current(), row, blocks, cfg, thr)
}

/// [`coarse_row`] on the instruction set `isa`.
pub fn coarse_row_on<T: Px>(
    isa: Isa,
    row: &[T],
    blocks: &[T],
    cfg: &CoarseConfig,
    thr: f32,
) -> Result<Peak, (Reject, f32)> {
    let w = row.len();
    if w < 3 {
        return Err((Reject::Border, 0.0));
    }
    let full = T::FULL as f32;
    let mut ex = Ranges::default();
    let (mut m0, mut m1, mut top);
    loop {
        let (v, pos) = if ex.n == 0 {
            first_max(isa, row, blocks)
        } else {
            max_outside(isa, row, blocks, &ex, true)
        };
        let vf = v.f();
        if vf <= thr {
            return Err((Reject::BelowThreshold, vf));
        }
        // Flat top: equal values around the maximum.
        let (mut a, mut b) = (pos, pos);
        while a > 0 && row[a - 1] == v {
            a -= 1;
        }
        while b + 1 < w && row[b + 1] == v {
            b += 1;
        }
        top = vf;
        m0 = a;
        m1 = b;
        if let Some((sa, sb)) = spike_at(row, pos, cfg) {
            if ex.n + 1 < ex.r.len() {
                ex.push(sa, sb);
                continue;
            }
        }
        break;
    }
    let saturated = if top >= full { m1 - m0 + 1 } else { 0 };
    let m = (m0 + m1) / 2;
    // Run above the threshold.
    let mut lo = T::run_back_on(isa, row, 0, m0, thr, true);
    let mut hi = T::run_fwd_on(isa, row, m1 + 1, w, thr, true) - 1;
    if lo == 0 || hi + 1 == w {
        return Err((Reject::Border, top));
    }
    // Background: the lowest of the two pixels beyond each end of the run.
    let mut bg = row[lo - 1].f().min(row[hi + 1].f());
    if lo >= 2 {
        bg = bg.min(row[lo - 2].f());
    }
    if hi + 2 < w {
        bg = bg.min(row[hi + 2].f());
    }
    // Width at half height, linear interpolation at both crossings. Walking out from the top,
    // a dip below half height is crossed when the profile is back at half height within the
    // width found so far (and inside the run above the threshold): speckle of 30-50 % on a
    // 20-40 px line dips there in most rows, and the first crossing gave a fraction of the
    // line's width, so the saturation test below rejected a line clipped over its top and the
    // ambiguity test took the line's other half for a second peak. A plain line has one
    // crossing per side; a separate bump farther than the line's own width stays outside.
    let half = bg + 0.5 * (top - bg);
    let mut l = T::run_back_on(isa, row, lo, m0, half, false);
    let mut r = T::run_fwd_on(isa, row, m1 + 1, hi + 1, half, false) - 1;
    loop {
        let reach = r + 1 - l;
        let (l0, r0) = (l, r);
        let stop = l.saturating_sub(reach).max(lo);
        if let Some(j) = (stop..l).rev().find(|&j| row[j].f() >= half) {
            l = T::run_back_on(isa, row, lo, j + 1, half, false);
        }
        let stop = (r + reach).min(hi);
        if let Some(j) = (r + 1..=stop).find(|&j| row[j].f() >= half) {
            r = T::run_fwd_on(isa, row, j, hi + 1, half, false) - 1;
        }
        if (l, r) == (l0, r0) {
            break;
        }
    }
    let xl = {
        let (v0, v1) = (row[l - 1].f(), row[l].f());
        (l - 1) as f32 + ((half - v0) / (v1 - v0).max(1e-6)).clamp(0.0, 1.0)
    };
    let xr = {
        let (v0, v1) = (row[r].f(), row[r + 1].f());
        r as f32 + ((v0 - half) / (v0 - v1).max(1e-6)).clamp(0.0, 1.0)
    };
    let width = (xr - xl).max(0.5);
    // The run above the threshold crosses a dip under it when the line is back above it
    // within the line's width: the other half of a speckled wide line is not a second peak.
    // Not into a skipped specular spike, whose pixels are no part of the line.
    let reach = width as usize;
    let spike = |j: usize| ex.r[..ex.n].iter().any(|&(a, z)| a <= j && j <= z);
    loop {
        let (lo0, hi0) = (lo, hi);
        let stop = lo.saturating_sub(reach).max(1);
        if let Some(j) = (stop..lo.saturating_sub(1))
            .rev()
            .find(|&j| row[j].f() > thr)
            .filter(|&j| !spike(j))
        {
            let nl = T::run_back_on(isa, row, 0, j + 1, thr, true);
            if nl > 0 {
                lo = nl;
            }
        }
        let stop = (hi + reach).min(w - 2);
        if let Some(j) = (hi + 2..=stop)
            .find(|&j| row[j].f() > thr)
            .filter(|&j| !spike(j))
        {
            let nh = T::run_fwd_on(isa, row, j, w, thr, true) - 1;
            if nh + 1 < w {
                hi = nh;
            }
        }
        if (lo, hi) == (lo0, hi0) {
            break;
        }
    }
    // Over-exposed: a clipped run longer than `max_saturated_px` that is also most of the
    // line (over half its width at half height) hides where the line's centre is. A wide line
    // (20-40 px from a poor lens) clips over more than 12 px at its top alone and keeps its
    // symmetric flanks.
    if saturated > cfg.max_saturated_px && saturated as f32 > 0.5 * width {
        return Err((Reject::Saturated, top));
    }
    // A second peak outside the line and its immediate surroundings (spikes skipped).
    let mut second = 0.0;
    if cfg.ambiguity <= 1.0 {
        let gap = (width as usize + 1).max(2);
        let (a, z) = (lo.saturating_sub(gap), (hi + gap).min(w - 1));
        let rel = |v: T| ((v.f() - bg) / (top - bg).max(1.0)).max(0.0);
        let mut v2 = if ex.n == 0 {
            max_excluding(isa, row, blocks, a, z)
        } else {
            T::default()
        };
        if ex.n > 0 || (v2.f() > thr && rel(v2) >= cfg.ambiguity) {
            // Rare: look closer, skipping spikes.
            ex.push(a, z);
            loop {
                let (v, pos) = max_outside(isa, row, blocks, &ex, true);
                v2 = v;
                if v.f() <= thr || rel(v) < cfg.ambiguity || ex.n + 1 >= ex.r.len() {
                    break;
                }
                match spike_at(row, pos, cfg) {
                    Some((sa, sb)) => ex.push(sa, sb),
                    None => break,
                }
            }
        }
        second = rel(v2);
        if v2.f() > thr && second >= cfg.ambiguity {
            return Err((Reject::Ambiguous, top));
        }
    }
    let mut spikes = [(0u32, 0u32); 2];
    let mut spike_count = 0u8;
    for &(x, y) in &ex.r[..ex.n] {
        // Spike ranges are at most 8 px; the line's own exclusion is not a spike.
        if y - x <= 7 && (y < lo || x > hi) && (spike_count as usize) < spikes.len() {
            spikes[spike_count as usize] = (x as u32, y as u32);
            spike_count += 1;
        }
    }
    Ok(Peak {
        spikes,
        spike_count,
        m,
        top_lo: m0,
        top_hi: m1,
        peak: top,
        lo,
        hi,
        bg,
        thr,
        width,
        saturated: saturated as u16,
        second,
    })
}

/// A row under the threshold read again on its local background, next to the line of the rows
/// above: on a chessboard the row's level is the white squares', and the line crossing a black
/// square is a local peak under it (63-86 DN beside 85-96 DN in the `chessboard-jpeg` kind).
/// The peak is the highest pixel within max(width / 2, 2 px) of `near.col`; the background is
/// the higher of the lowest pixels within max(3 widths, 8 px) on each side (the valleys
/// between the line and the squares' edges), and the line must stand `margin` (the automatic
/// threshold over its level) above it. The coarse search then runs between the two valleys at
/// that level. None when the local level is not under `thr` or the line does not clear it.
pub fn coarse_row_local_on<T: Px>(
    isa: Isa,
    row: &[T],
    blocks: &mut [T],
    cfg: &CoarseConfig,
    thr: f32,
    margin: f32,
    near: Near,
) -> Option<Peak> {
    let w = row.len();
    if !near.col.is_finite() || near.col < 0.0 || near.col >= w as f64 || w < 3 {
        return None;
    }
    let width = near.width.max(1.0) as f64;
    let reach = (0.5 * width).max(2.0);
    let a = (near.col - reach).floor().max(0.0) as usize;
    let z = ((near.col + reach).ceil() as usize).min(w - 1);
    let pm = (a..=z).fold(a, |m, c| if row[c] > row[m] { c } else { m });
    let span = (3.0 * width).max(8.0) as usize;
    let lowest = |r: std::ops::RangeInclusive<usize>| {
        r.fold(None, |m: Option<usize>, c| match m {
            Some(k) if row[k] <= row[c] => Some(k),
            _ => Some(c),
        })
    };
    let lv = lowest(pm.saturating_sub(span)..=pm.checked_sub(1)?)?;
    let rv = lowest(pm + 1..=(pm + span).min(w - 1))?;
    let local = row[lv].f().max(row[rv].f()) + margin;
    if local >= thr || row[pm].f() <= local {
        return None;
    }
    let sub = &row[lv..=rv];
    let nb = sub.len().div_ceil(BLOCK);
    T::block_max_on(isa, sub, &mut blocks[..nb]);
    let single = CoarseConfig {
        ambiguity: 2.0,
        ..*cfg
    };
    let mut pk = coarse_row_on(isa, sub, &blocks[..nb], &single, local).ok()?;
    if ((lv + pk.m) as f64 - near.col).abs() > width.max(3.0) {
        return None;
    }
    pk.shift(lv);
    Some(pk)
}

/// Where the line was in the rows just before: the tie-breaker of an ambiguous row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Near {
    /// Column of the line in the nearest preceding row that held it (at most
    /// [`NEAR_ROWS`] rows back).
    pub col: f64,
    /// The line's width there (px).
    pub width: f32,
}

/// How many rows back a line still counts as the neighbour of an ambiguous row, and how far a
/// row must be from every other row with a line to be [`Reject::Isolated`].
pub const NEAR_ROWS: usize = 2;

/// Reject every accepted row with no other accepted row within [`NEAR_ROWS`] above or below:
/// a line crosses many rows, a lone row is a speck of the lit scene (a laser-off frame of a
/// wood slice gave two such rows of 21 DN over a dark background).
pub fn reject_isolated(out: &mut [super::LinePeak]) {
    let n = out.len();
    let mut last_valid: Option<usize> = None;
    for r in 0..n {
        if !out[r].is_valid() {
            continue;
        }
        let above = last_valid.is_some_and(|p| r - p <= NEAR_ROWS);
        let below = (r + 1..(r + 1 + NEAR_ROWS).min(n)).any(|k| out[k].is_valid());
        last_valid = Some(r);
        if !above && !below {
            out[r] = super::LinePeak::rejected(Reject::Isolated, out[r].intensity);
        }
    }
}

/// An ambiguous row (a second peak of at least [`CoarseConfig::ambiguity`] of the line's) read
/// again in a window around the line's column in the rows just above, `near.col` +- max(3
/// widths, 8 px): a specular spot or a board edge beside the line does not make a row lose a
/// line that continues its neighbours'. Inside the window the coarse search applies again
/// (threshold, saturation, a run that must not reach the window's ends); a second peak still
/// inside the window is either part of the line, when it lies within max(2 widths, 4 px) of
/// the line's run (a line split in two by dark print or a scratch: the run then spans both),
/// or makes the row ambiguous as before. The peak found must lie within max(width, 3 px) of
/// `near.col`. None when any of this fails: the row stays ambiguous. `blocks` is scratch of
/// the row's block count or more.
pub fn coarse_row_near<T: Px>(
    row: &[T],
    blocks: &mut [T],
    cfg: &CoarseConfig,
    thr: f32,
    near: Near,
) -> Option<Peak> {
    coarse_row_near_on(simd::current(), row, blocks, cfg, thr, near)
}

/// [`coarse_row_near`] on the instruction set `isa`.
pub fn coarse_row_near_on<T: Px>(
    isa: Isa,
    row: &[T],
    blocks: &mut [T],
    cfg: &CoarseConfig,
    thr: f32,
    near: Near,
) -> Option<Peak> {
    let w = row.len();
    if !near.col.is_finite() || near.col < 0.0 || near.col >= w as f64 {
        return None;
    }
    let width = near.width.max(1.0) as f64;
    let reach = (3.0 * width).max(8.0);
    let a = (near.col - reach).floor().max(0.0) as usize;
    let z = ((near.col + reach).ceil() as usize).min(w - 1);
    let sub = &row[a..=z];
    let nb = sub.len().div_ceil(BLOCK);
    T::block_max_on(isa, sub, &mut blocks[..nb]);
    let single = CoarseConfig {
        ambiguity: 2.0,
        ..*cfg
    };
    let mut pk = coarse_row_on(isa, sub, &blocks[..nb], &single, thr).ok()?;
    // The highest other peak in the window, beyond the line's own flanks.
    let gap = (pk.width as usize + 1).max(2);
    let (fl, fh) = (pk.lo.saturating_sub(gap), (pk.hi + gap).min(sub.len() - 1));
    let (mut v2, mut at2) = (0.0f32, 0usize);
    for (i, v) in sub.iter().enumerate() {
        if (i < fl || i > fh) && v.f() > v2 {
            (v2, at2) = (v.f(), i);
        }
    }
    let rel = ((v2 - pk.bg) / (pk.peak - pk.bg).max(1.0)).max(0.0);
    if v2 > thr && rel >= cfg.ambiguity {
        let merge = (2.0 * width).max(4.0) as usize;
        let close = if at2 < pk.lo {
            pk.lo - at2 <= merge
        } else {
            at2 - pk.hi <= merge
        };
        if !close {
            return None;
        }
        // One line in two pieces: the run spans both (and what lies between).
        let (mut lo, mut hi) = (pk.lo.min(at2), pk.hi.max(at2));
        while lo > 0 && sub[lo - 1].f() > thr {
            lo -= 1;
        }
        while hi + 1 < sub.len() && sub[hi + 1].f() > thr {
            hi += 1;
        }
        if lo == 0 || hi + 1 == sub.len() {
            return None;
        }
        pk.lo = lo;
        pk.hi = hi;
        pk.width = pk.width.max((hi - lo + 1) as f32 * 0.5);
    }
    pk.second = rel;
    if ((a + pk.m) as f64 - near.col).abs() > width.max(3.0) {
        return None;
    }
    pk.shift(a);
    Some(pk)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(row: &[u8], cfg: &CoarseConfig) -> Result<Peak, (Reject, f32)> {
        let mut s = CoarseScratch::default();
        let thr = s.threshold(cfg, 0, row);
        let blocks = s.for_width(row.len());
        block_max(row, blocks);
        coarse_row(row, blocks, cfg, thr)
    }

    fn line(w: usize, c: f64, sigma: f64, a: f64) -> Vec<u8> {
        (0..w)
            .map(|i| {
                let d = i as f64 - c;
                (8.0 + a * (-d * d / (2.0 * sigma * sigma)).exp())
                    .round()
                    .min(255.0) as u8
            })
            .collect()
    }

    #[test]
    fn swar_position_matches_scalar() {
        let row: Vec<u8> = (0..200).map(|i| ((i * 37 + 11) % 251) as u8).collect();
        for v in [0u8, 1, 11, 48, 128, 250, 255] {
            for start in 0..9 {
                let s = &row[start..];
                assert_eq!(
                    <u8 as Px>::position(s, v),
                    s.iter().position(|&x| x == v).unwrap_or(s.len()),
                    "{v} {start}"
                );
            }
        }
        let mut z = vec![7u8; 40];
        z[17] = 0;
        z[33] = 0;
        assert_eq!(<u8 as Px>::position(&z, 0), 17);
    }

    #[test]
    fn block_max_matches_scalar() {
        for len in [1usize, 63, 64, 65, 200, 1280] {
            let row: Vec<u8> = (0..len).map(|i| ((i * 37 + 11) % 251) as u8).collect();
            let mut b = vec![0u8; len.div_ceil(BLOCK)];
            block_max(&row, &mut b);
            for (k, &v) in b.iter().enumerate() {
                let s = &row[k * BLOCK..((k + 1) * BLOCK).min(len)];
                assert_eq!(v, *s.iter().max().unwrap());
            }
        }
    }

    #[test]
    fn finds_peak_width_and_skips_spike() {
        let mut row = line(300, 150.3, 1.6, 180.0);
        let p = run(&row, &CoarseConfig::default()).unwrap();
        assert_eq!(p.m, 150);
        assert!((p.width - 3.77).abs() < 0.4, "{}", p.width);
        row[170..173].fill(255);
        let p = run(&row, &CoarseConfig::default()).unwrap();
        assert_eq!(p.m, 150);
    }

    #[test]
    fn an_ambiguous_row_keeps_the_line_that_continues_its_neighbours() {
        let cfg = CoarseConfig::default();
        // The line at 150.3 and a reflection of 0.9 of its height at 40.
        let mut row = line(300, 150.3, 1.6, 180.0);
        for (i, v) in line(300, 40.0, 2.0, 162.0).into_iter().enumerate() {
            row[i] = row[i].max(v);
        }
        let mut s = CoarseScratch::default();
        let thr = s.threshold(&cfg, 0, &row);
        block_max(&row, s.for_width(row.len()));
        assert_eq!(
            s.row_near(&row, &cfg, thr, None).unwrap_err().0,
            Reject::Ambiguous
        );
        let near = |col| Some(Near { col, width: 3.8 });
        let p = s.row_near(&row, &cfg, thr, near(150.8)).unwrap();
        assert_eq!((p.m, p.lo > 140, p.hi < 160), (150, true, true));
        // The weaker peak is taken too when it is the one that continues the line.
        let q = s.row_near(&row, &cfg, thr, near(40.5)).unwrap();
        assert_eq!(q.m, 40);
        // A neighbour far from both peaks decides nothing.
        assert!(s.row_near(&row, &cfg, thr, near(100.0)).is_err());
    }

    #[test]
    fn a_lone_row_is_a_speck_and_a_line_of_two_rows_is_kept() {
        use crate::detect::LinePeak;
        let at = |c: f64| LinePeak {
            col: c,
            intensity: 100.0,
            width: 3.0,
            quality: 1.0,
            reject: None,
        };
        let mut out = vec![LinePeak::NONE; 20];
        out[1] = at(10.0); // alone
        out[7] = at(30.0); // with row 9, two apart
        out[9] = at(30.5);
        out[15] = at(50.0); // alone, 3 rows from 12 and 18
        out[19] = at(60.0); // alone at the end
        reject_isolated(&mut out);
        let kept: Vec<usize> = (0..20).filter(|&r| out[r].is_valid()).collect();
        assert_eq!(kept, vec![7, 9]);
        assert_eq!(out[1].reject, Some(Reject::Isolated));
        assert_eq!(out[15].reject, Some(Reject::Isolated));
        assert_eq!(out[19].reject, Some(Reject::Isolated));
    }

    #[test]
    fn sum_bytes_is_exact() {
        let v: Vec<u8> = (0..100_003).map(|i| (i % 256) as u8).collect();
        assert_eq!(sum_bytes(&v), v.iter().map(|&x| x as u64).sum::<u64>());
    }
}
