//! A GRBL 1.1h emulator on a pseudo-terminal.
//!
//! [`GrblEmulator::spawn`] opens a pty pair and serves the GRBL serial protocol on the master
//! from a thread; a driver opens [`GrblEmulator::port_path`] (e.g. `/dev/pts/7`) exactly as it
//! would open `/dev/ttyUSB0`. The motion model is analytic in `CLOCK_MONOTONIC` time, so
//! [`GrblEmulator::position_source`] gives the exact physical head position at any instant of
//! the retained history (30 s) and of the planned future.
//!
//! # Protocol
//! Faithful to GRBL 1.1h where it matters to a client:
//! - banner `\r\nGrbl 1.1h ['$' for help]\r\n` at power-up and after a soft reset (0x18); with
//!   homing enabled (`$22=1`) the machine powers up in `Alarm` with
//!   `[MSG:'$H'|'$X' to unlock]`. As in GRBL, a soft reset keeps the prior state: an idle,
//!   homed machine stays `Idle`, while a reset during motion kills the steppers, reports
//!   `ALARM:3` (`ALARM:6` during homing) and comes back in `Alarm`.
//! - every line is answered `ok` or `error:N` with GRBL's codes; a motion line is answered as
//!   soon as its block enters the planner (15 blocks), not when it completes. A line that finds
//!   the planner full waits (unanswered) until a block finishes.
//! - `$$`, `$#`, `$G`, `$I`, `$N`, `$C`, `$X`, `$H`, `$RST=`, `$N=value`, `$J=` jogs; g-code
//!   `G0 G1 G4 G17-19 G20 G21 G40 G53 G54-59 G61 G80 G90 G91 G94`, `M0-2 M3-5 M8 M9 M30`,
//!   words `F N P S T X Y Z` (Y and Z are accepted and ignored: a single-axis machine). Arcs,
//!   probing, offsets and M7 (mist: not in GRBL's default build) answer `error:20`.
//! - a laser wired to the spindle (M3/M5) or flood coolant (M8/M9) output
//!   ([`EmulatorConfig::laser`]): [`GrblEmulator::laser_source`] tells the simulated camera
//!   whether it shone at a frame's capture time. A reset switches both outputs off. A spindle
//!   or coolant switch waits for the queued motion to finish before it applies and is
//!   answered (GRBL's planner sync); in laser mode (`$32=1`) a power change alone applies at
//!   once, and the spindle output is lit at rest only in G1 motion mode with a power above 0
//!   (after a reset, `M3 S..` alone stays dark).
//! - realtime bytes act on arrival, even mid-line: `?` status report
//!   `<Idle|MPos:12.345,0.000,0.000|FS:0,0>` (with `|WCO:` and `|Ov:` every few reports as
//!   GRBL does; `WPos` when `$10` bit 0 is clear; `Bf:` when bit 1 is set), `!` feed hold
//!   (`Hold:1` while decelerating at `$120`, then `Hold:0`; a jog is cancelled instead), `~`
//!   resume (ignored until the hold is complete, as in GRBL), 0x85 jog cancel, 0x18 reset.
//!   As in GRBL, the hold takes effect a moment after `!` arrives
//!   ([`EmulatorConfig::hold_latency_us`]): a `?` sent right behind it is still answered
//!   `Run`, a `~` sent before it applies is dropped, and a reset then kills the motion.
//! - soft limits (`$20`, on when homing is enabled): a g-code target outside `[0, $130]`
//!   decelerates, raises `ALARM:2`, `[MSG:Reset to continue]` and ignores everything but `?`
//!   and reset until a reset; a jog beyond travel is refused with `error:15`.
//!   (Machine coordinates run over `[0, travel]` with home at 0, not GRBL's default negative
//!   space.)
//! - serial RX buffer of `rx_buffer` bytes: non-realtime bytes beyond it are still processed
//!   in order (no data is lost) but counted in [`GrblEmulator::rx_overflow_bytes`], so a test
//!   can prove that a character-counting client never overflows.
//!
//! - a failed homing cycle (`Fault::HomingFail`) answers `ALARM:N`, then after
//!   [`EmulatorConfig::homing_abort_seconds`] the `$H`'s `ok` and the reset (banner, lock);
//!   lines sent in between are discarded by that reset, as in GRBL.
//!
//! Deviations: CRLF counts as one line end (GRBL would answer the empty line between `\r` and
//! `\n` with a second `ok`); blocks join with a full stop (no junction look-ahead); a G4 sharing a
//! block with axis words is refused with `error:31`.
//!
//! # Physical position
//! `physical = slider_scale × carriage`, where the carriage follows the motor through a
//! backlash play of `backlash_mm`: moving +X it trails the motor by `backlash_mm`; after a
//! reversal it stays put until the motor has crossed the play, then follows exactly (moving −X
//! it coincides with the motor). Power-up and homing (which approaches 0 from +X) leave the
//! play taken up on the −X side, so a homed machine at rest has physical = scale × machine.

mod config;
mod gcode;
mod machine;
mod motion;
mod pty;
mod server;

use crate::{LaserSource, PositionSource};
pub use config::{EmulatorConfig, Fault, LaserWiring};
use crossbeam_channel::Sender;
use footscan_hal::Timestamp;
pub use machine::MachineState;
use machine::{Machine, Shared};
use server::{Cmd, Server};
use std::os::fd::OwnedFd;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

pub use motion::trapezoid_time;

/// The emulator's output history as a [`LaserSource`] for the simulated camera.
struct EmulatorLaser(Arc<Shared>);

impl LaserSource for EmulatorLaser {
    fn laser_on(&self, at: Timestamp) -> bool {
        self.0.lock().laser_at(at.as_secs_f64())
    }
}

/// The emulator's motion model as a [`PositionSource`] for the simulated camera.
struct EmulatorPosition(Arc<Shared>);

impl PositionSource for EmulatorPosition {
    fn physical_x(&self, at: Timestamp) -> f64 {
        self.0.lock().timeline.physical_at(at.as_secs_f64())
    }
}

/// A GRBL 1.1h controller on a pty; see the module docs.
pub struct GrblEmulator {
    path: PathBuf,
    shared: Arc<Shared>,
    cmds: Sender<Cmd>,
    wake_tx: OwnedFd,
    thread: Option<JoinHandle<()>>,
}

impl GrblEmulator {
    /// Open a pty and start serving. The power-up banner is written at once; a client that
    /// opens the port later finds it in the input queue (drivers flush and reset anyway).
    pub fn spawn(config: EmulatorConfig) -> std::io::Result<Self> {
        let pty = pty::Pty::open()?;
        let path = pty.path.clone();
        let (wake_rx, wake_tx) = pty::wake_pipe()?;
        let shared = Arc::new(Shared {
            machine: Mutex::new(Machine::new(&config)),
            config: config.clone(),
        });
        let (tx, rx) = crossbeam_channel::unbounded();
        let mut server = Server::new(
            shared.clone(),
            pty,
            wake_rx,
            rx,
            config.rx_buffer,
            config.status_latency_us,
        );
        server.power_up();
        let thread = std::thread::Builder::new()
            .name("grbl-emulator".into())
            .spawn(move || server.run())?;
        Ok(GrblEmulator {
            path,
            shared,
            cmds: tx,
            wake_tx,
            thread: Some(thread),
        })
    }

    /// The pty slave to open, e.g. `/dev/pts/7`.
    pub fn port_path(&self) -> &Path {
        &self.path
    }

    pub fn config(&self) -> &EmulatorConfig {
        &self.shared.config
    }

    /// Physical head position at any time, from the motion model (valid after the emulator is
    /// dropped too: it then reports the final plan).
    pub fn position_source(&self) -> Arc<dyn PositionSource> {
        Arc::new(EmulatorPosition(self.shared.clone()))
    }

    pub fn inject(&self, fault: Fault) {
        let _ = self.cmds.send(Cmd::Fault(fault));
        pty::wake(&self.wake_tx);
    }

    /// A USB serial adapter unplugged and plugged back while the controller kept power: the
    /// client's port hangs up, a new pty serves the same machine (state, position and motion
    /// carry on). Returns the new port path (point a stable symlink at it with
    /// [`GrblEmulator::link`]).
    pub fn replug(&self) -> std::io::Result<PathBuf> {
        let (tx, rx) = crossbeam_channel::bounded(1);
        self.cmds
            .send(Cmd::Replug(tx))
            .map_err(|_| std::io::Error::other("emulator stopped"))?;
        pty::wake(&self.wake_tx);
        rx.recv_timeout(std::time::Duration::from_secs(5))
            .map_err(|_| std::io::Error::other("emulator did not replug"))?
    }

    /// Point the symlink `link` at `target` atomically (a `/dev/serial/by-id/...` name that
    /// follows the device across replugs).
    pub fn link(target: &Path, link: &Path) -> std::io::Result<()> {
        let tmp = link.with_extension("relink");
        let _ = std::fs::remove_file(&tmp);
        std::os::unix::fs::symlink(target, &tmp)?;
        std::fs::rename(&tmp, link)
    }

    /// Most non-realtime bytes that waited in the RX buffer at once (at most `rx_buffer` for
    /// a client that counts characters).
    pub fn rx_peak_bytes(&self) -> usize {
        self.shared.lock().rx_peak
    }

    /// Machine (motor) position now, mm.
    pub fn machine_x(&self) -> f64 {
        self.machine_x_at(Timestamp::now())
    }

    /// Machine (motor) position at `t`, mm.
    pub fn machine_x_at(&self, t: Timestamp) -> f64 {
        self.shared.lock().timeline.machine_at(t.as_secs_f64())
    }

    /// Physical head position at `t`, mm (same as the position source).
    pub fn physical_x_at(&self, t: Timestamp) -> f64 {
        self.shared.lock().timeline.physical_at(t.as_secs_f64())
    }

    pub fn state(&self) -> MachineState {
        self.shared.lock().state(Timestamp::now().as_secs_f64())
    }

    /// Non-realtime bytes received while the RX buffer was full (0 for a client that counts
    /// characters correctly).
    pub fn rx_overflow_bytes(&self) -> u64 {
        self.shared.lock().rx_overflow
    }

    /// Whether the laser shone at any time, from the output history (for the simulated
    /// camera; valid after the emulator is dropped too).
    pub fn laser_source(&self) -> Arc<dyn LaserSource> {
        Arc::new(EmulatorLaser(self.shared.clone()))
    }

    /// Whether the laser is on now.
    pub fn laser_on(&self) -> bool {
        self.shared.lock().laser_at(Timestamp::now().as_secs_f64())
    }

    /// Current `$N` settings.
    pub fn settings(&self) -> std::collections::BTreeMap<u32, f64> {
        self.shared.lock().settings.clone()
    }
}

impl Drop for GrblEmulator {
    fn drop(&mut self) {
        let _ = self.cmds.send(Cmd::Stop);
        pty::wake(&self.wake_tx);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
