//! The renderer's own random numbers: wyrand for the background pixels (one multiply per 64
//! bits) and the SplitMix64 finaliser that makes every frame's streams a function of (seed,
//! frame index).

/// wyrand: one multiply per 64 random bits (background noise only).
pub(super) struct WyRand(pub(super) u64);

impl WyRand {
    #[inline(always)]
    pub(super) fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0xa076_1d64_78bd_642f);
        let t = (self.0 as u128).wrapping_mul((self.0 ^ 0xe703_7ed1_a0b4_28db) as u128);
        ((t >> 64) ^ t) as u64
    }
}

/// SplitMix64 finaliser of (seed, index, stream): independent streams per frame.
pub(crate) fn mix(seed: u64, index: u64, stream: u64) -> u64 {
    let mut z = seed
        .wrapping_add(index.wrapping_mul(0x9E37_79B9_7F4A_7C15))
        .wrapping_add(stream.wrapping_mul(0xD1B5_4A32_D192_ED03));
    for _ in 0..2 {
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
    }
    z
}
