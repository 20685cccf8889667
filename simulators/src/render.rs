//! Frames of the laser line with exact per-row ground truth.
//!
//! # Ground truth
//! For a head at physical slider position X the laser plane (see [`crate::optics`]) meets the
//! scene's height field in a curve. Parametrised by world y, its point is
//! `(x0(y) + tan(b) z, y, z)` with `x0(y) = X + L + tan(a) y` and `z` solving
//! `z = height(x0(y) + tan(b) z, y)` ([`Surface::plane_height`]). The curve is sampled every
//! 0.1 mm of y, ends of the valid stretches and jumps of the height field (steps: consecutive
//! samples more than 0.5 mm apart in height) are located by bisection to 1e-11 mm, and for
//! every integer row r between two consecutive samples of one side the y where the projected
//! row equals r is
//! found by Brent's method (|row - r| < 1e-10 px). The truth column is the projected column of
//! that point. Rules:
//! - [`RowTruth::NoLine`] where the plane meets no surface in the row, or the point projects
//!   outside the image columns [-0.5, width - 0.5].
//! - Where the projected curve crosses a row more than once (it folds near vertical walls),
//!   the crossing nearest to the camera centre is kept.
//! - There is no occlusion test: a point on the curve is seen if it projects into the image.
//! - Because the whole head moves together, the image of a given scene point depends only on
//!   its position relative to the head.
//!
//! # Rendering
//! Rows are independent. In a row with a line at truth column mu, pixel c receives
//! `A * integral over [c - 0.5, c + 0.5] of exp(-(u - mu)^2 / (2 sigma^2)) du` with
//! `A = peak_dn * gain` (reflectance is 1 for every surface: no shading model), evaluated with
//! erf over mu +- 6 sigma. With [`NoiseConfig::glass_reflection`] > 0 every row also gets a line
//! of amplitude `glass_reflection * A` at the glass (h = 0) column (where the sole touches the
//! glass the two coincide and add). The value of a pixel is
//! `ambient_dn * gain + signal`; with noise enabled, the signal is first multiplied by
//! `max(0, 1 + speckle * N(0,1))`, then Gaussian noise of variance
//! `mean * gain / electrons_per_dn + read_noise_dn^2` is added (shot noise as the Gaussian
//! approximation of Poisson; `electrons_per_dn = 0` disables it). Values are rounded and
//! clipped to 0..=255 (Gray8) or, for Gray16, scaled by 257 (255 DN = 65535) before rounding
//! and clipping to 0..=65535.
//!
//! Background pixels (no line nearby) are drawn from a 65536-entry table of the quantised
//! background distribution indexed by 16 random bits (quantiles at (i + 0.5) / 65536, so the
//! tails are truncated at about 4.3 sigma); the same table of standard-normal quantiles supplies
//! the Gaussian variates of line pixels. Specular spikes: a Poisson number (mean
//! `specular_spike_rate`) of saturated discs of radius 1.5 px, each in a random row, 5 to 40 px
//! to either side of that row's line (anywhere in the row if it has none).
//!
//! Noise is a deterministic function of (seed, frame index): frame k is identical however it is
//! reached.
//!
//! # Colour
//! With [`NoiseConfig::colour`] the camera is a colour camera under coloured room light: the
//! frame above is the laser's own channel (its response 1: red for a red laser); each pixel's
//! ambient part becomes `ambient_dn * ambient_rgb` and the rest, laser light with its noise,
//! `laser_rgb` times itself; the two other channels get independent read noise; then the pixel
//! is reduced to the camera's channel ([`footscan_hal::Channel`], the V4L2 driver's function).
//! The laser channel's noise is carried into the others in proportion to `laser_rgb` (small for
//! a laser): a simplification that keeps one rendered frame per colour frame. `texture` makes
//! the lit scene blotchy (a fixed pattern per camera pixel, the same in every channel): room
//! light on a textured scene, which a threshold must not take for the line.

use crate::foot::Foot;
use crate::optics::{check_range, Optics, Projector, SimError};
pub use crate::surface::{solve_plane_height, Surface};
use footscan_hal::{PixelFormat, Pixels};
use rand::{Rng, RngCore, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};
use std::sync::Arc;

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
fn texture_pattern(w: usize, h: usize, seed: u64) -> Vec<f32> {
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

/// A flat plate of unbounded extent at a known height (calibration target; 0 = a matte sheet
/// on the glass, the reference glass line).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plate {
    pub height_mm: f64,
}

impl Surface for Plate {
    fn height(&self, _x: f64, _y: f64) -> Option<f64> {
        Some(self.height_mm)
    }
    fn max_height(&self) -> f64 {
        self.height_mm
    }
    fn plane_height(&self, _x0: f64, _tan_b: f64, _y: f64) -> Option<f64> {
        Some(self.height_mm)
    }
}

/// What stands on the glass.
// Built once per renderer: the size difference of the variants does not matter.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug)]
pub enum Scene {
    /// Nothing: no line (a glass reflection may still be configured).
    Empty,
    Foot(Foot),
    /// A flat plate; `Plate { height_mm: 0.0 }` gives the glass line of an empty-platform pass.
    Plate {
        height_mm: f64,
    },
    /// Any other target (staircase gauge, ...).
    Surface(Arc<dyn Surface>),
}

impl Scene {
    fn surface(&self) -> Option<Arc<dyn Surface>> {
        match self {
            Scene::Empty => None,
            Scene::Foot(f) => Some(Arc::new(f.clone())),
            Scene::Plate { height_mm } => Some(Arc::new(Plate {
                height_mm: *height_mm,
            })),
            Scene::Surface(s) => Some(s.clone()),
        }
    }
}

/// Ground truth of one row.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum RowTruth {
    NoLine,
    /// Exact column of the line at the row centre and the world point imaged there.
    Line {
        col: f64,
        point: [f64; 3],
    },
}

/// Ground truth of one frame.
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
pub struct FrameTruth {
    /// Physical slider position the frame was rendered at.
    pub slider_x: f64,
    /// One entry per image row.
    pub rows: Vec<RowTruth>,
}

impl FrameTruth {
    /// Rows that have a line.
    pub fn line_count(&self) -> usize {
        self.rows
            .iter()
            .filter(|r| matches!(r, RowTruth::Line { .. }))
            .count()
    }
}

/// Longest speckle correlation along the row, px.
pub const MAX_SPECKLE_CORR: usize = 8;

/// Speckle deviates correlated along a row: the mean of the last `len` independent normals
/// times sqrt(len) (unit variance, correlation falling linearly to 0 over `len` px). `len` <= 1
/// uses the pixel's own deviate, so frames without correlation are as before.
struct Speckle {
    ring: [f64; MAX_SPECKLE_CORR],
    len: usize,
    i: usize,
    sum: f64,
    scale: f64,
}

impl Speckle {
    fn new(corr_px: f64) -> Self {
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
    fn start(&mut self, mut fresh: impl FnMut() -> f64) {
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
    fn next(&mut self, z: f64) -> f64 {
        if self.len <= 1 {
            return z;
        }
        self.sum += z - self.ring[self.i];
        self.ring[self.i] = z;
        self.i = (self.i + 1) % self.len;
        self.sum * self.scale
    }
}

const TABLE_BITS: u32 = 16;
const TABLE_LEN: usize = 1 << TABLE_BITS;
const SAMPLE_STEP_MM: f64 = 0.1;

/// Renders frames and their ground truth.
#[derive(Debug)]
pub struct Renderer {
    optics: Optics,
    proj: Projector,
    noise: NoiseConfig,
    scene: Scene,
    surface: Option<Arc<dyn Surface>>,
    seed: u64,
    gain: f64,
    /// Standard-normal quantiles at (i + 0.5) / TABLE_LEN.
    normal: Vec<f32>,
    bg8: Vec<u8>,
    bg16: Vec<u16>,
    /// Glass (h = 0) column per row (head-position independent).
    glass: Vec<Option<f64>>,
    /// Expected signal of the pixels of one row segment.
    signal: Vec<f32>,
    /// [`ColourCamera::texture`]'s pattern (empty without texture).
    texture: Vec<f32>,
}

impl Renderer {
    pub fn new(
        optics: Optics,
        noise: NoiseConfig,
        scene: Scene,
        seed: u64,
    ) -> Result<Self, SimError> {
        optics.validate()?;
        noise.validate()?;
        if let Scene::Plate { height_mm } = scene {
            check_range("plate.height_mm", height_mm, 0.0, 200.0)?;
        }
        let proj = optics.projector();
        let normal = (0..TABLE_LEN)
            .map(|i| inverse_normal_cdf((i as f64 + 0.5) / TABLE_LEN as f64) as f32)
            .collect();
        let mut glass_truth = FrameTruth::default();
        compute_truth(
            &proj,
            &optics,
            Some(&Plate { height_mm: 0.0 }),
            0.0,
            &mut glass_truth,
        );
        let glass = glass_truth
            .rows
            .iter()
            .map(|r| match r {
                RowTruth::Line { col, .. } => Some(*col),
                RowTruth::NoLine => None,
            })
            .collect();
        let surface = scene.surface();
        let texture = match &noise.colour {
            Some(c) if c.texture > 0.0 => {
                texture_pattern(optics.width as usize, optics.height as usize, seed)
            }
            _ => Vec::new(),
        };
        let mut r = Renderer {
            optics,
            proj,
            noise,
            scene,
            surface,
            seed,
            gain: 1.0,
            normal,
            bg8: Vec::new(),
            bg16: Vec::new(),
            glass,
            signal: Vec::new(),
            texture,
        };
        r.build_background();
        Ok(r)
    }

    pub fn optics(&self) -> &Optics {
        &self.optics
    }
    pub fn noise(&self) -> &NoiseConfig {
        &self.noise
    }
    pub fn scene(&self) -> &Scene {
        &self.scene
    }
    pub fn seed(&self) -> u64 {
        self.seed
    }
    pub fn gain(&self) -> f64 {
        self.gain
    }

    /// Analogue gain: multiplies the laser signal and the ambient level, and the shot noise
    /// with them (DN per electron = gain / electrons_per_dn); read noise is unchanged.
    pub fn set_gain(&mut self, gain: f64) -> Result<(), SimError> {
        check_range("gain", gain, 0.01, 100.0)?;
        self.gain = gain;
        self.build_background();
        Ok(())
    }

    /// Glass (h = 0) column of each row, the same at every head position.
    pub fn glass_columns(&self) -> &[Option<f64>] {
        &self.glass
    }

    /// Ground truth with the head at `physical_x`.
    pub fn truth(&self, physical_x: f64) -> FrameTruth {
        let mut t = FrameTruth::default();
        self.truth_into(physical_x, &mut t);
        t
    }

    /// Ground truth into an existing record (no allocation once `truth.rows` has its length).
    pub fn truth_into(&self, physical_x: f64, truth: &mut FrameTruth) {
        compute_truth(
            &self.proj,
            &self.optics,
            self.surface.as_deref(),
            physical_x,
            truth,
        );
    }

    fn scale(&self) -> f64 {
        match self.noise.format {
            PixelFormat::Gray8 => 1.0,
            PixelFormat::Gray16 => 257.0,
        }
    }

    fn max_value(&self) -> f64 {
        match self.noise.format {
            PixelFormat::Gray8 => 255.0,
            PixelFormat::Gray16 => 65535.0,
        }
    }

    fn build_background(&mut self) {
        let amb = self.noise.ambient_dn * self.gain;
        let sd = if self.noise.enabled {
            self.noise_sd(amb)
        } else {
            0.0
        };
        let (scale, max) = (self.scale(), self.max_value());
        let values = self
            .normal
            .iter()
            .map(|&z| ((amb + sd * z as f64) * scale).round().clamp(0.0, max));
        match self.noise.format {
            PixelFormat::Gray8 => self.bg8 = values.map(|v| v as u8).collect(),
            PixelFormat::Gray16 => self.bg16 = values.map(|v| v as u16).collect(),
        }
    }

    /// Noise standard deviation (DN) of a pixel with mean `mean` DN.
    #[inline]
    fn noise_sd(&self, mean: f64) -> f64 {
        let shot = if self.noise.electrons_per_dn > 0.0 {
            mean.max(0.0) * self.gain / self.noise.electrons_per_dn
        } else {
            0.0
        };
        (shot + self.noise.read_noise_dn * self.noise.read_noise_dn).sqrt()
    }

    /// Render frame `frame_index` with the head at `physical_x` into new buffers.
    pub fn render(&mut self, physical_x: f64, frame_index: u64) -> (Pixels, FrameTruth) {
        let mut pixels = Pixels::Gray8(Vec::new());
        let mut truth = FrameTruth::default();
        self.render_into(physical_x, frame_index, &mut pixels, &mut truth);
        (pixels, truth)
    }

    /// Render the frame with the head at `physical_x` into `pixels` (replaced by a buffer of
    /// the configured format and size if it is not one) and its truth into `truth`.
    /// Allocation-free once the buffers have their size.
    pub fn render_into(
        &mut self,
        physical_x: f64,
        frame_index: u64,
        pixels: &mut Pixels,
        truth: &mut FrameTruth,
    ) {
        self.render_into_lit(physical_x, frame_index, true, pixels, truth)
    }

    /// [`Renderer::render_into`] with the laser on or off: with it off the frame is the scene's
    /// background and noise only (no line, no glass reflection, no specular spike: all three
    /// are laser light) and every row's truth is [`RowTruth::NoLine`].
    pub fn render_into_lit(
        &mut self,
        physical_x: f64,
        frame_index: u64,
        laser_on: bool,
        pixels: &mut Pixels,
        truth: &mut FrameTruth,
    ) {
        self.truth_into(physical_x, truth);
        if !laser_on {
            truth.rows.iter_mut().for_each(|r| *r = RowTruth::NoLine);
        }
        let (w, h) = (self.optics.width as usize, self.optics.height as usize);
        let n = w * h;
        if pixels.len() != n || pixels.format() != self.noise.format {
            *pixels = match self.noise.format {
                PixelFormat::Gray8 => Pixels::Gray8(vec![0; n]),
                PixelFormat::Gray16 => Pixels::Gray16(vec![0; n]),
            };
        }
        let mut bg_rng = WyRand(mix(self.seed, frame_index, 0x5EED_0001));
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(mix(self.seed, frame_index, 0x5EED_0002));
        match pixels {
            Pixels::Gray8(buf) => {
                fill_background(buf, &self.bg8, &mut bg_rng);
                if laser_on {
                    self.draw_lines(buf, truth, &mut rng, |v| v as u8);
                    self.draw_spikes(buf, truth, &mut rng, u8::MAX);
                }
                self.reduce_colour(buf, &mut bg_rng, |v| v as u8);
            }
            Pixels::Gray16(buf) => {
                fill_background(buf, &self.bg16, &mut bg_rng);
                if laser_on {
                    self.draw_lines(buf, truth, &mut rng, |v| v as u16);
                    self.draw_spikes(buf, truth, &mut rng, u16::MAX);
                }
                self.reduce_colour(buf, &mut bg_rng, |v| v as u16);
            }
        }
    }

    /// A colour camera ([`NoiseConfig::colour`]): each pixel of the laser's channel, rendered
    /// above, becomes R, G, B (ambient times `ambient_rgb`, the rest, laser light, times
    /// `laser_rgb`; the two other channels get read noise of their own) and is reduced to the
    /// camera's channel in place, by the same function as the V4L2 driver's.
    fn reduce_colour<T: Copy + Into<u32>>(
        &self,
        buf: &mut [T],
        rng: &mut WyRand,
        cast: impl Fn(u32) -> T,
    ) {
        let Some(c) = &self.noise.colour else {
            return;
        };
        let (scale, max) = (self.scale(), self.max_value());
        let amb = self.noise.ambient_dn * self.gain * scale;
        let read = if self.noise.enabled {
            self.noise.read_noise_dn * scale
        } else {
            0.0
        };
        let normal = &self.normal;
        let mut other = |k: usize, lit: f64, v: f64, laser: f64| -> u32 {
            let z = if read > 0.0 {
                read * normal[(rng.next() & 0xFFFF) as usize] as f64
            } else {
                0.0
            };
            (amb * lit * c.ambient_rgb[k] + (v - amb) * laser + z)
                .round()
                .clamp(0.0, max) as u32
        };
        for (i, p) in buf.iter_mut().enumerate() {
            let v = (*p).into() as f64;
            // The scene's texture scales the light it reflects in every channel alike.
            let lit = match self.texture.get(i) {
                Some(&t) => 1.0 + c.texture * t as f64,
                None => 1.0,
            };
            // The rendered channel is the laser's own (response 1): its noise stays as drawn.
            let r = (amb * lit * c.ambient_rgb[0] + (v - amb) * c.laser_rgb[0])
                .round()
                .clamp(0.0, max) as u32;
            let g = other(1, lit, v, c.laser_rgb[1]);
            let b = other(2, lit, v, c.laser_rgb[2]);
            *p = cast(c.channel.of(r, g, b));
        }
    }

    fn draw_lines<T: Copy>(
        &mut self,
        buf: &mut [T],
        truth: &FrameTruth,
        rng: &mut Xoshiro256PlusPlus,
        cast: impl Fn(f64) -> T,
    ) {
        let w = self.optics.width as usize;
        let sigma = self.noise.line_sigma_px;
        let amp = self.noise.peak_dn * self.gain;
        let glass_amp = amp * self.noise.glass_reflection;
        let reach = (6.0 * sigma).ceil() + 1.0;
        let amb = self.noise.ambient_dn * self.gain;
        let (scale, max) = (self.scale(), self.max_value());
        let mut signal = std::mem::take(&mut self.signal);
        let mut speckle = Speckle::new(self.noise.speckle_corr_px);
        for (r, row_truth) in truth.rows.iter().enumerate() {
            let mut lines = [(0.0, 0.0); 2];
            let mut k = 0;
            if let RowTruth::Line { col, .. } = row_truth {
                lines[k] = (*col, amp);
                k += 1;
            }
            if glass_amp > 0.0 {
                if let Some(Some(col)) = self.glass.get(r) {
                    lines[k] = (*col, glass_amp);
                    k += 1;
                }
            }
            if k == 0 {
                continue;
            }
            let lo = lines[..k].iter().map(|l| l.0).fold(f64::INFINITY, f64::min) - reach;
            let hi = lines[..k]
                .iter()
                .map(|l| l.0)
                .fold(f64::NEG_INFINITY, f64::max)
                + reach;
            let c0 = lo.floor().max(0.0) as usize;
            let c1 = (hi.ceil().min(w as f64 - 1.0)).max(-1.0);
            if c1 < c0 as f64 {
                continue;
            }
            let c1 = c1 as usize;
            signal.clear();
            signal.resize(c1 - c0 + 1, 0.0);
            for &(mu, a) in &lines[..k] {
                add_gaussian(&mut signal, c0, mu, sigma, a, reach);
            }
            let row = &mut buf[r * w..(r + 1) * w];
            let normal = &self.normal;
            if self.noise.enabled {
                speckle.start(|| normal[(rng.next_u64() & 0xFFFF) as usize] as f64);
            }
            for (i, &s) in signal.iter().enumerate() {
                let s = s as f64;
                if s < 1e-3 {
                    // Far tail: leave the background pixel as drawn.
                    continue;
                }
                let v = if self.noise.enabled {
                    let bits = rng.next_u64();
                    let z1 = speckle.next(self.normal[(bits & 0xFFFF) as usize] as f64);
                    let z2 = self.normal[((bits >> 16) & 0xFFFF) as usize] as f64;
                    let mean = amb + s * (1.0 + self.noise.speckle * z1).max(0.0);
                    mean + self.noise_sd(mean) * z2
                } else {
                    amb + s
                };
                row[c0 + i] = cast((v * scale).round().clamp(0.0, max));
            }
        }
        self.signal = signal;
    }

    fn draw_spikes<T: Copy>(
        &self,
        buf: &mut [T],
        truth: &FrameTruth,
        rng: &mut Xoshiro256PlusPlus,
        sat: T,
    ) {
        let rate = self.noise.specular_spike_rate;
        if rate <= 0.0 {
            return;
        }
        let (w, h) = (self.optics.width as i64, self.optics.height as i64);
        // Poisson count by Knuth's method (rates are small); capped for safety.
        let limit = (-rate).exp();
        let mut p = rng.gen::<f64>();
        let mut count = 0;
        while p > limit && count < 10_000 {
            count += 1;
            p *= rng.gen::<f64>();
        }
        for _ in 0..count {
            let r = rng.gen_range(0..h);
            let c = match truth.rows[r as usize] {
                RowTruth::Line { col, .. } => {
                    let off = rng.gen_range(5.0..40.0);
                    if rng.gen::<bool>() {
                        col + off
                    } else {
                        col - off
                    }
                }
                RowTruth::NoLine => rng.gen_range(0.0..w as f64),
            }
            .round() as i64;
            for dr in -1..=1i64 {
                for dc in -1..=1i64 {
                    let (rr, cc) = (r + dr, c + dc);
                    if dr * dr + dc * dc <= 2 && (0..h).contains(&rr) && (0..w).contains(&cc) {
                        buf[(rr * w + cc) as usize] = sat;
                    }
                }
            }
        }
    }
}

/// Add `a * integral of exp(-(u - mu)^2 / (2 sigma^2))` over each pixel of `sig` (pixel i is
/// column c0 + i), within `reach` px of mu.
fn add_gaussian(sig: &mut [f32], c0: usize, mu: f64, sigma: f64, a: f64, reach: f64) {
    let k = a * sigma * (std::f64::consts::PI / 2.0).sqrt();
    let inv = 1.0 / (sigma * std::f64::consts::SQRT_2);
    let first = ((mu - reach).floor().max(c0 as f64)) as usize;
    let last = ((mu + reach).ceil() as usize).min(c0 + sig.len() - 1);
    if last < first {
        return;
    }
    let mut e_lo = libm::erf((first as f64 - 0.5 - mu) * inv);
    for c in first..=last {
        let e_hi = libm::erf((c as f64 + 0.5 - mu) * inv);
        sig[c - c0] += (k * (e_hi - e_lo)) as f32;
        e_lo = e_hi;
    }
}

fn fill_background<T: Copy>(buf: &mut [T], table: &[T], rng: &mut WyRand) {
    let mut chunks = buf.chunks_exact_mut(8);
    for ch in &mut chunks {
        let a = rng.next();
        let b = rng.next();
        ch[0] = table[(a & 0xFFFF) as usize];
        ch[1] = table[((a >> 16) & 0xFFFF) as usize];
        ch[2] = table[((a >> 32) & 0xFFFF) as usize];
        ch[3] = table[(a >> 48) as usize];
        ch[4] = table[(b & 0xFFFF) as usize];
        ch[5] = table[((b >> 16) & 0xFFFF) as usize];
        ch[6] = table[((b >> 32) & 0xFFFF) as usize];
        ch[7] = table[(b >> 48) as usize];
    }
    for v in chunks.into_remainder() {
        *v = table[(rng.next() & 0xFFFF) as usize];
    }
}

/// wyrand: one multiply per 64 random bits (background noise only).
struct WyRand(u64);

impl WyRand {
    #[inline(always)]
    fn next(&mut self) -> u64 {
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

/// Inverse standard normal CDF (Acklam's rational approximation with one Halley step,
/// relative error ~1e-15).
pub(crate) fn inverse_normal_cdf(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e+01,
        2.209460984245205e+02,
        -2.759285104469687e+02,
        1.383_577_518_672_69e2,
        -3.066479806614716e+01,
        2.506628277459239e+00,
    ];
    const B: [f64; 5] = [
        -5.447609879822406e+01,
        1.615858368580409e+02,
        -1.556989798598866e+02,
        6.680131188771972e+01,
        -1.328068155288572e+01,
    ];
    const C: [f64; 6] = [
        -7.784894002430293e-03,
        -3.223964580411365e-01,
        -2.400758277161838e+00,
        -2.549732539343734e+00,
        4.374664141464968e+00,
        2.938163982698783e+00,
    ];
    const D: [f64; 4] = [
        7.784695709041462e-03,
        3.224671290700398e-01,
        2.445134137142996e+00,
        3.754408661907416e+00,
    ];
    let p_low = 0.02425;
    let x = if p < p_low {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else if p <= 1.0 - p_low {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        let q = (-2.0 * (1.0 - p).ln()).sqrt();
        -(((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    };
    // Halley refinement.
    let e = 0.5 * libm::erfc(-x / std::f64::consts::SQRT_2) - p;
    let u = e * (2.0 * std::f64::consts::PI).sqrt() * (x * x / 2.0).exp();
    x - u / (1.0 + x * u / 2.0)
}

#[derive(Clone, Copy, Debug)]
struct Sample {
    y: f64,
    p: [f64; 3],
    col: f64,
    row: f64,
}

struct TruthCtx<'a> {
    proj: &'a Projector,
    surface: &'a dyn Surface,
    x: f64,
}

impl TruthCtx<'_> {
    #[inline]
    fn eval(&self, y: f64) -> Option<Sample> {
        let x0 = self.proj.laser_x(self.x, y, 0.0);
        let z = self.surface.plane_height(x0, self.proj.tan_b, y)?;
        let p = [x0 + self.proj.tan_b * z, y, z];
        let [col, row] = self.proj.project(self.x, p)?;
        Some(Sample { y, p, col, row })
    }
}

fn compute_truth(
    proj: &Projector,
    optics: &Optics,
    surface: Option<&dyn Surface>,
    x: f64,
    truth: &mut FrameTruth,
) {
    let h = optics.height as usize;
    truth.slider_x = x;
    truth.rows.clear();
    truth.rows.resize(h, RowTruth::NoLine);
    let Some(surface) = surface else { return };
    let ctx = TruthCtx { proj, surface, x };
    // y range the rows can see (generous: distortion and tilts are small).
    let zmax = surface.max_height().max(0.0);
    let half_rows = optics.cy.max(optics.height as f64 - optics.cy) + 32.0;
    let reach = 1.3 * half_rows * (optics.d_mm + zmax) / optics.f_px + 5.0;
    let (b0, b1) = surface.y_bounds();
    let y0 = (-reach).max(b0 - SAMPLE_STEP_MM);
    let y1 = reach.min(b1 + SAMPLE_STEP_MM);
    if y1 <= y0 {
        return;
    }
    let n = ((y1 - y0) / SAMPLE_STEP_MM).ceil() as usize;
    let cam = proj.camera_centre(x);
    let mut prev: Option<Sample> = None;
    let mut prev_y = y0;
    for i in 0..=n {
        let y = y0 + (y1 - y0) * i as f64 / n as f64;
        let cur = ctx.eval(y);
        match (prev, cur) {
            (Some(a), Some(b)) if (b.p[2] - a.p[2]).abs() > JUMP_MM => {
                // Possibly a jump of the height field (a step): image each side separately.
                let (ea, eb) = jump(&ctx, a, b);
                if let Some(ea) = ea {
                    segment(&ctx, a, ea, cam, optics, truth);
                }
                if let Some(eb) = eb {
                    segment(&ctx, eb, b, cam, optics, truth);
                }
            }
            (Some(a), Some(b)) => segment(&ctx, a, b, cam, optics, truth),
            (Some(a), None) => {
                if let Some(e) = edge(&ctx, a.y, y) {
                    segment(&ctx, a, e, cam, optics, truth);
                }
            }
            (None, Some(b)) if i > 0 => {
                if let Some(e) = edge(&ctx, b.y, prev_y) {
                    segment(&ctx, e, b, cam, optics, truth);
                }
            }
            _ => {}
        }
        prev = cur;
        prev_y = y;
    }
}

/// Height change between two samples beyond which [`jump`] looks for a discontinuity.
const JUMP_MM: f64 = 0.5;

/// Where the height field jumps between samples `a` and `b` (a step of a staircase): the last
/// sample on `a`'s side and the first on `b`'s, by bisection to 1e-11 mm (a sample belongs to
/// the side whose height it is nearer). On a continuous steep stretch this splits it at a
/// point, which loses nothing. A gap with no surface in between ends at the gap's edges.
fn jump(ctx: &TruthCtx, a: Sample, b: Sample) -> (Option<Sample>, Option<Sample>) {
    let (mut lo, mut hi) = (a, b);
    while (hi.y - lo.y).abs() > 1e-11 {
        let mid = 0.5 * (lo.y + hi.y);
        match ctx.eval(mid) {
            Some(m) if (m.p[2] - a.p[2]).abs() <= (m.p[2] - b.p[2]).abs() => lo = m,
            Some(m) => hi = m,
            None => return (edge(ctx, lo.y, mid), edge(ctx, hi.y, mid)),
        }
    }
    (Some(lo), Some(hi))
}

/// The last valid sample between `valid_y` (valid) and `invalid_y` (invalid), by bisection.
fn edge(ctx: &TruthCtx, valid_y: f64, invalid_y: f64) -> Option<Sample> {
    let (mut good, mut bad) = (valid_y, invalid_y);
    let mut best = ctx.eval(good)?;
    while (bad - good).abs() > 1e-11 {
        let mid = 0.5 * (good + bad);
        match ctx.eval(mid) {
            Some(s) => {
                good = mid;
                best = s;
            }
            None => bad = mid,
        }
    }
    Some(best)
}

fn segment(
    ctx: &TruthCtx,
    a: Sample,
    b: Sample,
    cam: [f64; 3],
    optics: &Optics,
    truth: &mut FrameTruth,
) {
    let (lo, hi) = if a.row <= b.row {
        (a.row, b.row)
    } else {
        (b.row, a.row)
    };
    let r0 = lo.ceil().max(0.0);
    let r1 = hi.floor().min(optics.height as f64 - 1.0);
    let mut r = r0;
    while r <= r1 {
        let target = r;
        r += 1.0;
        let s = if a.row == target {
            Some(a)
        } else if b.row == target {
            Some(b)
        } else {
            brent(ctx, a, b, target)
        };
        // Across a jump of the height field (a riser) row(y) is discontinuous: Brent then
        // closes in on the jump without a root, and that row has no crossing here.
        let Some(s) = s.filter(|s| (s.row - target).abs() < 1e-6) else {
            continue;
        };
        if s.col < -0.5 || s.col > optics.width as f64 - 0.5 {
            continue;
        }
        let d2 = dist2(s.p, cam);
        let slot = &mut truth.rows[target as usize];
        let better = match *slot {
            RowTruth::NoLine => true,
            RowTruth::Line { point, .. } => d2 < dist2(point, cam) - 1e-12,
        };
        if better {
            *slot = RowTruth::Line {
                col: s.col,
                point: s.p,
            };
        }
    }
}

fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
    (a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)
}

/// Brent's method on f(y) = row(y) - target over [a.y, b.y] (f changes sign there).
fn brent(ctx: &TruthCtx, a: Sample, b: Sample, target: f64) -> Option<Sample> {
    let (mut xa, mut fa) = (a.y, a.row - target);
    let (mut xb, mut fb) = (b.y, b.row - target);
    let mut sb = b;
    if fa * fb > 0.0 {
        return None;
    }
    if fa.abs() < fb.abs() {
        std::mem::swap(&mut xa, &mut xb);
        std::mem::swap(&mut fa, &mut fb);
        sb = a;
    }
    let (mut xc, mut fc) = (xa, fa);
    let mut mflag = true;
    let mut xd = xc;
    for _ in 0..100 {
        if fb.abs() < 1e-10 || (xb - xa).abs() < 1e-13 {
            return Some(sb);
        }
        let mut s = if fa != fc && fb != fc {
            xa * fb * fc / ((fa - fb) * (fa - fc))
                + xb * fa * fc / ((fb - fa) * (fb - fc))
                + xc * fa * fb / ((fc - fa) * (fc - fb))
        } else {
            xb - fb * (xb - xa) / (fb - fa)
        };
        let q = (3.0 * xa + xb) / 4.0;
        let out = !((s > q.min(xb)) && (s < q.max(xb)));
        if out
            || (mflag && (s - xb).abs() >= (xb - xc).abs() / 2.0)
            || (!mflag && (s - xb).abs() >= (xc - xd).abs() / 2.0)
            || (mflag && (xb - xc).abs() < 1e-14)
            || (!mflag && (xc - xd).abs() < 1e-14)
        {
            s = 0.5 * (xa + xb);
            mflag = true;
        } else {
            mflag = false;
        }
        let ss = ctx.eval(s)?;
        let fs = ss.row - target;
        xd = xc;
        xc = xb;
        fc = fb;
        if fa * fs < 0.0 {
            xb = s;
            fb = fs;
            sb = ss;
        } else {
            xa = s;
            fa = fs;
        }
        if fa.abs() < fb.abs() {
            std::mem::swap(&mut xa, &mut xb);
            std::mem::swap(&mut fa, &mut fb);
            // Keep the sample of the new best point.
            sb = ctx.eval(xb)?;
        }
    }
    Some(sb)
}

mod sloped;
pub use sloped::render_sloped_line;

#[cfg(test)]
mod tests;
