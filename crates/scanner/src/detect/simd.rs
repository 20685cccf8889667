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
    Avx2,
    /// AVX-512F + BW.
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
                }
                Isa::Avx512 => {
                    std::arch::is_x86_feature_detected!("sse4.1")
                        && std::arch::is_x86_feature_detected!("avx2")
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

    /// The set detectors use unless a thread forces one (detected once): AVX2 before
    /// AVX-512, which was 2-6 % slower per frame on this machine's CPU (docs/method.md
    /// section 4.7: a block's reduction starts with two extracts, and the rest of the row
    /// work gains nothing from the wider registers); AVX-512 stays available by force.
    pub fn detected() -> Isa {
        static BEST: OnceLock<Isa> = OnceLock::new();
        *BEST.get_or_init(|| {
            [Isa::Avx2, Isa::Avx512, Isa::Sse41]
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

/// Maximum of each 64-pixel block of a Gray8 row (see [`super::coarse::block_max`]).
#[inline]
pub fn block_max_u8(isa: Isa, row: &[u8], blocks: &mut [u8]) {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: an `Isa` above Scalar reaches here only from `current()`, which returns a
        // forced set only after `with_isa` checked it, or the detected one.
        match isa {
            Isa::Avx512 => return unsafe { x86::block_max_u8_avx512(row, blocks) },
            Isa::Avx2 => return unsafe { x86::block_max_u8_avx2(row, blocks) },
            Isa::Sse41 => return unsafe { x86::block_max_u8_sse41(row, blocks) },
            Isa::Scalar => {}
        }
    }
    let _ = isa;
    super::coarse::block_max_scalar(row, blocks)
}

/// Maximum of each 64-pixel block of a Gray16 row.
#[inline]
pub fn block_max_u16(isa: Isa, row: &[u16], blocks: &mut [u16]) {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: as in `block_max_u8`.
        match isa {
            Isa::Avx512 => return unsafe { x86::block_max_u16_avx512(row, blocks) },
            Isa::Avx2 => return unsafe { x86::block_max_u16_avx2(row, blocks) },
            Isa::Sse41 => return unsafe { x86::block_max_u16_sse41(row, blocks) },
            Isa::Scalar => {}
        }
    }
    let _ = isa;
    super::coarse::block_max_scalar(row, blocks)
}

/// The `k`-th smallest (0-based) of 64 bytes: the value `select_nth_unstable(k)` puts at `k`.
/// Built bit by bit from the top: the largest v with at most k values below it, each step
/// one packed compare and a population count.
#[inline]
pub fn kth_u8(isa: Isa, v: &[u8; 64], k: usize) -> u8 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: as in `block_max_u8`.
        match isa {
            Isa::Avx512 => return unsafe { x86::kth_u8_avx512(v, k) },
            Isa::Avx2 => return unsafe { x86::kth_u8_avx2(v, k) },
            Isa::Sse41 => return unsafe { x86::kth_u8_sse41(v, k) },
            Isa::Scalar => {}
        }
    }
    let _ = isa;
    let mut s = *v;
    *s.select_nth_unstable(k).1
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

    /// Maximum of the 8 u16 lanes of `x` (inverted, `phminposuw`).
    #[target("x86_64+sse4.1")]
    #[inline]
    unsafe fn hmax_u16(x: __m128i) -> u16 {
        let inv = _mm_xor_si128(x, _mm_set1_epi8(-1));
        65535 - (_mm_cvtsi128_si32(_mm_minpos_epu16(inv)) & 0xffff) as u16
    }

    fn tail<T: Copy + Ord + Default>(row: &[T], blocks: &mut [T]) {
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
        for (b, ch) in blocks.iter_mut().zip(row.chunks_exact(BLOCK)) {
            let p = ch.as_ptr() as *const __m128i;
            let m = _mm_max_epu8(
                _mm_max_epu8(_mm_loadu_si128(p), _mm_loadu_si128(p.add(1))),
                _mm_max_epu8(_mm_loadu_si128(p.add(2)), _mm_loadu_si128(p.add(3))),
            );
            *b = hmax_u8(m);
        }
        tail(row, blocks);
    }

    #[target("x86_64+avx2+sse4.1")]
    pub unsafe fn block_max_u8_avx2(row: &[u8], blocks: &mut [u8]) {
        for (b, ch) in blocks.iter_mut().zip(row.chunks_exact(BLOCK)) {
            let p = ch.as_ptr() as *const __m256i;
            let m = _mm256_max_epu8(_mm256_loadu_si256(p), _mm256_loadu_si256(p.add(1)));
            let m = _mm_max_epu8(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m));
            *b = hmax_u8(m);
        }
        tail(row, blocks);
    }

    #[target("x86_64+avx512f+avx512bw+avx2+sse4.1")]
    pub unsafe fn block_max_u8_avx512(row: &[u8], blocks: &mut [u8]) {
        for (b, ch) in blocks.iter_mut().zip(row.chunks_exact(BLOCK)) {
            let z = _mm512_loadu_si512(ch.as_ptr() as *const _);
            let m = _mm256_max_epu8(_mm512_castsi512_si256(z), _mm512_extracti64x4_epi64::<1>(z));
            let m = _mm_max_epu8(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m));
            *b = hmax_u8(m);
        }
        tail(row, blocks);
    }

    #[target("x86_64+sse4.1")]
    pub unsafe fn block_max_u16_sse41(row: &[u16], blocks: &mut [u16]) {
        for (b, ch) in blocks.iter_mut().zip(row.chunks_exact(BLOCK)) {
            let p = ch.as_ptr() as *const __m128i;
            let mut m = _mm_loadu_si128(p);
            for i in 1..8 {
                m = _mm_max_epu16(m, _mm_loadu_si128(p.add(i)));
            }
            *b = hmax_u16(m);
        }
        tail(row, blocks);
    }

    #[target("x86_64+avx2+sse4.1")]
    pub unsafe fn block_max_u16_avx2(row: &[u16], blocks: &mut [u16]) {
        for (b, ch) in blocks.iter_mut().zip(row.chunks_exact(BLOCK)) {
            let p = ch.as_ptr() as *const __m256i;
            let m = _mm256_max_epu16(
                _mm256_max_epu16(_mm256_loadu_si256(p), _mm256_loadu_si256(p.add(1))),
                _mm256_max_epu16(_mm256_loadu_si256(p.add(2)), _mm256_loadu_si256(p.add(3))),
            );
            let m = _mm_max_epu16(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m));
            *b = hmax_u16(m);
        }
        tail(row, blocks);
    }

    #[target("x86_64+avx512f+avx512bw+avx2+sse4.1")]
    pub unsafe fn block_max_u16_avx512(row: &[u16], blocks: &mut [u16]) {
        for (b, ch) in blocks.iter_mut().zip(row.chunks_exact(BLOCK)) {
            let p = ch.as_ptr();
            let z = _mm512_max_epu16(
                _mm512_loadu_si512(p as *const _),
                _mm512_loadu_si512(p.add(32) as *const _),
            );
            let m = _mm256_max_epu16(_mm512_castsi512_si256(z), _mm512_extracti64x4_epi64::<1>(z));
            let m = _mm_max_epu16(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m));
            *b = hmax_u16(m);
        }
        tail(row, blocks);
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

    #[target("x86_64+sse4.1")]
    pub unsafe fn kth_u8_sse41(v: &[u8; 64], k: usize) -> u8 {
        let p = v.as_ptr() as *const __m128i;
        let x = [0, 1, 2, 3].map(|i| _mm_loadu_si128(p.add(i)));
        let mut ans = 0u8;
        for bit in (0..8).rev() {
            let c = ans | (1 << bit);
            let cv = _mm_set1_epi8(c as i8);
            let n: u32 = x.iter().map(|&x| below_128(x, cv).count_ones()).sum();
            if n as usize <= k {
                ans = c;
            }
        }
        ans
    }

    #[target("x86_64+avx2+sse4.1")]
    pub unsafe fn kth_u8_avx2(v: &[u8; 64], k: usize) -> u8 {
        let p = v.as_ptr() as *const __m256i;
        let flip = _mm256_set1_epi8(i8::MIN);
        let a = _mm256_xor_si256(_mm256_loadu_si256(p), flip);
        let b = _mm256_xor_si256(_mm256_loadu_si256(p.add(1)), flip);
        let mut ans = 0u8;
        for bit in (0..8).rev() {
            let c = ans | (1 << bit);
            let cv = _mm256_set1_epi8((c ^ 0x80) as i8);
            let n = (_mm256_movemask_epi8(_mm256_cmpgt_epi8(cv, a)) as u32).count_ones()
                + (_mm256_movemask_epi8(_mm256_cmpgt_epi8(cv, b)) as u32).count_ones();
            if n as usize <= k {
                ans = c;
            }
        }
        ans
    }

    #[target("x86_64+avx512f+avx512bw+avx2+sse4.1")]
    pub unsafe fn kth_u8_avx512(v: &[u8; 64], k: usize) -> u8 {
        let z = _mm512_loadu_si512(v.as_ptr() as *const _);
        let mut ans = 0u8;
        for bit in (0..8).rev() {
            let c = ans | (1 << bit);
            let n = _mm512_cmplt_epu8_mask(z, _mm512_set1_epi8(c as i8)).count_ones();
            if n as usize <= k {
                ans = c;
            }
        }
        ans
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
