//! A simulated camera: a [`footscan_hal::Camera`] that renders each frame at the slider's
//! true (physical) position at the frame's capture time, and logs the frame's ground truth.
//!
//! Timing: free-running at `fps` from [`Camera::start`]. Slot k of a stream started at t0 has
//! capture time (middle of exposure) t_k = t0 + (k - base) / fps, where `base` is the first
//! sequence number of the stream (0 for the first stream; a restarted stream continues the
//! numbering, so the truth log never sees a sequence number twice). `next_frame` sleeps until
//! the next slot, asks the [`PositionSource`] for the physical x at t_k, renders frame k (noise
//! index k) into a pooled buffer and returns it with `seq = k`, `timestamp = t_k`.
//! - Captured slots wait in a ring of [`RING_BUFFERS`] frames (the V4L2 driver's default
//!   buffer count, `[hardware.camera] buffers`), oldest first: a caller late by up to that
//!   many periods loses nothing; a slot captured while the ring is full is lost (sequence
//!   gap), as a V4L2 driver drops a frame that finds no free buffer.
//! - With [`NoiseConfig::drop_rate`](crate::render::NoiseConfig) > 0 a slot is lost with that
//!   probability, decided by a hash of (camera seed, k): deterministic. Slots whose head
//!   position lies in one of [`NoiseConfig::drop_x_mm`]'s ranges are lost too (a gap).
//! - If the next slot is further away than `timeout`, `next_frame` sleeps for `timeout` and
//!   returns [`HalError::Timeout`]; it never hangs.
//! - Exposure is stored only (it does not change the image). Gain is passed to the renderer:
//!   it multiplies the laser signal and the ambient level (see [`Renderer::set_gain`]).
//! - [`SimCamera::inject_unplug`] (or a [`CameraFaults`] handle from another thread) makes the
//!   next `next_frame` return [`HalError::Disconnected`] and stops the stream; while unplugged,
//!   `start` and `next_frame` keep failing with `Disconnected` until [`CameraFaults::replug`].
//! - What stands on the glass can change between frames (calibration: the operator puts the
//!   next target in place): [`SimCamera::set_scene`], or a [`SceneHandle`] from another owner;
//!   the next frame rendered shows the new scene.

use crate::optics::SimError;
use crate::render::{FrameTruth, Renderer, Scene};
use crate::{LaserSource, PositionSource};
use footscan_hal::{Camera, CameraInfo, Frame, FramePool, HalError, HalResult, Timestamp};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

/// Ground truth of every delivered frame, by sequence number. Cloning shares the log.
#[derive(Clone, Debug, Default)]
pub struct TruthLog(Arc<Mutex<BTreeMap<u64, FrameTruth>>>);

impl TruthLog {
    pub fn new() -> Self {
        Self::default()
    }

    fn lock(&self) -> MutexGuard<'_, BTreeMap<u64, FrameTruth>> {
        // A panic while holding the lock cannot leave the map inconsistent.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub fn insert(&self, seq: u64, truth: FrameTruth) {
        self.lock().insert(seq, truth);
    }

    /// Truth of frame `seq` (a copy).
    pub fn get(&self, seq: u64) -> Option<FrameTruth> {
        self.lock().get(&seq).cloned()
    }

    /// Physical slider x of frame `seq`.
    pub fn slider_x(&self, seq: u64) -> Option<f64> {
        self.lock().get(&seq).map(|t| t.slider_x)
    }

    pub fn len(&self) -> usize {
        self.lock().len()
    }

    pub fn is_empty(&self) -> bool {
        self.lock().is_empty()
    }

    /// Sequence numbers logged so far, ascending.
    pub fn seqs(&self) -> Vec<u64> {
        self.lock().keys().copied().collect()
    }

    /// Take everything logged so far, leaving the log empty.
    pub fn drain(&self) -> BTreeMap<u64, FrameTruth> {
        std::mem::take(&mut *self.lock())
    }

    pub fn clear(&self) {
        self.lock().clear();
    }
}

/// Changes the scene of a [`SimCamera`] that another owner holds; the next frame rendered
/// shows it. Cloning shares the handle.
#[derive(Clone, Debug, Default)]
pub struct SceneHandle(Arc<Mutex<Option<Scene>>>);

impl SceneHandle {
    /// Show `scene` from the next frame on.
    pub fn set(&self, scene: Scene) {
        *self.0.lock().unwrap_or_else(|e| e.into_inner()) = Some(scene);
    }

    fn take(&self) -> Option<Scene> {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).take()
    }
}

/// Fault injection for a [`SimCamera`] that another thread owns.
#[derive(Clone, Debug, Default)]
pub struct CameraFaults {
    unplugged: Arc<AtomicBool>,
}

impl CameraFaults {
    /// Simulate pulling the cable.
    pub fn unplug(&self) {
        self.unplugged.store(true, Ordering::SeqCst);
    }
    /// Plug it back in (then `start` works again).
    pub fn replug(&self) {
        self.unplugged.store(false, Ordering::SeqCst);
    }
    pub fn is_unplugged(&self) -> bool {
        self.unplugged.load(Ordering::SeqCst)
    }
}

#[derive(Clone, Copy, Debug)]
struct Stream {
    t0: Timestamp,
    base: u64,
    /// The first slot not yet captured.
    next: u64,
}

/// The simulated camera.
pub struct SimCamera {
    renderer: Renderer,
    fps: f64,
    position: Arc<dyn PositionSource>,
    /// None: the laser always shines.
    laser: Option<Arc<dyn LaserSource>>,
    seed: u64,
    pool: FramePool,
    name: String,
    exposure_us: u32,
    stream: Option<Stream>,
    /// Captured slots not yet delivered, oldest first (at most `buffers`).
    ring: std::collections::VecDeque<u64>,
    buffers: usize,
    next_seq: u64,
    truth: TruthLog,
    faults: CameraFaults,
    scene: SceneHandle,
    scratch: FrameTruth,
}

impl std::fmt::Debug for SimCamera {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimCamera")
            .field("name", &self.name)
            .field("fps", &self.fps)
            .field("seed", &self.seed)
            .field("stream", &self.stream)
            .finish_non_exhaustive()
    }
}

/// Frame buffers kept in the pool.
const POOL_BUFFERS: usize = 6;
/// Captured frames the camera holds for a late caller: the V4L2 driver's default.
pub const RING_BUFFERS: usize = 4;

impl SimCamera {
    /// `fps` must be in (0, 10000]; `seed` drives the frame-drop decisions (the image noise
    /// comes from the renderer's own seed and the frame's sequence number).
    pub fn new(
        renderer: Renderer,
        fps: f64,
        position: Arc<dyn PositionSource>,
        seed: u64,
    ) -> HalResult<Self> {
        if !(fps.is_finite() && fps > 0.0 && fps <= 10_000.0) {
            return Err(HalError::InvalidArgument {
                device: "sim-camera".into(),
                detail: format!("fps = {fps}: expected a number in (0, 10000]"),
            });
        }
        let o = renderer.optics();
        let pool = FramePool::new(o.width, o.height, renderer.noise().format, POOL_BUFFERS);
        Ok(SimCamera {
            renderer,
            fps,
            position,
            laser: None,
            seed,
            pool,
            name: "sim-camera".into(),
            exposure_us: 1000,
            stream: None,
            ring: std::collections::VecDeque::with_capacity(RING_BUFFERS),
            buffers: RING_BUFFERS,
            next_seq: 0,
            truth: TruthLog::new(),
            faults: CameraFaults::default(),
            scene: SceneHandle::default(),
            scratch: FrameTruth::default(),
        })
    }

    /// Render each frame with the laser as `laser` says at its capture time (the GRBL
    /// emulator's output, [`crate::grbl::GrblEmulator::laser_source`]).
    pub fn set_laser_source(&mut self, laser: Arc<dyn LaserSource>) {
        self.laser = Some(laser);
    }

    /// The shared ground-truth log (clone it before handing the camera away).
    pub fn truth_log(&self) -> TruthLog {
        self.truth.clone()
    }

    /// Make the next `next_frame` fail with `Disconnected` (see the module doc).
    pub fn inject_unplug(&self) {
        self.faults.unplug();
    }

    /// A handle to inject faults from another thread.
    pub fn faults(&self) -> CameraFaults {
        self.faults.clone()
    }

    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    /// Render `scene` from now on (same optics, noise, seed and gain).
    pub fn set_scene(&mut self, scene: Scene) -> Result<(), SimError> {
        let r = &self.renderer;
        let mut next = Renderer::new(r.optics().clone(), r.noise().clone(), scene, r.seed())?;
        next.set_gain(r.gain())?;
        self.renderer = next;
        Ok(())
    }

    /// A handle that changes the scene while someone else owns the camera.
    pub fn scene_handle(&self) -> SceneHandle {
        self.scene.clone()
    }

    pub fn fps(&self) -> f64 {
        self.fps
    }

    /// Hold `n` (at least 1) captured frames for a late caller instead of [`RING_BUFFERS`].
    pub fn set_ring_buffers(&mut self, n: usize) {
        self.buffers = n.max(1);
        self.ring.reserve(self.buffers);
    }

    /// Whether slot `k` is lost at capture (drop rate, or the head in a drop range).
    fn lost_at_capture(&self, k: u64, tk: Timestamp) -> bool {
        if self.slot_dropped(k) {
            return true;
        }
        let drops = &self.renderer.noise().drop_x_mm;
        !drops.is_empty() && {
            let x = self.position.physical_x(tk);
            drops.iter().any(|r| r[0] <= x && x <= r[1])
        }
    }

    fn disconnected(&self) -> HalError {
        HalError::Disconnected {
            device: self.name.clone(),
            reason: "simulated unplug".into(),
        }
    }

    fn slot_time(&self, s: &Stream, k: u64) -> Timestamp {
        s.t0 + Duration::from_secs_f64((k - s.base) as f64 / self.fps)
    }

    fn slot_dropped(&self, k: u64) -> bool {
        let p = self.renderer.noise().drop_rate;
        p > 0.0
            && (crate::render::mix(self.seed, k, 0xD809) >> 11) as f64 / (1u64 << 53) as f64 <= p
    }
}

impl Camera for SimCamera {
    fn info(&self) -> CameraInfo {
        let o = self.renderer.optics();
        CameraInfo {
            name: self.name.clone(),
            width: o.width,
            height: o.height,
            format: self.renderer.noise().format,
            fps: self.fps,
        }
    }

    fn start(&mut self) -> HalResult<()> {
        if self.faults.is_unplugged() {
            return Err(self.disconnected());
        }
        if self.stream.is_none() {
            self.ring.clear();
            self.stream = Some(Stream {
                t0: Timestamp::now(),
                base: self.next_seq,
                next: self.next_seq,
            });
        }
        Ok(())
    }

    fn stop(&mut self) -> HalResult<()> {
        self.stream = None;
        self.ring.clear();
        Ok(())
    }

    fn next_frame(&mut self, timeout: Duration) -> HalResult<Frame> {
        if self.faults.is_unplugged() {
            self.stream = None;
            return Err(self.disconnected());
        }
        let Some(mut s) = self.stream else {
            return Err(HalError::NotStreaming {
                device: self.name.clone(),
            });
        };
        let deadline = Timestamp::now() + timeout;
        loop {
            // Slots captured since the last look enter the ring while it has room.
            let now = Timestamp::now();
            while self.slot_time(&s, s.next) <= now {
                let k = s.next;
                s.next += 1;
                if self.ring.len() < self.buffers && !self.lost_at_capture(k, self.slot_time(&s, k))
                {
                    self.ring.push_back(k);
                }
            }
            self.next_seq = s.next;
            let Some(k) = self.ring.pop_front() else {
                let tk = self.slot_time(&s, s.next);
                if tk > deadline {
                    deadline.sleep_until();
                    self.stream = Some(s);
                    return Err(HalError::Timeout {
                        device: self.name.clone(),
                        what: "a frame".into(),
                        after: timeout,
                    });
                }
                tk.sleep_until();
                continue;
            };
            let tk = self.slot_time(&s, k);
            self.stream = Some(s);
            if let Some(scene) = self.scene.take() {
                self.set_scene(scene)
                    .map_err(|e| HalError::InvalidArgument {
                        device: self.name.clone(),
                        detail: format!("scene: {e}"),
                    })?;
            }
            let x = self.position.physical_x(tk);
            let lit = self.laser.as_ref().is_none_or(|l| l.laser_on(tk));
            let mut frame = self.pool.take(k, tk);
            self.renderer
                .render_into_lit(x, k, lit, &mut frame.pixels, &mut self.scratch);
            self.truth.insert(k, std::mem::take(&mut self.scratch));
            return Ok(frame);
        }
    }

    fn exposure_us(&self) -> u32 {
        self.exposure_us
    }

    fn set_exposure_us(&mut self, us: u32) -> HalResult<()> {
        if us == 0 {
            return Err(HalError::InvalidArgument {
                device: self.name.clone(),
                detail: "exposure_us = 0: expected at least 1".into(),
            });
        }
        self.exposure_us = us;
        Ok(())
    }

    fn gain(&self) -> f64 {
        self.renderer.gain()
    }

    fn set_gain(&mut self, gain: f64) -> HalResult<()> {
        self.renderer
            .set_gain(gain)
            .map_err(|e| HalError::InvalidArgument {
                device: self.name.clone(),
                detail: e.to_string(),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::Optics;
    use crate::render::{NoiseConfig, RowTruth, Scene};

    /// A small, fast camera (same geometry scaled down by 4).
    fn small_optics() -> Optics {
        Optics {
            width: 320,
            height: 256,
            f_px: 500.0,
            cx: 160.9,
            cy: 127.5,
            ..Optics::default()
        }
    }

    /// Head moving at a constant speed from a given instant.
    struct Linear {
        t0: Timestamp,
        x0: f64,
        v: f64,
    }

    impl PositionSource for Linear {
        fn physical_x(&self, at: Timestamp) -> f64 {
            self.x0 + self.v * at.secs_after(self.t0)
        }
    }

    fn camera(fps: f64, noise: NoiseConfig, pos: Arc<dyn PositionSource>) -> SimCamera {
        let r = Renderer::new(small_optics(), noise, Scene::Plate { height_mm: 5.0 }, 9).unwrap();
        SimCamera::new(r, fps, pos, 3).unwrap()
    }

    #[test]
    fn frames_arrive_at_the_frame_rate_with_truth_at_the_true_position() {
        let pos = Arc::new(Linear {
            t0: Timestamp::now(),
            x0: 10.0,
            v: 50.0,
        });
        let mut cam = camera(50.0, NoiseConfig::default(), pos.clone());
        let log = cam.truth_log();
        cam.start().unwrap();
        let start = Timestamp::now();
        let mut frames = Vec::new();
        for _ in 0..15 {
            frames.push(cam.next_frame(Duration::from_millis(500)).unwrap());
        }
        let elapsed = Timestamp::now().secs_after(start);
        assert!(
            elapsed > 0.26 && elapsed < 0.45,
            "15 frames at 50 fps took {elapsed}"
        );
        for (i, f) in frames.iter().enumerate() {
            assert_eq!(f.seq, i as u64, "consecutive sequence numbers");
            assert_eq!((f.width, f.height), (320, 256));
            if i > 0 {
                let dt = f.timestamp.secs_after(frames[i - 1].timestamp);
                assert!((dt - 0.02).abs() < 1e-6, "slot spacing {dt}");
            }
            let t = log.get(f.seq).unwrap();
            assert!((t.slider_x - pos.physical_x(f.timestamp)).abs() < 1e-9);
            let fresh = cam.renderer().truth(t.slider_x);
            assert_eq!(t, fresh);
            assert!(
                matches!(t.rows[128], RowTruth::Line { point, .. } if (point[0] - t.slider_x - 70.0).abs() < 0.1)
            );
        }
        assert_eq!(log.len(), 15);
        assert_eq!(log.drain().len(), 15);
        assert!(log.is_empty());
    }

    #[test]
    fn the_scene_changes_from_the_next_frame() {
        let mut cam = camera(
            200.0,
            NoiseConfig::noise_free(),
            Arc::new(crate::FixedPosition(0.0)),
        );
        let handle = cam.scene_handle();
        let log = cam.truth_log();
        cam.set_gain(1.5).unwrap();
        cam.start().unwrap();
        let z = |seq: u64| match log.get(seq).unwrap().rows[128] {
            RowTruth::Line { point, .. } => point[2],
            RowTruth::NoLine => f64::NAN,
        };
        let a = cam.next_frame(Duration::from_millis(500)).unwrap().seq;
        assert_eq!(z(a), 5.0);
        handle.set(Scene::Plate { height_mm: 12.0 });
        let b = cam.next_frame(Duration::from_millis(500)).unwrap().seq;
        assert_eq!(z(b), 12.0);
        assert_eq!(cam.gain(), 1.5, "gain survives the swap");
        cam.set_scene(Scene::Empty).unwrap();
        let c = cam.next_frame(Duration::from_millis(500)).unwrap().seq;
        assert!(z(c).is_nan());
        handle.set(Scene::Plate { height_mm: -3.0 });
        let e = cam.next_frame(Duration::from_millis(500)).unwrap_err();
        assert!(e.to_string().contains("plate.height_mm"), "{e}");
    }

    #[test]
    fn a_slow_consumer_sees_sequence_gaps() {
        let mut cam = camera(
            100.0,
            NoiseConfig::default(),
            Arc::new(crate::FixedPosition(0.0)),
        );
        cam.start().unwrap();
        let mut seqs = Vec::new();
        for _ in 0..14 {
            seqs.push(cam.next_frame(Duration::from_millis(200)).unwrap().seq);
            std::thread::sleep(Duration::from_millis(35));
        }
        // 3.5 slots a call: the ring fills within a few calls, then slots are lost.
        let gaps = seqs.windows(2).filter(|w| w[1] > w[0] + 1).count();
        assert!(gaps >= 5, "{seqs:?}");
        assert!(seqs.windows(2).all(|w| w[1] > w[0]));
        // The ring delivers the oldest frame it holds, as V4L2 does: a consumer that keeps
        // taking 35 ms a frame gets frames about four of its own calls old, never older.
        let f = cam.next_frame(Duration::from_millis(200)).unwrap();
        let age = Timestamp::now().secs_after(f.timestamp);
        assert!(
            age < (RING_BUFFERS + 1) as f64 * 0.035 + 0.02,
            "{age} s old"
        );
    }

    #[test]
    fn a_caller_late_within_the_ring_loses_nothing() {
        let mut cam = camera(
            100.0,
            NoiseConfig::default(),
            Arc::new(crate::FixedPosition(0.0)),
        );
        cam.start().unwrap();
        let mut seqs = vec![cam.next_frame(Duration::from_millis(200)).unwrap().seq];
        // 3.5 periods late: slots 1-3 wait in the ring (a V4L2 driver's 4 buffers).
        std::thread::sleep(Duration::from_millis(35));
        for _ in 0..8 {
            seqs.push(cam.next_frame(Duration::from_millis(200)).unwrap().seq);
        }
        assert_eq!(seqs, (0..9).collect::<Vec<u64>>());
        // With one buffer, the same lateness loses slots.
        let mut one = camera(
            100.0,
            NoiseConfig::default(),
            Arc::new(crate::FixedPosition(0.0)),
        );
        one.set_ring_buffers(1);
        one.start().unwrap();
        let a = one.next_frame(Duration::from_millis(200)).unwrap().seq;
        std::thread::sleep(Duration::from_millis(35));
        let b = one.next_frame(Duration::from_millis(200)).unwrap().seq;
        let c = one.next_frame(Duration::from_millis(200)).unwrap().seq;
        assert_eq!((a, b), (0, 1));
        assert!(c > 2, "slots 2 and 3 found the one buffer full: {c}");
    }

    #[test]
    fn drop_rate_loses_slots_deterministically() {
        let noise = NoiseConfig {
            drop_rate: 0.3,
            ..NoiseConfig::default()
        };
        let mut cam = camera(200.0, noise, Arc::new(crate::FixedPosition(0.0)));
        // The lost slots are a fixed function of (seed, slot).
        let lost: Vec<bool> = (0..2000).map(|k| cam.slot_dropped(k)).collect();
        let n = lost.iter().filter(|&&d| d).count();
        assert!((500..700).contains(&n), "{n} of 2000 lost at rate 0.3");
        assert_eq!(
            lost,
            (0..2000).map(|k| cam.slot_dropped(k)).collect::<Vec<_>>()
        );
        cam.start().unwrap();
        let seqs: Vec<u64> = (0..30)
            .map(|_| cam.next_frame(Duration::from_millis(500)).unwrap().seq)
            .collect();
        assert!(seqs.iter().all(|&k| !lost[k as usize]), "{seqs:?}");
        assert!(seqs.windows(2).any(|w| w[1] > w[0] + 1), "{seqs:?}");
    }

    #[test]
    fn errors_not_streaming_timeout_and_unplug() {
        let mut cam = camera(
            2.0,
            NoiseConfig::default(),
            Arc::new(crate::FixedPosition(0.0)),
        );
        assert!(matches!(
            cam.next_frame(Duration::from_millis(10)),
            Err(HalError::NotStreaming { .. })
        ));
        cam.start().unwrap();
        let f = cam.next_frame(Duration::from_millis(100)).unwrap();
        assert_eq!(f.seq, 0);
        let t = Timestamp::now();
        let e = cam.next_frame(Duration::from_millis(20)).unwrap_err();
        assert!(e.is_timeout(), "{e}");
        let waited = Timestamp::now().secs_after(t);
        assert!((0.019..0.2).contains(&waited), "{waited}");
        // Unplug from another handle.
        let faults = cam.faults();
        faults.unplug();
        assert!(cam
            .next_frame(Duration::from_millis(10))
            .unwrap_err()
            .is_disconnect());
        assert!(cam.start().unwrap_err().is_disconnect());
        faults.replug();
        cam.start().unwrap();
        let g = cam.next_frame(Duration::from_millis(100)).unwrap();
        assert!(g.seq > f.seq, "numbering continues across restarts");
        cam.inject_unplug();
        assert!(cam
            .next_frame(Duration::from_millis(10))
            .unwrap_err()
            .is_disconnect());
        // Controls.
        cam.set_gain(2.0).unwrap();
        assert_eq!(cam.gain(), 2.0);
        assert!(cam.set_gain(0.0).is_err());
        cam.set_exposure_us(500).unwrap();
        assert_eq!(cam.exposure_us(), 500);
        assert!(cam.set_exposure_us(0).is_err());
        assert_eq!(cam.info().width, 320);
        assert!(SimCamera::new(
            Renderer::new(small_optics(), NoiseConfig::default(), Scene::Empty, 0).unwrap(),
            0.0,
            Arc::new(crate::FixedPosition(0.0)),
            0
        )
        .is_err());
    }
}
