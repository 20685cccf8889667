//! The protocol thread: serial I/O on the pty master, realtime bytes, line execution.

use super::config::Fault;
use super::gcode::{self, err, Action, Modal};
use super::machine::{format_setting, Machine, MachineState, Shared, PLANNER_BLOCKS};
use super::motion::{MoveKind, Spec};
use super::pty::{self, Pty};
use crossbeam_channel::Receiver;
use std::collections::VecDeque;
use std::os::fd::OwnedFd;
use std::sync::{Arc, MutexGuard};

/// The power-up/reset banner line (printed after an empty line).
pub(crate) const BANNER: &str = "\r\nGrbl 1.1h ['$' for help]";

pub(crate) enum Cmd {
    Fault(Fault),
    Replug(crossbeam_channel::Sender<std::io::Result<std::path::PathBuf>>),
    Stop,
}

/// A line that could not complete yet; no `ok` is sent until it does.
#[derive(Clone, Debug)]
enum Blocked {
    /// Planner full: the block waits for room.
    Queue(Spec),
    /// G4: waits for the planner to empty, then dwells.
    Sync(f64),
    Dwell(f64),
    Homing,
    /// A failed homing cycle aborting: at the instant given, the `$H`'s `ok` and the reset.
    HomingAbort(f64),
    /// A spindle or coolant switch: GRBL waits for the queued motion to finish before it
    /// switches the output and answers.
    Outputs,
    /// A soft-limit alarm is pending; the line that caused it is never answered.
    Alarm,
}

const OUTBOX_LIMIT: usize = 1 << 18;
/// History kept for `physical_x` at past timestamps.
const HISTORY_S: f64 = 30.0;

pub(crate) struct Server {
    shared: Arc<Shared>,
    pty: Option<Pty>,
    wake_rx: OwnedFd,
    cmds: Receiver<Cmd>,
    rx_buffer: usize,
    status_latency: f64,
    /// When a received feed hold takes effect (see `EmulatorConfig::hold_latency_us`).
    pending_hold: Option<f64>,
    /// Received, unprocessed non-realtime bytes (the serial RX buffer, plus whatever an
    /// over-sending client pushed beyond it, counted in `rx_overflow`).
    input: VecDeque<u8>,
    last_cr: bool,
    blocked: Option<Blocked>,
    modal: Modal,
    silent: bool,
    outbox: VecDeque<(f64, Vec<u8>)>,
    outbox_bytes: usize,
    wco_counter: u32,
    ovr_counter: u32,
    /// Injected faults still to fire.
    homing_fail: Option<u8>,
    /// The alarm the running homing cycle will end with.
    homing_failing: Option<u8>,
    drop_ok: u32,
    corrupt_ok: u32,
    corrupt_status: u32,
    reject_next: Option<u8>,
}

fn now_s() -> f64 {
    footscan_hal::Timestamp::now().as_secs_f64()
}

/// Format like GRBL's printFloat with 3 decimals, never printing "-0.000".
fn f3(v: f64) -> String {
    let s = format!("{v:.3}");
    if s == "-0.000" {
        "0.000".into()
    } else {
        s
    }
}

impl Server {
    pub fn new(
        shared: Arc<Shared>,
        pty: Pty,
        wake_rx: OwnedFd,
        cmds: Receiver<Cmd>,
        rx_buffer: usize,
        status_latency_us: u64,
    ) -> Server {
        Server {
            shared,
            pty: Some(pty),
            wake_rx,
            cmds,
            rx_buffer: rx_buffer.max(1),
            status_latency: status_latency_us as f64 * 1e-6,
            pending_hold: None,
            input: VecDeque::new(),
            last_cr: false,
            blocked: None,
            modal: Modal::new(0.0),
            silent: false,
            outbox: VecDeque::new(),
            outbox_bytes: 0,
            wco_counter: 0,
            ovr_counter: 0,
            homing_fail: None,
            homing_failing: None,
            drop_ok: 0,
            corrupt_ok: 0,
            corrupt_status: 0,
            reject_next: None,
        }
    }

    fn machine(&self) -> MutexGuard<'_, Machine> {
        self.shared
            .machine
            .lock()
            .unwrap_or_else(|e| e.into_inner())
    }

    fn emit_at(&mut self, release: f64, s: &str) {
        if s == "ok" && self.drop_ok > 0 {
            self.drop_ok -= 1;
            return;
        }
        let s = if s == "ok" && self.corrupt_ok > 0 {
            self.corrupt_ok -= 1;
            "0k"
        } else {
            s
        };
        if self.outbox_bytes + s.len() + 2 > OUTBOX_LIMIT {
            // Nobody is reading the port; a real UART would drop the bytes too.
            return;
        }
        let mut b = Vec::with_capacity(s.len() + 2);
        b.extend_from_slice(s.as_bytes());
        b.extend_from_slice(b"\r\n");
        self.outbox_bytes += b.len();
        self.outbox.push_back((release, b));
    }

    fn emit(&mut self, s: &str) {
        self.emit_at(0.0, s);
    }

    fn respond(&mut self, r: Result<(), u8>) {
        match r {
            Ok(()) => self.emit("ok"),
            Err(code) => self.emit(&format!("error:{code}")),
        }
    }

    /// Power-up messages, written before the thread starts so that they are in the pty before
    /// `spawn` returns (a client that flushes its input on open then never sees them late).
    pub fn power_up(&mut self) {
        self.emit(BANNER);
        if self.machine().alarm {
            self.emit("[MSG:'$H'|'$X' to unlock]");
        }
        self.flush(now_s());
    }

    pub fn run(mut self) {
        let mut buf = [0u8; 256];
        loop {
            if !self.handle_cmds() {
                return;
            }
            if self.pty.is_none() {
                // Disconnected: nothing to serve until a replug or Stop.
                match self.cmds.recv() {
                    Ok(Cmd::Fault(_)) => continue,
                    Ok(Cmd::Replug(reply)) => {
                        let _ = reply.send(self.replug());
                        continue;
                    }
                    _ => return,
                }
            }
            let now = now_s();
            self.tick(now);
            if !self.silent {
                self.process_lines();
                self.flush(now_s());
            }
            // Sleep until input, a wake-up, or the next scheduled event.
            let now = now_s();
            let mut next = self.machine().next_event(now);
            if let Some(Blocked::Dwell(t) | Blocked::HomingAbort(t)) = self.blocked {
                next = Some(next.map_or(t, |n| n.min(t)));
            }
            if let Some(t) = self.pending_hold {
                next = Some(next.map_or(t, |n| n.min(t)));
            }
            if let Some(&(t, _)) = self.outbox.front() {
                if t > now {
                    next = Some(next.map_or(t, |n| n.min(t)));
                }
            }
            let timeout = next.map_or(0.02, |t| (t - now).clamp(0.0, 0.02));
            let mut events = 0;
            if !self.silent {
                events |= libc::POLLIN;
                if self.outbox.front().is_some_and(|&(t, _)| t <= now) {
                    events |= libc::POLLOUT;
                }
            }
            let master = self.pty.as_ref().map(|p| &p.master);
            let (rev, woke) = pty::poll2(master, events, &self.wake_rx, timeout);
            if woke {
                pty::drain(&self.wake_rx);
            }
            // Faults injected before the client wrote what just arrived act on it.
            if !self.handle_cmds() {
                return;
            }
            if self.pty.is_none() {
                continue;
            }
            if rev & libc::POLLIN != 0 && !self.silent {
                let res = pty::read_nb(&self.pty.as_ref().expect("open").master, &mut buf);
                match res {
                    Ok(Some(n)) if n > 0 => {
                        for &b in &buf[..n] {
                            self.on_byte(b);
                        }
                    }
                    Ok(_) => {}
                    Err(e) => {
                        tracing::debug!("grbl emulator: read: {e}");
                        std::thread::sleep(std::time::Duration::from_millis(5));
                    }
                }
            } else if rev & (libc::POLLHUP | libc::POLLERR) != 0 {
                // Cannot happen while we hold the slave open; avoid spinning if it does.
                std::thread::sleep(std::time::Duration::from_millis(5));
            }
        }
    }

    /// Apply pending commands; false on Stop.
    fn handle_cmds(&mut self) -> bool {
        while let Ok(cmd) = self.cmds.try_recv() {
            match cmd {
                Cmd::Stop => return false,
                Cmd::Fault(f) => self.fault(f),
                Cmd::Replug(reply) => {
                    let _ = reply.send(self.replug());
                }
            }
        }
        true
    }

    /// Hang up the current pty and serve the same machine on a new one.
    fn replug(&mut self) -> std::io::Result<std::path::PathBuf> {
        self.pty = None;
        self.outbox.clear();
        self.outbox_bytes = 0;
        self.input.clear();
        self.last_cr = false;
        let pty = Pty::open()?;
        let path = pty.path.clone();
        self.pty = Some(pty);
        Ok(path)
    }

    fn fault(&mut self, f: Fault) {
        let now = now_s();
        match f {
            Fault::HomingFail(code) => self.homing_fail = Some(code),
            Fault::DropOk(n) => self.drop_ok += n,
            Fault::CorruptOk(n) => self.corrupt_ok += n,
            Fault::CorruptStatus(n) => self.corrupt_status += n,
            Fault::RejectNext(code) => self.reject_next = Some(code),
            Fault::Silence(s) => self.silent = s,
            Fault::Disconnect => {
                // Closing the master (and our slave handle) hangs up the client's port.
                self.pty = None;
                self.outbox.clear();
                self.outbox_bytes = 0;
            }
            Fault::Alarm(code) => {
                {
                    let mut m = self.machine();
                    m.halt(now);
                    m.alarm = true;
                }
                self.blocked = None;
                self.emit(&format!("ALARM:{code}"));
                if code == 1 || code == 2 {
                    self.machine().critical = true;
                    self.emit("[MSG:Reset to continue]");
                } else {
                    // Any other alarm aborts through the reset path: re-init and banner.
                    self.reinit(now);
                }
            }
        }
    }

    /// Realtime bytes act at once; everything else goes to the line buffer.
    fn on_byte(&mut self, b: u8) {
        let now = now_s();
        match b {
            b'?' => {
                let mut report = self.status_report(now);
                if self.corrupt_status > 0 {
                    self.corrupt_status -= 1;
                    // Line noise on one character of the position.
                    if let Some(i) = report.find("Pos:") {
                        report.replace_range(i + 4..i + 5, "#");
                    }
                }
                self.emit_at(now + self.status_latency, &report);
                self.flush(now);
            }
            b'!' => {
                let latency = self.shared.config.hold_latency_us as f64 * 1e-6;
                if latency > 0.0 {
                    self.pending_hold.get_or_insert(now + latency);
                } else {
                    self.machine().feed_hold(now);
                }
            }
            // A cycle start that arrives before the hold it would end has taken effect is
            // dropped, as in GRBL (the hold wins when both are pending).
            b'~' if self.pending_hold.is_some() => {}
            b'~' => self.machine().cycle_start(now),
            0x18 => self.soft_reset(now),
            0x85 => {
                if self.machine().jog_cancel(now) {
                    let x = self.machine().timeline.end_x();
                    self.modal.x = x;
                    if let Some(Blocked::Queue(spec)) = self.blocked {
                        if spec.kind == MoveKind::Jog {
                            // Acknowledge but discard a jog that was waiting for planner room.
                            self.blocked = None;
                            self.emit("ok");
                        }
                    }
                }
            }
            0x80..=0xff => {} // overrides, safety door, coolant toggles: not emulated
            _ => {
                if self.input.len() >= self.rx_buffer {
                    let mut m = self.machine();
                    if m.rx_overflow == 0 {
                        tracing::warn!(
                            "grbl emulator: serial RX buffer ({} bytes) overflow: the client is not counting characters",
                            self.rx_buffer
                        );
                    }
                    m.rx_overflow += 1;
                }
                self.input.push_back(b);
                {
                    let n = self.input.len();
                    let mut m = self.machine();
                    m.rx_peak = m.rx_peak.max(n);
                }
                if b == b'\n' || b == b'\r' {
                    self.process_lines();
                }
            }
        }
    }

    fn soft_reset(&mut self, now: f64) {
        self.pending_hold = None;
        let (moving, homing) = {
            let m = self.machine();
            (m.is_moving(now), m.state(now) == MachineState::Home)
        };
        {
            let mut m = self.machine();
            m.halt(now);
            m.critical = false;
            if moving {
                m.alarm = true;
            }
        }
        if moving {
            self.emit(if homing { "ALARM:6" } else { "ALARM:3" });
        }
        self.reinit(now);
    }

    /// GRBL's re-initialisation after a reset or abort: flush input, reset the parser, banner.
    fn reinit(&mut self, now: f64) {
        self.homing_failing = None;
        self.input.clear();
        self.last_cr = false;
        self.blocked = None;
        let (alarm, x) = {
            let mut m = self.machine();
            m.check_mode = false;
            (m.alarm, m.timeline.machine_at(now))
        };
        self.modal = Modal::new(x);
        self.machine().set_outputs(now, false, false);
        self.wco_counter = 0;
        self.ovr_counter = 0;
        self.emit(BANNER);
        if alarm {
            self.emit("[MSG:'$H'|'$X' to unlock]");
        }
    }

    /// Advance time-driven state: blocked lines, homing completion, soft-limit alarms.
    fn tick(&mut self, now: f64) {
        if self.pending_hold.is_some_and(|t| now >= t) {
            self.pending_hold = None;
            self.machine().feed_hold(now);
        }
        let fire_alarm = {
            let mut m = self.machine();
            m.timeline.prune(now - HISTORY_S);
            match m.pending_alarm {
                Some((code, t)) if now >= t => {
                    m.pending_alarm = None;
                    m.hold = None;
                    m.alarm = true;
                    m.critical = true;
                    Some(code)
                }
                _ => None,
            }
        };
        if let Some(code) = fire_alarm {
            self.blocked = None;
            self.emit(&format!("ALARM:{code}"));
            self.emit("[MSG:Reset to continue]");
        }
        match self.blocked.clone() {
            Some(Blocked::Homing) => {
                let done = {
                    let mut m = self.machine();
                    match m.homing_until {
                        Some(t) if now >= t => {
                            m.homing_until = None;
                            true
                        }
                        None => true,
                        _ => false,
                    }
                };
                if done {
                    self.blocked = None;
                    if let Some(code) = self.homing_failing.take() {
                        // GRBL: the alarm, the `$H` line's `ok` after the abort (seen
                        // 0.55 s later in grbl-sim), then the reset path (banner, lock).
                        {
                            let mut m = self.machine();
                            m.halt(now);
                            m.alarm = true;
                        }
                        self.emit(&format!("ALARM:{code}"));
                        let abort = self.shared.config.homing_abort_seconds.max(0.0);
                        self.blocked = Some(Blocked::HomingAbort(now + abort));
                        self.tick(now);
                    } else {
                        self.modal.x = 0.0;
                        self.emit("ok");
                    }
                }
            }
            Some(Blocked::Queue(spec)) => {
                let queued = {
                    let mut m = self.machine();
                    if m.planner_full(now) {
                        false
                    } else {
                        m.queue(now, spec);
                        true
                    }
                };
                if queued {
                    self.blocked = None;
                    self.emit("ok");
                }
            }
            Some(Blocked::Sync(p)) => {
                let empty = {
                    let m = self.machine();
                    m.busy(now) == 0 && m.hold.is_none()
                };
                if empty {
                    self.blocked = Some(Blocked::Dwell(now + p));
                    self.tick(now);
                }
            }
            Some(Blocked::Dwell(t)) if now >= t => {
                self.blocked = None;
                self.emit("ok");
            }
            Some(Blocked::HomingAbort(t)) if now >= t => {
                self.blocked = None;
                self.emit("ok");
                // The reset discards whatever arrived during the abort.
                self.reinit(now);
            }
            Some(Blocked::Outputs) => {
                let empty = {
                    let m = self.machine();
                    m.busy(now) == 0 && m.hold.is_none()
                };
                if empty {
                    self.blocked = None;
                    self.apply_outputs(now);
                    self.emit("ok");
                }
            }
            _ => {}
        }
    }

    fn process_lines(&mut self) {
        loop {
            if self.blocked.is_some() || self.silent || self.machine().critical {
                return;
            }
            let Some(end) = self.input.iter().position(|&c| c == b'\n' || c == b'\r') else {
                return;
            };
            let raw: Vec<u8> = self.input.drain(..end).collect();
            let term = self.input.pop_front().expect("terminator");
            // "\r\n" ends one line (GRBL itself would answer the empty line between them).
            let crlf_tail = term == b'\n' && self.last_cr && raw.is_empty();
            self.last_cr = term == b'\r';
            if crlf_tail {
                continue;
            }
            self.execute_line(&raw);
            let now = now_s();
            self.tick(now);
            self.flush(now);
        }
    }

    fn execute_line(&mut self, raw: &[u8]) {
        if let Some(code) = self.reject_next.take() {
            return self.respond(Err(code));
        }
        let line = gcode::clean(raw);
        if line.len() > gcode::MAX_LINE {
            return self.respond(Err(err::OVERFLOW));
        }
        if line.is_empty() {
            return self.respond(Ok(()));
        }
        let now = now_s();
        if line[0] == b'$' {
            let r = self.system_line(&line, now);
            if let Some(r) = r {
                self.respond(r);
            }
            return;
        }
        let state = self.machine().state(now);
        if matches!(state, MachineState::Alarm | MachineState::Jog) {
            return self.respond(Err(err::SYSTEM_GC_LOCK));
        }
        let mut modal = self.modal.clone();
        let action = match gcode::interpret(&line, &mut modal) {
            Ok(a) => a,
            Err(e) => return self.respond(Err(e)),
        };
        match action {
            Action::None => {
                let laser_mode = self.machine().laser_mode();
                let switched =
                    (modal.spindle_on, modal.flood) != (self.modal.spindle_on, self.modal.flood);
                let power = modal.spindle != self.modal.spindle;
                self.modal = modal;
                if state == MachineState::Check {
                    return self.respond(Ok(()));
                }
                if switched || (power && !laser_mode) {
                    // GRBL syncs the planner before a spindle or coolant switch (in laser mode
                    // too; there a power change alone applies at once): the answer comes when
                    // the queued motion has run.
                    self.blocked = Some(Blocked::Outputs);
                    self.tick(now);
                    return;
                }
                self.apply_outputs(now);
                self.respond(Ok(()));
            }
            Action::Dwell(p) => {
                self.modal = modal;
                if state == MachineState::Check {
                    return self.respond(Ok(()));
                }
                self.apply_outputs(now);
                self.blocked = Some(Blocked::Sync(p));
                self.tick(now);
            }
            Action::Move { x, rapid, feed } => {
                let (soft, travel, max_rate) = {
                    let m = self.machine();
                    (m.soft_limits(), m.travel(), m.max_rate())
                };
                if soft && !(-1e-6..=travel + 1e-6).contains(&x) {
                    // GRBL: feed hold if in a cycle, then reset and ALARM:2; the line gets no
                    // answer and everything but '?' and reset is ignored until reset.
                    self.machine().soft_limit(now);
                    self.blocked = Some(Blocked::Alarm);
                    self.tick(now);
                    return;
                }
                self.modal = modal;
                if state == MachineState::Check {
                    return self.respond(Ok(()));
                }
                self.apply_outputs(now);
                let spec = Spec {
                    kind: MoveKind::Line,
                    target: x,
                    feed: if rapid { max_rate } else { feed },
                };
                self.queue_or_block(now, spec);
            }
        }
    }

    /// The spindle and coolant outputs of the modal state, to the machine (the laser). In
    /// laser mode (`$32=1`) GRBL 1.1h lights the spindle output at rest only in a G1 motion
    /// mode with a power above 0 (after a reset the mode is G0, and `M3 S..` stays dark).
    fn apply_outputs(&mut self, now: f64) {
        let laser_mode = self.machine().laser_mode();
        let spindle = self.modal.spindle_on
            && (!laser_mode
                || (self.modal.motion == gcode::Motion::Linear && self.modal.spindle > 0.0));
        let flood = self.modal.flood;
        self.machine().set_outputs(now, spindle, flood);
    }

    fn queue_or_block(&mut self, now: f64, spec: Spec) {
        let queued = {
            let mut m = self.machine();
            if m.planner_full(now) {
                false
            } else {
                m.queue(now, spec);
                true
            }
        };
        if queued {
            self.respond(Ok(()));
        } else {
            self.blocked = Some(Blocked::Queue(spec));
        }
    }

    /// `$` commands, after GRBL's `system_execute_line`. `None` means the answer comes later.
    fn system_line(&mut self, line: &[u8], now: f64) -> Option<Result<(), u8>> {
        let state = self.machine().state(now);
        let rest = &line[1..];
        match rest.first().copied() {
            None => {
                self.emit(
                    "[HLP:$$ $# $G $I $N $x=val $Nx=line $J=line $SLP $C $X $H ~ ! ? ctrl-x]",
                );
                Some(Ok(()))
            }
            Some(b'J') => {
                if !matches!(state, MachineState::Idle | MachineState::Jog) {
                    return Some(Err(err::IDLE_ERROR));
                }
                if rest.get(1) != Some(&b'=') {
                    return Some(Err(err::INVALID_STATEMENT));
                }
                let (target, feed) = match gcode::interpret_jog(&rest[2..], &self.modal) {
                    Ok(v) => v,
                    Err(e) => return Some(Err(e)),
                };
                let Some(x) = target else {
                    return Some(Ok(()));
                };
                let (soft, travel) = {
                    let m = self.machine();
                    (m.soft_limits(), m.travel())
                };
                if soft && !(-1e-6..=travel + 1e-6).contains(&x) {
                    return Some(Err(err::TRAVEL_EXCEEDED));
                }
                self.modal.x = x;
                self.queue_or_block(
                    now,
                    Spec {
                        kind: MoveKind::Jog,
                        target: x,
                        feed,
                    },
                );
                None
            }
            Some(c @ (b'$' | b'G' | b'C' | b'X')) => {
                if rest.len() != 1 {
                    return Some(Err(err::INVALID_STATEMENT));
                }
                match c {
                    b'$' => {
                        if matches!(state, MachineState::Run | MachineState::Hold(_)) {
                            return Some(Err(err::IDLE_ERROR));
                        }
                        let lines: Vec<String> = self
                            .machine()
                            .settings
                            .iter()
                            .map(|(&k, &v)| format_setting(k, v))
                            .collect();
                        for l in lines {
                            self.emit(&l);
                        }
                    }
                    b'G' => {
                        let r = self.modal.report();
                        self.emit(&r);
                    }
                    b'C' => {
                        if state == MachineState::Check {
                            self.emit("[MSG:Disabled]");
                            self.soft_reset(now);
                            return None;
                        }
                        if state != MachineState::Idle {
                            return Some(Err(err::IDLE_ERROR));
                        }
                        self.machine().check_mode = true;
                        self.emit("[MSG:Enabled]");
                    }
                    _ => {
                        if state == MachineState::Alarm {
                            self.emit("[MSG:Caution: Unlocked]");
                            self.machine().alarm = false;
                        }
                    }
                }
                Some(Ok(()))
            }
            Some(c) => {
                if !matches!(state, MachineState::Idle | MachineState::Alarm) {
                    return Some(Err(err::IDLE_ERROR));
                }
                match c {
                    b'#' if rest.len() == 1 => {
                        for l in [
                            "[G54:0.000,0.000,0.000]",
                            "[G55:0.000,0.000,0.000]",
                            "[G56:0.000,0.000,0.000]",
                            "[G57:0.000,0.000,0.000]",
                            "[G58:0.000,0.000,0.000]",
                            "[G59:0.000,0.000,0.000]",
                            "[G28:0.000,0.000,0.000]",
                            "[G30:0.000,0.000,0.000]",
                            "[G92:0.000,0.000,0.000]",
                            "[TLO:0.000]",
                            "[PRB:0.000,0.000,0.000:0]",
                        ] {
                            self.emit(l);
                        }
                        Some(Ok(()))
                    }
                    b'H' if rest.len() == 1 => {
                        if !self.machine().homing_enabled() {
                            return Some(Err(err::SETTING_DISABLED));
                        }
                        self.machine().start_homing(now);
                        self.homing_failing = self.homing_fail.take();
                        self.blocked = Some(Blocked::Homing);
                        self.tick(now);
                        None
                    }
                    b'I' if rest.len() == 1 => {
                        self.emit("[VER:1.1h.20190830:]");
                        let opt = format!("[OPT:V,{PLANNER_BLOCKS},{}]", self.rx_buffer);
                        self.emit(&opt);
                        Some(Ok(()))
                    }
                    b'N' if rest.len() == 1 => {
                        self.emit("$N0=");
                        self.emit("$N1=");
                        Some(Ok(()))
                    }
                    b'R' if rest.starts_with(b"RST=") => {
                        match &rest[4..] {
                            b"$" | b"*" => {
                                let cfg = self.shared.config.clone();
                                self.machine().settings = super::machine::default_settings(&cfg);
                            }
                            b"#" => {}
                            _ => return Some(Err(err::INVALID_STATEMENT)),
                        }
                        self.emit("[MSG:Restoring defaults]");
                        Some(Ok(()))
                    }
                    _ => Some(self.store_setting(rest)),
                }
            }
        }
    }

    /// `$N=value`.
    fn store_setting(&mut self, rest: &[u8]) -> Result<(), u8> {
        let mut i = 0;
        let n = gcode::read_float(rest, &mut i).ok_or(err::BAD_NUMBER_FORMAT)?;
        if rest.get(i) != Some(&b'=') {
            return Err(err::INVALID_STATEMENT);
        }
        i += 1;
        let v = gcode::read_float(rest, &mut i).ok_or(err::BAD_NUMBER_FORMAT)?;
        if i != rest.len() || n > 255.0 || n.fract() != 0.0 {
            return Err(err::INVALID_STATEMENT);
        }
        if v < 0.0 {
            return Err(err::NEGATIVE_VALUE);
        }
        let k = n as u32;
        let mut m = self.machine();
        if !m.settings.contains_key(&k) {
            return Err(err::INVALID_STATEMENT);
        }
        if k == 20 && v != 0.0 && !m.homing_enabled() {
            return Err(err::SOFT_LIMIT_ERROR);
        }
        m.settings.insert(k, v);
        if k == 22 && v == 0.0 {
            m.settings.insert(20, 0.0);
        }
        Ok(())
    }

    fn status_report(&mut self, now: f64) -> String {
        let m = self.machine();
        let state = m.state(now);
        let x = m.timeline.machine_at(now);
        let rate = m.timeline.velocity_at(now).abs() * 60.0;
        let mask = m.status_mask();
        let busy = m.busy(now);
        drop(m);
        let mut s = format!("<{state}|");
        let pos = format!("{},0.000,0.000", f3(x));
        if mask & 1 != 0 {
            s += &format!("MPos:{pos}");
        } else {
            // No work offsets are emulated: WCO is zero, so WPos equals MPos.
            s += &format!("WPos:{pos}");
        }
        if mask & 2 != 0 {
            let rx_free = self.rx_buffer.saturating_sub(self.input.len());
            s += &format!(
                "|Bf:{},{rx_free}",
                PLANNER_BLOCKS - busy.min(PLANNER_BLOCKS)
            );
        }
        s += &format!("|FS:{rate:.0},0");
        let busy_state = !matches!(
            state,
            MachineState::Idle | MachineState::Alarm | MachineState::Check
        );
        // GRBL interleaves WCO and override fields every few reports.
        if self.wco_counter > 0 {
            self.wco_counter -= 1;
        } else {
            self.wco_counter = if busy_state { 29 } else { 9 };
            if self.ovr_counter == 0 {
                self.ovr_counter = 1;
            }
            s += "|WCO:0.000,0.000,0.000";
        }
        if self.ovr_counter > 0 {
            self.ovr_counter -= 1;
        } else {
            self.ovr_counter = if busy_state { 19 } else { 9 };
            s += "|Ov:100,100,100";
        }
        s.push('>');
        s
    }

    fn flush(&mut self, now: f64) {
        let Some(pty) = &self.pty else {
            return;
        };
        if self.silent {
            return;
        }
        while let Some((t, bytes)) = self.outbox.front_mut() {
            if *t > now {
                break;
            }
            match pty::write_nb(&pty.master, bytes) {
                Ok(0) => break,
                Ok(n) if n < bytes.len() => {
                    bytes.drain(..n);
                    self.outbox_bytes -= n;
                    break;
                }
                Ok(n) => {
                    self.outbox_bytes -= n;
                    self.outbox.pop_front();
                }
                Err(e) => {
                    tracing::debug!("grbl emulator: write: {e}");
                    self.outbox.clear();
                    self.outbox_bytes = 0;
                    break;
                }
            }
        }
    }
}
