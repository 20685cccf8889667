//! The image's noise and artefacts: their configuration (see the renderer's module doc,
//! "Rendering" and "Colour"), the colour camera's fixed texture and the speckle deviates
//! correlated along a row.

use super::rng::mix;
use crate::optics::{check_range, SimError};
use footscan_hal::PixelFormat;
use serde::{Deserialize, Serialize};

/// Image noise and artefacts.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct NoiseConfig {
    /// Gaussian sigma of the line profile across columns (px).
    pub line_sigma_px: f64,
    /// Peak amplitude of the line (DN, before pixel integration).
    pub peak_dn: f64,
    /// Ambient level (DN).
    pub ambient_dn: f64,
    /// Read noise standard deviation (DN).
    pub read_noise_dn: f64,
    /// Electrons per DN at gain 1 for shot noise; 0 disables shot noise.
    pub electrons_per_dn: f64,
    /// Multiplicative per-pixel speckle on the laser signal (relative sigma).
    pub speckle: f64,
    /// Correlation length of the speckle along the row, px: each pixel's speckle is the mean of
    /// this many independent deviates shared with its neighbours (a box of that width, variance
    /// kept), as a laser's speckle grains span several pixels. 0 or 1: independent per pixel.
    pub speckle_corr_px: f64,
    /// Relative intensity of a weak second line at the glass (h = 0) column; 0 = off.
    pub glass_reflection: f64,
    /// Expected number of specular spikes (small saturated blobs) per frame.
    pub specular_spike_rate: f64,
    /// Probability that the camera drops a frame slot.
    pub drop_rate: f64,
    /// Head positions (slider mm, [from, to]) over which the camera drops every frame: a
    /// deterministic gap for tests of the scan's quality gate.
    pub drop_x_mm: Vec<[f64; 2]>,
    /// Pixel format of rendered frames.
    pub format: PixelFormat,
    /// false = noise-free: exact pixel-integrated Gaussian plus ambient, rounded.
    pub enabled: bool,
    /// A colour camera: the frame is rendered in colour and reduced to one channel as the V4L2
    /// driver reduces a colour format ([`ColourCamera`]); None: a monochrome camera.
    pub colour: Option<ColourCamera>,
}

/// A colour camera under coloured room light (see the module doc, "Colour").
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ColourCamera {
    /// The laser's response in R, G, B relative to its channel's (a red laser on a Bayer
    /// sensor: about [1, 0.06, 0.03]).
    pub laser_rgb: [f64; 3],
    /// The ambient light off the scene in R, G, B relative to `ambient_dn` (room light on
    /// skin: about [1, 0.85, 0.75]; white paper under daylight: [1, 1, 1]).
    pub ambient_rgb: [f64; 3],
    /// The channel the camera delivers (the driver's `channel`).
    pub channel: footscan_hal::Channel,
    /// Texture of the lit scene: the ambient light varies by +- this fraction over blotches of
    /// 6 to 24 px (skin, a sock's weave, the room behind the glass); 0 = uniform light.
    #[serde(default)]
    pub texture: f64,
}

impl ColourCamera {
    /// A red laser under warm room light on skin, reduced to R - (G + B) / 2.
    pub fn red_laser() -> Self {
        ColourCamera {
            laser_rgb: [1.0, 0.06, 0.03],
            ambient_rgb: [1.0, 0.85, 0.75],
            channel: footscan_hal::Channel::RedMinusOthers,
            texture: 0.0,
        }
    }
}

/// A fixed blotchy pattern in [-1, 1] (value noise on 24 px and 6 px grids, bilinear).
pub(super) fn texture_pattern(w: usize, h: usize, seed: u64) -> Vec<f32> {
    let grid = |cell: usize, stream: u64| {
        let (gw, gh) = (w / cell + 2, h / cell + 2);
        let v: Vec<f32> = (0..gw * gh)
            .map(|i| (mix(seed, i as u64, stream) >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0)
            .collect();
        move |x: usize, y: usize| {
            let (fx, fy) = (x as f32 / cell as f32, y as f32 / cell as f32);
            let (i, j) = (fx as usize, fy as usize);
            let (tx, ty) = (fx - i as f32, fy - j as f32);
            let at = |a: usize, b: usize| v[b * gw + a];
            (at(i, j) * (1.0 - tx) + at(i + 1, j) * tx) * (1.0 - ty)
                + (at(i, j + 1) * (1.0 - tx) + at(i + 1, j + 1) * tx) * ty
        }
    };
    let (coarse, fine) = (grid(24, 0x7E47_0001), grid(6, 0x7E47_0002));
    (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            (0.7 * coarse(x, y) + 0.5 * fine(x, y)).clamp(-1.0, 1.0)
        })
        .collect()
}

impl Default for NoiseConfig {
    fn default() -> Self {
        NoiseConfig {
            line_sigma_px: 1.6,
            peak_dn: 180.0,
            ambient_dn: 8.0,
            read_noise_dn: 2.0,
            electrons_per_dn: 40.0,
            speckle: 0.15,
            speckle_corr_px: 0.0,
            glass_reflection: 0.0,
            specular_spike_rate: 0.0,
            drop_rate: 0.0,
            drop_x_mm: Vec::new(),
            format: PixelFormat::Gray8,
            enabled: true,
            colour: None,
        }
    }
}

impl NoiseConfig {
    /// The default line with noise disabled.
    pub fn noise_free() -> Self {
        NoiseConfig {
            enabled: false,
            ..NoiseConfig::default()
        }
    }

    pub fn validate(&self) -> Result<(), SimError> {
        check_range("line_sigma_px", self.line_sigma_px, 0.2, 50.0)?;
        check_range("peak_dn", self.peak_dn, 0.0, 1e5)?;
        check_range("ambient_dn", self.ambient_dn, 0.0, 1e5)?;
        check_range("read_noise_dn", self.read_noise_dn, 0.0, 1e3)?;
        check_range("electrons_per_dn", self.electrons_per_dn, 0.0, 1e6)?;
        check_range("speckle", self.speckle, 0.0, 10.0)?;
        check_range(
            "speckle_corr_px",
            self.speckle_corr_px,
            0.0,
            MAX_SPECKLE_CORR as f64,
        )?;
        check_range("glass_reflection", self.glass_reflection, 0.0, 10.0)?;
        check_range("specular_spike_rate", self.specular_spike_rate, 0.0, 1e4)?;
        check_range("drop_rate", self.drop_rate, 0.0, 1.0)?;
        if let Some(c) = &self.colour {
            check_range("colour.texture", c.texture, 0.0, 1.0)?;
        }
        for r in &self.drop_x_mm {
            check_range("drop_x_mm", r[1] - r[0], 0.0, 1e4)?;
        }
        if let Some(c) = &self.colour {
            for (k, v) in c.laser_rgb.iter().chain(&c.ambient_rgb).enumerate() {
                let key = if k < 3 {
                    "colour.laser_rgb"
                } else {
                    "colour.ambient_rgb"
                };
                check_range(key, *v, 0.0, 10.0)?;
            }
        }
        Ok(())
    }
}

/// Longest speckle correlation along the row, px.
pub const MAX_SPECKLE_CORR: usize = 8;

/// Speckle deviates correlated along a row: the mean of the last `len` independent normals
/// times sqrt(len) (unit variance, correlation falling linearly to 0 over `len` px). `len` <= 1
/// uses the pixel's own deviate, so frames without correlation are as before.
pub(crate) struct Speckle {
    ring: [f64; MAX_SPECKLE_CORR],
    len: usize,
    i: usize,
    sum: f64,
    scale: f64,
}

impl Speckle {
    pub(crate) fn new(corr_px: f64) -> Self {
        let len = (corr_px.round() as usize).clamp(1, MAX_SPECKLE_CORR);
        Speckle {
            ring: [0.0; MAX_SPECKLE_CORR],
            len,
            i: 0,
            sum: 0.0,
            scale: 1.0 / (len as f64).sqrt(),
        }
    }
    /// Start a row: the ring is filled with `fresh()` deviates.
    pub(crate) fn start(&mut self, mut fresh: impl FnMut() -> f64) {
        if self.len > 1 {
            self.sum = 0.0;
            for k in 0..self.len {
                self.ring[k] = fresh();
                self.sum += self.ring[k];
            }
        }
    }
    /// The next pixel's deviate; `z` is a fresh independent one.
    #[inline]
    pub(crate) fn next(&mut self, z: f64) -> f64 {
        if self.len <= 1 {
            return z;
        }
        self.sum += z - self.ring[self.i];
        self.ring[self.i] = z;
        self.i = (self.i + 1) % self.len;
        self.sum * self.scale
    }
}
