//! What a test sets up on the emulator: the machine's configuration, the laser's wiring and
//! the faults it can inject. A file of its own because the handle (mod.rs), the machine
//! (machine.rs) and the pty server (server.rs) all read it, and none of them owns it.

use serde::{Deserialize, Serialize};

/// Emulated machine. Defaults: a 330 mm slider at 3000 mm/min and 500 mm/s² with homing.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct EmulatorConfig {
    /// `$110`, mm/min.
    pub max_rate_mm_min: f64,
    /// `$120`, mm/s².
    pub accel_mm_s2: f64,
    /// `$130`, mm: soft limits are `[0, travel]`.
    pub travel_mm: f64,
    /// Physical position = scale × machine position (slider calibration error).
    pub slider_scale: f64,
    /// Play between motor and carriage, mm (see the module docs).
    pub backlash_mm: f64,
    /// `$22` (and `$20` soft limits with it).
    pub homing_enabled: bool,
    /// Simulated duration of `$H`.
    pub homing_seconds: f64,
    /// Delay between sampling a status report and sending it.
    pub status_latency_us: u64,
    /// Delay before a feed hold (`!`) takes effect. GRBL answers a `?` sent right behind a
    /// `!` before the hold applies (the report still says `Run`), and ignores a `~` that
    /// arrives before it; grbl-sim showed it for milliseconds. 0 applies the hold at once.
    pub hold_latency_us: u64,
    /// Time from a failed homing cycle's `ALARM:N` to the `ok` of its `$H` and the reset
    /// that follows (GRBL 1.1h in grbl-sim: about 0.55 s); lines arriving in between are
    /// discarded by that reset.
    pub homing_abort_seconds: f64,
    /// Serial RX buffer, bytes (reported in `$I` as `[OPT:V,15,N]`).
    pub rx_buffer: usize,
    /// What switches the laser: `always` (wired to its own supply: always on, as before the
    /// laser was switchable), `spindle` (M3/M4 on, M5 off) or `flood` (M8 on, M9 off).
    pub laser: LaserWiring,
}

/// Where the simulated laser is wired.
#[derive(Clone, Copy, Debug, Default, Serialize, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "lowercase")]
pub enum LaserWiring {
    #[default]
    Always,
    Spindle,
    Flood,
}

impl LaserWiring {
    pub(super) fn on(self, spindle: bool, flood: bool) -> bool {
        match self {
            LaserWiring::Always => true,
            LaserWiring::Spindle => spindle,
            LaserWiring::Flood => flood,
        }
    }
}

impl Default for EmulatorConfig {
    fn default() -> Self {
        EmulatorConfig {
            max_rate_mm_min: 3000.0,
            accel_mm_s2: 500.0,
            travel_mm: 330.0,
            slider_scale: 1.0,
            backlash_mm: 0.0,
            homing_enabled: true,
            homing_seconds: 0.3,
            status_latency_us: 0,
            hold_latency_us: 10_000,
            homing_abort_seconds: 0.3,
            rx_buffer: 128,
            laser: LaserWiring::Always,
        }
    }
}

/// Faults a test can inject.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fault {
    /// Raise `ALARM:N`: motion stops dead, state `Alarm`. Codes 1 and 2 (hard/soft limit) are
    /// critical: `[MSG:Reset to continue]` and nothing but `?` and reset is served until a
    /// reset. Other codes abort through GRBL's reset path (banner, `'$H'|'$X' to unlock`).
    Alarm(u8),
    /// Stop answering (and reading) anything, realtime `?` included; `false` resumes and the
    /// pending input is then processed in order.
    Silence(bool),
    /// Close the pty master: the client's port hangs up (EIO / POLLHUP).
    Disconnect,
    /// The next `$H` fails after `homing_seconds` with `ALARM:N` (8: pull-off did not clear
    /// the switch, 9: no switch found), answered `ok` as GRBL does after the abort, then the
    /// reset path: banner and `'$H'|'$X' to unlock`.
    HomingFail(u8),
    /// The next N `ok` answers are not sent (a UART that dropped them).
    DropOk(u32),
    /// The next N `ok` answers arrive as `0k` (a flipped bit).
    CorruptOk(u32),
    /// The next N status reports arrive corrupted (a digit of `MPos` replaced by line noise).
    CorruptStatus(u32),
    /// The next line is answered `error:N` without being executed.
    RejectNext(u8),
}
