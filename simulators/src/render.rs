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

mod kinds;
mod noise;
mod normal;
mod rng;
mod root;
mod scene;
mod sloped;
mod truth;

pub use kinds::{render_kind, KindFrame, LineKind, LIT_DN};
pub use noise::{ColourCamera, NoiseConfig, MAX_SPECKLE_CORR};
pub(crate) use normal::inverse_normal_cdf;
pub(crate) use rng::mix;
pub use scene::{Plate, Scene};
pub use sloped::render_sloped_line;
pub use truth::{FrameTruth, RowTruth};

use crate::optics::{check_range, Optics, Projector, SimError};
pub use crate::surface::{solve_plane_height, Surface};
use footscan_hal::{PixelFormat, Pixels};
use noise::{texture_pattern, Speckle};
use rand::{Rng, RngCore, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use rng::WyRand;
use std::sync::Arc;
use truth::compute_truth;

const TABLE_BITS: u32 = 16;
const TABLE_LEN: usize = 1 << TABLE_BITS;

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
            *p = cast(c.channel.of_full(r, g, b, max as u32));
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

#[cfg(test)]
mod tests;
