//! Machine state shared between the protocol thread and observers (position source, tests).

use super::config::{EmulatorConfig, LaserWiring};
use super::motion::{MoveKind, Spec, Timeline};
use std::collections::BTreeMap;
use std::sync::{Mutex, MutexGuard};

/// GRBL's usable planner blocks (`BLOCK_BUFFER_SIZE - 1`).
pub(crate) const PLANNER_BLOCKS: usize = 15;

/// Settings that print as integers in `$$`.
const INT_SETTINGS: &[u32] = &[0, 1, 2, 3, 4, 5, 6, 10, 13, 20, 21, 22, 23, 26, 30, 31, 32];

/// GRBL 1.1h defaults, with the X axis and homing taken from the config.
pub(crate) fn default_settings(cfg: &EmulatorConfig) -> BTreeMap<u32, f64> {
    let homing = if cfg.homing_enabled { 1.0 } else { 0.0 };
    [
        (0, 10.0),
        (1, 25.0),
        (2, 0.0),
        (3, 0.0),
        (4, 0.0),
        (5, 0.0),
        (6, 0.0),
        (10, 1.0),
        (11, 0.010),
        (12, 0.002),
        (13, 0.0),
        // Soft limits need homing ($20 requires $22); on whenever homing is.
        (20, homing),
        (21, 0.0),
        (22, homing),
        (23, 0.0),
        (24, 25.0),
        (25, 500.0),
        (26, 250.0),
        (27, 1.0),
        (30, 1000.0),
        (31, 0.0),
        (32, 0.0),
        (100, 250.0),
        (101, 250.0),
        (102, 250.0),
        (110, cfg.max_rate_mm_min),
        (111, 500.0),
        (112, 500.0),
        (120, cfg.accel_mm_s2),
        (121, 10.0),
        (122, 10.0),
        (130, cfg.travel_mm),
        (131, 200.0),
        (132, 200.0),
    ]
    .into_iter()
    .collect()
}

pub(crate) fn format_setting(k: u32, v: f64) -> String {
    if INT_SETTINGS.contains(&k) {
        format!("${k}={}", v.round() as i64)
    } else {
        format!("${k}={v:.3}")
    }
}

#[derive(Clone, Debug)]
pub(crate) struct Hold {
    /// When the hold deceleration ends (`Hold:1` before, `Hold:0` after).
    pub t_stop: f64,
    /// Blocks to run on resume, in order.
    pub held: Vec<Spec>,
}

#[derive(Clone, Debug)]
pub(crate) struct Machine {
    pub settings: BTreeMap<u32, f64>,
    pub timeline: Timeline,
    pub alarm: bool,
    /// Hard/soft limit alarm: everything but `?` and reset is ignored until reset.
    pub critical: bool,
    pub homing_until: Option<f64>,
    pub homing_seconds: f64,
    pub hold: Option<Hold>,
    pub check_mode: bool,
    /// Soft-limit alarm raised once the hold deceleration it triggered ends.
    pub pending_alarm: Option<(u8, f64)>,
    /// Bytes received beyond the RX buffer by a client that does not count characters.
    pub rx_overflow: u64,
    /// Most non-realtime bytes ever waiting in the RX buffer at once.
    pub rx_peak: usize,
    pub laser_wiring: LaserWiring,
    /// When the laser changed state (time, on), oldest first; before the first, it is off
    /// unless wired to be always on.
    pub laser_changes: Vec<(f64, bool)>,
}

impl Machine {
    pub fn new(cfg: &EmulatorConfig) -> Machine {
        Machine {
            settings: default_settings(cfg),
            timeline: Timeline::new(0.0, cfg.backlash_mm, cfg.slider_scale),
            alarm: cfg.homing_enabled,
            critical: false,
            homing_until: None,
            homing_seconds: cfg.homing_seconds,
            hold: None,
            check_mode: false,
            pending_alarm: None,
            rx_overflow: 0,
            rx_peak: 0,
            laser_wiring: cfg.laser,
            laser_changes: Vec::new(),
        }
    }

    /// Record the outputs after a block or a reset at `now` (a change of the laser only).
    pub fn set_outputs(&mut self, now: f64, spindle: bool, flood: bool) {
        let on = self.laser_wiring.on(spindle, flood);
        if self.laser_at(now) != on {
            // Keep the history bounded like the motion timeline's (a scan switches a few times).
            if self.laser_changes.len() >= 4096 {
                self.laser_changes.drain(..2048);
            }
            self.laser_changes.push((now, on));
        }
    }

    /// Whether the laser shone at `t`.
    pub fn laser_at(&self, t: f64) -> bool {
        if self.laser_wiring == LaserWiring::Always {
            return true;
        }
        self.laser_changes
            .iter()
            .rev()
            .find(|c| c.0 <= t)
            .is_some_and(|c| c.1)
    }

    fn setting(&self, k: u32) -> f64 {
        self.settings.get(&k).copied().unwrap_or(0.0)
    }
    pub fn max_rate(&self) -> f64 {
        self.setting(110)
    }
    pub fn accel(&self) -> f64 {
        self.setting(120)
    }
    pub fn travel(&self) -> f64 {
        self.setting(130)
    }
    pub fn soft_limits(&self) -> bool {
        self.setting(20) != 0.0
    }
    pub fn homing_enabled(&self) -> bool {
        self.setting(22) != 0.0
    }
    /// `$32`: laser mode.
    pub fn laser_mode(&self) -> bool {
        self.setting(32) != 0.0
    }
    pub fn status_mask(&self) -> u32 {
        self.setting(10) as u32
    }

    pub fn state(&self, now: f64) -> MachineState {
        if self.alarm {
            return MachineState::Alarm;
        }
        if self.homing_until.is_some_and(|t| now < t) {
            return MachineState::Home;
        }
        if let Some(h) = &self.hold {
            return MachineState::Hold(if now < h.t_stop { 1 } else { 0 });
        }
        if self.check_mode {
            return MachineState::Check;
        }
        match self.timeline.active(now) {
            Some(m) if m.spec.kind == MoveKind::Jog => MachineState::Jog,
            Some(_) => MachineState::Run,
            None => MachineState::Idle,
        }
    }

    /// Whether a reset now would kill steppers mid-motion (GRBL then raises ALARM:3).
    pub fn is_moving(&self, now: f64) -> bool {
        matches!(
            self.state(now),
            MachineState::Run | MachineState::Jog | MachineState::Home | MachineState::Hold(1)
        ) || self.pending_alarm.is_some()
    }

    /// Planner blocks in use.
    pub fn busy(&self, now: f64) -> usize {
        self.timeline.busy_count(now) + self.hold.as_ref().map_or(0, |h| h.held.len())
    }

    pub fn planner_full(&self, now: f64) -> bool {
        self.busy(now) >= PLANNER_BLOCKS
    }

    /// Queue a block; it starts at once unless the machine is holding.
    pub fn queue(&mut self, now: f64, mut spec: Spec) {
        spec.feed = spec.feed.min(self.max_rate());
        if let Some(h) = &mut self.hold {
            h.held.push(spec);
            return;
        }
        let a = self.accel();
        self.timeline.push(now, spec, a);
    }

    /// `!`: decelerate to a hold. Jogs are cancelled instead.
    pub fn feed_hold(&mut self, now: f64) {
        match self.state(now) {
            MachineState::Run => {
                let a = self.accel();
                let (t_stop, held) = self.timeline.decel_stop(now, a);
                self.hold = Some(Hold { t_stop, held });
            }
            MachineState::Jog => {
                self.jog_cancel(now);
            }
            MachineState::Idle => {
                self.hold = Some(Hold {
                    t_stop: now,
                    held: Vec::new(),
                })
            }
            _ => {}
        }
    }

    /// `~`: resume from a completed hold (ignored while still decelerating, as GRBL does).
    pub fn cycle_start(&mut self, now: f64) {
        if self.pending_alarm.is_some() {
            return;
        }
        let done = matches!(&self.hold, Some(h) if now >= h.t_stop);
        if done {
            let held = self.hold.take().map(|h| h.held).unwrap_or_default();
            for spec in held {
                self.queue(now, spec);
            }
        }
    }

    /// 0x85: decelerate and discard all queued jog motion. Returns whether a jog was cancelled.
    pub fn jog_cancel(&mut self, now: f64) -> bool {
        if self.state(now) != MachineState::Jog {
            return false;
        }
        let a = self.accel();
        let _ = self.timeline.decel_stop(now, a);
        true
    }

    /// Stop dead (reset, alarm): steppers killed, plan and hold discarded.
    pub fn halt(&mut self, now: f64) {
        self.timeline.stop_now(now);
        self.hold = None;
        self.homing_until = None;
        self.pending_alarm = None;
    }

    pub fn start_homing(&mut self, now: f64) {
        self.alarm = false;
        let secs = self.homing_seconds.max(0.0);
        self.timeline.push_linear(now, 0.0, secs);
        self.homing_until = Some(now + secs);
    }

    /// Soft limit hit by a g-code block: decelerate if moving, then ALARM:2 at the stop.
    pub fn soft_limit(&mut self, now: f64) -> f64 {
        let a = self.accel();
        let (t_stop, _) = self.timeline.decel_stop(now, a);
        self.hold = Some(Hold {
            t_stop,
            held: Vec::new(),
        });
        self.pending_alarm = Some((2, t_stop));
        t_stop
    }

    /// The earliest future instant at which the state changes by itself.
    pub fn next_event(&self, now: f64) -> Option<f64> {
        let mut t = self.timeline.next_end_after(now);
        let mut consider = |c: Option<f64>| {
            if let Some(c) = c.filter(|&c| c > now) {
                t = Some(t.map_or(c, |t: f64| t.min(c)));
            }
        };
        consider(self.homing_until);
        consider(self.pending_alarm.map(|p| p.1));
        consider(self.hold.as_ref().map(|h| h.t_stop));
        t
    }
}

/// GRBL machine state as reported in `<...|`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MachineState {
    Idle,
    Run,
    /// `Hold:1` decelerating, `Hold:0` stopped and ready to resume.
    Hold(u8),
    Jog,
    Alarm,
    Home,
    Check,
}

impl std::fmt::Display for MachineState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            MachineState::Idle => write!(f, "Idle"),
            MachineState::Run => write!(f, "Run"),
            MachineState::Hold(n) => write!(f, "Hold:{n}"),
            MachineState::Jog => write!(f, "Jog"),
            MachineState::Alarm => write!(f, "Alarm"),
            MachineState::Home => write!(f, "Home"),
            MachineState::Check => write!(f, "Check"),
        }
    }
}

/// The machine and its configuration, shared by the emulator's handle (mod.rs) and the thread
/// that serves the pty (server.rs).
pub(crate) struct Shared {
    pub machine: Mutex<Machine>,
    pub config: EmulatorConfig,
}

impl Shared {
    pub(super) fn lock(&self) -> MutexGuard<'_, Machine> {
        self.machine.lock().unwrap_or_else(|e| e.into_inner())
    }
}
