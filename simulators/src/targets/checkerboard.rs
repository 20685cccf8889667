//! Checkerboard images for the OpenCV reference calibration: a printed board at a 3D pose above
//! the glass, seen by the scanner's camera under a lamp, optionally with the laser line where
//! the laser plane meets the board, and exact ground truth for the corners and the line. The
//! board and its pose ([`Checkerboard`], [`BoardPose`]) are described in `footscan_targets`,
//! which calibration reads too; this file renders them.
//!
//! # Geometry
//! Board coordinates (u, v) in mm, inner corner (i, j) at `(i * square, j * square)`; the
//! squares cover `u in [-square, inner_cols * square]`, `v in [-square, inner_rows * square]`
//! (square (a, b) = (floor(u / square), floor(v / square)) is black when a + b is even), with a
//! white margin of `margin_mm` around them. A [`BoardPose`] places the board in the world:
//! `P = origin + R (u, v, 0)`, `R = Rz Ry Rx` of `rotation_deg`. The camera and laser are the
//! general model of [`crate::optics`] with the head at physical slider position X.
//!
//! # Rendering
//! Pixel (c, r) covers `[c - 0.5, c + 0.5] x [r - 0.5, r + 0.5]`. The pixel-corner lattice is
//! undistorted once per renderer (Newton, to 1e-15), intersected with the board plane per shot,
//! and a pixel's albedo is the mean over 16 x 16 sub-samples (a sheared grid, so that edges
//! along either axis are resolved to 1/256 px) wherever its four corners disagree
//! or a checker corner is within 2 px (elsewhere the pixel is uniform); sub-samples take board
//! coordinates bilinearly from the lattice (error ~1e-6 px). A pixel's signal is
//! `lamp_dn * albedo` (white 0.9, black 0.06, nothing off the board) plus the laser line: per
//! image row the exact column mu where the laser/board line crosses the row centre, drawn as a
//! pixel-integrated Gaussian of `line_sigma_px` and amplitude `peak_dn * albedo` at that point.
//! Then `ambient_dn` is added everywhere and the noise of [`NoiseConfig`] applied (speckle on
//! the laser signal, shot and read noise, rounding and clipping), deterministic in
//! (seed, frame index).

use crate::optics::{rotation_zyx_deg, Optics, Projector, SimError};
use crate::render::NoiseConfig;
use footscan_hal::{PixelFormat, Pixels};
use footscan_targets::{BoardPose, Checkerboard};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

/// Albedo of the white squares and margin.
pub const WHITE: f64 = 0.9;
/// Albedo of the black squares.
pub const BLACK: f64 = 0.06;

/// Albedo of the print at board coordinates: [`WHITE`] or [`BLACK`] by the board's pattern
/// (`Checkerboard::is_black`), None off the board.
pub fn board_albedo(board: &Checkerboard, u: f64, v: f64) -> Option<f64> {
    board
        .is_black(u, v)
        .map(|black| if black { BLACK } else { WHITE })
}

/// Lighting of one shot.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    /// Signal of albedo 1 under the lamp (DN).
    pub lamp_dn: f64,
    /// Laser on.
    pub laser: bool,
}

/// The laser line in one image row.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LinePoint {
    /// Exact column at the row centre.
    pub col: f64,
    /// The world point imaged there (on the board and on the laser plane).
    pub point: [f64; 3],
}

/// One rendered image with its ground truth.
#[derive(Clone, Debug)]
pub struct BoardShot {
    pub pixels: Pixels,
    /// Image position [col, row] of every inner corner in [`Checkerboard::corners`] order;
    /// None when it projects outside the image.
    pub corners: Vec<Option<[f64; 2]>>,
    /// Per image row: the laser line on the board (None without laser or off the board).
    pub line: Vec<Option<LinePoint>>,
}

/// Renders checkerboard shots for one camera.
#[derive(Debug)]
pub struct BoardRenderer {
    optics: Optics,
    proj: Projector,
    noise: NoiseConfig,
    seed: u64,
    /// Undistorted normalised camera coordinates of the pixel corners, (w + 1) x (h + 1).
    lattice: Vec<[f64; 2]>,
}

const SUB: usize = 16;

impl BoardRenderer {
    pub fn new(optics: Optics, noise: NoiseConfig, seed: u64) -> Result<Self, SimError> {
        optics.validate()?;
        noise.validate()?;
        let proj = optics.projector();
        let (w, h) = (optics.width as usize, optics.height as usize);
        let mut lattice = Vec::with_capacity((w + 1) * (h + 1));
        for r in 0..=h {
            for c in 0..=w {
                let xd = (c as f64 - 0.5 - proj.cx) / proj.f_px;
                let yd = (r as f64 - 0.5 - proj.cy) / proj.f_px;
                lattice.push(undistort(&proj, xd, yd));
            }
        }
        Ok(BoardRenderer {
            optics,
            proj,
            noise,
            seed,
            lattice,
        })
    }

    pub fn optics(&self) -> &Optics {
        &self.optics
    }

    pub fn noise(&self) -> &NoiseConfig {
        &self.noise
    }

    /// Render `board` at `pose` with the head at `physical_x`; `frame_index` selects the noise.
    pub fn render(
        &self,
        board: &Checkerboard,
        pose: &BoardPose,
        physical_x: f64,
        light: Lighting,
        frame_index: u64,
    ) -> BoardShot {
        let (w, h) = (self.optics.width as usize, self.optics.height as usize);
        let corners: Vec<Option<[f64; 2]>> = board
            .corners()
            .iter()
            .map(|&[u, v]| {
                self.proj
                    .project(physical_x, pose.world(u, v))
                    .filter(|p| p[0] >= -0.5 && p[0] <= w as f64 - 0.5)
                    .filter(|p| p[1] >= -0.5 && p[1] <= h as f64 - 0.5)
            })
            .collect();
        let albedo = self.albedo_image(board, pose, physical_x, &corners);
        let line = if light.laser {
            self.line_truth(board, pose, physical_x)
        } else {
            vec![None; h]
        };
        // Expected signal, then noise.
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(crate::render::mix(
            self.seed,
            frame_index,
            0xB0A2_D001,
        ));
        let n = &self.noise;
        let mut laser = vec![0.0f64; w * h];
        let reach = (6.0 * n.line_sigma_px).ceil() + 1.0;
        for (r, lp) in line.iter().enumerate() {
            let Some(lp) = lp else { continue };
            let (u, v) = board_coords(pose, lp.point);
            let a = n.peak_dn * board_albedo(board, u, v).unwrap_or(0.0);
            add_gaussian(
                &mut laser[r * w..(r + 1) * w],
                lp.col,
                n.line_sigma_px,
                a,
                reach,
            );
        }
        let (scale, max) = match n.format {
            PixelFormat::Gray8 => (1.0, 255.0),
            PixelFormat::Gray16 => (257.0, 65535.0),
        };
        let values = albedo.iter().zip(&laser).map(|(&alb, &las)| {
            let v = if n.enabled {
                let las = if las > 0.0 {
                    las * (1.0 + n.speckle * gauss(&mut rng)).max(0.0)
                } else {
                    0.0
                };
                let mean = n.ambient_dn + light.lamp_dn * alb + las;
                let shot = if n.electrons_per_dn > 0.0 {
                    mean.max(0.0) / n.electrons_per_dn
                } else {
                    0.0
                };
                mean + (shot + n.read_noise_dn * n.read_noise_dn).sqrt() * gauss(&mut rng)
            } else {
                n.ambient_dn + light.lamp_dn * alb + las
            };
            (v * scale).round().clamp(0.0, max)
        });
        let pixels = match n.format {
            PixelFormat::Gray8 => Pixels::Gray8(values.map(|v| v as u8).collect()),
            PixelFormat::Gray16 => Pixels::Gray16(values.map(|v| v as u16).collect()),
        };
        BoardShot {
            pixels,
            corners,
            line,
        }
    }

    /// Mean albedo of every pixel.
    fn albedo_image(
        &self,
        board: &Checkerboard,
        pose: &BoardPose,
        x: f64,
        corners: &[Option<[f64; 2]>],
    ) -> Vec<f64> {
        let (w, h) = (self.optics.width as usize, self.optics.height as usize);
        let rcam = &self.proj.r;
        let c = [x, 0.0, -self.proj.d_mm];
        let rb = rotation_zyx_deg(pose.rotation_deg);
        let nb = [rb[0][2], rb[1][2], rb[2][2]];
        let o = pose.origin_mm;
        let num = nb[0] * (o[0] - c[0]) + nb[1] * (o[1] - c[1]) + nb[2] * (o[2] - c[2]);
        // Board coordinates of the lattice (NaN where the ray misses the plane).
        let uv: Vec<[f64; 2]> = self
            .lattice
            .iter()
            .map(|&[xn, yn]| {
                let d = [
                    rcam[0][0] * xn + rcam[0][1] * yn + rcam[0][2],
                    rcam[1][0] * xn + rcam[1][1] * yn + rcam[1][2],
                    rcam[2][0] * xn + rcam[2][1] * yn + rcam[2][2],
                ];
                let den = nb[0] * d[0] + nb[1] * d[1] + nb[2] * d[2];
                let t = num / den;
                if !(den.abs() > 1e-12 && t > 0.0) {
                    return [f64::NAN; 2];
                }
                let q = [
                    c[0] + t * d[0] - o[0],
                    c[1] + t * d[1] - o[1],
                    c[2] + t * d[2] - o[2],
                ];
                [
                    rb[0][0] * q[0] + rb[1][0] * q[1] + rb[2][0] * q[2],
                    rb[0][1] * q[0] + rb[1][1] * q[1] + rb[2][1] * q[2],
                ]
            })
            .collect();
        // Pixels near a checker corner or a board corner are always sub-sampled.
        let mut flagged = vec![false; w * h];
        let [u0, u1, v0, v1] = board.extent();
        let outer = [[u0, v0], [u1, v0], [u0, v1], [u1, v1]]
            .map(|[u, v]| self.proj.project(x, pose.world(u, v)));
        for p in corners.iter().copied().chain(outer).flatten() {
            let (pc, pr) = (p[0].round() as i64, p[1].round() as i64);
            for r in pr - 2..=pr + 2 {
                for cc in pc - 2..=pc + 2 {
                    if (0..h as i64).contains(&r) && (0..w as i64).contains(&cc) {
                        flagged[r as usize * w + cc as usize] = true;
                    }
                }
            }
        }
        let lw = w + 1;
        let alb = |p: [f64; 2]| {
            if p[0].is_nan() {
                0.0
            } else {
                board_albedo(board, p[0], p[1]).unwrap_or(0.0)
            }
        };
        let mut out = vec![0.0; w * h];
        for r in 0..h {
            for cc in 0..w {
                let q = [
                    uv[r * lw + cc],
                    uv[r * lw + cc + 1],
                    uv[(r + 1) * lw + cc],
                    uv[(r + 1) * lw + cc + 1],
                ];
                let a = q.map(alb);
                let uniform = a.iter().all(|&v| v == a[0]) && !flagged[r * w + cc];
                out[r * w + cc] = if uniform || q.iter().any(|p| p[0].is_nan()) {
                    (a[0] + a[1] + a[2] + a[3]) / 4.0
                } else {
                    let mut sum = 0.0;
                    // A sheared grid: edges along either axis are resolved to 1/SUB^2.
                    let s = SUB as f64;
                    for i in 0..SUB {
                        for j in 0..SUB {
                            let fx = (j as f64 + (i as f64 + 0.5) / s) / s;
                            let fy = (i as f64 + (j as f64 + 0.5) / s) / s;
                            let lerp = |k: usize| {
                                let top = q[0][k] + (q[1][k] - q[0][k]) * fx;
                                let bot = q[2][k] + (q[3][k] - q[2][k]) * fx;
                                top + (bot - top) * fy
                            };
                            sum += alb([lerp(0), lerp(1)]);
                        }
                    }
                    sum / (SUB * SUB) as f64
                };
            }
        }
        out
    }

    /// Exact laser line on the board per row.
    fn line_truth(&self, board: &Checkerboard, pose: &BoardPose, x: f64) -> Vec<Option<LinePoint>> {
        let h = self.optics.height as usize;
        let w = self.optics.width as f64;
        let mut out = vec![None; h];
        // Laser plane n_l . p = X + L with n_l = (1, -tan a, -tan b); board p = o + u e_u + v e_v.
        let rb = rotation_zyx_deg(pose.rotation_deg);
        let eu = [rb[0][0], rb[1][0], rb[2][0]];
        let ev = [rb[0][1], rb[1][1], rb[2][1]];
        let nl = [1.0, -self.proj.tan_a, -self.proj.tan_b];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let (al, be) = (dot(nl, eu), dot(nl, ev));
        let ga = x + self.proj.l_mm - dot(nl, pose.origin_mm);
        let norm = (al * al + be * be).sqrt();
        if norm < 1e-12 {
            return out;
        }
        // Line in board coordinates: (u, v) = p0 + t dir.
        let p0 = [al * ga / (norm * norm), be * ga / (norm * norm)];
        let dir = [-be / norm, al / norm];
        // Clip t to the board extent.
        let [u0, u1, v0, v1] = board.extent();
        let (mut t0, mut t1) = (f64::NEG_INFINITY, f64::INFINITY);
        for (p, d, lo, hi) in [(p0[0], dir[0], u0, u1), (p0[1], dir[1], v0, v1)] {
            if d.abs() < 1e-15 {
                if p < lo || p > hi {
                    return out;
                }
            } else {
                let (a, b) = ((lo - p) / d, (hi - p) / d);
                t0 = t0.max(a.min(b));
                t1 = t1.min(a.max(b));
            }
        }
        if t1 <= t0 {
            return out;
        }
        let at = |t: f64| {
            let (u, v) = (p0[0] + t * dir[0], p0[1] + t * dir[1]);
            let p = pose.world(u, v);
            self.proj.project(x, p).map(|img| (img, p))
        };
        let n = 2000;
        let mut prev: Option<(f64, [f64; 2])> = None;
        for k in 0..=n {
            let t = t0 + (t1 - t0) * k as f64 / n as f64;
            let Some((img, _)) = at(t) else {
                prev = None;
                continue;
            };
            if let Some((tp, ip)) = prev {
                let (ra, rb2) = (ip[1], img[1]);
                let lo = ra.min(rb2).ceil().max(0.0) as i64;
                let hi = ra.max(rb2).floor().min(h as f64 - 1.0) as i64;
                for row in lo..=hi {
                    // Bisection on row(t) - row over [tp, t].
                    let (mut a, mut b) = (tp, t);
                    let fa = ra - row as f64;
                    for _ in 0..60 {
                        let m = 0.5 * (a + b);
                        let Some((im, _)) = at(m) else { break };
                        if (im[1] - row as f64) * fa > 0.0 {
                            a = m;
                        } else {
                            b = m;
                        }
                    }
                    if let Some((im, p)) = at(0.5 * (a + b)) {
                        if im[0] >= -0.5 && im[0] <= w - 0.5 && out[row as usize].is_none() {
                            out[row as usize] = Some(LinePoint {
                                col: im[0],
                                point: p,
                            });
                        }
                    }
                }
            }
            prev = Some((t, img));
        }
        out
    }
}

/// Board (u, v) of a world point on the board.
fn board_coords(pose: &BoardPose, p: [f64; 3]) -> (f64, f64) {
    let rb = rotation_zyx_deg(pose.rotation_deg);
    let q = [
        p[0] - pose.origin_mm[0],
        p[1] - pose.origin_mm[1],
        p[2] - pose.origin_mm[2],
    ];
    (
        rb[0][0] * q[0] + rb[1][0] * q[1] + rb[2][0] * q[2],
        rb[0][1] * q[0] + rb[1][1] * q[1] + rb[2][1] * q[2],
    )
}

/// Invert the Brown-Conrady distortion of `proj` by Newton's method.
fn undistort(proj: &Projector, xd: f64, yd: f64) -> [f64; 2] {
    let (mut x, mut y) = (xd, yd);
    for _ in 0..30 {
        let [fx, fy] = proj.distort(x, y);
        let (ex, ey) = (fx - xd, fy - yd);
        if ex.abs() < 1e-15 && ey.abs() < 1e-15 {
            break;
        }
        // Numerical Jacobian is plenty here (smooth, near identity).
        let e = 1e-7;
        let [ax, ay] = proj.distort(x + e, y);
        let [bx, by] = proj.distort(x, y + e);
        let (j11, j21, j12, j22) = ((ax - fx) / e, (ay - fy) / e, (bx - fx) / e, (by - fy) / e);
        let det = j11 * j22 - j12 * j21;
        x -= (j22 * ex - j12 * ey) / det;
        y -= (-j21 * ex + j11 * ey) / det;
    }
    [x, y]
}

/// Add `a * integral of exp(-(u - mu)^2 / (2 sigma^2))` over each pixel of `row`.
fn add_gaussian(row: &mut [f64], mu: f64, sigma: f64, a: f64, reach: f64) {
    let k = a * sigma * (std::f64::consts::PI / 2.0).sqrt();
    let inv = 1.0 / (sigma * std::f64::consts::SQRT_2);
    let first = (mu - reach).floor().max(0.0) as usize;
    let last = ((mu + reach).ceil().max(0.0) as usize).min(row.len().saturating_sub(1));
    if last < first {
        return;
    }
    let mut e_lo = libm::erf((first as f64 - 0.5 - mu) * inv);
    for (c, v) in row.iter_mut().enumerate().take(last + 1).skip(first) {
        let e_hi = libm::erf((c as f64 + 0.5 - mu) * inv);
        *v += k * (e_hi - e_lo);
        e_lo = e_hi;
    }
}

/// A standard normal variate (Box-Muller).
fn gauss(rng: &mut Xoshiro256PlusPlus) -> f64 {
    let u1: f64 = rng.gen::<f64>().max(1e-300);
    let u2: f64 = rng.gen();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> Optics {
        Optics {
            width: 320,
            height: 256,
            f_px: 500.0,
            cx: 160.9,
            cy: 127.5,
            ..Optics::default()
        }
    }

    fn flat_pose(z: f64) -> BoardPose {
        BoardPose {
            origin_mm: [-40.0, -25.0, z],
            rotation_deg: [0.0, 0.0, 0.0],
        }
    }

    #[test]
    fn corners_and_line_truth_are_consistent_with_the_optics() {
        let o = small();
        let r = BoardRenderer::new(o.clone(), NoiseConfig::noise_free(), 1).unwrap();
        let board = Checkerboard::default();
        let pose = BoardPose {
            origin_mm: [-35.0, -30.0, 20.0],
            rotation_deg: [10.0, -15.0, 5.0],
        };
        let shot = r.render(
            &board,
            &pose,
            -30.0,
            Lighting {
                lamp_dn: 100.0,
                laser: true,
            },
            0,
        );
        let proj = o.projector();
        for (c, uv) in shot.corners.iter().zip(board.corners()) {
            let p = proj.project(-30.0, pose.world(uv[0], uv[1])).unwrap();
            assert_eq!(*c, Some(p));
        }
        let mut n = 0;
        for (row, lp) in shot.line.iter().enumerate() {
            let Some(lp) = lp else { continue };
            n += 1;
            let img = proj.project(-30.0, lp.point).unwrap();
            assert!((img[1] - row as f64).abs() < 1e-8 && (img[0] - lp.col).abs() < 1e-12);
            assert!((proj.laser_x(-30.0, lp.point[1], lp.point[2]) - lp.point[0]).abs() < 1e-9);
            let nb = pose.normal();
            let q = [0, 1, 2].map(|k| lp.point[k] - pose.origin_mm[k]);
            assert!((nb[0] * q[0] + nb[1] * q[1] + nb[2] * q[2]).abs() < 1e-9);
        }
        assert!(n > 100, "line rows {n}");
    }

    #[test]
    fn edges_are_antialiased_at_the_right_place() {
        // Flat board at 0 mm, ideal optics: a vertical square edge at u = 0 lies at world
        // x = -40 (origin) and column cx + F (x - X) / D.
        let o = Optics {
            k1: 0.0,
            k2: 0.0,
            camera_tilt_deg: [0.0; 3],
            ..small()
        };
        let r = BoardRenderer::new(o.clone(), NoiseConfig::noise_free(), 1).unwrap();
        let board = Checkerboard {
            margin_mm: 8.0,
            ..Checkerboard::default()
        };
        let pose = flat_pose(0.0);
        let x = -0.1;
        let lamp = 200.0;
        let light = Lighting {
            lamp_dn: lamp,
            laser: false,
        };
        let shot = r.render(&board, &pose, x, light, 0);
        let Pixels::Gray8(px) = &shot.pixels else {
            panic!("Gray8 expected")
        };
        // Edge between square (-1, 0) (white, u < 0) and (0, 0) (black) at world x = -40.
        let e = o.cx + o.f_px * (-40.0 - x) / o.d_mm;
        let row = (o.cy + o.f_px * (-25.0 + 6.0) / o.d_mm).round() as usize;
        let p = e.round() as usize;
        let f = e - (p as f64 - 0.5);
        let ambient = NoiseConfig::noise_free().ambient_dn;
        let expect = ambient + lamp * (WHITE * f + BLACK * (1.0 - f));
        let got = px[row * o.width as usize + p] as f64;
        assert!(
            (got - expect).abs() <= 1.0,
            "got {got} expect {expect} f {f}"
        );
        // Uniform pixels either side.
        let white = px[row * o.width as usize + p - 3] as f64;
        let black = px[row * o.width as usize + p + 3] as f64;
        assert!((white - (ambient + lamp * WHITE)).abs() <= 0.5, "{white}");
        assert!((black - (ambient + lamp * BLACK)).abs() <= 0.5, "{black}");
    }
}
