//! Collecting calibration data through the scanner itself.
//!
//! A [`CalibrationRig`] puts a target in place and captures frames with the head still at a
//! slider position. [`DeviceRig`] does it with any [`Camera`] and [`Slider`] (the same code drives
//! real hardware and the simulator) and asks an [`Operator`] to place the targets: on hardware
//! a person putting the plate on spacers ([`ConsoleOperator`]), in the simulator a scene swap
//! ([`SimOperator`]). [`RenderRig`] renders frames directly (no devices, no real-time clock) for
//! tests and benchmarks whose point is the mathematics.

pub use super::data::{InsystemData, PlateObservation, StairFrame};
use super::plan::CalibrationPlan;
use super::CalibError;
use crate::detect::{Detector, LinePeak};
use footscan_hal::{Camera, Frame, Slider, Timestamp};
use footscan_sim::camera::SceneHandle;
use footscan_sim::optics::Optics;
use footscan_sim::render::{NoiseConfig, Renderer, Scene};
use footscan_sim::targets::Staircase;
use std::sync::Arc;
use std::time::Duration;

/// What the operator is asked to put on the glass.
#[derive(Clone, Debug, PartialEq)]
pub enum Target {
    /// The flat plate on spacers of this height (0: a matte sheet on the glass).
    Plate { height_mm: f64 },
    /// The staircase gauge block, anywhere in the middle of the glass, roughly along x.
    Staircase,
    /// Nothing.
    Empty,
}

impl std::fmt::Display for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Target::Plate { height_mm } => write!(f, "the plate at {height_mm} mm"),
            Target::Staircase => write!(f, "the staircase gauge block"),
            Target::Empty => write!(f, "an empty platform"),
        }
    }
}

/// Whoever puts the calibration targets on the glass.
pub trait Operator: Send {
    fn place(&mut self, target: &Target) -> Result<(), CalibError>;
}

/// A person at the scanner: prints what to do and waits for Enter.
pub struct ConsoleOperator;

impl Operator for ConsoleOperator {
    fn place(&mut self, target: &Target) -> Result<(), CalibError> {
        eprintln!("Put {target} on the glass, then press Enter.");
        let mut line = String::new();
        std::io::stdin()
            .read_line(&mut line)
            .map_err(|e| CalibError::Plan(format!("waiting for the operator: {e}")))?;
        Ok(())
    }
}

/// The simulator's operator: swaps the scene the simulated camera renders.
pub struct SimOperator {
    handle: SceneHandle,
    staircase: Arc<Staircase>,
}

impl SimOperator {
    pub fn new(handle: SceneHandle, staircase: Staircase) -> Self {
        SimOperator {
            handle,
            staircase: Arc::new(staircase),
        }
    }
}

impl Operator for SimOperator {
    fn place(&mut self, target: &Target) -> Result<(), CalibError> {
        self.handle.set(scene_of(target, &self.staircase));
        Ok(())
    }
}

fn scene_of(target: &Target, staircase: &Arc<Staircase>) -> Scene {
    match target {
        Target::Plate { height_mm } => Scene::Plate {
            height_mm: *height_mm,
        },
        Target::Staircase => Scene::Surface(staircase.clone()),
        Target::Empty => Scene::Empty,
    }
}

/// Puts targets in place and captures frames with the head still.
pub trait CalibrationRig {
    fn place(&mut self, target: &Target) -> Result<(), CalibError>;
    /// Move the head to `x_mm` (controller coordinates), wait until it is still, and hand `n`
    /// frames taken there to `sink`. Returns the slider position as the controller reports it.
    fn capture(
        &mut self,
        x_mm: f64,
        n: usize,
        sink: &mut dyn FnMut(&Frame),
    ) -> Result<f64, CalibError>;
}

/// A camera, a slider and an operator: the scanner itself.
pub struct DeviceRig {
    pub camera: Box<dyn Camera>,
    pub slider: Box<dyn Slider>,
    pub operator: Box<dyn Operator>,
    pub feed_mm_min: f64,
    pub move_timeout: Duration,
    pub frame_timeout: Duration,
    started: bool,
}

impl DeviceRig {
    pub fn new(
        camera: Box<dyn Camera>,
        slider: Box<dyn Slider>,
        operator: Box<dyn Operator>,
        feed_mm_min: f64,
    ) -> Self {
        let fps = camera.info().fps.max(1.0);
        DeviceRig {
            camera,
            slider,
            operator,
            feed_mm_min,
            move_timeout: Duration::from_secs(60),
            frame_timeout: Duration::from_secs_f64((10.0 / fps).max(1.0)),
            started: false,
        }
    }
}

impl Drop for DeviceRig {
    fn drop(&mut self) {
        let _ = self.camera.stop();
    }
}

impl CalibrationRig for DeviceRig {
    fn place(&mut self, target: &Target) -> Result<(), CalibError> {
        self.operator.place(target)
    }

    fn capture(
        &mut self,
        x_mm: f64,
        n: usize,
        sink: &mut dyn FnMut(&Frame),
    ) -> Result<f64, CalibError> {
        self.slider.move_to(x_mm, self.feed_mm_min)?;
        let st = self.slider.wait_idle(self.move_timeout)?;
        if !self.started {
            self.camera.start()?;
            self.started = true;
        }
        // A free-running camera may hand out a frame exposed before the head stopped (or
        // before the operator's change): use only frames exposed after the idle report.
        let still_since: Timestamp = st.timestamp;
        let mut got = 0;
        let mut skipped = 0;
        while got < n {
            let f = self.camera.next_frame(self.frame_timeout)?;
            if f.timestamp <= still_since {
                skipped += 1;
                if skipped > 1000 {
                    return Err(CalibError::Plan(
                        "the camera keeps delivering frames older than the slider's idle report"
                            .into(),
                    ));
                }
                continue;
            }
            sink(&f);
            got += 1;
        }
        Ok(st.x_mm)
    }
}

/// Frames rendered directly (no camera, no slider, no clock): for tests and benchmarks. The
/// physical head position is `slider_scale * x`.
pub struct RenderRig {
    renderer: Renderer,
    staircase: Arc<Staircase>,
    slider_scale: f64,
    next_index: u64,
}

impl RenderRig {
    pub fn new(
        optics: Optics,
        noise: NoiseConfig,
        seed: u64,
        staircase: Staircase,
        slider_scale: f64,
    ) -> Result<Self, CalibError> {
        let renderer = Renderer::new(optics, noise, Scene::Empty, seed)
            .map_err(|e| CalibError::Sim(e.to_string()))?;
        Ok(RenderRig {
            renderer,
            staircase: Arc::new(staircase),
            slider_scale,
            next_index: 0,
        })
    }
}

impl CalibrationRig for RenderRig {
    fn place(&mut self, target: &Target) -> Result<(), CalibError> {
        let r = &self.renderer;
        self.renderer = Renderer::new(
            r.optics().clone(),
            r.noise().clone(),
            scene_of(target, &self.staircase),
            r.seed(),
        )
        .map_err(|e| CalibError::Sim(e.to_string()))?;
        Ok(())
    }

    fn capture(
        &mut self,
        x_mm: f64,
        n: usize,
        sink: &mut dyn FnMut(&Frame),
    ) -> Result<f64, CalibError> {
        let o = self.renderer.optics();
        let (w, h) = (o.width, o.height);
        for _ in 0..n {
            let k = self.next_index;
            self.next_index += 1;
            let (pixels, _) = self.renderer.render(self.slider_scale * x_mm, k);
            sink(&Frame::new(k, Timestamp::default(), w, h, pixels));
        }
        Ok(x_mm)
    }
}

/// Progress callback: (what, done, total).
pub type Progress<'a> = &'a mut dyn FnMut(&str, usize, usize);

/// Acquire the plate at every height of the plan and the staircase pass.
pub fn acquire_insystem(
    rig: &mut dyn CalibrationRig,
    plan: &CalibrationPlan,
    detector: &mut dyn Detector,
    progress: Progress,
) -> Result<InsystemData, CalibError> {
    plan.validate()?;
    let stair_x = plan.stair_positions();
    let total = plan.plate_heights_mm.len() + stair_x.len();
    let mut done = 0;
    let mut size = (0u32, 0u32);
    let mut lines: Vec<LinePeak> = Vec::new();
    let mut plates = Vec::new();
    for &h in &plan.plate_heights_mm {
        progress(&format!("plate at {h} mm"), done, total);
        rig.place(&Target::Plate { height_mm: h })?;
        let mut per_frame: Vec<Vec<f64>> = Vec::new();
        rig.capture(plan.plate_x_mm, plan.frames_per_height, &mut |f| {
            size = (f.width, f.height);
            lines.clear();
            lines.resize(f.height as usize, LinePeak::NONE);
            detector.detect(f, &mut lines);
            per_frame.push(lines.iter().map(valid_col).collect());
        })?;
        plates.push(average_frames(h, &per_frame));
        done += 1;
    }
    progress("staircase", done, total);
    rig.place(&Target::Staircase)?;
    let mut stair = Vec::new();
    for &x in &stair_x {
        let mut col = Vec::new();
        let reported = rig.capture(x, 1, &mut |f| {
            lines.clear();
            lines.resize(f.height as usize, LinePeak::NONE);
            detector.detect(f, &mut lines);
            col = lines.iter().map(valid_col).collect();
        })?;
        stair.push(StairFrame {
            x_mm: reported,
            col,
        });
        done += 1;
        progress("staircase", done, total);
    }
    rig.place(&Target::Empty)?;
    Ok(InsystemData {
        width: size.0,
        height: size.1,
        plates,
        stair,
        staircase: plan.staircase.clone(),
    })
}

fn valid_col(l: &LinePeak) -> f64 {
    if l.is_valid() {
        l.col
    } else {
        f64::NAN
    }
}

/// Per-row mean and standard deviation over frames.
pub fn average_frames(height_mm: f64, frames: &[Vec<f64>]) -> PlateObservation {
    let rows = frames.first().map_or(0, Vec::len);
    let mut col = vec![f64::NAN; rows];
    let mut std = vec![f64::NAN; rows];
    for r in 0..rows {
        let v: Vec<f64> = frames
            .iter()
            .map(|f| f[r])
            .filter(|c| c.is_finite())
            .collect();
        if v.len() * 4 < frames.len() * 3 || v.len() < 2 {
            continue;
        }
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|c| (c - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
        col[r] = m;
        std[r] = var.sqrt();
    }
    PlateObservation {
        height_mm,
        frames: frames.len(),
        col,
        std,
    }
}
