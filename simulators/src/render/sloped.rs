//! A straight laser line at a chosen slope, for the detector benches: the scenes of the
//! [`super::Renderer`] give slopes only as the geometry happens to make them, and draw the
//! profile along the row; here the line crosses rows at exactly `slope` px per row with the
//! Gaussian of `line_sigma_px` across the line (so wider along the row when sloped), under the
//! same noise model as the renderer (speckle with its correlation, shot and read noise).

use super::{NoiseConfig, Speckle};
use rand::SeedableRng;
use rand_distr_free::normal;
use rand_xoshiro::Xoshiro256PlusPlus;

/// Box-Muller without a distribution crate.
mod rand_distr_free {
    use rand::Rng;
    pub fn normal(rng: &mut impl Rng) -> f64 {
        let u: f64 = rng.gen::<f64>().max(1e-300);
        let v: f64 = rng.gen();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// A `w` x `h` Gray8 frame of the line col(r) = c0 + `slope` r through the middle, and the
/// true column of each row. Pixel values integrate the line over the pixel (5 x 5 samples);
/// `noise.enabled = false` gives the exact integral plus ambient, rounded.
pub fn render_sloped_line(
    w: usize,
    h: usize,
    slope: f64,
    noise: &NoiseConfig,
    seed: u64,
) -> (Vec<u8>, Vec<f64>) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x510E_D11E);
    let sigma = noise.line_sigma_px;
    // A fractional start so rows sweep every subpixel offset.
    let c0 = 0.5 * w as f64 - 0.5 * slope * h as f64 + 0.37;
    let norm = (1.0 + slope * slope).sqrt();
    let truth: Vec<f64> = (0..h).map(|r| c0 + slope * r as f64).collect();
    let mut px = vec![0u8; w * h];
    let mut speckle = Speckle::new(noise.speckle_corr_px);
    let read2 = noise.read_noise_dn * noise.read_noise_dn;
    for r in 0..h {
        let reach = 8.0 * sigma * norm + slope;
        let lo = (truth[r] - reach).floor().max(0.0) as usize;
        let hi = ((truth[r] + reach).ceil().max(0.0) as usize).min(w - 1);
        if noise.enabled {
            speckle.start(|| normal(&mut rng));
        }
        for c in 0..w {
            let mut s = 0.0;
            if (lo..=hi).contains(&c) {
                for i in 0..5 {
                    for j in 0..5 {
                        let x = c as f64 - 0.4 + 0.2 * i as f64;
                        let y = r as f64 - 0.4 + 0.2 * j as f64;
                        let d = (x - c0 - slope * y) / norm;
                        s += (-d * d / (2.0 * sigma * sigma)).exp();
                    }
                }
                s *= noise.peak_dn / 25.0;
            }
            let v = if noise.enabled {
                let z1 = if s > 1e-3 {
                    speckle.next(normal(&mut rng))
                } else {
                    0.0
                };
                let mean = noise.ambient_dn + s * (1.0 + noise.speckle * z1).max(0.0);
                let shot = if noise.electrons_per_dn > 0.0 {
                    mean.max(0.0) / noise.electrons_per_dn
                } else {
                    0.0
                };
                mean + (shot + read2).sqrt() * normal(&mut rng)
            } else {
                noise.ambient_dn + s
            };
            px[r * w + c] = v.round().clamp(0.0, 255.0) as u8;
        }
    }
    (px, truth)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_free_line_peaks_on_its_truth_at_every_slope() {
        for slope in [0.0, 1.0, 2.5] {
            let noise = NoiseConfig {
                line_sigma_px: 1.0,
                ..NoiseConfig::noise_free()
            };
            let (px, truth) = render_sloped_line(256, 40, slope, &noise, 1);
            for (r, t) in truth.iter().enumerate() {
                let row = &px[r * 256..(r + 1) * 256];
                let max = (0..256).max_by_key(|&c| row[c]).unwrap();
                assert!((max as f64 - t).abs() <= 0.6, "slope {slope} row {r}");
                assert_eq!(row[0], 8, "ambient away from the line");
            }
        }
    }

    #[test]
    fn correlated_speckle_is_correlated_along_the_row() {
        // A wide flat line: the speckle dominates; neighbours agree when correlated.
        let lag1 = |corr: f64| {
            let noise = NoiseConfig {
                line_sigma_px: 40.0,
                speckle: 0.5,
                speckle_corr_px: corr,
                read_noise_dn: 0.0,
                electrons_per_dn: 0.0,
                peak_dn: 100.0,
                ..NoiseConfig::default()
            };
            let (px, _) = render_sloped_line(200, 50, 0.0, &noise, 3);
            let (mut sxy, mut sxx) = (0.0, 0.0);
            for r in 0..50 {
                let row: Vec<f64> = px[r * 200 + 90..r * 200 + 110]
                    .iter()
                    .map(|&v| v as f64 - 108.0)
                    .collect();
                for k in 0..19 {
                    sxy += row[k] * row[k + 1];
                    sxx += row[k] * row[k];
                }
            }
            sxy / sxx
        };
        let (indep, corr) = (lag1(0.0), lag1(4.0));
        assert!(
            indep.abs() < 0.15,
            "independent speckle: lag-1 correlation {indep}"
        );
        assert!(corr > 0.6, "4 px speckle: lag-1 correlation {corr}");
    }
}
