//! Explicit SIMD kernels of the coarse search, chosen at run time per instruction set.
//!
//! The profile of the per-row pass (docs/method.md, "Detector at the memory floor") showed two
//! kernels far above the byte-summing floor: the block maxima (a 64-to-1 horizontal reduction
//! per block, which the compiler left to scalar compares) and the automatic threshold's two
//! order statistics of 64 samples (`select_nth_unstable`, every 8th row). Both are rewritten
//! here with intrinsics for SSE4.1, AVX2 and AVX-512BW; every kernel returns exactly what the
//! portable code of [`super::coarse`] returns (integers: no rounding can differ), and that code
//! stays the `Scalar` path the tests compare against.
//!
//! Dispatch: [`Isa::detected`] is the fastest set this CPU runs, found once. A thread may force
//! a lower one ([`with_isa`]): the benchmark times each set in turn and the tests compare each
//! with the scalar path. Detectors read [`current`] once per frame and pass it down, so the
//! per-row cost of the choice is one predictable branch. The kernels are compiled with
//! `multiversion`'s `#[target]` (each one a `target_feature` function under the matching
//! `cfg(target_arch)`), so other architectures build the scalar path alone.

use std::cell::Cell;
use std::sync::OnceLock;

/// An instruction set the kernels are written for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Isa {
    /// The portable code: no explicit SIMD (the compiler may still use the target's baseline,
    /// SSE2 on x86_64).
    Scalar,
    Sse41,
    /// AVX2 + FMA.
    Avx2,
    /// AVX-512F + BW (and AVX2 + FMA).
    Avx512,
}

impl Isa {
    pub const ALL: [Isa; 4] = [Isa::Scalar, Isa::Sse41, Isa::Avx2, Isa::Avx512];

    pub fn as_str(self) -> &'static str {
        match self {
            Isa::Scalar => "scalar",
            Isa::Sse41 => "sse4.1",
            Isa::Avx2 => "avx2",
            Isa::Avx512 => "avx512",
        }
    }

    /// Whether this CPU runs the set.
    pub fn supported(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        {
            match self {
                Isa::Scalar => true,
                Isa::Sse41 => std::arch::is_x86_feature_detected!("sse4.1"),
                Isa::Avx2 => {
                    std::arch::is_x86_feature_detected!("sse4.1")
                        && std::arch::is_x86_feature_detected!("avx2")
                        && std::arch::is_x86_feature_detected!("fma")
                }
                Isa::Avx512 => {
                    std::arch::is_x86_feature_detected!("sse4.1")
                        && std::arch::is_x86_feature_detected!("avx2")
                        && std::arch::is_x86_feature_detected!("fma")
                        && std::arch::is_x86_feature_detected!("avx512f")
                        && std::arch::is_x86_feature_detected!("avx512bw")
                }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            self == Isa::Scalar
        }
    }

    /// The sets this CPU runs, scalar first.
    pub fn available() -> Vec<Isa> {
        Isa::ALL.into_iter().filter(|i| i.supported()).collect()
    }

    /// The set detectors use unless a thread forces one (detected once): the fastest on this
    /// machine's CPU. AVX-512 was 2-6 % slower than AVX2 before the packed block scans and
    /// order statistics (docs/method.md 4.7); since them it is 3 % (bezier-plus) and 7-8 %
    /// (cog) faster (4.7.1), and AVX2 is the fallback.
    pub fn detected() -> Isa {
        static BEST: OnceLock<Isa> = OnceLock::new();
        *BEST.get_or_init(|| {
            [Isa::Avx512, Isa::Avx2, Isa::Sse41]
                .into_iter()
                .find(|i| i.supported())
                .unwrap_or(Isa::Scalar)
        })
    }
}

impl std::str::FromStr for Isa {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        Isa::ALL
            .into_iter()
            .find(|i| i.as_str() == s)
            .ok_or_else(|| format!("instruction set {s:?}: valid are scalar, sse4.1, avx2, avx512"))
    }
}

thread_local! {
    static FORCED: Cell<Option<Isa>> = const { Cell::new(None) };
}

/// The set this thread's detectors use: the forced one ([`with_isa`]) or [`Isa::detected`].
#[inline]
pub fn current() -> Isa {
    FORCED.with(|f| f.get()).unwrap_or_else(Isa::detected)
}

/// An instruction set this CPU lacks was asked for.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("instruction set {} is not supported by this CPU (available: {})", .isa.as_str(), list(.available))]
pub struct UnsupportedIsa {
    pub isa: Isa,
    pub available: Vec<Isa>,
}

fn list(isas: &[Isa]) -> String {
    isas.iter()
        .map(|i| i.as_str())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Run `f` with this thread's detectors on `isa`. Err (naming the set) if the CPU lacks it:
/// a kernel for a missing set would fault.
pub fn with_isa<R>(isa: Isa, f: impl FnOnce() -> R) -> Result<R, UnsupportedIsa> {
    if !isa.supported() {
        return Err(UnsupportedIsa {
            isa,
            available: Isa::available(),
        });
    }
    let before = FORCED.with(|c| c.replace(Some(isa)));
    struct Restore(Option<Isa>);
    impl Drop for Restore {
        fn drop(&mut self) {
            FORCED.with(|c| c.set(self.0));
        }
    }
    let _restore = Restore(before);
    Ok(f())
}

/// Return from the calling function with the kernel of `isa` (`[avx512, avx2, sse4.1]`
/// functions of the x86 module, applied to the arguments); fall through on the scalar set or
/// another architecture. The one dispatch of every per-set kernel.
macro_rules! on_set {
    ($isa:expr, [$k512:ident, $k2:ident, $k41:ident]($($arg:expr),*)) => {
        #[cfg(target_arch = "x86_64")]
        {
            // SAFETY: an `Isa` above Scalar reaches here only from `current()`, which returns
            // a forced set only after `with_isa` checked it, or the detected one.
            match $isa {
                Isa::Avx512 => return unsafe { x86::$k512($($arg),*) },
                Isa::Avx2 => return unsafe { x86::$k2($($arg),*) },
                Isa::Sse41 => return unsafe { x86::$k41($($arg),*) },
                Isa::Scalar => {}
            }
        }
    };
}

/// Maximum of each 64-pixel block of a Gray8 row (see [`super::coarse::block_max`]).
#[inline]
pub fn block_max_u8(isa: Isa, row: &[u8], blocks: &mut [u8]) {
    on_set!(
        isa,
        [block_max_u8_avx512, block_max_u8_avx2, block_max_u8_sse41](row, blocks)
    );
    let _ = isa;
    super::coarse::block_max_scalar(row, blocks)
}

/// Maximum of each 64-pixel block of a Gray16 row.
#[inline]
pub fn block_max_u16(isa: Isa, row: &[u16], blocks: &mut [u16]) {
    on_set!(
        isa,
        [
            block_max_u16_avx512,
            block_max_u16_avx2,
            block_max_u16_sse41
        ](row, blocks)
    );
    let _ = isa;
    super::coarse::block_max_scalar(row, blocks)
}

/// The `k`-th smallest (0-based) of 64 bytes: the value `select_nth_unstable(k)` puts at `k`.
/// Built bit by bit from the top: the largest v with at most k values below it, each step
/// one packed compare and a population count.
#[inline]
pub fn kth_u8(isa: Isa, v: &[u8; 64], k: usize) -> u8 {
    if isa == Isa::Scalar {
        let mut s = *v;
        return *s.select_nth_unstable(k).1;
    }
    // The packed sets search three at once ([`kth3_u8`]); one of the three is asked for.
    kth3_u8(isa, v, k, v, k, k).0
}

/// The three order statistics of a row's background at once: the `ks`-th smallest of `s` and
/// the `kd1`-th and `kd2`-th of `d` ([`kth_u8`] each). The three bit-by-bit searches are
/// independent, so interleaving them hides each step's compare-count-decide latency behind
/// the others' (one search alone is a chain of 8 dependent steps).
#[inline]
pub fn kth3_u8(
    isa: Isa,
    s: &[u8; 64],
    ks: usize,
    d: &[u8; 64],
    kd1: usize,
    kd2: usize,
) -> (u8, u8, u8) {
    on_set!(
        isa,
        [kth3_u8_avx512, kth3_u8_avx2, kth3_u8_sse41](s, ks, d, kd1, kd2)
    );
    let _ = isa;
    let kth = |v: &[u8; 64], k: usize| {
        let mut v = *v;
        *v.select_nth_unstable(k).1
    };
    (kth(s, ks), kth(d, kd1), kth(d, kd2))
}

/// The largest of `blocks` (block maxima of a row) and the first index holding it; (0, 0) for
/// a row of zeros, as the scalar scan gives. The scalar scan is a chain of dependent
/// compare-and-moves, one per block; here 16 blocks (8 for Gray16) per packed max.
#[inline]
pub fn first_max_u8(isa: Isa, blocks: &[u8]) -> Option<(u8, usize)> {
    #[cfg(target_arch = "x86_64")]
    if isa != Isa::Scalar && blocks.len() >= 16 {
        // SAFETY: SSE2 is part of the x86_64 baseline. Gray8's short scans are SSE2, not
        // SSE4.1: a `target_feature` kernel cannot be inlined into the portable coarse search,
        // and the calls cost more than they saved (docs/method.md 4.7.2).
        return Some(unsafe { x86::first_max_u8_sse2(blocks) });
    }
    let _ = (isa, blocks);
    None
}

/// [`first_max_u8`] of Gray16 block maxima.
#[inline]
pub fn first_max_u16(isa: Isa, blocks: &[u16]) -> Option<(u16, usize)> {
    #[cfg(target_arch = "x86_64")]
    if isa != Isa::Scalar && blocks.len() >= 8 {
        // SAFETY: every set above Scalar includes SSE4.1 (see `on_set!`).
        return Some(unsafe { x86::first_max_u16_sse41(blocks) });
    }
    let _ = (isa, blocks);
    None
}

/// The largest of `blocks` outside the indices `lo..=hi` (0 if none is left). None: use the
/// portable code (scalar set, or a row too short or too long for the packed indices).
#[inline]
pub fn max_outside_u8(isa: Isa, blocks: &[u8], lo: usize, hi: usize) -> Option<u8> {
    #[cfg(target_arch = "x86_64")]
    if isa != Isa::Scalar && blocks.len() >= 16 && blocks.len() <= 256 {
        // SAFETY: SSE2 is part of the x86_64 baseline.
        return Some(unsafe { x86::max_outside_u8_sse2(blocks, lo, hi) });
    }
    let _ = (isa, blocks, lo, hi);
    None
}

/// [`max_outside_u8`] of Gray16 block maxima.
#[inline]
pub fn max_outside_u16(isa: Isa, blocks: &[u16], lo: usize, hi: usize) -> Option<u16> {
    #[cfg(target_arch = "x86_64")]
    if isa != Isa::Scalar && blocks.len() >= 8 && blocks.len() <= 65536 {
        // SAFETY: every set above Scalar includes SSE4.1 (see `on_set!`).
        return Some(unsafe { x86::max_outside_u16_sse41(blocks, lo, hi) });
    }
    let _ = (isa, blocks, lo, hi);
    None
}

/// First index of `v` in `s` (`s.len()` if absent), 16 bytes per compare. None: the portable
/// code.
#[inline]
pub fn position_u8(isa: Isa, s: &[u8], v: u8) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    if isa != Isa::Scalar && s.len() >= 16 {
        // SAFETY: SSE2 is part of the x86_64 baseline.
        return Some(unsafe { x86::position_u8_sse2(s, v) });
    }
    let _ = (isa, s, v);
    None
}

/// [`position_u8`] of a Gray16 slice (8 values per compare).
#[inline]
pub fn position_u16(isa: Isa, s: &[u16], v: u16) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    if isa != Isa::Scalar && s.len() >= 8 {
        // SAFETY: every set above Scalar includes SSE4.1 (see `on_set!`).
        return Some(unsafe { x86::position_u16_sse41(s, v) });
    }
    let _ = (isa, s, v);
    None
}

/// The first index of a byte <= `c` in `s` (None if there is none): the end of a run of the
/// line going right. The portable loop is one compare and branch per pixel, and its exit
/// (where the run ends, a different place every row) is a mispredicted branch; here 16
/// pixels per compare and the end from the mask. SSE2 on every set above scalar (runs are a
/// few pixels long), inlined into the coarse search.
#[inline]
pub fn first_at_most_u8(s: &[u8], c: u8) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of the x86_64 baseline.
    return unsafe { x86::first_at_most_u8_sse2(s, c) };
    #[cfg(not(target_arch = "x86_64"))]
    s.iter().position(|&v| v <= c)
}

/// The last index of a byte <= `c` in `s` (None if there is none): the end of a run going
/// left ([`first_at_most_u8`]).
#[inline]
pub fn last_at_most_u8(s: &[u8], c: u8) -> Option<usize> {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: SSE2 is part of the x86_64 baseline.
    return unsafe { x86::last_at_most_u8_sse2(s, c) };
    #[cfg(not(target_arch = "x86_64"))]
    s.iter().rposition(|&v| v <= c)
}

/// p(s) = sum a_i s^i and p'(s), given `a` and `da` (da_i = (i + 1) a_(i+1), so p' = sum
/// da_i s^i), both zero-padded to a multiple of 4 terms. Horner's rule is one chain of
/// dependent multiply-adds per term; here the terms are split by i mod 4 into four
/// polynomials in s^4 evaluated side by side in the lanes of one register (two on SSE4.1),
/// p(s) = P0(s^4) + s P1(s^4) + s^2 P2(s^4) + s^3 P3(s^4): a quarter of the chain. The sums
/// round differently from Horner's (relative 1e-16, far below the 1e-6 px the root is found
/// to). None on the scalar set: the caller keeps Horner's rule.
#[inline]
pub fn poly_and_derivative(isa: Isa, a: &[f64], da: &[f64], s: f64) -> Option<(f64, f64)> {
    debug_assert!(a.len().is_multiple_of(4) && a.len() == da.len());
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: as in `block_max_u8`.
        match isa {
            Isa::Avx512 | Isa::Avx2 => return Some(unsafe { x86::poly4_avx2(a, da, s) }),
            Isa::Sse41 => return Some(unsafe { x86::poly4_sse41(a, da, s) }),
            Isa::Scalar => {}
        }
    }
    let _ = (isa, a, da, s);
    None
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use super::super::coarse::BLOCK;
    use multiversion::target;
    use std::arch::x86_64::*;

    /// Maximum of the 16 bytes of `x`: SSE4.1 `phminposuw` finds the least of 8 u16 lanes, so
    /// the bytes are inverted (max becomes min) and each lane's two bytes folded into its low
    /// byte first.
    #[target("x86_64+sse4.1")]
    #[inline]
    unsafe fn hmax_u8(x: __m128i) -> u8 {
        let inv = _mm_xor_si128(x, _mm_set1_epi8(-1));
        let folded = _mm_min_epu8(inv, _mm_srli_epi16::<8>(inv));
        255 - (_mm_cvtsi128_si32(_mm_minpos_epu16(folded)) & 0xff) as u8
    }

    /// Maximum of the 16 bytes of `x` by SSE2 alone (shifts and `pmaxub`): four steps
    /// instead of `phminposuw`'s one, but inlinable into the portable code (SSE2 is the
    /// x86_64 baseline), where the short scans of the coarse search are called.
    #[inline(always)]
    unsafe fn hmax_u8_sse2(x: __m128i) -> u8 {
        let x = _mm_max_epu8(x, _mm_srli_si128::<8>(x));
        let x = _mm_max_epu8(x, _mm_srli_si128::<4>(x));
        let x = _mm_max_epu8(x, _mm_srli_si128::<2>(x));
        let x = _mm_max_epu8(x, _mm_srli_si128::<1>(x));
        _mm_cvtsi128_si32(x) as u8
    }

    /// Maximum of the 8 u16 lanes of `x` (inverted, `phminposuw`).
    #[target("x86_64+sse4.1")]
    #[inline]
    unsafe fn hmax_u16(x: __m128i) -> u16 {
        let inv = _mm_xor_si128(x, _mm_set1_epi8(-1));
        65535 - (_mm_cvtsi128_si32(_mm_minpos_epu16(inv)) & 0xffff) as u16
    }

    /// The one body of every set's block maxima: `reduce` gives the maximum of one whole
    /// 64-pixel block (the set's own loads and packed max), the tail is folded here. Inlined
    /// into each set's `#[target]` function, so it compiles with that set's instructions.
    #[inline(always)]
    fn each_block<T: Copy + Ord + Default>(
        row: &[T],
        blocks: &mut [T],
        reduce: impl Fn(*const T) -> T,
    ) {
        for (b, ch) in blocks.iter_mut().zip(row.chunks_exact(BLOCK)) {
            *b = reduce(ch.as_ptr());
        }
        let full = row.len() / BLOCK;
        if !row.len().is_multiple_of(BLOCK) {
            blocks[full] = row[full * BLOCK..]
                .iter()
                .copied()
                .fold(T::default(), T::max);
        }
    }

    #[target("x86_64+sse4.1")]
    pub unsafe fn block_max_u8_sse41(row: &[u8], blocks: &mut [u8]) {
        each_block(row, blocks, |p| {
            let p = p as *const __m128i;
            let m = _mm_max_epu8(
                _mm_max_epu8(_mm_loadu_si128(p), _mm_loadu_si128(p.add(1))),
                _mm_max_epu8(_mm_loadu_si128(p.add(2)), _mm_loadu_si128(p.add(3))),
            );
            hmax_u8(m)
        })
    }

    #[target("x86_64+avx2+fma+sse4.1")]
    pub unsafe fn block_max_u8_avx2(row: &[u8], blocks: &mut [u8]) {
        each_block(row, blocks, |p| {
            let p = p as *const __m256i;
            let m = _mm256_max_epu8(_mm256_loadu_si256(p), _mm256_loadu_si256(p.add(1)));
            hmax_u8(_mm_max_epu8(
                _mm256_castsi256_si128(m),
                _mm256_extracti128_si256::<1>(m),
            ))
        })
    }

    #[target("x86_64+avx512f+avx512bw+avx2+fma+sse4.1")]
    pub unsafe fn block_max_u8_avx512(row: &[u8], blocks: &mut [u8]) {
        each_block(row, blocks, |p| {
            let z = _mm512_loadu_si512(p as *const _);
            let m = _mm256_max_epu8(_mm512_castsi512_si256(z), _mm512_extracti64x4_epi64::<1>(z));
            hmax_u8(_mm_max_epu8(
                _mm256_castsi256_si128(m),
                _mm256_extracti128_si256::<1>(m),
            ))
        })
    }

    #[target("x86_64+sse4.1")]
    pub unsafe fn block_max_u16_sse41(row: &[u16], blocks: &mut [u16]) {
        each_block(row, blocks, |p| {
            let p = p as *const __m128i;
            let mut m = _mm_loadu_si128(p);
            for i in 1..8 {
                m = _mm_max_epu16(m, _mm_loadu_si128(p.add(i)));
            }
            hmax_u16(m)
        })
    }

    #[target("x86_64+avx2+fma+sse4.1")]
    pub unsafe fn block_max_u16_avx2(row: &[u16], blocks: &mut [u16]) {
        each_block(row, blocks, |p| {
            let p = p as *const __m256i;
            let m = _mm256_max_epu16(
                _mm256_max_epu16(_mm256_loadu_si256(p), _mm256_loadu_si256(p.add(1))),
                _mm256_max_epu16(_mm256_loadu_si256(p.add(2)), _mm256_loadu_si256(p.add(3))),
            );
            hmax_u16(_mm_max_epu16(
                _mm256_castsi256_si128(m),
                _mm256_extracti128_si256::<1>(m),
            ))
        })
    }

    #[target("x86_64+avx512f+avx512bw+avx2+fma+sse4.1")]
    pub unsafe fn block_max_u16_avx512(row: &[u16], blocks: &mut [u16]) {
        each_block(row, blocks, |p| {
            let z = _mm512_max_epu16(
                _mm512_loadu_si512(p as *const _),
                _mm512_loadu_si512(p.add(32) as *const _),
            );
            let m = _mm256_max_epu16(_mm512_castsi512_si256(z), _mm512_extracti64x4_epi64::<1>(z));
            hmax_u16(_mm_max_epu16(
                _mm256_castsi256_si128(m),
                _mm256_extracti128_si256::<1>(m),
            ))
        })
    }

    /// Bytes of `x` below `c` (unsigned), as a bit mask: signed compare after flipping the top
    /// bit (SSE2/AVX2 compare signed bytes only).
    #[target("x86_64+sse4.1")]
    #[inline]
    unsafe fn below_128(x: __m128i, c: __m128i) -> u32 {
        let flip = _mm_set1_epi8(i8::MIN);
        _mm_movemask_epi8(_mm_cmpgt_epi8(
            _mm_xor_si128(c, flip),
            _mm_xor_si128(x, flip),
        )) as u32
    }

    /// The one body of every set's three order statistics: three bit-by-bit searches from the
    /// top, interleaved (each the largest v with at most k values below it); `below_s(c)` and
    /// `below_d(c)` count the values of `s` and of `d` below c with the set's own compares.
    #[inline(always)]
    fn search3(
        below_s: impl Fn(u8) -> usize,
        below_d: impl Fn(u8) -> usize,
        ks: usize,
        kd1: usize,
        kd2: usize,
    ) -> (u8, u8, u8) {
        let (mut a, mut b, mut c) = (0u8, 0u8, 0u8);
        for bit in (0..8).rev() {
            let (ca, cb, cc) = (a | (1 << bit), b | (1 << bit), c | (1 << bit));
            let (na, nb, nc) = (below_s(ca), below_d(cb), below_d(cc));
            if na <= ks {
                a = ca;
            }
            if nb <= kd1 {
                b = cb;
            }
            if nc <= kd2 {
                c = cc;
            }
        }
        (a, b, c)
    }

    #[target("x86_64+sse4.1")]
    pub unsafe fn kth3_u8_sse41(
        s: &[u8; 64],
        ks: usize,
        d: &[u8; 64],
        kd1: usize,
        kd2: usize,
    ) -> (u8, u8, u8) {
        let (ps, pd) = (s.as_ptr() as *const __m128i, d.as_ptr() as *const __m128i);
        let xs = [0, 1, 2, 3].map(|i| _mm_loadu_si128(ps.add(i)));
        let xd = [0, 1, 2, 3].map(|i| _mm_loadu_si128(pd.add(i)));
        let below = |x: &[__m128i; 4], c: u8| -> usize {
            let cv = _mm_set1_epi8(c as i8);
            x.iter()
                .map(|&x| below_128(x, cv).count_ones())
                .sum::<u32>() as usize
        };
        search3(|c| below(&xs, c), |c| below(&xd, c), ks, kd1, kd2)
    }

    #[target("x86_64+avx2+fma+sse4.1")]
    pub unsafe fn kth3_u8_avx2(
        s: &[u8; 64],
        ks: usize,
        d: &[u8; 64],
        kd1: usize,
        kd2: usize,
    ) -> (u8, u8, u8) {
        let flip = _mm256_set1_epi8(i8::MIN);
        let load = |p: *const u8, i: usize| {
            _mm256_xor_si256(_mm256_loadu_si256((p as *const __m256i).add(i)), flip)
        };
        let xs = (load(s.as_ptr(), 0), load(s.as_ptr(), 1));
        let xd = (load(d.as_ptr(), 0), load(d.as_ptr(), 1));
        let below = |x: (__m256i, __m256i), c: u8| -> usize {
            let cv = _mm256_set1_epi8((c ^ 0x80) as i8);
            ((_mm256_movemask_epi8(_mm256_cmpgt_epi8(cv, x.0)) as u32).count_ones()
                + (_mm256_movemask_epi8(_mm256_cmpgt_epi8(cv, x.1)) as u32).count_ones())
                as usize
        };
        search3(|c| below(xs, c), |c| below(xd, c), ks, kd1, kd2)
    }

    #[target("x86_64+avx512f+avx512bw+avx2+fma+sse4.1")]
    pub unsafe fn kth3_u8_avx512(
        s: &[u8; 64],
        ks: usize,
        d: &[u8; 64],
        kd1: usize,
        kd2: usize,
    ) -> (u8, u8, u8) {
        let zs = _mm512_loadu_si512(s.as_ptr() as *const _);
        let zd = _mm512_loadu_si512(d.as_ptr() as *const _);
        let below = |z: __m512i, c: u8| {
            _mm512_cmplt_epu8_mask(z, _mm512_set1_epi8(c as i8)).count_ones() as usize
        };
        search3(|c| below(zs, c), |c| below(zd, c), ks, kd1, kd2)
    }

    /// The 16-byte pieces of a slice of at least 16: whole pieces from the start, then one
    /// ending at the slice's end (overlapping the one before; max and "first match" are
    /// unchanged by looking at a byte twice). Offsets of each piece.
    #[inline(always)]
    fn pieces(n: usize, lanes: usize) -> impl Iterator<Item = usize> {
        let whole = n / lanes;
        let tail = (!n.is_multiple_of(lanes)).then_some(n - lanes);
        (0..whole).map(move |i| i * lanes).chain(tail)
    }

    #[inline]
    pub unsafe fn first_max_u8_sse2(blocks: &[u8]) -> (u8, usize) {
        let p = blocks.as_ptr();
        let mut m = _mm_setzero_si128();
        for o in pieces(blocks.len(), 16) {
            m = _mm_max_epu8(m, _mm_loadu_si128(p.add(o) as *const __m128i));
        }
        let mx = hmax_u8_sse2(m);
        (mx, position_u8_sse2(blocks, mx))
    }

    #[target("x86_64+sse4.1")]
    pub unsafe fn first_max_u16_sse41(blocks: &[u16]) -> (u16, usize) {
        let p = blocks.as_ptr();
        let mut m = _mm_setzero_si128();
        for o in pieces(blocks.len(), 8) {
            m = _mm_max_epu16(m, _mm_loadu_si128(p.add(o) as *const __m128i));
        }
        let mx = hmax_u16(m);
        (mx, position_u16_sse41(blocks, mx))
    }

    #[inline]
    pub unsafe fn position_u8_sse2(s: &[u8], v: u8) -> usize {
        let p = s.as_ptr();
        let vv = _mm_set1_epi8(v as i8);
        for o in pieces(s.len(), 16) {
            let hit = _mm_movemask_epi8(_mm_cmpeq_epi8(
                _mm_loadu_si128(p.add(o) as *const __m128i),
                vv,
            ));
            if hit != 0 {
                return o + hit.trailing_zeros() as usize;
            }
        }
        s.len()
    }

    #[target("x86_64+sse4.1")]
    pub unsafe fn position_u16_sse41(s: &[u16], v: u16) -> usize {
        let p = s.as_ptr();
        let vv = _mm_set1_epi16(v as i16);
        for o in pieces(s.len(), 8) {
            let hit = _mm_movemask_epi8(_mm_cmpeq_epi16(
                _mm_loadu_si128(p.add(o) as *const __m128i),
                vv,
            ));
            if hit != 0 {
                return o + (hit.trailing_zeros() / 2) as usize;
            }
        }
        s.len()
    }

    /// Block indices as packed bytes: piece offset + 0..15 (blocks.len() <= 256).
    #[inline]
    pub unsafe fn max_outside_u8_sse2(blocks: &[u8], lo: usize, hi: usize) -> u8 {
        let p = blocks.as_ptr();
        let step = _mm_setr_epi8(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        // Indices are at most 255; a range beyond it clamps without changing the test.
        let (lv, hv) = (
            _mm_set1_epi8(lo.min(255) as u8 as i8),
            _mm_set1_epi8(hi.min(255) as u8 as i8),
        );
        let mut m = _mm_setzero_si128();
        for o in pieces(blocks.len(), 16) {
            let idx = _mm_add_epi8(_mm_set1_epi8(o as u8 as i8), step);
            let inside = _mm_and_si128(
                _mm_cmpeq_epi8(_mm_max_epu8(idx, lv), idx),
                _mm_cmpeq_epi8(_mm_min_epu8(idx, hv), idx),
            );
            let v = _mm_andnot_si128(inside, _mm_loadu_si128(p.add(o) as *const __m128i));
            m = _mm_max_epu8(m, v);
        }
        hmax_u8_sse2(m)
    }

    #[target("x86_64+sse4.1")]
    pub unsafe fn max_outside_u16_sse41(blocks: &[u16], lo: usize, hi: usize) -> u16 {
        let p = blocks.as_ptr();
        let step = _mm_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7);
        let (lv, hv) = (
            _mm_set1_epi16(lo.min(65535) as u16 as i16),
            _mm_set1_epi16(hi.min(65535) as u16 as i16),
        );
        let mut m = _mm_setzero_si128();
        for o in pieces(blocks.len(), 8) {
            let idx = _mm_add_epi16(_mm_set1_epi16(o as u16 as i16), step);
            let inside = _mm_and_si128(
                _mm_cmpeq_epi16(_mm_max_epu16(idx, lv), idx),
                _mm_cmpeq_epi16(_mm_min_epu16(idx, hv), idx),
            );
            let v = _mm_andnot_si128(inside, _mm_loadu_si128(p.add(o) as *const __m128i));
            m = _mm_max_epu16(m, v);
        }
        hmax_u16(m)
    }

    /// Mask of the bytes <= c among the 16 at `p`.
    #[inline(always)]
    unsafe fn at_most_mask(p: *const u8, c: __m128i) -> u32 {
        let v = _mm_loadu_si128(p as *const __m128i);
        _mm_movemask_epi8(_mm_cmpeq_epi8(_mm_min_epu8(v, c), v)) as u32
    }

    #[inline]
    pub unsafe fn first_at_most_u8_sse2(s: &[u8], c: u8) -> Option<usize> {
        let cv = _mm_set1_epi8(c as i8);
        let p = s.as_ptr();
        let mut o = 0;
        while o + 16 <= s.len() {
            let m = at_most_mask(p.add(o), cv);
            if m != 0 {
                return Some(o + m.trailing_zeros() as usize);
            }
            o += 16;
        }
        s[o..].iter().position(|&v| v <= c).map(|k| o + k)
    }

    #[inline]
    pub unsafe fn last_at_most_u8_sse2(s: &[u8], c: u8) -> Option<usize> {
        let cv = _mm_set1_epi8(c as i8);
        let p = s.as_ptr();
        let mut e = s.len();
        while e >= 16 {
            let m = at_most_mask(p.add(e - 16), cv);
            if m != 0 {
                return Some(e - 16 + 31 - m.leading_zeros() as usize);
            }
            e -= 16;
        }
        s[..e].iter().rposition(|&v| v <= c)
    }

    /// `super::poly_and_derivative` with the four i-mod-4 polynomials in the lanes of one
    /// 256-bit register, a fused multiply-add per four terms.
    #[target("x86_64+avx2+fma+sse4.1")]
    pub unsafe fn poly4_avx2(a: &[f64], da: &[f64], s: f64) -> (f64, f64) {
        let s2 = s * s;
        let s4 = _mm256_set1_pd(s2 * s2);
        let (pa, pd) = (a.as_ptr(), da.as_ptr());
        let mut k = a.len();
        let (mut p, mut q) = (_mm256_setzero_pd(), _mm256_setzero_pd());
        while k >= 4 {
            k -= 4;
            p = _mm256_fmadd_pd(p, s4, _mm256_loadu_pd(pa.add(k)));
            q = _mm256_fmadd_pd(q, s4, _mm256_loadu_pd(pd.add(k)));
        }
        // Lane j times s^j, then the sum of the lanes.
        let pw = _mm256_setr_pd(1.0, s, s2, s2 * s);
        let (p, q) = (_mm256_mul_pd(p, pw), _mm256_mul_pd(q, pw));
        let hsum = |v: __m256d| {
            let h = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd::<1>(v));
            _mm_cvtsd_f64(_mm_add_sd(h, _mm_unpackhi_pd(h, h)))
        };
        (hsum(p), hsum(q))
    }

    /// `poly4_avx2` in two 128-bit registers per polynomial, without FMA.
    #[target("x86_64+sse4.1")]
    pub unsafe fn poly4_sse41(a: &[f64], da: &[f64], s: f64) -> (f64, f64) {
        let s2 = s * s;
        let s4 = _mm_set1_pd(s2 * s2);
        let (pa, pd) = (a.as_ptr(), da.as_ptr());
        let mut k = a.len();
        let z = _mm_setzero_pd();
        let (mut p0, mut p1, mut q0, mut q1) = (z, z, z, z);
        while k >= 4 {
            k -= 4;
            p0 = _mm_add_pd(_mm_mul_pd(p0, s4), _mm_loadu_pd(pa.add(k)));
            p1 = _mm_add_pd(_mm_mul_pd(p1, s4), _mm_loadu_pd(pa.add(k + 2)));
            q0 = _mm_add_pd(_mm_mul_pd(q0, s4), _mm_loadu_pd(pd.add(k)));
            q1 = _mm_add_pd(_mm_mul_pd(q1, s4), _mm_loadu_pd(pd.add(k + 2)));
        }
        let (w0, w1) = (_mm_setr_pd(1.0, s), _mm_setr_pd(s2, s2 * s));
        let p = _mm_add_pd(_mm_mul_pd(p0, w0), _mm_mul_pd(p1, w1));
        let q = _mm_add_pd(_mm_mul_pd(q0, w0), _mm_mul_pd(q1, w1));
        let hsum = |h: __m128d| _mm_cvtsd_f64(_mm_add_sd(h, _mm_unpackhi_pd(h, h)));
        (hsum(p), hsum(q))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows of every length class (whole blocks, a tail, shorter than a block) with the
    /// maximum at every place a reduction could lose it.
    #[test]
    fn block_maxima_match_the_scalar_path_on_every_set() {
        for isa in Isa::available() {
            for len in [1usize, 63, 64, 65, 127, 128, 200, 1280, 1283] {
                for seed in 0..40usize {
                    let mut row: Vec<u8> = (0..len)
                        .map(|i| ((i * 37 + seed * 11) % 199) as u8)
                        .collect();
                    if len > seed {
                        row[seed * 29 % len] = 200 + (seed % 56) as u8;
                    }
                    let nb = len.div_ceil(64);
                    let (mut a, mut b) = (vec![0u8; nb], vec![0u8; nb]);
                    super::super::coarse::block_max_scalar(&row, &mut a);
                    block_max_u8(isa, &row, &mut b);
                    assert_eq!(a, b, "{isa:?} u8 len {len} seed {seed}");
                    let row16: Vec<u16> = row
                        .iter()
                        .enumerate()
                        .map(|(i, &v)| v as u16 * 257 + (i % 3) as u16)
                        .collect();
                    let (mut a, mut b) = (vec![0u16; nb], vec![0u16; nb]);
                    super::super::coarse::block_max_scalar(&row16, &mut a);
                    block_max_u16(isa, &row16, &mut b);
                    assert_eq!(a, b, "{isa:?} u16 len {len} seed {seed}");
                }
            }
        }
    }

    #[test]
    fn order_statistics_match_select_nth_on_every_set() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for isa in Isa::available() {
            for trial in 0..300 {
                let mut v = [0u8; 64];
                for x in v.iter_mut() {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    // Narrow and wide spreads, ties, both ends of the range.
                    *x = match trial % 4 {
                        0 => (state % 256) as u8,
                        1 => 120 + (state % 5) as u8,
                        2 => [0u8, 255][(state % 2) as usize],
                        _ => (state % 30) as u8 * 8,
                    };
                }
                for k in [0usize, 1, 16, 32, 48, 63] {
                    let mut s = v;
                    let want = *s.select_nth_unstable(k).1;
                    assert_eq!(kth_u8(isa, &v, k), want, "{isa:?} trial {trial} k {k}");
                }
            }
        }
    }

    /// The packed block scans against the portable ones: every length class (shorter than a
    /// register, whole registers, a tail that overlaps), ties, the range at every place.
    #[test]
    fn block_scans_match_the_scalar_path_on_every_set() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for isa in Isa::available() {
            for len in [1usize, 7, 8, 9, 15, 16, 17, 20, 31, 32, 33, 64, 100, 256] {
                for trial in 0..60 {
                    let top = [3u64, 40, 256][trial % 3];
                    let b: Vec<u8> = (0..len).map(|_| (next() % top) as u8).collect();
                    let b16: Vec<u16> = b.iter().map(|&v| v as u16 * 250 + 3).collect();
                    let first = |v: &[u8]| {
                        let m = v.iter().copied().max().unwrap();
                        (m, v.iter().position(|&x| x == m).unwrap())
                    };
                    if let Some(got) = first_max_u8(isa, &b) {
                        assert_eq!(got, first(&b), "{isa:?} len {len} trial {trial}");
                    }
                    if let Some((m, i)) = first_max_u16(isa, &b16) {
                        assert_eq!((i, m), (first(&b).1, b16[first(&b).1]), "{isa:?} u16");
                    }
                    let (lo, hi) = ((next() as usize) % len, (next() as usize) % len);
                    let (lo, hi) = (lo.min(hi), lo.max(hi));
                    let want = b
                        .iter()
                        .enumerate()
                        .filter(|&(i, _)| i < lo || i > hi)
                        .map(|(_, &v)| v)
                        .max()
                        .unwrap_or(0);
                    if let Some(got) = max_outside_u8(isa, &b, lo, hi) {
                        assert_eq!(got, want, "{isa:?} len {len} [{lo}, {hi}]");
                    }
                    if let Some(got) = max_outside_u16(isa, &b16, lo, hi) {
                        let w16 =
                            if want == 0 && b.iter().enumerate().all(|(i, _)| i >= lo && i <= hi) {
                                0
                            } else {
                                want as u16 * 250 + 3
                            };
                        assert_eq!(got, w16, "{isa:?} u16 len {len} [{lo}, {hi}]");
                    }
                    for v in [b[len / 2], 255, 0] {
                        let want = b.iter().position(|&x| x == v).unwrap_or(len);
                        if let Some(got) = position_u8(isa, &b, v) {
                            assert_eq!(got, want, "{isa:?} position {v} len {len}");
                        }
                        let v16 = v as u16 * 250 + 3;
                        let want = b16.iter().position(|&x| x == v16).unwrap_or(len);
                        if let Some(got) = position_u16(isa, &b16, v16) {
                            assert_eq!(got, want, "{isa:?} position16 {v} len {len}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn run_ends_match_the_portable_search() {
        for len in [0usize, 1, 5, 15, 16, 17, 31, 32, 40, 100] {
            for seed in 0..50usize {
                let s: Vec<u8> = (0..len)
                    .map(|i| ((i * 131 + seed * 17) % 97 + 100) as u8)
                    .collect();
                for c in [0u8, 99, 120, 150, 196, 255] {
                    assert_eq!(first_at_most_u8(&s, c), s.iter().position(|&v| v <= c));
                    assert_eq!(last_at_most_u8(&s, c), s.iter().rposition(|&v| v <= c));
                }
            }
        }
    }

    #[test]
    fn three_order_statistics_at_once_match_one_at_a_time() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for isa in Isa::available() {
            for trial in 0..200 {
                let mut v = [[0u8; 64]; 2];
                for x in v.iter_mut().flatten() {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    *x = [(state % 256) as u8, (state % 3) as u8][trial % 2];
                }
                let want = (
                    kth_u8(Isa::Scalar, &v[0], 48),
                    kth_u8(Isa::Scalar, &v[1], 32),
                    kth_u8(Isa::Scalar, &v[1], 60),
                );
                assert_eq!(kth3_u8(isa, &v[0], 48, &v[1], 32, 60), want, "{isa:?}");
            }
        }
    }

    /// The packed polynomial against Horner's rule, relative 1e-12, over the degrees and
    /// arguments the root search uses.
    #[test]
    fn packed_polynomial_matches_horner() {
        for isa in Isa::available() {
            for n in 2..40usize {
                let a: Vec<f64> = (0..n).map(|i| ((i * 7919) % 23) as f64 - 11.5).collect();
                let p4 = n.next_multiple_of(4);
                let mut a4 = a.clone();
                a4.resize(p4, 0.0);
                let mut d4: Vec<f64> = (0..n - 1).map(|i| (i + 1) as f64 * a[i + 1]).collect();
                d4.resize(p4, 0.0);
                for s in [0.0, 0.02, 0.3, 1.0, 1.7, 49.0] {
                    let (p, dp) = footscan_geom::bernstein::horner(&a, s);
                    let Some((q, dq)) = poly_and_derivative(isa, &a4, &d4, s) else {
                        continue;
                    };
                    let scale = a.iter().map(|c| c.abs()).sum::<f64>() * s.max(1.0).powi(n as i32);
                    assert!(
                        (p - q).abs() <= 1e-12 * scale,
                        "{isa:?} n {n} s {s}: {p} {q}"
                    );
                    assert!(
                        (dp - dq).abs() <= 1e-12 * scale * n as f64,
                        "{isa:?} n {n} s {s}"
                    );
                }
            }
        }
    }

    #[test]
    fn a_set_the_cpu_lacks_is_refused_by_name() {
        for isa in Isa::ALL {
            let r = with_isa(isa, current);
            if isa.supported() {
                assert_eq!(r.unwrap(), isa);
            } else {
                let e = r.unwrap_err().to_string();
                assert!(e.contains(isa.as_str()) && e.contains("available"), "{e}");
            }
        }
        assert!("neon".parse::<Isa>().unwrap_err().contains("avx2"));
    }
}
