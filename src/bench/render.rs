//! The simulator's frame renderer: frames per second on one core.

use footscan::scan::ScanConfig;
use footscan_hal::Pixels;
use footscan_sim::foot::Foot;
use footscan_sim::render::{FrameTruth, Renderer, Scene};
use serde::Serialize;
use std::time::Instant;

#[derive(Clone, Debug, Serialize)]
pub struct RenderRow {
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub frames: u64,
    pub ms_per_frame: f64,
    pub fps_per_core: f64,
    /// Ground truth alone (root finding per row), without pixels.
    pub truth_ms_per_frame: f64,
}

/// Render `frames` frames sweeping the head over the scan range, for the foot, a plate and an
/// empty platform.
pub fn run(cfg: &ScanConfig, frames: u64) -> Result<Vec<RenderRow>, footscan::pipeline::BoxError> {
    let sim = &cfg.sim;
    let scenes = [
        ("foot", Scene::Foot(Foot::new(sim.foot.clone())?)),
        ("plate 10 mm", Scene::Plate { height_mm: 10.0 }),
        ("empty", Scene::Empty),
    ];
    let mut rows = Vec::new();
    for (name, scene) in scenes {
        let mut r = Renderer::new(sim.optics.clone(), sim.noise.clone(), scene, sim.seed)?;
        let (w, h) = (sim.optics.width, sim.optics.height);
        let n = frames.max(1);
        let xs: Vec<f64> = (0..n)
            .map(|k| {
                cfg.scan.start_mm + (cfg.scan.end_mm - cfg.scan.start_mm) * k as f64 / n as f64
            })
            .collect();
        let row = super::on_one_core(|| {
            let mut px = match sim.noise.format {
                footscan_hal::PixelFormat::Gray8 => Pixels::Gray8(vec![0; (w * h) as usize]),
                footscan_hal::PixelFormat::Gray16 => Pixels::Gray16(vec![0; (w * h) as usize]),
            };
            let mut truth = FrameTruth {
                slider_x: 0.0,
                rows: Vec::new(),
            };
            r.render_into(xs[0], 0, &mut px, &mut truth); // warm-up
            let t0 = Instant::now();
            for (k, &x) in xs.iter().enumerate() {
                r.render_into(x, k as u64, &mut px, &mut truth);
            }
            let full = t0.elapsed().as_secs_f64() / n as f64;
            let t1 = Instant::now();
            for &x in &xs {
                r.truth_into(x, &mut truth);
            }
            let truth_only = t1.elapsed().as_secs_f64() / n as f64;
            RenderRow {
                scene: name.to_string(),
                width: w,
                height: h,
                frames: n,
                ms_per_frame: full * 1e3,
                fps_per_core: 1.0 / full,
                truth_ms_per_frame: truth_only * 1e3,
            }
        });
        rows.push(row);
    }
    Ok(rows)
}

pub fn table(rows: &[RenderRow]) -> String {
    let mut s = format!(
        "{:<12} {:>10} {:>7} {:>12} {:>12} {:>14}\n",
        "scene", "size", "frames", "ms/frame", "fps/core", "truth ms/frame"
    );
    for r in rows {
        s += &format!(
            "{:<12} {:>10} {:>7} {:>12.3} {:>12.0} {:>14.3}\n",
            r.scene,
            format!("{}x{}", r.width, r.height),
            r.frames,
            r.ms_per_frame,
            r.fps_per_core,
            r.truth_ms_per_frame
        );
    }
    s
}
