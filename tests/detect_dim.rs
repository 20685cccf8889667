//! A dim line on a dark board, as a JPEG camera delivers it: a line 11-15 DN above a background
//! of 0, every 8x8 block passed through the DCT and quantised with JPEG's luminance table. The
//! block quantisation leaves the background at exactly 0 almost everywhere, so the row's noise
//! measures 0 and the contrast the automatic threshold asks for must follow that noise, not a
//! fixed 20 DN. Noise-only frames (a blank frame, dark read noise through the same quantisation,
//! plain read noise of 2 DN) must still give no row.

use footscan::detect::{self, DetectParams, LinePeak};
use footscan_hal::{Frame, Pixels, Timestamp};

const W: usize = 640;
const H: usize = 480;

/// JPEG's luminance quantisation table (ITU T.81 Annex K), quality 50.
const Q50: [u16; 64] = [
    16, 11, 10, 16, 24, 40, 51, 61, 12, 12, 14, 19, 26, 58, 60, 55, 14, 13, 16, 24, 40, 57, 69, 56,
    14, 17, 22, 29, 51, 87, 80, 62, 18, 22, 37, 56, 68, 109, 103, 77, 24, 35, 55, 64, 81, 104, 113,
    92, 49, 64, 78, 87, 103, 121, 120, 101, 72, 92, 95, 98, 112, 100, 103, 99,
];

/// The table at a JPEG quality (libjpeg's scaling).
fn table(quality: u32) -> [f64; 64] {
    let s = if quality < 50 {
        5000 / quality
    } else {
        200 - 2 * quality
    };
    Q50.map(|q| ((q as u32 * s + 50) / 100).clamp(1, 255) as f64)
}

/// Each 8x8 block through the forward DCT, quantisation at `quality`, the inverse DCT, then
/// rounding and clamping to 0..255 as a decoder does.
fn jpeg_blocks(img: &[f64], quality: u32) -> Vec<u8> {
    let q = table(quality);
    let c = |k: usize| if k == 0 { (0.5f64).sqrt() } else { 1.0 };
    let mut basis = [[0.0f64; 8]; 8];
    for (k, b) in basis.iter_mut().enumerate() {
        for (x, v) in b.iter_mut().enumerate() {
            *v = 0.5 * c(k) * (((2 * x + 1) * k) as f64 * std::f64::consts::PI / 16.0).cos();
        }
    }
    let mut out = vec![0u8; W * H];
    for by in (0..H).step_by(8) {
        for bx in (0..W).step_by(8) {
            let px = |y: usize, x: usize| img[(by + y) * W + bx + x] - 128.0;
            let mut coef = [0.0f64; 64];
            for v in 0..8 {
                for u in 0..8 {
                    let mut s = 0.0;
                    for y in 0..8 {
                        for x in 0..8 {
                            s += basis[v][y] * basis[u][x] * px(y, x);
                        }
                    }
                    coef[v * 8 + u] = (s / q[v * 8 + u]).round() * q[v * 8 + u];
                }
            }
            for y in 0..8 {
                for x in 0..8 {
                    let mut s = 0.0;
                    for v in 0..8 {
                        for u in 0..8 {
                            s += basis[v][y] * basis[u][x] * coef[v * 8 + u];
                        }
                    }
                    out[(by + y) * W + bx + x] = (s + 128.0).round().clamp(0.0, 255.0) as u8;
                }
            }
        }
    }
    out
}

/// Deterministic standard normal deviates (splitmix64 and Box-Muller), so the frames are the
/// same on every run without a random-number crate.
struct Gauss(u64);

impl Gauss {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// The line's true column in row `r`: slanted and gently curved, so its sub-pixel phase sweeps.
fn truth(r: usize) -> f64 {
    let t = r as f64 / H as f64;
    300.0 + 40.0 * t + 12.0 * (t - 0.5).powi(2)
}

/// A frame: a Gaussian line of `peak_dn` (sigma `sigma` px, pixel-integrated) over 0, read noise
/// `read_dn`, then JPEG blocks at `quality` (None: rounded only).
fn frame(peak_dn: f64, sigma: f64, read_dn: f64, quality: Option<u32>, seed: u64) -> Vec<u8> {
    let mut g = Gauss(seed);
    let mut img = vec![0.0f64; W * H];
    let erf = |x: f64| libm::erf(x);
    let k = sigma * std::f64::consts::SQRT_2;
    let norm = (2.0 * std::f64::consts::PI).sqrt() * sigma;
    for r in 0..H {
        let c = truth(r);
        for x in 0..W {
            let d = x as f64 - c;
            let line = if peak_dn > 0.0 && d.abs() < 8.0 * sigma {
                // Pixel-integrated: the mean of the Gaussian over [x - 0.5, x + 0.5].
                peak_dn * norm * 0.5 * (erf((d + 0.5) / k) - erf((d - 0.5) / k))
            } else {
                0.0
            };
            let n = if read_dn > 0.0 {
                read_dn * g.normal()
            } else {
                0.0
            };
            img[r * W + x] = line + n;
        }
    }
    match quality {
        Some(q) => jpeg_blocks(&img, q),
        None => img
            .iter()
            .map(|&v| v.round().clamp(0.0, 255.0) as u8)
            .collect(),
    }
}

/// Rows found by the default detector, and the RMS error of their columns (px).
fn detect(px: Vec<u8>, name: &str) -> (usize, f64) {
    let mut det = detect::build(name, &DetectParams::default()).unwrap();
    let f = Frame::new(
        0,
        Timestamp::default(),
        W as u32,
        H as u32,
        Pixels::Gray8(px),
    );
    let mut out = vec![LinePeak::NONE; H];
    det.detect(&f, &mut out);
    let (mut n, mut sq) = (0, 0.0);
    for (r, p) in out.iter().enumerate() {
        if p.is_valid() {
            n += 1;
            sq += (p.col - truth(r)).powi(2);
        }
    }
    (n, (sq / n.max(1) as f64).sqrt())
}

#[test]
fn a_dim_jpeg_line_on_a_dark_board_is_found() {
    for (peak, quality) in [(11.0, 75), (13.0, 85), (15.0, 90), (12.0, 95)] {
        let px = frame(peak, 1.6, 0.0, Some(quality), 1);
        let top = px.iter().copied().max().unwrap();
        let zeros = px.iter().filter(|&&v| v == 0).count() as f64 / px.len() as f64;
        for name in ["bezier-plus", "cog"] {
            let (n, rms) = detect(px.clone(), name);
            println!(
                "peak {peak} DN q{quality} (max {top} DN, {:.0} % zeros) {name}: {n}/{H} rows, \
                 rms {rms:.3} px",
                100.0 * zeros
            );
            assert!(
                n as f64 >= 0.98 * H as f64,
                "{name} peak {peak}: {n}/{H} rows"
            );
            assert!(rms < 0.35, "{name} peak {peak}: rms {rms:.3} px");
        }
    }
}

#[test]
fn a_dim_line_under_dark_read_noise_is_found() {
    // Weak read noise that the quantisation mostly erases: the line is still 10x above it.
    let px = frame(13.0, 1.6, 0.6, Some(85), 2);
    let (n, rms) = detect(px, "bezier-plus");
    println!("peak 13 DN, read 0.6 DN, q85: {n}/{H} rows, rms {rms:.3} px");
    assert!(n as f64 >= 0.98 * H as f64, "{n}/{H} rows");
    assert!(rms < 0.35, "rms {rms:.3} px");
}

#[test]
fn noise_only_frames_give_no_rows() {
    let cases: [(&str, Vec<u8>); 5] = [
        ("blank", vec![0u8; W * H]),
        ("blank at 40 DN", vec![40u8; W * H]),
        (
            "dark read noise 0.6 DN, q85",
            frame(0.0, 1.6, 0.6, Some(85), 3),
        ),
        ("read noise 2 DN, q75", frame(0.0, 1.6, 2.0, Some(75), 4)),
        ("read noise 2 DN, raw", frame(0.0, 1.6, 2.0, None, 5)),
    ];
    for (what, px) in cases {
        for name in ["bezier-plus", "cog"] {
            let (n, _) = detect(px.clone(), name);
            println!("{what} {name}: {n} rows");
            assert_eq!(n, 0, "{what}, {name}: {n} rows on a frame without a line");
        }
    }
}
