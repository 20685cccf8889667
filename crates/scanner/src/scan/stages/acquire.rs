//! The source stage: frames from the camera, each labelled with the slider position at its
//! capture time (docs/method.md section 3.1, continuous mode).
//!
//! A poller thread owns the slider while the head moves and timestamps every status report;
//! each frame's X is interpolated between the two reports around its capture timestamp, so a
//! frame is never labelled with a position it was not taken at.

use crate::pipeline::{BoxError, Emitter, Source};
use crate::scan::error::{DeviceError, DeviceRole};
use crate::scan::item::{AcquiredFrame, FrameMeta, Item};
use crate::scan::{Devices, ScanCounters, ScanPlan};
use crossbeam_channel::{Receiver, RecvTimeoutError};
use footscan_hal::{
    Camera, DeviceFault, FaultKind, HalError, Slider, SliderState, SliderStatus, Timestamp,
};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

pub struct Acquire {
    devices: Option<Devices>,
    plan: ScanPlan,
    counters: Arc<ScanCounters>,
}

impl Acquire {
    pub fn new(devices: Devices, plan: ScanPlan, counters: Arc<ScanCounters>) -> Self {
        Acquire {
            devices: Some(devices),
            plan,
            counters,
        }
    }
}

/// Slider reports while the scan move runs; ends when the head is idle at the target.
enum Poll {
    Status(SliderStatus),
    Done,
    Failed(HalError),
}

fn poll_slider(
    slider: &mut dyn Slider,
    period: Duration,
    abort: &AtomicBool,
    tx: crossbeam_channel::Sender<Poll>,
) {
    let mut moved = false;
    loop {
        if abort.load(Ordering::Relaxed) {
            let _ = slider.stop();
            let _ = tx.send(Poll::Done);
            return;
        }
        let next = Timestamp::now() + period;
        match slider.status() {
            Ok(st) => {
                let _ = tx.send(Poll::Status(st));
                if st.state == SliderState::Alarm {
                    // The driver knows which alarm it was; wait_idle reports it.
                    let e = match slider.wait_idle(Duration::from_millis(50)) {
                        Err(e @ HalError::Alarm { .. }) => e,
                        _ => HalError::Alarm {
                            device: "slider".into(),
                            code: 0,
                            message: "controller entered the alarm state during the scan move"
                                .into(),
                        },
                    };
                    let _ = tx.send(Poll::Failed(e));
                    return;
                }
                moved |= st.state.is_moving();
                if moved && st.state == SliderState::Idle {
                    let _ = tx.send(Poll::Done);
                    return;
                }
            }
            Err(e) => {
                let _ = tx.send(Poll::Failed(e));
                return;
            }
        }
        next.sleep_until();
    }
}

/// Linear interpolation of X over timestamped reports.
struct Track {
    samples: VecDeque<(Timestamp, f64)>,
    /// The windows (their halves) of the last [`RECENT`] reports seen, kept or not: the
    /// narrowest is what an answer read at once takes now (it widens with a lasting load).
    recent: [f64; RECENT],
    seen: usize,
    /// Reports passed over for a late answer.
    skipped: u64,
}

impl Default for Track {
    fn default() -> Self {
        Track {
            samples: VecDeque::new(),
            recent: [f64::INFINITY; RECENT],
            seen: 0,
            skipped: 0,
        }
    }
}

const RECENT: usize = 16;
/// A report whose window is this much wider than the narrowest recent one was answered late.
const LATE_ANSWER_S: f64 = 0.002;
/// ... but it is taken all the same when the last one kept is this old: the frame waiting
/// for it must not wait long (the camera holds 4 frames, 80 ms at 50 fps).
const MAX_REPORT_GAP_S: f64 = 0.03;

impl Track {
    /// Keeps a report unless its answer was read late: a busy host that reads the answer
    /// 20 ms late puts the midpoint 10 ms late, 0.75 mm at a 75 mm/s scan. The reports on
    /// either side interpolate across the one passed over (the head moves at a steady feed).
    fn push(&mut self, s: &SliderStatus) {
        self.recent[self.seen % RECENT] = s.uncertainty_s;
        self.seen += 1;
        let narrowest = self.recent.iter().copied().fold(f64::INFINITY, f64::min);
        if let Some(&(last, _)) = self.samples.back() {
            if s.timestamp <= last {
                return;
            }
            if s.uncertainty_s > narrowest + LATE_ANSWER_S
                && s.timestamp.secs_after(last) < MAX_REPORT_GAP_S
            {
                self.skipped += 1;
                return;
            }
        }
        self.samples.push_back((s.timestamp, s.x_mm));
    }
    fn last_time(&self) -> Option<Timestamp> {
        self.samples.back().map(|s| s.0)
    }
    /// X at `t`, or None if `t` is outside the reports seen so far.
    fn at(&mut self, t: Timestamp) -> Option<f64> {
        // Keep two samples before t: frames arrive in time order.
        while self.samples.len() > 2 && self.samples[1].0 <= t {
            self.samples.pop_front();
        }
        let (t0, x0) = *self.samples.front()?;
        if t < t0 {
            return None;
        }
        for w in self.samples.iter().zip(self.samples.iter().skip(1)) {
            let ((ta, xa), (tb, xb)) = (*w.0, *w.1);
            if ta <= t && t <= tb {
                let span = tb.secs_after(ta);
                return Some(if span <= 0.0 {
                    xb
                } else {
                    xa + (xb - xa) * t.secs_after(ta) / span
                });
            }
        }
        if self.samples.len() == 1 && t == t0 {
            return Some(x0);
        }
        None
    }
}

impl Source<Item> for Acquire {
    fn run(&mut self, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Devices {
            mut camera,
            mut slider,
        } = self.devices.take().ok_or("acquire stage run twice")?;
        let plan = self.plan.clone();
        let sl = |e| DeviceError::hal(DeviceRole::Slider, e);
        slider
            .move_to(plan.start_mm, plan.approach_feed_mm_min)
            .map_err(sl)?;
        slider.wait_idle(plan.move_timeout).map_err(sl)?;
        let cam = |e| DeviceError::hal(DeviceRole::Camera, e);
        if plan.laser_off_ends {
            self.laser_off_frame(slider.as_mut(), camera.as_mut(), out, &plan)?;
        } else {
            camera.start().map_err(cam)?;
        }
        if plan.laser {
            slider.laser(true).map_err(sl)?;
        }
        // Taken after the laser came on: frames before it are never labelled (nor used).
        let before = slider.status().map_err(sl)?;
        slider.move_to(plan.end_mm, plan.feed_mm_min).map_err(sl)?;

        let abort = AtomicBool::new(false);
        let (tx, rx) = crossbeam_channel::unbounded();
        let result = std::thread::scope(|s| {
            let poller = std::thread::Builder::new()
                .name("slider-poll".into())
                .spawn_scoped(s, || {
                    poll_slider(slider.as_mut(), plan.poll_period, &abort, tx)
                })
                .expect("spawn slider poller");
            let r = self.frames(camera.as_mut(), &rx, before, out, &plan);
            if r.is_err() || out.is_cancelled() {
                abort.store(true, Ordering::Relaxed);
            }
            let _ = poller.join();
            r
        });
        let result = result.and_then(|()| {
            if plan.laser_off_ends && !out.is_cancelled() {
                slider.wait_idle(plan.move_timeout).map_err(sl)?;
                self.laser_off_frame(slider.as_mut(), camera.as_mut(), out, &plan)?;
            }
            Ok(())
        });
        if plan.laser {
            // Off after the scan, whatever happened (a failed scan leaves no laser shining).
            let _ = slider.laser(false);
        }
        let _ = camera.stop();
        result
    }
}

impl Acquire {
    /// Switch the laser off, take a frame at rest and pass it on marked laser-off (the camera
    /// is started if it is not streaming). The frame is the second stamped after the
    /// controller accepted the command: the first may have begun its exposure before.
    fn laser_off_frame(
        &self,
        slider: &mut dyn Slider,
        camera: &mut dyn Camera,
        out: &mut Emitter<Item>,
        plan: &ScanPlan,
    ) -> Result<(), BoxError> {
        let sl = |e| DeviceError::hal(DeviceRole::Slider, e);
        let cam = |e| DeviceError::hal(DeviceRole::Camera, e);
        slider.laser(false).map_err(sl)?;
        let off = Timestamp::now();
        let at = slider.status().map_err(sl)?;
        camera.start().map_err(cam)?;
        let mut after = 0;
        let frame = loop {
            let f = camera.next_frame(plan.frame_timeout).map_err(cam)?;
            if f.timestamp > off {
                after += 1;
                if after == 2 {
                    break f;
                }
            }
        };
        let meta = FrameMeta {
            index: 0,
            seq: frame.seq,
            timestamp: frame.timestamp,
            x_mm: at.x_mm,
        };
        let _ = out.emit(Item::Frame(AcquiredFrame {
            meta,
            frame,
            laser_off: true,
        }));
        Ok(())
    }
}

impl Acquire {
    fn frames(
        &self,
        camera: &mut dyn Camera,
        rx: &Receiver<Poll>,
        before: SliderStatus,
        out: &mut Emitter<Item>,
        plan: &ScanPlan,
    ) -> Result<(), BoxError> {
        let mut track = Track::default();
        track.push(&before);
        let mut done = false;
        let mut last_seq: Option<u64> = None;
        let mut last_x = f64::NEG_INFINITY;
        let mut index = 0u64;
        let min_advance = plan.step_mm * 0.05;
        while !out.is_cancelled() {
            let frame = camera
                .next_frame(plan.frame_timeout)
                .map_err(|e| DeviceError::hal(DeviceRole::Camera, e))?;
            if let Some(prev) = last_seq {
                let gap = frame.seq.saturating_sub(prev + 1);
                if gap > 0 {
                    out.dropped(gap);
                    self.counters.add_dropped(gap);
                }
            }
            last_seq = Some(frame.seq);
            // Wait for a report at or after this frame's capture time.
            while !done && track.last_time().is_none_or(|t| t < frame.timestamp) {
                match rx.recv_timeout(plan.move_timeout) {
                    Ok(Poll::Status(st)) => track.push(&st),
                    Ok(Poll::Done) => done = true,
                    Ok(Poll::Failed(e)) => {
                        return Err(DeviceError::hal(DeviceRole::Slider, e).into())
                    }
                    Err(RecvTimeoutError::Timeout) => {
                        return Err(DeviceError {
                            role: DeviceRole::Slider,
                            fault: Some(DeviceFault {
                                device: "slider".into(),
                                kind: FaultKind::Timeout,
                            }),
                            source: "no slider status report within the move timeout".into(),
                        }
                        .into())
                    }
                    Err(RecvTimeoutError::Disconnected) => done = true,
                }
            }
            let Some(x) = track.at(frame.timestamp) else {
                if done {
                    break; // taken after the move ended
                }
                continue; // before the first report
            };
            if x < last_x + min_advance {
                self.counters.add_stationary(1);
                if done {
                    break;
                }
                continue;
            }
            last_x = x;
            let meta = FrameMeta {
                index,
                seq: frame.seq,
                timestamp: frame.timestamp,
                x_mm: x,
            };
            index += 1;
            self.counters.add_frame();
            if out
                .emit(Item::Frame(AcquiredFrame {
                    meta,
                    frame,
                    laser_off: false,
                }))
                .is_err()
            {
                break;
            }
        }
        if track.skipped > 0 {
            tracing::debug!(
                "{} slider reports passed over: answered late",
                track.skipped
            );
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn st(t_ms: u64, x: f64) -> SliderStatus {
        SliderStatus {
            uncertainty_s: 0.0005,
            state: SliderState::Run,
            x_mm: x,
            feed_mm_min: 0.0,
            timestamp: Timestamp {
                nanos: t_ms * 1_000_000,
            },
        }
    }

    #[test]
    fn track_interpolates_between_reports() {
        let mut tr = Track::default();
        tr.push(&st(0, 0.0));
        tr.push(&st(10, 1.0));
        tr.push(&st(20, 3.0));
        let t = |ms: f64| Timestamp {
            nanos: (ms * 1e6) as u64,
        };
        assert_eq!(tr.at(t(5.0)), Some(0.5));
        assert_eq!(tr.at(t(15.0)), Some(2.0));
        assert_eq!(tr.at(t(25.0)), None);
        assert!((tr.at(t(19.0)).unwrap() - 2.8).abs() < 1e-12);
    }

    #[test]
    fn a_report_answered_late_is_passed_over() {
        let t = |ms: f64| Timestamp {
            nanos: (ms * 1e6) as u64,
        };
        let mut tr = Track::default();
        tr.push(&st(0, 0.0));
        tr.push(&st(10, 1.0));
        // Read 20 ms late: its midpoint says 15 ms for the position of 5 ms.
        tr.push(&SliderStatus {
            uncertainty_s: 0.0105,
            ..st(15, 0.5)
        });
        tr.push(&st(20, 2.0));
        assert_eq!(tr.skipped, 1);
        assert!((tr.at(t(15.0)).unwrap() - 1.5).abs() < 1e-12);
        // With no narrow answer for 30 ms, a wide one is taken.
        tr.push(&SliderStatus {
            uncertainty_s: 0.0105,
            ..st(25, 2.5)
        });
        tr.push(&SliderStatus {
            uncertainty_s: 0.0105,
            ..st(55, 5.5)
        });
        assert_eq!(tr.skipped, 2);
        assert!((tr.at(t(50.0)).unwrap() - 5.0).abs() < 1e-12);
        // A lasting load widens every answer: after 16 wide ones they are the norm again.
        for k in 0..16 {
            tr.push(&SliderStatus {
                uncertainty_s: 0.0105,
                ..st(60 + k, 6.0 + 0.1 * k as f64)
            });
        }
        let kept = tr.samples.len();
        tr.push(&SliderStatus {
            uncertainty_s: 0.0105,
            ..st(80, 8.0)
        });
        assert_eq!(tr.samples.len(), kept + 1);
    }
}
