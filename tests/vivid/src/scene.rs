//! The frames pushed through the loop: the simulator's laser line over the parametric foot,
//! with the frame id in the first rows, and their ground truth.

use crate::code;
use footscan_hal::{PixelFormat, Pixels};
use footscan_sim::foot::{Foot, FootParams};
use footscan_sim::optics::Optics;
use footscan_sim::render::{FrameTruth, NoiseConfig, Renderer, Scene};

/// Distinct images in the cycle (frame id k shows image k % CYCLE).
pub const CYCLE: u32 = 16;
const SEED: u64 = 7;

/// The simulated scanner scaled to `width` x `height` (focal length scaled with the width so
/// the laser line stays in the image; principal point near the centre).
pub fn optics(width: u32, height: u32) -> Optics {
    let d = Optics::default();
    let s = width as f64 / d.width as f64;
    Optics {
        width,
        height,
        f_px: d.f_px * s,
        cx: width as f64 / 2.0 + 3.7 * s,
        cy: height as f64 / 2.0 - 2.1 * s,
        ..d
    }
}

/// Renders the frame of any id, independently of any other instance.
pub struct Frames {
    renderer: Renderer,
    width: usize,
}

impl Frames {
    pub fn new(width: u32, height: u32) -> Self {
        let foot = Foot::new(FootParams::default()).expect("default foot");
        let noise = NoiseConfig {
            format: PixelFormat::Gray8,
            ..NoiseConfig::default()
        };
        let renderer = Renderer::new(optics(width, height), noise, Scene::Foot(foot), SEED)
            .expect("valid optics");
        Frames {
            renderer,
            width: width as usize,
        }
    }

    /// Head position of image `j`: the line sweeps the foot from heel to toes.
    fn slider_x(j: u32) -> f64 {
        60.0 + 14.0 * j as f64
    }

    /// Frame `id` in `format` (GREY, RGB3 or YUYV), packed rows, id code included, and its
    /// truth. Colour frames: a red laser over a grey checkerboard of 16 px squares (30 and
    /// 90 DN) that a red-minus-others channel cancels: R = board + v, G = board + v / 16,
    /// B = board + v / 32 with v the monochrome frame.
    pub fn render_format(&mut self, id: u32, format: &[u8; 4]) -> (Vec<u8>, FrameTruth) {
        let (grey, truth) = self.render(id);
        if format == b"GREY" {
            return (grey, truth);
        }
        let w = self.width;
        let h = grey.len() / w;
        let mut rgb = vec![0u8; w * h * 3];
        for (i, &v) in grey.iter().enumerate() {
            let (x, y) = (i % w, i / w);
            let board = if (x / 16 + y / 16) % 2 == 0 {
                30u32
            } else {
                90
            };
            let v = v as u32;
            let px = [board + v, board + v / 16, board + v / 32].map(|c| c.min(255) as u8);
            rgb[3 * i..3 * i + 3].copy_from_slice(&px);
        }
        match format {
            b"RGB3" => {
                code::write_id_rgb(&mut rgb, w, id);
                (rgb, truth)
            }
            b"YUYV" => {
                let mut yuyv = crate::yuyv::from_rgb(&rgb, w, h);
                code::write_id_yuyv(&mut yuyv, w, id);
                (yuyv, truth)
            }
            other => panic!("no frames in {}", String::from_utf8_lossy(other)),
        }
    }

    /// The image and truth of frame `id` (noise drawn for image `id % CYCLE`), id code included.
    pub fn render(&mut self, id: u32) -> (Vec<u8>, FrameTruth) {
        let j = id % CYCLE;
        let (px, truth) = self.renderer.render(Self::slider_x(j), j as u64);
        let Pixels::Gray8(mut v) = px else {
            unreachable!("Gray8 configured")
        };
        code::write_id(&mut v, self.width, id);
        (v, truth)
    }
}
