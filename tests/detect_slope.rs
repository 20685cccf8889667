//! Sloped and thin lines: a straight line crossing rows at 0 to 2.5 px per row, line sigma
//! 0.6 to 3 px (across the line), speckle and sensor noise. bezier-plus's smoothing along the
//! line must follow it at every slope (it is what beats the per-row baselines).

use footscan::detect::{build, DetectParams, LinePeak};
use footscan_hal::{Frame, Pixels, Timestamp};

/// A deterministic normal deviate stream (xorshift + Box-Muller).
struct Rng(u64);
impl Rng {
    fn u(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn n(&mut self) -> f64 {
        (-2.0 * self.u().ln()).sqrt() * (std::f64::consts::TAU * self.u()).cos()
    }
}

/// Line col(r) = c0 + slope r, Gaussian of `sigma` across the line, 8 DN ambient, peak 180 DN,
/// pixel-integrated (5 x 5 sub-samples), 15 % speckle (independent per pixel), read noise 2 DN
/// and shot noise at 40 e-/DN when `noisy`. Returns the frame and the true column per row.
fn sloped(w: usize, h: usize, slope: f64, sigma: f64, noisy: bool, seed: u64) -> (Frame, Vec<f64>) {
    let mut rng = Rng(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let c0 = 0.5 * w as f64 - 0.5 * slope * h as f64 + 0.37;
    let norm = (1.0 + slope * slope).sqrt();
    let mut px = vec![0u8; w * h];
    let truth: Vec<f64> = (0..h).map(|r| c0 + slope * r as f64).collect();
    for r in 0..h {
        let centre = truth[r];
        let lo = (centre - 8.0 * sigma * norm).floor().max(0.0) as usize;
        let hi = ((centre + 8.0 * sigma * norm).ceil() as usize).min(w - 1);
        for c in 0..w {
            let mut v = 0.0;
            if (lo..=hi).contains(&c) {
                for i in 0..5 {
                    for j in 0..5 {
                        let (x, y) = (
                            c as f64 - 0.4 + 0.2 * i as f64,
                            r as f64 - 0.4 + 0.2 * j as f64,
                        );
                        // Distance across the line.
                        let d = (x - c0 - slope * y) / norm;
                        v += (-d * d / (2.0 * sigma * sigma)).exp() / 25.0;
                    }
                }
                v *= 180.0;
            }
            if noisy {
                v *= (1.0 + 0.15 * rng.n()).max(0.0);
            }
            let mut total = 8.0 + v;
            if noisy {
                total += 2.0 * rng.n() + (total / 40.0).sqrt() * rng.n();
            }
            px[r * w + c] = total.round().clamp(0.0, 255.0) as u8;
        }
    }
    (
        Frame::new(
            0,
            Timestamp::default(),
            w as u32,
            h as u32,
            Pixels::Gray8(px),
        ),
        truth,
    )
}

/// RMS error of `name` over rows 8..h-8 (rows without a line count as 1 px).
fn rms(name: &str, f: &Frame, truth: &[f64]) -> f64 {
    let mut d = build(name, &DetectParams::default()).unwrap();
    let mut out = vec![LinePeak::NONE; truth.len()];
    d.detect(f, &mut out);
    let h = truth.len();
    let s: f64 = (8..h - 8)
        .map(|r| {
            if out[r].is_valid() {
                (out[r].col - truth[r]).powi(2).min(1.0)
            } else {
                1.0
            }
        })
        .sum();
    (s / (h - 16) as f64).sqrt()
}

#[test]
fn bezier_plus_keeps_its_advantage_on_sloped_lines() {
    let (w, h) = (512, 160);
    println!("slope sigma  bezier-plus    cog  ratio");
    for slope in [0.0, 0.5, 1.0, 1.5, 2.5] {
        for sigma in [1.0, 1.6, 3.0] {
            let (mut bp, mut cog) = (0.0, 0.0);
            for seed in 1..=3 {
                let (f, t) = sloped(w, h, slope, sigma, true, seed);
                bp += rms("bezier-plus", &f, &t) / 3.0;
                cog += rms("cog", &f, &t) / 3.0;
            }
            println!(
                "{slope:5.1} {sigma:5.1} {bp:12.4} {cog:6.4} {:6.2}",
                bp / cog
            );
            assert!(
                bp < 0.75 * cog,
                "slope {slope} sigma {sigma}: {bp} vs cog {cog}"
            );
        }
    }
}
