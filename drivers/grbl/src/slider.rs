//! [`GrblSlider`]: the [`Slider`] implementation, on top of the link (serial port, lines)
//! and the answer tracker (which line an answer belongs to).
//!
//! This layer knows what a scanner wants from the controller: connect and reconnect
//! (bringing a controller that kept moving to rest before the reset), homing with a timeout
//! that aborts the cycle, moves, jogs, feed hold and resume, stop, status polling on absolute
//! slots, settings. How a line is sent and its answer awaited is in `exchange.rs`.

use crate::link::Link;
use crate::message::{banner_version, StatusReport};
use crate::settings::{BuildInfo, GrblSettings};
use crate::tracker::{GrblStats, LineKind, Tracker};
use crate::wait::WaitPolicy;
use footscan_hal::{
    HalError, HalResult, Slider, SliderInfo, SliderSettings, SliderState, SliderStatus,
};
use std::time::{Duration, Instant};

/// Driver settings.
#[derive(Clone, Debug, PartialEq)]
pub struct GrblConfig {
    pub baud: u32,
    /// How long a command may go unanswered (and a `?` without a report) before
    /// [`HalError::Timeout`]. A motion line that waits for planner room keeps waiting while the
    /// controller reports motion.
    pub response_timeout: Duration,
    /// Wait for the banner after the soft reset in `connect` and `stop`. Boards that reset on
    /// port open (Arduino DTR) need the bootloader's ~2 s on top.
    pub reset_timeout: Duration,
    /// The homing timeout an application passes to [`Slider::home`] (see
    /// [`GrblSlider::home_configured`]).
    pub homing_timeout: Duration,
    /// Status polling period of `wait_idle`, the feed hold and jog cancel waits, and
    /// [`GrblSlider::poll_status`].
    pub poll_interval: Duration,
    /// Serial RX buffer of the controller for character counting; replaced by the value in
    /// `$I`'s `[OPT:...]` when the controller reports one.
    pub rx_buffer: usize,
    /// The output the laser is wired to; None: the laser is not switched by the controller.
    pub laser: Option<LaserOutput>,
    /// How much longer than its settings (`$110`, `$120`) a controller may take to stop: the
    /// stopping deadlines are this times the planned deceleration, plus `response_timeout`.
    /// 2 covers real boards; grbl-sim on a loaded 2-core machine runs at 20-40 % of real time
    /// and needs 5.
    pub motion_slack: f64,
}

/// The controller output that switches the laser (GRBL boards have a spindle enable/PWM pin
/// and coolant pins; a line laser sits on whichever is free).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LaserOutput {
    /// `M3 S<power>` on, `M5` off. With laser mode on (`$32=1`) GRBL 1.1h lights the spindle
    /// output at rest only in a G1/G2/G3 motion mode (after a reset the mode is G0, and
    /// `M3 S..` then leaves it dark), so in laser mode "on" is sent as `G1 F.. M3 S..`: the
    /// laser is lit at rest in both modes.
    Spindle { power: f64 },
    /// `M8` on, `M9` off (flood coolant pin).
    Flood,
    /// `M7` on, `M9` off (mist coolant pin: only in GRBL builds with `ENABLE_M7`).
    Mist,
}

impl LaserOutput {
    /// The g-code line switching the laser on or off; `laser_mode` is GRBL's `$32`.
    pub fn command(self, on: bool, laser_mode: bool) -> String {
        match (self, on) {
            // G1 without axis words only sets the motion mode; it needs a feed rate (error:22
            // without one after a reset). The F is modal only: every move sends its own.
            (LaserOutput::Spindle { power }, true) if laser_mode => {
                format!("G1F{LASER_MODE_FEED}M3S{power}")
            }
            (LaserOutput::Spindle { power }, true) => format!("M3S{power}"),
            (LaserOutput::Spindle { .. }, false) => "M5".into(),
            (LaserOutput::Flood, true) => "M8".into(),
            (LaserOutput::Mist, true) => "M7".into(),
            (LaserOutput::Flood | LaserOutput::Mist, false) => "M9".into(),
        }
    }
}

/// The feed that `G1` carries when laser mode needs the motion mode set at rest (any valid
/// value: no motion follows from it).
const LASER_MODE_FEED: u32 = 100;

/// Acceleration assumed for the stopping deadlines when the controller did not list `$120`
/// (GRBL's default, 10 mm/s²: the slowest plausible stop).
const DEFAULT_ACCEL: f64 = 10.0;
/// Maximum rate assumed likewise (GRBL's default `$110`, 500 mm/min).
const DEFAULT_MAX_RATE: f64 = 500.0;

impl Default for GrblConfig {
    fn default() -> Self {
        GrblConfig {
            baud: 115_200,
            response_timeout: Duration::from_secs(2),
            reset_timeout: Duration::from_secs(5),
            homing_timeout: Duration::from_secs(60),
            poll_interval: Duration::from_millis(20),
            rx_buffer: 128,
            laser: None,
            motion_slack: 2.0,
        }
    }
}

/// A GRBL 1.1 controller driving the scan axis (X) of the slider.
///
/// All I/O is synchronous on the caller's thread: every call writes what it needs, then reads
/// and routes incoming lines until its own answer arrives or its deadline passes. Lines are
/// routed as GRBL interleaves them: `ok`/`error:N` answer the oldest unanswered line sent
/// (character-counting order), `<...>` status reports answer `?`, `ALARM:N`, `[MSG:...]` and
/// banners update the alarm and reset state whenever they arrive.
pub struct GrblSlider {
    pub(crate) config: GrblConfig,
    pub(crate) link: Link,
    pub(crate) tracker: Tracker,
    build_info: Option<BuildInfo>,
    /// `$$` of the last connect: the stopping deadlines and laser mode come from it.
    settings: Option<GrblSettings>,
    /// The target of the last accepted move and the banner count when it was sent (a reset
    /// since flushed it): [`Slider::wait_idle`] does not take an `Idle` reported before the
    /// move has begun for its end.
    moving_to: Option<(f64, u64)>,
}

impl std::fmt::Debug for GrblSlider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GrblSlider")
            .field("port", &self.port_name())
            .field("connected", &self.link.is_open())
            .field("banner", &self.tracker.banner())
            .field("alarm", &self.tracker.alarm())
            .field("in_flight_bytes", &self.tracker.in_flight_bytes())
            .field("stats", &self.tracker.stats)
            .finish()
    }
}

impl GrblSlider {
    pub fn new(port: impl Into<String>, config: GrblConfig) -> Self {
        GrblSlider {
            link: Link::new(port.into(), config.response_timeout),
            tracker: Tracker::new(config.rx_buffer),
            config,
            build_info: None,
            settings: None,
            moving_to: None,
        }
    }

    pub fn port_name(&self) -> &str {
        self.link.device()
    }
    pub fn config(&self) -> &GrblConfig {
        &self.config
    }
    /// The last banner, e.g. `Grbl 1.1h ['$' for help]`.
    pub fn banner(&self) -> Option<&str> {
        self.tracker.banner()
    }
    /// The alarm the controller is known to be in (0: locked without a code), if any.
    pub fn alarm(&self) -> Option<u32> {
        self.tracker.alarm()
    }
    /// The controller's serial RX buffer used for character counting.
    pub fn rx_buffer(&self) -> usize {
        self.tracker.rx_buffer()
    }
    pub fn is_connected(&self) -> bool {
        self.link.is_open()
    }
    /// `$I` of the last connect, if the controller answered it.
    pub fn build_info(&self) -> Option<&BuildInfo> {
        self.build_info.as_ref()
    }
    /// `$$` as read at the last connect (or refreshed by [`GrblSlider::read_settings`]).
    pub fn known_settings(&self) -> Option<&GrblSettings> {
        self.settings.as_ref()
    }
    /// Whether GRBL's laser mode (`$32=1`) is in force, as last read; None before a connect
    /// that could read `$$`. Laser on/off mean the same in both modes (see [`LaserOutput`]).
    pub fn laser_mode(&self) -> Option<bool> {
        self.settings.as_ref().map(GrblSettings::laser_mode)
    }

    /// How long stopping from full speed may take, plus the response timeout: the deadline of
    /// a feed hold or a jog cancel. From the scan axis' `$110` and `$120` (the driver moves X
    /// only; GRBL's defaults where the controller listed none), times
    /// [`GrblConfig::motion_slack`] because a controller may run slower than its settings.
    pub fn stop_deadline(&self) -> Duration {
        let (rate, accel) = self.rate_and_accel();
        let decel_s = rate / 60.0 / accel;
        let slack = self.config.motion_slack.max(1.0);
        self.config.response_timeout + Duration::from_secs_f64(slack * decel_s)
    }

    /// X's maximum rate (mm/min) and acceleration (mm/s²), as read or GRBL's defaults.
    fn rate_and_accel(&self) -> (f64, f64) {
        let s = self.settings.as_ref();
        let rate = s
            .and_then(|s| s.max_rate(0))
            .filter(|r| *r > 0.0)
            .unwrap_or(DEFAULT_MAX_RATE);
        let accel = s
            .and_then(|s| s.acceleration(0))
            .filter(|a| *a > 0.0)
            .unwrap_or(DEFAULT_ACCEL);
        (rate, accel)
    }

    /// How long a move of `distance_mm` at `feed_mm_min` takes on this controller (trapezoid
    /// at `$120`, feed clamped to `$110`), for callers that choose a `wait_idle` timeout.
    pub fn move_duration(&self, distance_mm: f64, feed_mm_min: f64) -> Duration {
        let (rate, a) = self.rate_and_accel();
        let v = feed_mm_min.min(rate).max(1e-9) / 60.0;
        let d = distance_mm.abs();
        // Accelerate to v and back takes v/a seconds over v²/a mm; a short move is a triangle.
        let t = if d * a >= v * v {
            d / v + v / a
        } else {
            2.0 * (d / a).sqrt()
        };
        Duration::from_secs_f64(t)
    }
    /// Faults absorbed so far.
    pub fn stats(&self) -> GrblStats {
        self.tracker.stats
    }
    /// The full last status report (with sub-states such as `Hold:1`).
    pub fn last_report(&self) -> Option<&StatusReport> {
        self.tracker.last_report().map(|(r, _)| r)
    }

    // ----- connection --------------------------------------------------------------------

    /// Open the port, soft reset (0x18), wait for the banner, read `$I` (build info, RX buffer
    /// size) and a first status report. With `hold_first`, a controller found moving is
    /// brought to rest before the reset (see [`GrblSlider::reconnect`]).
    fn open_and_reset(&mut self, hold_first: bool) -> HalResult<SliderInfo> {
        self.link.close();
        self.tracker.reopen(self.config.rx_buffer);
        self.build_info = None;
        self.link.open(self.config.baud)?;
        if hold_first {
            self.bring_to_rest();
        }
        self.tracker.clear_garbage();
        let since = self.tracker.banners();
        self.realtime(0x18)?;
        // Wait for the banner, tolerating noise before it (boot loaders, line garbage).
        let timeout = self.config.reset_timeout;
        let deadline = Instant::now() + timeout;
        let mut noise: Vec<String> = Vec::new();
        while self.tracker.banners() == since {
            match self.pump(deadline) {
                Ok(true) => {}
                Ok(false) => {
                    noise.extend(self.tracker.garbage().map(String::from));
                    if noise.is_empty() {
                        return Err(self.timeout("the GRBL banner after a soft reset", timeout));
                    }
                    return Err(self.bad(format!(
                        "no GRBL banner within {timeout:?}; received instead: {}",
                        noise.join(" | ")
                    )));
                }
                Err(HalError::BadData { detail, .. }) => noise.push(detail),
                Err(e) => return Err(e),
            }
        }
        let banner = self.tracker.banner().unwrap_or_default().to_string();
        match banner_version(&banner) {
            Some(v) if v.starts_with("1.") => {}
            _ => {
                return Err(self.bad(format!(
                    "unsupported firmware {banner:?} (this driver speaks GRBL 1.1)"
                )))
            }
        }
        // Build info carries the RX buffer size; not fatal if a clone does not support $I.
        // A second banner may follow the first (a board that reset itself on port open and
        // then again on our 0x18): it swallows the line, so ask again.
        for attempt in 1.. {
            match self.command("$I") {
                Ok(lines) => {
                    self.build_info = BuildInfo::parse(&lines);
                    break;
                }
                Err(HalError::Rejected { .. }) => break,
                Err(HalError::Disconnected { .. }) if self.link.is_open() && attempt < 3 => {
                    tracing::debug!(
                        "{}: controller reset again during connect",
                        self.port_name()
                    );
                }
                Err(e) => return Err(e),
            }
        }
        // Settings: the stopping deadlines and laser mode depend on them. A clone that refuses
        // `$$` keeps the defaults.
        // A first `$$` answered badly is asked again: on grbl-sim it came back unreadable now
        // and then right after the reset (2 of 3 fresh simulators in one run), and the driver
        // went on with the defaults' deadlines and no laser mode.
        self.settings = None;
        for attempt in 1..=3 {
            match self.read_settings() {
                Ok(s) => {
                    self.settings = Some(s);
                    break;
                }
                Err(e @ (HalError::Rejected { .. } | HalError::BadData { .. })) => {
                    tracing::warn!(
                        "{}: `$$` not read (attempt {attempt} of 3): {e}",
                        self.port_name()
                    );
                    std::thread::sleep(Duration::from_millis(100));
                }
                Err(e) => return Err(e),
            }
        }
        let deadline = Instant::now() + self.config.response_timeout;
        self.query_status(deadline)?;
        Ok(SliderInfo {
            port: self.port_name().to_string(),
            banner,
            laser_mode: self.laser_mode(),
        })
    }

    /// Before a reset on reconnect: a controller that kept power may still be moving; a reset
    /// then would kill the steppers (ALARM:3, position lost). Cancel a jog, or feed hold a
    /// program, and wait for the stop. A controller that does not answer at once may be
    /// booting (boards that reset on port open) or briefly stalled (grbl-sim under load did
    /// for over 5 s): it is asked again until the reset timeout, and only a controller silent
    /// that long is reset as it is.
    fn bring_to_rest(&mut self) {
        let deadline = Instant::now() + self.config.reset_timeout;
        let st = loop {
            match self.query_status(Instant::now() + self.config.response_timeout) {
                Ok(st) => break st,
                Err(HalError::Timeout { .. } | HalError::BadData { .. })
                    if Instant::now() < deadline => {}
                Err(_) => return,
            }
        };
        let result = match st.state {
            SliderState::Jog => self.jog_cancel(),
            SliderState::Run | SliderState::Hold => self.realtime(b'!').and_then(|_| {
                self.wait_at_rest("the feed hold before the reset")
                    .map(|_| ())
            }),
            _ => Ok(()),
        };
        if let Err(e) = result {
            tracing::warn!(
                "{}: could not stop the motion before the reset: {}",
                self.port_name(),
                footscan_util::Chain(&e)
            );
        }
    }

    /// Reopen the port after a disconnect (a USB serial adapter unplugged and back, ideally
    /// under the same `/dev/serial/by-id/` path): retries opening while the port is absent,
    /// for up to `wait`, then connects as [`Slider::connect`] does.
    ///
    /// A controller that kept power and was moving is brought to rest first (jog cancel, or
    /// feed hold and wait) so the soft reset keeps its position. Unlock policy: the driver
    /// never sends `$X` on its own. A controller that comes back locked (it power-cycled
    /// with homing enabled, or alarmed) is reported by [`GrblSlider::alarm`]; the caller
    /// homes it, because the position it had is not to be trusted.
    pub fn reconnect(&mut self, wait: Duration) -> HalResult<SliderInfo> {
        self.link.close();
        let deadline = Instant::now() + wait;
        loop {
            match self.open_and_reset(true) {
                Ok(info) => {
                    self.tracker.stats.reconnects += 1;
                    return Ok(info);
                }
                Err(e @ HalError::Disconnected { .. }) => {
                    if Instant::now() >= deadline {
                        return Err(e);
                    }
                    std::thread::sleep(self.config.poll_interval.max(Duration::from_millis(50)));
                }
                Err(e) => return Err(e),
            }
        }
    }

    /// Soft reset (0x18) and wait for the banner; the planner and RX buffer are cleared.
    pub fn soft_reset(&mut self) -> HalResult<()> {
        self.drain_pending()?;
        let since = self.tracker.banners();
        self.realtime(0x18)?;
        self.wait_banner(since, self.config.reset_timeout)
    }

    // ----- settings and locks ------------------------------------------------------------

    /// `$$` as a typed map (kept: the stopping deadlines and laser mode follow it).
    pub fn read_settings(&mut self) -> HalResult<GrblSettings> {
        let s = GrblSettings {
            raw: Slider::settings(self)?,
        };
        self.settings = Some(s.clone());
        Ok(s)
    }

    /// `$X`: clear the alarm lock without homing.
    pub fn unlock(&mut self) -> HalResult<()> {
        self.command("$X")?;
        self.tracker.clear_alarm();
        Ok(())
    }

    /// [`Slider::home`] with the configured `homing_timeout`.
    pub fn home_configured(&mut self) -> HalResult<()> {
        let t = self.config.homing_timeout;
        self.home(t)
    }

    fn fail_if_alarm(&self) -> HalResult<()> {
        match self.tracker.alarm() {
            Some(code) => Err(self.alarm_error(code)),
            None => Ok(()),
        }
    }

    // ----- motion ------------------------------------------------------------------------

    fn check_move(&self, x_mm: f64, feed_mm_min: f64) -> HalResult<()> {
        if !(x_mm.is_finite() && feed_mm_min.is_finite() && feed_mm_min > 0.0) {
            return Err(HalError::InvalidArgument {
                device: self.port_name().to_string(),
                detail: format!("bad move: x {x_mm} mm at {feed_mm_min} mm/min"),
            });
        }
        Ok(())
    }

    /// `$J=G90 G21 X.. F..`: jog to `x_mm` (cancelled by [`Slider::stop`] with 0x85).
    pub fn jog_to(&mut self, x_mm: f64, feed_mm_min: f64) -> HalResult<()> {
        self.check_move(x_mm, feed_mm_min)?;
        self.fail_if_alarm()?;
        let line = format!("$J=G90G21X{x_mm:.4}F{feed_mm_min:.3}");
        self.command_with(&line, WaitPolicy::motion(self.config.response_timeout))?;
        Ok(())
    }

    /// Jog cancel (0x85): decelerate a `$J=` jog and drop any queued jogs; waits until the
    /// controller has left the `Jog` state. A no-op when not jogging.
    pub fn jog_cancel(&mut self) -> HalResult<()> {
        self.realtime(0x85)?;
        self.wait_state(
            "the jog cancel to stop the jog",
            self.stop_deadline(),
            |st, _| st != SliderState::Jog,
        )
        .map(|_| ())
    }

    /// After a feed hold: wait until the machine is at rest, `Hold:0` or `Idle` (or any
    /// state that does not move). GRBL answers a `?` sent right after `!` before the hold
    /// takes effect, so `Run` (or `Jog`) still means stopping, as does `Hold:1`; a reset or a
    /// resume sent then would kill the motion (ALARM:3) or be ignored.
    fn wait_at_rest(&mut self, what: &str) -> HalResult<SliderStatus> {
        self.wait_state(what, self.stop_deadline(), |st, sub| {
            !(st.is_moving() || (st == SliderState::Hold && sub != Some(0)))
        })
    }

    /// Poll the status until `done(state, substate)`, for at most `budget`. Each query gets
    /// the full response timeout, so a deadline that passes names the motion waited for, not
    /// the query. An alarm ends the wait with its code.
    fn wait_state(
        &mut self,
        what: &str,
        budget: Duration,
        done: impl Fn(SliderState, Option<u8>) -> bool,
    ) -> HalResult<SliderStatus> {
        let deadline = Instant::now() + budget;
        loop {
            let s = self.query_status(Instant::now() + self.config.response_timeout)?;
            let sub = self.last_report().and_then(|r| r.substate);
            if done(s.state, sub) {
                return Ok(s);
            }
            if s.state == SliderState::Alarm {
                return Err(self.alarm_error(self.tracker.alarm().unwrap_or(0)));
            }
            if Instant::now() >= deadline {
                let word = match sub {
                    Some(n) => format!("{:?}:{n}", s.state),
                    None => format!("{:?}", s.state),
                };
                return Err(
                    self.timeout(format!("{what} (still {word} at X {:.3})", s.x_mm), budget)
                );
            }
            std::thread::sleep(self.config.poll_interval);
        }
    }

    /// Poll `?` at the configured rate (`poll_interval`, scheduled on absolute times so the
    /// rate does not drift by the round trip) and hand each report, stamped on
    /// CLOCK_MONOTONIC at the midpoint of query and answer, to `on_report` until it returns
    /// true. Returns the number of reports; [`HalError::Timeout`] if `on_report` never said
    /// stop within `timeout`.
    pub fn poll_status(
        &mut self,
        timeout: Duration,
        mut on_report: impl FnMut(&SliderStatus) -> bool,
    ) -> HalResult<usize> {
        let start = Instant::now();
        let deadline = start + timeout;
        let period = self.config.poll_interval;
        let mut n = 0usize;
        loop {
            let probe = deadline.min(Instant::now() + self.config.response_timeout);
            let s = self.query_status(probe)?;
            n += 1;
            if on_report(&s) {
                return Ok(n);
            }
            // The next slot after now: a slow answer skips slots rather than bursting.
            let slots = (start.elapsed().as_nanos() / period.as_nanos().max(1)) as u32 + 1;
            let next = start + period * slots;
            let now = Instant::now();
            if now >= deadline || next >= deadline {
                return Err(self.timeout(
                    format!("the status polled {n} times to reach the awaited condition"),
                    timeout,
                ));
            }
            if next > now {
                std::thread::sleep(next - now);
            }
        }
    }
}

impl Slider for GrblSlider {
    fn connect(&mut self) -> HalResult<SliderInfo> {
        self.open_and_reset(false)
    }

    /// `$H`: answered when the cycle ends. A failed cycle is the `ALARM:N` GRBL raises (6 to
    /// 9, with their meaning). A cycle still running at `timeout` is aborted with a soft reset
    /// (GRBL then raises ALARM:6 and stays locked) so the machine does not keep seeking a
    /// switch nobody waits for; the error says so.
    fn home(&mut self, timeout: Duration) -> HalResult<()> {
        self.prepare_to_send()?;
        let since = self.tracker.banners();
        let id = self.send_line("$H", LineKind::Homing)?;
        // No $G resync on timeout: GRBL reads no line while homing.
        match self.wait_answer(id, WaitPolicy::alone(timeout)) {
            Ok(()) => {
                self.tracker.clear_alarm();
                Ok(())
            }
            Err(e @ HalError::Alarm { .. }) => {
                // GRBL resets after a failed cycle: a line sent before its banner would be
                // discarded by it. Wait for it (a controller that does not reset is left).
                if self.tracker.banners() == since {
                    let t = self.config.reset_timeout;
                    if let Err(w) = self.wait_banner(since, t) {
                        tracing::debug!(
                            "{}: no reset after the homing alarm: {w}",
                            self.port_name()
                        );
                    }
                }
                Err(e)
            }
            Err(HalError::Timeout { .. }) if self.link.is_open() => {
                let aborted = self.soft_reset();
                Err(self.timeout(
                    match aborted {
                        Ok(()) => "the homing cycle ($H) to finish; aborted it with a soft reset: the machine is not homed".to_string(),
                        Err(e) => format!("the homing cycle ($H) to finish; the soft reset to abort it failed too: {}", footscan_util::Chain(&e)),
                    },
                    timeout,
                ))
            }
            Err(e) => Err(e),
        }
    }

    fn move_to(&mut self, x_mm: f64, feed_mm_min: f64) -> HalResult<()> {
        self.check_move(x_mm, feed_mm_min)?;
        self.fail_if_alarm()?;
        // Modes ride along on every move, so nothing depends on the parser's modal state
        // (a reset restores G90 G21, but startup lines may not).
        let line = format!("G90G21G1X{x_mm:.4}F{feed_mm_min:.3}");
        self.command_with(&line, WaitPolicy::motion(self.config.response_timeout))?;
        self.moving_to = Some((x_mm, self.tracker.banners()));
        Ok(())
    }

    fn status(&mut self) -> HalResult<SliderStatus> {
        let deadline = Instant::now() + self.config.response_timeout;
        self.query_status(deadline)
    }

    /// GRBL answers `ok` once a move is planned and starts the cycle a moment later: a status
    /// asked in between says `Idle` at the old place (grbl-sim, slowed by a busy machine, did
    /// so for long enough that a test's move "ended" where it began, 3 runs in 9). So an `Idle`
    /// short of the last move's target, before any motion was reported, is waited past for up
    /// to a response timeout.
    fn wait_idle(&mut self, timeout: Duration) -> HalResult<SliderStatus> {
        let deadline = Instant::now() + timeout;
        let banners = self.tracker.banners();
        let mut target = self
            .moving_to
            .take()
            .filter(|&(_, b)| b == banners)
            .map(|(x, _)| x);
        let tolerance = self
            .settings
            .as_ref()
            .and_then(|s| s.steps_per_mm(0))
            .map_or(0.01, |k| 1.5 / k.max(1.0));
        let mut settle: Option<Instant> = None;
        loop {
            let probe = deadline.min(Instant::now() + self.config.response_timeout);
            let s = match self.query_status(probe) {
                Err(HalError::Timeout { .. }) if Instant::now() >= deadline => {
                    return Err(self.timeout("the controller to become idle", timeout));
                }
                r => r?,
            };
            match s.state {
                SliderState::Idle => match target {
                    Some(t) if (s.x_mm - t).abs() > tolerance => {
                        let until = *settle
                            .get_or_insert_with(|| Instant::now() + self.config.response_timeout);
                        if Instant::now() >= until.min(deadline)
                            || self.tracker.banners() != banners
                        {
                            return Ok(s);
                        }
                    }
                    _ => return Ok(s),
                },
                SliderState::Alarm => {
                    return Err(self.alarm_error(self.tracker.alarm().unwrap_or(0)))
                }
                // Under way: the next Idle is the move's end, wherever it stops.
                _ => target = None,
            }
            if Instant::now() >= deadline {
                return Err(self.timeout(
                    format!(
                        "the controller to become idle (last {:?} at X {:.3})",
                        s.state, s.x_mm
                    ),
                    timeout,
                ));
            }
            std::thread::sleep(self.config.poll_interval);
        }
    }

    fn feed_hold(&mut self) -> HalResult<()> {
        self.realtime(b'!')
    }

    /// Resume a feed hold. GRBL ignores `~` until the hold has come to rest (`Hold:0`), and a
    /// hold asked for just before may not have taken effect yet (the state still says `Run`,
    /// or `Idle` for a machine at rest): so wait for rest, send `~`, and confirm that the state
    /// stays out of `Hold` for two reports in a row, sending `~` again whenever it is `Hold:0`.
    fn resume(&mut self) -> HalResult<()> {
        self.wait_at_rest("the feed hold to come to rest before the resume")?;
        self.realtime(b'~')?;
        let budget = self.stop_deadline();
        let deadline = Instant::now() + budget;
        let mut out_of_hold = 0;
        loop {
            std::thread::sleep(self.config.poll_interval);
            let s = self.query_status(Instant::now() + self.config.response_timeout)?;
            let sub = self.last_report().and_then(|r| r.substate);
            if s.state != SliderState::Hold {
                out_of_hold += 1;
                if out_of_hold >= 2 {
                    return Ok(());
                }
                continue;
            }
            out_of_hold = 0;
            if Instant::now() >= deadline {
                return Err(self.timeout(
                    format!(
                        "the resume (`~`) to leave the hold (still Hold at X {:.3})",
                        s.x_mm
                    ),
                    budget,
                ));
            }
            // A `~` that arrived before the hold applied was dropped: send it again at rest.
            if sub == Some(0) {
                self.realtime(b'~')?;
            }
        }
    }

    fn stop(&mut self) -> HalResult<()> {
        let deadline = Instant::now() + self.config.response_timeout;
        let s = self.query_status(deadline)?;
        match s.state {
            // Nothing stays queued after a jog cancel.
            SliderState::Jog => self.jog_cancel(),
            SliderState::Run | SliderState::Hold => {
                // Feed hold first so the reset does not kill the steppers mid-motion (which
                // would lose the position and alarm); then reset to discard the planner.
                self.realtime(b'!')?;
                self.wait_at_rest("the feed hold before the reset")?;
                self.soft_reset()
            }
            SliderState::Home => self.soft_reset(),
            _ => Ok(()),
        }
    }

    /// The configured output's command (see [`LaserOutput`]). GRBL switches the spindle and
    /// coolant outputs in step with the planner (after the queued motion, in laser mode too:
    /// there only a power change applies at once), so a laser switched during a move comes on
    /// when the move ends, and this returns then. A refusal names the command and the
    /// controller's `error:N` with its meaning.
    fn laser(&mut self, on: bool) -> HalResult<()> {
        let Some(out) = self.config.laser else {
            return Err(HalError::InvalidArgument {
                device: self.port_name().to_string(),
                detail: "no laser output configured (laser = \"spindle\", \"flood\" or \"mist\")"
                    .into(),
            });
        };
        self.fail_if_alarm()?;
        let line = out.command(on, self.laser_mode().unwrap_or(false));
        // Outside laser mode GRBL answers a spindle or coolant line only once the queued
        // motion has finished: patient while the machine moves, like a motion line.
        match self.command_with(&line, WaitPolicy::motion(self.config.response_timeout)) {
            Ok(_) => Ok(()),
            Err(HalError::Rejected {
                device,
                code,
                message,
            }) => Err(HalError::Rejected {
                device,
                code,
                message: format!(
                    "laser {} refused: the controller answered `{line}` with error:{code} ({message})",
                    if on { "on" } else { "off" }
                ),
            }),
            Err(e) => Err(e),
        }
    }

    fn settings(&mut self) -> HalResult<SliderSettings> {
        self.command("$$")?;
        let s = self.tracker.take_settings();
        if s.is_empty() {
            return Err(self.bad("`$$` listed no settings"));
        }
        Ok(s)
    }
}
