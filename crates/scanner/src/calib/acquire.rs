//! Collecting calibration data through the scanner itself.
//!
//! A [`CalibrationRig`] puts a target in place and captures frames with the head still at a
//! slider position. [`DeviceRig`] does it with any [`Camera`] and [`Slider`] (the same code drives
//! real hardware and the simulator) and asks an [`Operator`] to place the targets: on hardware
//! a person putting the plate on spacers ([`ConsoleOperator`]), in the simulator a scene swap
//! ([`SimOperator`]). [`RenderRig`] renders frames directly (no devices, no real-time clock) for
//! tests and benchmarks whose point is the mathematics.

pub use super::data::{InsystemData, PlateObservation, StairFrame};
use super::CalibError;
use footscan_hal::{Camera, Frame, Slider, Timestamp};
use footscan_sim::camera::SceneHandle;
use footscan_sim::optics::Optics;
use footscan_sim::render::{NoiseConfig, Renderer, Scene};
use footscan_sim::targets::Staircase;
use footscan_targets::Placement;
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

/// A person at the scanner places the targets with their own hands: nothing to do here (the
/// guided procedure's [`Guide`](super::guided::Guide) tells them what to place and waits).
pub struct Person;

impl Operator for Person {
    fn place(&mut self, _target: &Target) -> Result<(), CalibError> {
        Ok(())
    }
}

/// What the simulator's operator may put on the glass instead of what was asked.
#[derive(Clone, Debug, PartialEq)]
pub enum Mistake {
    /// The plate on spacers of another height.
    Plate { height_mm: f64 },
    /// The staircase placed elsewhere.
    StaircaseAt(Placement),
    /// Nothing at all.
    Nothing,
    /// The staircase left on the glass.
    Staircase,
}

/// Mistakes the simulator's operator will make: the first time it is asked for a target it
/// puts the paired mistake there instead (once each, in order). Shared, so a test can add
/// mistakes to an opened rig.
#[derive(Clone, Default)]
pub struct Mistakes(Arc<std::sync::Mutex<Vec<(Target, Mistake)>>>);

impl Mistakes {
    pub fn push(&self, asked: Target, placed: Mistake) {
        self.0.lock().unwrap().push((asked, placed));
    }
    fn take(&self, asked: &Target) -> Option<Mistake> {
        let mut v = self.0.lock().unwrap();
        let k = v.iter().position(|(t, _)| t == asked)?;
        Some(v.remove(k).1)
    }
}

/// The simulator's operator: swaps the scene the simulated camera renders (making the
/// mistakes it was given).
pub struct SimOperator {
    handle: SceneHandle,
    staircase: Arc<Staircase>,
    pub mistakes: Mistakes,
}

impl SimOperator {
    pub fn new(handle: SceneHandle, staircase: Staircase) -> Self {
        SimOperator {
            handle,
            staircase: Arc::new(staircase),
            mistakes: Mistakes::default(),
        }
    }
}

impl Operator for SimOperator {
    fn place(&mut self, target: &Target) -> Result<(), CalibError> {
        let scene = match self.mistakes.take(target) {
            None => scene_of(target, &self.staircase),
            Some(Mistake::Plate { height_mm }) => Scene::Plate { height_mm },
            Some(Mistake::Nothing) => Scene::Empty,
            Some(Mistake::Staircase) => Scene::Surface(self.staircase.clone()),
            Some(Mistake::StaircaseAt(p)) => Scene::Surface(Arc::new(
                Staircase::new(self.staircase.geometry().clone(), p)
                    .map_err(|e| CalibError::Sim(e.to_string()))?,
            )),
        };
        self.handle.set(scene);
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
    /// Check the moves to `positions` (controller mm) against the controller's limits before
    /// anything moves.
    fn check_moves(&mut self, _positions: &[f64]) -> Result<(), CalibError> {
        Ok(())
    }
    /// Bring the devices back after a fault ended a step, so the step can be repeated.
    fn recover(&mut self) -> Result<(), CalibError> {
        Ok(())
    }
}

/// A camera, a slider and an operator: the scanner itself.
pub struct DeviceRig {
    pub camera: Box<dyn Camera>,
    pub slider: Box<dyn Slider>,
    pub operator: Box<dyn Operator>,
    pub feed_mm_min: f64,
    pub move_timeout: Duration,
    pub frame_timeout: Duration,
    /// The controller switches the laser: on while frames are taken, off after.
    pub laser: bool,
    /// Home after a fault (the controller has a homing cycle, `$22=1`).
    pub home_to_recover: bool,
    started: bool,
    laser_on: bool,
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
            laser: false,
            home_to_recover: false,
            started: false,
            laser_on: false,
        }
    }
}

impl DeviceRig {
    /// A slider error as the operator should read it: a controller in alarm (which answers
    /// no line, so the move itself only timed out) is reported as its alarm, named.
    fn named_slider_fault(&mut self, e: footscan_hal::HalError) -> footscan_hal::HalError {
        if matches!(e, footscan_hal::HalError::Alarm { .. }) {
            return e;
        }
        match self.slider.wait_idle(Duration::from_secs(1)) {
            Err(a @ footscan_hal::HalError::Alarm { .. }) => a,
            _ => e,
        }
    }
}

impl Drop for DeviceRig {
    fn drop(&mut self) {
        if self.laser_on {
            let _ = self.slider.laser(false);
        }
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
        let mut st = match self
            .slider
            .move_to(x_mm, self.feed_mm_min)
            .and_then(|()| self.slider.wait_idle(self.move_timeout))
        {
            Ok(st) => st,
            Err(e) => return Err(self.named_slider_fault(e).into()),
        };
        if self.laser && !self.laser_on {
            self.slider.laser(true)?;
            self.laser_on = true;
            st = self.slider.status()?;
        }
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

    fn check_moves(&mut self, positions: &[f64]) -> Result<(), CalibError> {
        let settings = self.slider.settings()?;
        self.home_to_recover = settings.get(&22).is_some_and(|&v| v != 0.0);
        check_controller(&settings, positions, self.feed_mm_min)
    }

    /// Reconnect the slider (a soft reset clears what the fault left) and home it when the
    /// controller has homing: after an alarm the position is not to be trusted. Without
    /// homing an alarm-locked controller stays locked, and the next move says so.
    fn recover(&mut self) -> Result<(), CalibError> {
        self.laser_on = false;
        self.slider.connect()?;
        if self.home_to_recover {
            self.slider.home(self.move_timeout)?;
        }
        Ok(())
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

/// The controller's limits against the moves: every position inside the travel `$130` when
/// soft limits are on (`$20=1`), the feed within `$110`. `settings` as `$$` lists them.
pub fn check_controller(
    settings: &footscan_hal::SliderSettings,
    positions: &[f64],
    feed_mm_min: f64,
) -> Result<(), CalibError> {
    if let Some(&max) = settings.get(&110) {
        if feed_mm_min > max + 1e-9 {
            return Err(CalibError::Plan(format!(
                "the calibration moves at scan.approach_feed_mm_min = {feed_mm_min} mm/min, \
                 above the controller's X max rate $110 = {max} mm/min"
            )));
        }
    }
    let soft = settings.get(&20).is_some_and(|&v| v != 0.0);
    if let (true, Some(&travel)) = (soft, settings.get(&130)) {
        if let Some(x) = positions.iter().find(|&&x| !(0.0..=travel).contains(&x)) {
            return Err(CalibError::Plan(format!(
                "the plan moves the head to x = {x} mm, outside the controller's travel \
                 0..{travel} mm ($130, soft limits on): change plate_x_mm, stair_start_mm, \
                 stair_end_mm or glass_positions_mm"
            )));
        }
    }
    Ok(())
}
