//! Frames of the kinds of real laser line the detector has missed (issue 34), with their true
//! column per row.
//!
//! Real frames of other people's scanners showed four kinds of line that the plain simulator
//! (a Gaussian on a flat dark scene, section 2 of the renderer) never makes. Each is a
//! condition here: [`render_kind`] draws one region of that kind, its parameters drawn from the
//! ranges below by the seed, so a test can judge a detector on many regions of a kind against
//! the truth instead of against the few real frames (which stay out of the tuning).
//!
//! - [`LineKind::SaturatedColour`]: a red laser seen by a colour camera, so bright that red
//!   clips over a run of 4-11 px and green and blue, which a Bayer filter lets some of the laser
//!   through, clip at its centre: the centre is white (R = G = B = 255) and R - (G + B) / 2, the
//!   channel that separates the laser from room light, drops to 0 exactly there.
//! - [`LineKind::WideSpeckled`]: a laser with a poor lens: a line 20-40 px wide at half height
//!   with a glow three times wider around it, speckle of 30-50 % correlated over 3-8 px.
//! - [`LineKind::Chessboard`]: a line running along (0-3 px from) the edges of a black and
//!   white chessboard's squares, the board blurred by the lens and sharpened by the camera (the
//!   overshoot makes every edge a thin line in every channel), then stored as JPEG does with
//!   4:2:0 chroma: the colour of every 2 x 2 block is their mean, so the red of a red laser moves
//!   in 2-pixel steps. The detector sees the red channel.
//! - [`LineKind::LensCurved`]: a line bent by strong lens distortion (a sagitta of 15-40 px over
//!   the region) on a board whose reflectance varies by +-35 % over blotches of 12-48 px, and
//!   whose width grows toward the region's ends as the lens defocuses there.
//!
//! Lines are pixel-integrated Gaussians across the row (sigma along the row grown by the line's
//! local slope); noise is speckle (multiplicative on laser light), shot noise (40 e-/DN) and
//! read noise, then rounding and clipping to 0..=255.

use super::mix;
use footscan_hal::Channel;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

/// A kind of real laser line (module doc).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LineKind {
    SaturatedColour,
    WideSpeckled,
    Chessboard,
    LensCurved,
}

impl LineKind {
    pub const ALL: [LineKind; 4] = [
        LineKind::SaturatedColour,
        LineKind::WideSpeckled,
        LineKind::Chessboard,
        LineKind::LensCurved,
    ];

    pub fn name(self) -> &'static str {
        match self {
            LineKind::SaturatedColour => "saturated-colour",
            LineKind::WideSpeckled => "wide-speckled",
            LineKind::Chessboard => "chessboard-jpeg",
            LineKind::LensCurved => "lens-curved",
        }
    }
}

/// One rendered region of a [`LineKind`].
#[derive(Clone, Debug)]
pub struct KindFrame {
    pub width: usize,
    pub height: usize,
    /// The grey channel the detector sees, row-major.
    pub pixels: Vec<u8>,
    /// True column of the line's centre per row.
    pub truth: Vec<f64>,
    /// Rows where the line is plainly lit: its laser light at the centre is at least
    /// [`LIT_DN`] in the detector's channel and the line lies inside the image.
    pub lit: Vec<bool>,
    /// The channel `pixels` were reduced to from the colour camera's R, G, B.
    pub channel: Channel,
    /// The camera's R, G, B before the reduction, row-major, where the kind is defined by them
    /// ([`LineKind::SaturatedColour`]); empty otherwise.
    pub rgb: Vec<[u8; 3]>,
}

/// Least laser light at the line's centre (DN) for a row to count as lit.
pub const LIT_DN: f64 = 25.0;

/// Shot noise: electrons per DN.
const ELECTRONS_PER_DN: f64 = 40.0;

struct Noise {
    rng: Xoshiro256PlusPlus,
}

impl Noise {
    fn normal(&mut self) -> f64 {
        let u: f64 = self.rng.gen::<f64>().max(1e-300);
        let v: f64 = self.rng.gen();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.rng.gen::<f64>()
    }
    /// `w` speckle deviates of unit variance correlated over `corr` px (a moving box of
    /// independent normals, as the renderer's `Speckle`).
    fn speckle_row(&mut self, w: usize, corr: usize, out: &mut Vec<f64>) {
        let corr = corr.max(1);
        let z: Vec<f64> = (0..w + corr).map(|_| self.normal()).collect();
        out.clear();
        let scale = 1.0 / (corr as f64).sqrt();
        let mut s: f64 = z[..corr].iter().sum();
        for c in 0..w {
            out.push(s * scale);
            s += z[c + corr] - z[c];
        }
    }
    /// Shot and read noise on a pixel of mean `mean` DN.
    fn sensor(&mut self, mean: f64, read_dn: f64) -> f64 {
        let var = mean.max(0.0) / ELECTRONS_PER_DN + read_dn * read_dn;
        mean + var.sqrt() * self.normal()
    }
}

/// Pixel-integrated Gaussian of unit peak centred at `mu`, sigma `s`, at column `c`.
fn integrated(c: f64, mu: f64, s: f64) -> f64 {
    let k = 1.0 / (s * std::f64::consts::SQRT_2);
    s * (std::f64::consts::PI / 2.0).sqrt()
        * (libm::erf((c + 0.5 - mu) * k) - libm::erf((c - 0.5 - mu) * k))
}

/// A Gaussian-blurred square wave of period `2 * size` (+1 on even squares, -1 on odd), the
/// lens's blur `blur` px: separable, so a blurred chessboard is the product of two of them.
fn blurred_square(x: f64, size: f64, offset: f64, blur: f64) -> f64 {
    let u = x - offset;
    let k = (u / size).floor();
    let sign = if (k as i64).rem_euclid(2) == 0 {
        1.0
    } else {
        -1.0
    };
    // The two nearest edges dominate; a third is beyond 12 sigma for the sizes used.
    let d0 = u - k * size;
    let d1 = (k + 1.0) * size - u;
    let e = |d: f64| libm::erf(d / (blur * std::f64::consts::SQRT_2));
    sign * (e(d0) + e(d1) - 1.0)
}

/// Value noise in [-1, 1] on a grid of `cell` px, bilinear.
fn value_noise(seed: u64, cell: f64, x: f64, y: f64) -> f64 {
    let (fx, fy) = (x / cell, y / cell);
    let (i, j) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - i, fy - j);
    let at = |a: f64, b: f64| {
        let h = mix(seed, (a as i64 as u64) << 32 ^ (b as i64 as u64), 0x4B1D);
        (h >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (at(i, j) * (1.0 - tx) + at(i + 1.0, j) * tx) * (1.0 - ty)
        + (at(i, j + 1.0) * (1.0 - tx) + at(i + 1.0, j + 1.0) * tx) * ty
}

/// A region of `kind`, `width` x `height` px (at least 128 x 64), its parameters and noise
/// drawn from `seed`.
pub fn render_kind(kind: LineKind, width: usize, height: usize, seed: u64) -> KindFrame {
    assert!(
        width >= 128 && height >= 64,
        "render_kind: {width} x {height} px, want at least 128 x 64"
    );
    let mut n = Noise {
        rng: Xoshiro256PlusPlus::seed_from_u64(mix(seed, kind as u64, 0x00C0_DE34)),
    };
    match kind {
        LineKind::SaturatedColour => saturated_colour(width, height, &mut n),
        LineKind::WideSpeckled => wide_speckled(width, height, &mut n),
        LineKind::Chessboard => chessboard(width, height, &mut n),
        LineKind::LensCurved => lens_curved(width, height, seed, &mut n),
    }
}

/// Column of the line in row `r`: through `c0` at the region's middle row.
fn line_col(c0: f64, slope: f64, curv: f64, h: usize, r: usize) -> (f64, f64) {
    let y = r as f64 - 0.5 * h as f64;
    (c0 + slope * y + curv * y * y, slope + 2.0 * curv * y)
}

fn saturated_colour(w: usize, h: usize, n: &mut Noise) -> KindFrame {
    let sigma = n.uniform(1.2, 2.2);
    // Red laser light at the centre, before clipping: 4-11 px of red clip.
    let peak = n.uniform(1000.0, 2500.0);
    let ambient = n.uniform(40.0, 90.0);
    let ambient_rgb = [1.0, 0.9, 0.8];
    // A Bayer filter's leak of a bright red laser into green and blue (and the sensor's bloom).
    let leak = [1.0, n.uniform(0.3, 0.4), n.uniform(0.28, 0.38)];
    let slope = n.uniform(-0.3, 0.3);
    let c0 = 0.5 * w as f64 + n.uniform(-0.5, 0.5) * 0.2 * w as f64;
    let (speckle, read) = (0.15, 1.5);
    let ch = Channel::RedMinusOthers;
    let mut px = vec![0u8; w * h];
    let mut camera = vec![[0u8; 3]; w * h];
    let (mut truth, mut lit) = (Vec::with_capacity(h), Vec::with_capacity(h));
    let mut sp = Vec::new();
    for r in 0..h {
        let (mu, s) = line_col(c0, slope, 0.0, h, r);
        let sr = sigma * (1.0 + s * s).sqrt();
        truth.push(mu);
        lit.push(mu > 8.0 && mu < w as f64 - 9.0);
        n.speckle_row(w, 2, &mut sp);
        for c in 0..w {
            let d = c as f64 - mu;
            let laser = if d.abs() < 8.0 * sr {
                peak * integrated(c as f64, mu, sr) * (1.0 + speckle * sp[c]).max(0.0)
            } else {
                0.0
            };
            let mut rgb = [0u32; 3];
            for k in 0..3 {
                let v = n.sensor(ambient * ambient_rgb[k] + leak[k] * laser, read);
                rgb[k] = v.round().clamp(0.0, 255.0) as u32;
            }
            px[r * w + c] = ch.of(rgb[0], rgb[1], rgb[2]) as u8;
            camera[r * w + c] = rgb.map(|v| v as u8);
        }
    }
    KindFrame {
        width: w,
        height: h,
        pixels: px,
        truth,
        lit,
        channel: ch,
        rgb: camera,
    }
}

fn wide_speckled(w: usize, h: usize, n: &mut Noise) -> KindFrame {
    let fwhm = n.uniform(20.0, 40.0);
    let sigma = fwhm / (8.0 * 2f64.ln()).sqrt();
    let glow = n.uniform(0.2, 0.35);
    let peak = n.uniform(120.0, 200.0);
    let ambient = 10.0;
    let speckle = n.uniform(0.3, 0.5);
    let corr = n.uniform(3.0, 8.0).round() as usize;
    let slope = n.uniform(-0.5, 0.5);
    let c0 = 0.5 * w as f64 + n.uniform(-0.5, 0.5) * 0.2 * w as f64;
    let reach = 8.0 * 3.0 * sigma;
    let mut px = vec![0u8; w * h];
    let (mut truth, mut lit) = (Vec::with_capacity(h), Vec::with_capacity(h));
    let mut sp = Vec::new();
    for r in 0..h {
        let (mu, s) = line_col(c0, slope, 0.0, h, r);
        let g = (1.0 + s * s).sqrt();
        truth.push(mu);
        lit.push(mu > 3.0 * fwhm && mu < w as f64 - 3.0 * fwhm);
        n.speckle_row(w, corr, &mut sp);
        for c in 0..w {
            let d = c as f64 - mu;
            let laser = if d.abs() < reach {
                let x = c as f64;
                let core = integrated(x, mu, sigma * g);
                let halo = glow * integrated(x, mu, 3.0 * sigma * g);
                peak * (core + halo) * (1.0 + speckle * sp[c]).max(0.0)
            } else {
                0.0
            };
            px[r * w + c] = n.sensor(ambient + laser, 2.0).round().clamp(0.0, 255.0) as u8;
        }
    }
    KindFrame {
        width: w,
        height: h,
        pixels: px,
        truth,
        lit,
        channel: Channel::Green,
        rgb: Vec::new(),
    }
}

fn chessboard(w: usize, h: usize, n: &mut Noise) -> KindFrame {
    let size = n.uniform(24.0, 48.0);
    let (ox, oy) = (n.uniform(0.0, size), n.uniform(0.0, size));
    let (white, black) = (n.uniform(0.75, 0.9), n.uniform(0.15, 0.3));
    let blur = n.uniform(0.7, 1.2);
    // The camera's sharpening: v + a (v - wide blur of v), overshoot at every edge.
    let (sharpen, wide) = (n.uniform(0.5, 1.0), 2.5 * blur);
    let ambient = n.uniform(60.0, 130.0);
    let sigma = n.uniform(1.2, 2.5);
    let peak = n.uniform(150.0, 230.0);
    let slope = n.uniform(-0.02, 0.02);
    // Along the edge nearest the region's centre, 0-3 px to either side of it.
    let k = ((0.5 * w as f64 - ox) / size).round();
    let c0 = ox + k * size + n.uniform(-3.0, 3.0);
    let (speckle, read) = (0.15, 1.5);
    let board = |x: f64, y: f64, b: f64| {
        let t = blurred_square(x, size, ox, b) * blurred_square(y, size, oy, b);
        0.5 * (white + black) + 0.5 * (white - black) * t
    };
    // Full-resolution R, G, B, then 4:2:0 chroma.
    let mut rgb = vec![[0.0f64; 3]; w * h];
    let (mut truth, mut lit) = (Vec::with_capacity(h), Vec::with_capacity(h));
    let mut sp = Vec::new();
    for r in 0..h {
        let (mu, s) = line_col(c0, slope, 0.0, h, r);
        let sr = sigma * (1.0 + s * s).sqrt();
        truth.push(mu);
        let y = r as f64;
        let centre_refl = board(mu, y, blur);
        lit.push(peak * centre_refl >= LIT_DN && mu > 8.0 && mu < w as f64 - 9.0);
        n.speckle_row(w, 2, &mut sp);
        for c in 0..w {
            let x = c as f64;
            let refl = board(x, y, blur);
            let seen = refl + sharpen * (refl - board(x, y, wide));
            let laser = if (x - mu).abs() < 8.0 * sr {
                peak * refl * integrated(x, mu, sr) * (1.0 + speckle * sp[c]).max(0.0)
            } else {
                0.0
            };
            let amb = ambient * seen.max(0.0);
            let leak = [1.0, 0.06, 0.03];
            let px = &mut rgb[r * w + c];
            for k in 0..3 {
                px[k] = n.sensor(amb + leak[k] * laser, read).clamp(0.0, 255.0);
            }
        }
    }
    // JPEG's colour transform (JFIF), chroma averaged over 2 x 2 blocks, back to R.
    let mut px = vec![0u8; w * h];
    for by in (0..h).step_by(2) {
        for bx in (0..w).step_by(2) {
            let mut cells = [(0usize, 0.0f64); 4];
            let (mut cr, mut m) = (0.0, 0);
            for dy in 0..2 {
                for dx in 0..2 {
                    let (yy, xx) = (by + dy, bx + dx);
                    if yy < h && xx < w {
                        let [r, g, b] = rgb[yy * w + xx];
                        let luma = (0.299 * r + 0.587 * g + 0.114 * b).round();
                        cr += 0.5 * r - 0.418_688 * g - 0.081_312 * b;
                        cells[m] = (yy * w + xx, luma);
                        m += 1;
                    }
                }
            }
            let cr = (cr / m as f64).round();
            for &(i, luma) in &cells[..m] {
                px[i] = (luma + 1.402 * cr).round().clamp(0.0, 255.0) as u8;
            }
        }
    }
    KindFrame {
        width: w,
        height: h,
        pixels: px,
        truth,
        lit,
        channel: Channel::Red,
        rgb: Vec::new(),
    }
}

fn lens_curved(w: usize, h: usize, seed: u64, n: &mut Noise) -> KindFrame {
    let sag = n.uniform(15.0, 40.0) * if n.rng.gen::<bool>() { 1.0 } else { -1.0 };
    let curv = sag / (0.5 * h as f64).powi(2);
    let slope = n.uniform(-0.3, 0.3);
    let c0 = 0.5 * w as f64 + n.uniform(-0.5, 0.5) * 0.2 * w as f64 - 0.5 * sag;
    let sigma = n.uniform(1.3, 2.2);
    let peak = n.uniform(140.0, 200.0);
    let texture = 0.35;
    let cell = n.uniform(12.0, 48.0);
    let ambient = 20.0;
    let (speckle, corr) = (0.2, 3);
    let tseed = mix(seed, 0x7E47, 0x3);
    let refl = |x: f64, y: f64| 1.0 + texture * value_noise(tseed, cell, x, y);
    let mut px = vec![0u8; w * h];
    let (mut truth, mut lit) = (Vec::with_capacity(h), Vec::with_capacity(h));
    let mut sp = Vec::new();
    for r in 0..h {
        let (mu, s) = line_col(c0, slope, curv, h, r);
        let t = (r as f64 - 0.5 * h as f64) / (0.5 * h as f64);
        // Defocus toward the ends of the region.
        let sr = sigma * (1.0 + 0.4 * t * t) * (1.0 + s * s).sqrt();
        truth.push(mu);
        let y = r as f64;
        lit.push(peak * refl(mu, y) >= LIT_DN && mu > 8.0 && mu < w as f64 - 9.0);
        n.speckle_row(w, corr, &mut sp);
        for c in 0..w {
            let x = c as f64;
            let rf = refl(x, y);
            let laser = if (x - mu).abs() < 8.0 * sr {
                peak * rf * integrated(x, mu, sr) * (1.0 + speckle * sp[c]).max(0.0)
            } else {
                0.0
            };
            px[r * w + c] = n
                .sensor(ambient * rf + laser, 2.0)
                .round()
                .clamp(0.0, 255.0) as u8;
        }
    }
    KindFrame {
        width: w,
        height: h,
        pixels: px,
        truth,
        lit,
        channel: Channel::Luma,
        rgb: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each kind shows what makes it that kind.
    #[test]
    fn each_kind_has_its_defining_trait() {
        let (w, h) = (320, 96);
        // White centre: R = G = B = 255 at the line's centre, so the plain colour difference
        // is near 0 there and high on either side of it.
        let f = render_kind(LineKind::SaturatedColour, w, h, 1);
        let (mut split, mut rows) = (0, 0);
        for r in 0..h {
            let c = f.truth[r].round() as usize;
            let diff = |x: usize| {
                let [r, g, b] = f.rgb[r * w + x].map(|v| v as u32);
                r.saturating_sub((g + b) / 2)
            };
            let side = (c - 8..c + 8).map(diff).max().unwrap();
            rows += 1;
            let white = (c - 1..=c + 1).any(|x| f.rgb[r * w + x] == [255; 3]);
            let dip = (c - 1..=c + 1).map(diff).min().unwrap();
            split += (white && dip < 30 && side > 60) as usize;
        }
        let c = f.truth[0].round() as usize;
        assert!(
            split * 10 >= rows * 8,
            "{split} of {rows} rows split; row 0: {:?}",
            &f.rgb[c - 8..c + 8]
        );
        // Wide: more than 20 px above half the row's peak.
        let f = render_kind(LineKind::WideSpeckled, w, h, 1);
        let row = &f.pixels[(h / 2) * w..(h / 2 + 1) * w];
        let max = *row.iter().max().unwrap();
        let wide = row
            .iter()
            .filter(|&&v| v as f64 > 0.5 * (max as f64 + 10.0))
            .count();
        assert!(wide >= 15, "{wide} px above half height");
        // Chessboard: away from the line, the red channel holds the board's squares.
        let f = render_kind(LineKind::Chessboard, w, h, 1);
        let row = &f.pixels[(h / 2) * w..(h / 2) * w + 100];
        let (lo, hi) = (row.iter().min().unwrap(), row.iter().max().unwrap());
        assert!(*hi as i32 - *lo as i32 > 40, "board contrast {lo}..{hi}");
        // Curved: the truth bends by the sagitta over the region.
        let f = render_kind(LineKind::LensCurved, w, h, 1);
        let mid = f.truth[h / 2] - 0.5 * (f.truth[0] + f.truth[h - 1]);
        assert!(mid.abs() > 5.0, "sagitta {mid}");
        assert!(f.lit.iter().filter(|&&l| l).count() > h / 2);
    }

    #[test]
    fn a_kind_is_the_same_for_a_seed_and_differs_between_seeds() {
        for k in LineKind::ALL {
            let a = render_kind(k, 160, 64, 5);
            assert_eq!(a.pixels, render_kind(k, 160, 64, 5).pixels, "{}", k.name());
            assert_ne!(a.pixels, render_kind(k, 160, 64, 6).pixels, "{}", k.name());
        }
    }
}
