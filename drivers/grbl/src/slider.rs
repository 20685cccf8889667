//! [`GrblSlider`]: the [`Slider`] implementation over a serial port.

use crate::codes::{alarm_message, error_message};
use crate::message::{banner_version, parse_line, Message, StatusReport};
use crate::settings::{BuildInfo, GrblSettings};
use footscan_hal::{
    HalError, HalResult, Slider, SliderInfo, SliderSettings, SliderState, SliderStatus, Timestamp,
};
use serialport::{ClearBuffer, SerialPort};
use std::collections::VecDeque;
use std::io::{ErrorKind, Read, Write};
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
}

impl Default for GrblConfig {
    fn default() -> Self {
        GrblConfig {
            baud: 115_200,
            response_timeout: Duration::from_secs(2),
            reset_timeout: Duration::from_secs(5),
            homing_timeout: Duration::from_secs(60),
            poll_interval: Duration::from_millis(20),
            rx_buffer: 128,
        }
    }
}

/// How a sent line ended.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Outcome {
    Ok,
    Error(u32),
    /// Never answered: the controller alarmed (and discards its input) or reset.
    LostToAlarm(u32),
    LostToReset,
    /// No `ok`/`error:N` arrived for it before the answer of a later `$G` sync: the controller
    /// dropped it or it arrived mangled.
    Lost,
}

/// Counters of the faults the driver absorbed since it was created.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct GrblStats {
    /// Lines GRBL would never send (line noise, a wrong baud rate), ignored.
    pub garbage_lines: u64,
    /// Of those, status reports (`<...`) that did not parse; the `?` was asked again.
    pub corrupt_reports: u64,
    /// Answers (`ok`/`error:N`) that never arrived, found by a `$G` resync.
    pub lost_answers: u64,
    /// `$G` resyncs of the answer counting (after a timeout or noise while lines were pending).
    pub resyncs: u64,
    /// Successful [`GrblSlider::reconnect`]s.
    pub reconnects: u64,
}

/// Times a `?` is asked again after a corrupted report before giving up with `BadData`.
const STATUS_RETRIES: u32 = 3;

#[derive(Clone, Debug)]
struct InFlight {
    id: u64,
    /// Bytes it occupies in the controller's RX buffer (line + '\n').
    len: usize,
    line: String,
    /// A `$G` sent to resynchronise: answers missing before its `[GC:...]` are lost.
    sync: bool,
}

/// A GRBL 1.1 controller driving the scan axis (X) of the slider.
///
/// All I/O is synchronous on the caller's thread: every call writes what it needs, then reads
/// and routes incoming lines until its own answer arrives or its deadline passes. Lines are
/// routed as GRBL interleaves them: `ok`/`error:N` answer the oldest unanswered line sent
/// (character-counting order), `<...>` status reports answer `?`, `ALARM:N`, `[MSG:...]` and
/// banners update the alarm and reset state whenever they arrive.
pub struct GrblSlider {
    port_name: String,
    config: GrblConfig,
    port: Option<Box<dyn SerialPort>>,
    rx: Vec<u8>,
    next_id: u64,
    in_flight: VecDeque<InFlight>,
    answered: VecDeque<(u64, Outcome, String)>,
    reports: u64,
    last_report: Option<(StatusReport, Timestamp)>,
    wco: Option<Vec<f64>>,
    alarm: Option<u32>,
    banners: u64,
    banner: Option<String>,
    rx_buffer: usize,
    settings_acc: SliderSettings,
    feedback: Vec<String>,
    jogging: bool,
    /// When the bytes now at the end of `rx` arrived.
    rx_time: Timestamp,
    build_info: Option<BuildInfo>,
    stats: GrblStats,
    /// The answer counting may be off (a timeout, or noise while lines were pending): the
    /// next command resyncs with `$G` first.
    unsynced: bool,
    /// The last few garbage lines, for error messages.
    garbage: VecDeque<String>,
    /// The line a resync runs for, and its answer once the resync has seen it.
    awaited: Option<(u64, Option<(Outcome, String)>)>,
}

impl std::fmt::Debug for GrblSlider {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GrblSlider")
            .field("port", &self.port_name)
            .field("connected", &self.port.is_some())
            .field("banner", &self.banner)
            .field("alarm", &self.alarm)
            .field("in_flight", &self.in_flight.len())
            .field("stats", &self.stats)
            .finish()
    }
}

fn midpoint(a: Timestamp, b: Timestamp) -> Timestamp {
    Timestamp {
        nanos: a.nanos + (b.nanos.saturating_sub(a.nanos)) / 2,
    }
}

/// Longest line GRBL accepts (its line buffer is 80 bytes including the terminator).
const MAX_LINE: usize = 79;

impl GrblSlider {
    pub fn new(port: impl Into<String>, config: GrblConfig) -> Self {
        let rx_buffer = config.rx_buffer;
        GrblSlider {
            port_name: port.into(),
            config,
            port: None,
            rx: Vec::new(),
            next_id: 0,
            in_flight: VecDeque::new(),
            answered: VecDeque::new(),
            reports: 0,
            last_report: None,
            wco: None,
            alarm: None,
            banners: 0,
            banner: None,
            rx_buffer,
            settings_acc: SliderSettings::new(),
            feedback: Vec::new(),
            jogging: false,
            rx_time: Timestamp::default(),
            build_info: None,
            stats: GrblStats::default(),
            unsynced: false,
            garbage: VecDeque::new(),
            awaited: None,
        }
    }

    pub fn port_name(&self) -> &str {
        &self.port_name
    }
    pub fn config(&self) -> &GrblConfig {
        &self.config
    }
    /// The last banner, e.g. `Grbl 1.1h ['$' for help]`.
    pub fn banner(&self) -> Option<&str> {
        self.banner.as_deref()
    }
    /// The alarm the controller is known to be in (0: locked without a code), if any.
    pub fn alarm(&self) -> Option<u32> {
        self.alarm
    }
    /// The controller's serial RX buffer used for character counting.
    pub fn rx_buffer(&self) -> usize {
        self.rx_buffer
    }
    pub fn is_connected(&self) -> bool {
        self.port.is_some()
    }
    /// `$I` of the last connect, if the controller answered it.
    pub fn build_info(&self) -> Option<&BuildInfo> {
        self.build_info.as_ref()
    }
    /// Faults absorbed so far.
    pub fn stats(&self) -> GrblStats {
        self.stats
    }

    // ----- errors -------------------------------------------------------------------------

    fn timeout(&self, what: impl Into<String>, after: Duration) -> HalError {
        HalError::Timeout {
            device: self.port_name.clone(),
            what: what.into(),
            after,
        }
    }

    fn bad(&self, detail: impl Into<String>) -> HalError {
        HalError::BadData {
            device: self.port_name.clone(),
            detail: detail.into(),
        }
    }

    fn alarm_error(&self, code: u32) -> HalError {
        HalError::Alarm {
            device: self.port_name.clone(),
            code,
            message: alarm_message(code).to_string(),
        }
    }

    fn rejected(&self, code: u32, line: &str) -> HalError {
        HalError::Rejected {
            device: self.port_name.clone(),
            code,
            message: format!("{} (`{line}`)", error_message(code)),
        }
    }

    /// The port is gone: drop it so later calls fail fast until `connect`.
    fn lost(&mut self, reason: impl Into<String>) -> HalError {
        self.port = None;
        self.in_flight.clear();
        self.rx.clear();
        HalError::Disconnected {
            device: self.port_name.clone(),
            reason: reason.into(),
        }
    }

    fn not_open(&self) -> HalError {
        HalError::Disconnected {
            device: self.port_name.clone(),
            reason: "port not open (call connect)".into(),
        }
    }

    // ----- raw I/O ------------------------------------------------------------------------

    fn write_raw(&mut self, bytes: &[u8]) -> HalResult<()> {
        let timeout = self.config.response_timeout;
        let Some(port) = self.port.as_mut() else {
            return Err(self.not_open());
        };
        let _ = port.set_timeout(timeout);
        // No flush: tcdrain has no timeout and would hang on a controller that stopped reading.
        match port.write_all(bytes) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == ErrorKind::TimedOut => {
                Err(self.timeout("the port to accept written bytes", timeout))
            }
            Err(e) => Err(self.lost(format!("write failed: {e}"))),
        }
    }

    /// One read of whatever is available, waiting until `deadline` at most.
    /// Returns whether anything arrived.
    fn read_some(&mut self, deadline: Instant) -> HalResult<bool> {
        let left = deadline.saturating_duration_since(Instant::now());
        let Some(port) = self.port.as_mut() else {
            return Err(self.not_open());
        };
        let _ = port.set_timeout(left);
        let mut buf = [0u8; 1024];
        match port.read(&mut buf) {
            Ok(0) => Err(self.lost("end of file on the port (hung up)")),
            Ok(n) => {
                self.rx_time = Timestamp::now();
                self.rx.extend_from_slice(&buf[..n]);
                Ok(true)
            }
            Err(e)
                if matches!(
                    e.kind(),
                    ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted
                ) =>
            {
                Ok(false)
            }
            Err(e) => Err(self.lost(format!("read failed: {e}"))),
        }
    }

    /// The next complete line already received, if any.
    fn take_line(&mut self) -> HalResult<Option<String>> {
        while let Some(i) = self.rx.iter().position(|&b| b == b'\n') {
            let raw: Vec<u8> = self.rx.drain(..=i).collect();
            let s = String::from_utf8_lossy(&raw).trim().to_string();
            if !s.is_empty() {
                return Ok(Some(s));
            }
        }
        if self.rx.len() > 512 {
            let junk: Vec<u8> = std::mem::take(&mut self.rx);
            return Err(self.bad(format!(
                "{} bytes without a line end: {:?}",
                junk.len(),
                String::from_utf8_lossy(&junk[..64])
            )));
        }
        Ok(None)
    }

    /// Route the next line, reading until one is complete or `deadline` passes.
    /// Returns false at the deadline.
    fn pump(&mut self, deadline: Instant) -> HalResult<bool> {
        loop {
            if let Some(line) = self.take_line()? {
                self.route(&line, self.rx_time)?;
                return Ok(true);
            }
            if Instant::now() >= deadline {
                return Ok(false);
            }
            self.read_some(deadline)?;
        }
    }

    /// Route everything that has already arrived, without waiting.
    fn drain_pending(&mut self) -> HalResult<()> {
        loop {
            while let Some(line) = self.take_line()? {
                self.route(&line, self.rx_time)?;
            }
            if !self.read_some(Instant::now())? {
                return Ok(());
            }
        }
    }

    fn lose_in_flight(&mut self, outcome: Outcome) {
        for f in self.in_flight.drain(..) {
            self.answered.push_back((f.id, outcome, f.line));
        }
    }

    /// The line router.
    fn route(&mut self, line: &str, at: Timestamp) -> HalResult<()> {
        match parse_line(line) {
            Message::Ok | Message::Error(_) => {
                let outcome = match parse_line(line) {
                    Message::Error(c) => Outcome::Error(c),
                    _ => Outcome::Ok,
                };
                match self.in_flight.pop_front() {
                    Some(f) => self.answered.push_back((f.id, outcome, f.line)),
                    None => tracing::debug!("{}: unsolicited {line:?}", self.port_name),
                }
            }
            Message::Alarm(code) => {
                tracing::warn!("{}: ALARM:{code}: {}", self.port_name, alarm_message(code));
                self.alarm = Some(code);
                self.jogging = false;
                self.lose_in_flight(Outcome::LostToAlarm(code));
            }
            Message::Status(r) => {
                self.reports += 1;
                if let Some(w) = &r.wco {
                    self.wco = Some(w.clone());
                }
                if r.state == SliderState::Alarm {
                    self.alarm.get_or_insert(0);
                } else {
                    self.alarm = None;
                }
                if r.state != SliderState::Jog {
                    self.jogging = false;
                }
                self.last_report = Some((r, at));
            }
            Message::Banner(b) => {
                self.banners += 1;
                self.banner = Some(b);
                self.wco = None;
                self.jogging = false;
                self.lose_in_flight(Outcome::LostToReset);
            }
            Message::Feedback(f) => {
                if f.starts_with("GC:") {
                    // `$G` answers in order: every line sent before a sync `$G` and still
                    // unanswered now has lost its answer.
                    if let Some(i) = self.in_flight.iter().position(|l| l.sync) {
                        for l in self.in_flight.drain(..i).collect::<Vec<_>>() {
                            self.stats.lost_answers += 1;
                            self.answered.push_back((l.id, Outcome::Lost, l.line));
                        }
                    }
                }
                if f == "MSG:'$H'|'$X' to unlock" {
                    self.alarm.get_or_insert(0);
                } else if f == "MSG:Caution: Unlocked" {
                    self.alarm = None;
                } else if let Some(opt) = f.strip_prefix("OPT:") {
                    // [OPT:V,15,128]: options, planner blocks, RX buffer bytes.
                    if let Some(n) = opt.split(',').nth(2).and_then(|n| n.trim().parse().ok()) {
                        self.rx_buffer = n;
                    }
                }
                if self.feedback.len() < 256 {
                    self.feedback.push(format!("[{f}]"));
                }
            }
            Message::Setting(k, v) => {
                self.settings_acc.insert(k, v);
            }
            Message::Other(o) => {
                if self.feedback.len() < 256 {
                    self.feedback.push(o);
                }
            }
            Message::Garbage(g) => {
                // Tolerated and counted: a mangled status report is asked again by
                // query_status; anything else may have been a mangled `ok`, so the answer
                // counting is resynchronised before the next command.
                let shown: String = g.chars().take(80).collect();
                tracing::warn!("{}: unexpected line {shown:?}", self.port_name);
                self.stats.garbage_lines += 1;
                if g.starts_with('<') {
                    self.stats.corrupt_reports += 1;
                } else if !self.in_flight.is_empty() {
                    self.unsynced = true;
                }
                if self.garbage.len() >= 8 {
                    self.garbage.pop_front();
                }
                self.garbage.push_back(shown);
            }
        }
        Ok(())
    }

    // ----- commands -----------------------------------------------------------------------

    fn in_flight_bytes(&self) -> usize {
        self.in_flight.iter().map(|f| f.len).sum()
    }

    /// Send one line (no line end) and register it for an answer.
    fn send_line(&mut self, line: &str) -> HalResult<u64> {
        self.send_line_as(line, false)
    }

    fn send_line_as(&mut self, line: &str, sync: bool) -> HalResult<u64> {
        let line = line.trim();
        if line.len() > MAX_LINE || line.contains(['\n', '\r']) {
            return Err(HalError::InvalidArgument {
                device: self.port_name.clone(),
                detail: format!(
                    "not a single GRBL line of at most {MAX_LINE} characters: {line:?}"
                ),
            });
        }
        if self.port.is_none() {
            return Err(self.not_open());
        }
        let mut bytes = Vec::with_capacity(line.len() + 1);
        bytes.extend_from_slice(line.as_bytes());
        bytes.push(b'\n');
        let id = self.next_id;
        self.next_id += 1;
        // Register first: the answer may be read by the same call that notices it.
        self.in_flight.push_back(InFlight {
            id,
            len: bytes.len(),
            line: line.to_string(),
            sync,
        });
        if let Err(e) = self.write_raw(&bytes) {
            self.in_flight.retain(|f| f.id != id);
            return Err(e);
        }
        Ok(id)
    }

    /// Wait for the answer to line `id`. With `patient`, the deadline is extended while the
    /// controller reports motion (a line waiting for planner room is answered only when a
    /// block completes).
    fn wait_answer(&mut self, id: u64, timeout: Duration, patient: bool) -> HalResult<()> {
        self.wait_answer_with(id, timeout, patient, true)
    }

    /// With `resync`, a timeout is followed by a `$G` sync that tells a late answer from a
    /// lost one, so the counting of later answers stays right either way.
    fn wait_answer_with(
        &mut self,
        id: u64,
        timeout: Duration,
        patient: bool,
        resync: bool,
    ) -> HalResult<()> {
        let mut deadline = Instant::now() + timeout;
        let mut synced = false;
        loop {
            while let Some(&(aid, _, _)) = self.answered.front() {
                if aid > id {
                    break;
                }
                let (aid, outcome, line) = self.answered.pop_front().expect("front");
                if aid < id && self.awaited.as_ref().is_some_and(|(w, _)| *w == aid) {
                    // A resync inside the wait for `aid` settled its fate: hand it back.
                    self.awaited = Some((aid, Some((outcome, line))));
                    continue;
                }
                if aid < id {
                    if let Outcome::Error(c) = outcome {
                        tracing::warn!(
                            "{}: unawaited `{line}` failed: error:{c}: {}",
                            self.port_name,
                            error_message(c)
                        );
                    }
                    continue;
                }
                return match outcome {
                    Outcome::Ok => Ok(()),
                    Outcome::Error(c) => Err(self.rejected(c, &line)),
                    Outcome::LostToAlarm(c) => Err(self.alarm_error(c)),
                    Outcome::LostToReset => Err(HalError::Disconnected {
                        device: self.port_name.clone(),
                        reason: format!("the controller reset while `{line}` was pending"),
                    }),
                    Outcome::Lost => Err(self.timeout(
                        format!(
                            "an answer to `{line}` (lost: an ok/error for the lines up to it never arrived; answer counting resynchronised with $G)"
                        ),
                        timeout,
                    )),
                };
            }
            if !self.in_flight.iter().any(|f| f.id == id) {
                return Err(self.bad(format!("answer to line #{id} went missing")));
            }
            if !self.pump(deadline)? {
                if patient {
                    // A live controller answers '?' within milliseconds; half the response
                    // timeout keeps a dead one's total under 1.5x that timeout.
                    let probe = Instant::now() + self.config.response_timeout / 2;
                    let busy = matches!(
                        self.query_status(probe)?.state,
                        SliderState::Run | SliderState::Jog | SliderState::Home
                    );
                    if busy {
                        if resync && !synced && self.port.is_some() {
                            // The answer may be lost while the machine runs (a scan move is
                            // seconds long): queue a `$G` behind the line now. GRBL answers in
                            // order, so a late answer still comes first; a lost one is marked
                            // so by the `[GC:...]` and returned above without waiting for the
                            // motion to end.
                            synced = true;
                            self.stats.resyncs += 1;
                            self.send_line_as("$G", true)?;
                        }
                        deadline = Instant::now() + timeout;
                        continue;
                    }
                }
                let line = self
                    .in_flight
                    .iter()
                    .find(|f| f.id == id)
                    .map(|f| f.line.clone())
                    .unwrap_or_default();
                if resync && !synced && self.port.is_some() {
                    synced = true;
                    // Settles this line's fate: answered late (then returned above) or lost.
                    self.awaited = Some((id, None));
                    let r = self.resync();
                    if let Some((aid, Some((outcome, line)))) = self.awaited.take() {
                        self.answered.push_front((aid, outcome, line));
                    }
                    if r.is_ok() {
                        continue;
                    }
                }
                self.unsynced = true;
                if !self.garbage.is_empty() {
                    let g: Vec<String> = self.garbage.iter().cloned().collect();
                    return Err(self.bad(format!(
                        "no answer to `{line}` within {timeout:?}; received instead: {}",
                        g.join(" | ")
                    )));
                }
                return Err(self.timeout(format!("an answer to `{line}`"), timeout));
            }
        }
    }

    /// Send `$G` and wait for its answer: GRBL answers lines in order, so any line sent
    /// before it and still unanswered when its `[GC:...]` arrives has lost its answer.
    fn resync(&mut self) -> HalResult<()> {
        self.stats.resyncs += 1;
        let id = self.send_line_as("$G", true)?;
        let t = self.config.response_timeout;
        self.wait_answer_with(id, t, false, false)
            .map_err(|e| match e {
                HalError::Timeout { .. } => self.timeout(
                    "an answer to `$G` (resynchronising the answer counting after a lost or late answer)",
                    t,
                ),
                e => e,
            })?;
        self.unsynced = false;
        Ok(())
    }

    /// Send a line and wait for its `ok`; returns the feedback lines that arrived meanwhile
    /// (`[...]`, `$N=...`).
    pub fn command(&mut self, line: &str) -> HalResult<Vec<String>> {
        self.command_with(line, self.config.response_timeout, false)
    }

    fn command_with(
        &mut self,
        line: &str,
        timeout: Duration,
        patient: bool,
    ) -> HalResult<Vec<String>> {
        self.drain_pending()?;
        if self.unsynced {
            self.resync()?;
        }
        self.garbage.clear();
        self.feedback.clear();
        let id = self.send_line(line)?;
        self.wait_answer(id, timeout, patient)?;
        Ok(std::mem::take(&mut self.feedback))
    }

    fn realtime(&mut self, byte: u8) -> HalResult<()> {
        self.write_raw(&[byte])
    }

    /// Send `?` and wait until `deadline` for the report it triggers.
    /// A corrupted report (line noise) is asked for again, up to [`STATUS_RETRIES`] times.
    fn query_status(&mut self, deadline: Instant) -> HalResult<SliderStatus> {
        self.drain_pending()?;
        let start = Instant::now();
        let mut asked = 0;
        let sent = loop {
            let before = self.reports;
            let corrupt_before = self.stats.corrupt_reports;
            let sent = Timestamp::now();
            self.realtime(b'?')?;
            asked += 1;
            while self.reports == before && self.stats.corrupt_reports == corrupt_before {
                if !self.pump(deadline)? {
                    return Err(self.timeout("a status report", start.elapsed()));
                }
            }
            if self.reports != before {
                break sent;
            }
            if asked > STATUS_RETRIES {
                let last = self.garbage.back().cloned().unwrap_or_default();
                return Err(self.bad(format!(
                    "{asked} status reports in a row were corrupted; the last: {last:?}"
                )));
            }
            tracing::debug!("{}: corrupted status report, asking again", self.port_name);
        };
        let (r, at) = self.last_report.clone().expect("report recorded");
        let x = r
            .machine_x(self.wco.as_deref())
            .ok_or_else(|| self.bad("status report without X"))?;
        Ok(SliderStatus {
            state: r.state,
            x_mm: x,
            feed_mm_min: r.feed.unwrap_or(0.0),
            timestamp: midpoint(sent, at),
        })
    }

    /// The full last status report (with sub-states such as `Hold:1`).
    pub fn last_report(&self) -> Option<&StatusReport> {
        self.last_report.as_ref().map(|(r, _)| r)
    }

    fn fail_if_alarm(&self) -> HalResult<()> {
        match self.alarm {
            Some(code) => Err(self.alarm_error(code)),
            None => Ok(()),
        }
    }

    fn check_move(&self, x_mm: f64, feed_mm_min: f64) -> HalResult<()> {
        if !(x_mm.is_finite() && feed_mm_min.is_finite() && feed_mm_min > 0.0) {
            return Err(HalError::InvalidArgument {
                device: self.port_name.clone(),
                detail: format!("bad move: x {x_mm} mm at {feed_mm_min} mm/min"),
            });
        }
        Ok(())
    }

    /// `$X`: clear the alarm lock without homing.
    pub fn unlock(&mut self) -> HalResult<()> {
        self.command("$X")?;
        self.alarm = None;
        Ok(())
    }

    /// [`Slider::home`] with the configured `homing_timeout`.
    pub fn home_configured(&mut self) -> HalResult<()> {
        let t = self.config.homing_timeout;
        self.home(t)
    }

    /// `$J=G90 G21 X.. F..`: jog to `x_mm` (cancelled by [`Slider::stop`] with 0x85).
    pub fn jog_to(&mut self, x_mm: f64, feed_mm_min: f64) -> HalResult<()> {
        self.check_move(x_mm, feed_mm_min)?;
        self.fail_if_alarm()?;
        let line = format!("$J=G90G21X{x_mm:.4}F{feed_mm_min:.3}");
        self.command_with(&line, self.config.response_timeout, true)?;
        self.jogging = true;
        Ok(())
    }

    /// Stream g-code lines with GRBL's character-counting flow control: as many lines are in
    /// flight as fit in the controller's RX buffer. Returns when every line is accepted (not
    /// executed); the first `error:N` stops the stream with [`HalError::Rejected`] naming the
    /// line (lines already sent after it still run, as with any GRBL streamer).
    pub fn stream<I, S>(&mut self, lines: I) -> HalResult<usize>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<str>,
    {
        self.drain_pending()?;
        if self.unsynced {
            self.resync()?;
        }
        self.garbage.clear();
        let cap = self.rx_buffer.saturating_sub(1).max(1);
        let timeout = self.config.response_timeout;
        let mut sent: VecDeque<(u64, usize)> = VecDeque::new();
        let mut count = 0;
        for (i, l) in lines.into_iter().enumerate() {
            let l = l.as_ref().trim();
            if l.is_empty() {
                continue;
            }
            if l.len() + 1 > cap {
                return Err(HalError::InvalidArgument {
                    device: self.port_name.clone(),
                    detail: format!("line {} longer than the RX buffer: {l:?}", i + 1),
                });
            }
            while self.in_flight_bytes() + l.len() + 1 > cap {
                match sent.pop_front() {
                    Some((id, idx)) => self
                        .wait_answer(id, timeout, true)
                        .map_err(|e| self.annotate(e, idx))?,
                    // Only a resync `$G` is left in flight: wait for its answer.
                    None => {
                        if !self.pump(Instant::now() + timeout)? {
                            return Err(self.timeout("room in the controller's RX buffer", timeout));
                        }
                    }
                }
            }
            let id = self.send_line(l)?;
            sent.push_back((id, i));
            count += 1;
        }
        while let Some((id, idx)) = sent.pop_front() {
            self.wait_answer(id, timeout, true)
                .map_err(|e| self.annotate(e, idx))?;
        }
        Ok(count)
    }

    fn annotate(&self, e: HalError, idx: usize) -> HalError {
        match e {
            HalError::Rejected {
                device,
                code,
                message,
            } => HalError::Rejected {
                device,
                code,
                message: format!("line {}: {message}", idx + 1),
            },
            e => e,
        }
    }

    /// Wait until the state is no longer `Hold:1` (deceleration in progress).
    fn wait_hold_complete(&mut self, deadline: Instant) -> HalResult<SliderStatus> {
        loop {
            let s = self.query_status(deadline)?;
            let decelerating = s.state == SliderState::Hold
                && self.last_report().and_then(|r| r.substate) != Some(0);
            if !decelerating {
                return Ok(s);
            }
            if Instant::now() >= deadline {
                return Err(self.timeout("the feed hold to complete", self.config.response_timeout));
            }
            std::thread::sleep(self.config.poll_interval);
        }
    }

    fn wait_banner(&mut self, since: u64, timeout: Duration) -> HalResult<()> {
        let deadline = Instant::now() + timeout;
        while self.banners == since {
            if !self.pump(deadline)? {
                return Err(self.timeout("the GRBL banner after a soft reset", timeout));
            }
        }
        Ok(())
    }

    /// Open the port, soft reset (0x18), wait for the banner, read `$I` (build info, RX buffer
    /// size) and a first status report. With `hold_first`, a controller found moving is
    /// brought to rest before the reset (see [`GrblSlider::reconnect`]).
    fn open_and_reset(&mut self, hold_first: bool) -> HalResult<SliderInfo> {
        self.port = None;
        self.rx.clear();
        self.in_flight.clear();
        self.answered.clear();
        self.alarm = None;
        self.banner = None;
        self.last_report = None;
        self.jogging = false;
        self.rx_buffer = self.config.rx_buffer;
        self.garbage.clear();
        self.unsynced = false;
        self.build_info = None;
        let port = serialport::new(&self.port_name, self.config.baud)
            .timeout(self.config.response_timeout)
            .open()
            .map_err(|e| {
                let absent = matches!(e.kind, serialport::ErrorKind::NoDevice)
                    || matches!(e.kind, serialport::ErrorKind::Io(ErrorKind::NotFound));
                if absent {
                    HalError::Disconnected {
                        device: self.port_name.clone(),
                        reason: format!("cannot open: {e}"),
                    }
                } else {
                    HalError::Io {
                        device: self.port_name.clone(),
                        source: e.into(),
                    }
                }
            })?;
        let _ = port.clear(ClearBuffer::All);
        self.port = Some(port);
        if hold_first {
            self.bring_to_rest();
        }
        self.garbage.clear();
        let since = self.banners;
        self.realtime(0x18)?;
        // Wait for the banner, tolerating noise before it (boot loaders, line garbage).
        let timeout = self.config.reset_timeout;
        let deadline = Instant::now() + timeout;
        let mut noise: Vec<String> = Vec::new();
        while self.banners == since {
            match self.pump(deadline) {
                Ok(true) => {}
                Ok(false) => {
                    noise.extend(self.garbage.iter().cloned());
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
        let banner = self.banner.clone().unwrap_or_default();
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
                Err(HalError::Disconnected { .. }) if self.port.is_some() && attempt < 3 => {
                    tracing::debug!("{}: controller reset again during connect", self.port_name);
                }
                Err(e) => return Err(e),
            }
        }
        let deadline = Instant::now() + self.config.response_timeout;
        self.query_status(deadline)?;
        Ok(SliderInfo {
            port: self.port_name.clone(),
            banner,
        })
    }

    /// Before a reset on reconnect: a controller that kept power may still be moving; a reset
    /// then would kill the steppers (ALARM:3, position lost). Cancel a jog, or feed hold a
    /// program, and wait for the stop. Best effort: a controller that does not answer (it is
    /// rebooting) is simply reset.
    fn bring_to_rest(&mut self) {
        let deadline = Instant::now() + self.config.response_timeout;
        let Ok(st) = self.query_status(deadline) else {
            return;
        };
        let result = match st.state {
            SliderState::Jog => self.jog_cancel(),
            SliderState::Run | SliderState::Hold => self.realtime(b'!').and_then(|_| {
                let deadline = Instant::now() + self.config.response_timeout;
                self.wait_hold_complete(deadline).map(|_| ())
            }),
            _ => Ok(()),
        };
        if let Err(e) = result {
            tracing::warn!(
                "{}: could not stop the motion before the reset: {e}",
                self.port_name
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
        self.port = None;
        let deadline = Instant::now() + wait;
        loop {
            match self.open_and_reset(true) {
                Ok(info) => {
                    self.stats.reconnects += 1;
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

    /// `$$` as a typed map.
    pub fn read_settings(&mut self) -> HalResult<GrblSettings> {
        Ok(GrblSettings {
            raw: Slider::settings(self)?,
        })
    }

    /// Jog cancel (0x85): decelerate a `$J=` jog and drop any queued jogs; waits until the
    /// controller has left the `Jog` state. A no-op when not jogging.
    pub fn jog_cancel(&mut self) -> HalResult<()> {
        self.realtime(0x85)?;
        self.jogging = false;
        let deadline = Instant::now() + self.config.response_timeout;
        loop {
            let s = self.query_status(deadline)?;
            if s.state != SliderState::Jog {
                return Ok(());
            }
            if Instant::now() >= deadline {
                return Err(self.timeout("the jog cancel", self.config.response_timeout));
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

    /// Soft reset (0x18) and wait for the banner; the planner and RX buffer are cleared.
    pub fn soft_reset(&mut self) -> HalResult<()> {
        self.drain_pending()?;
        let since = self.banners;
        self.realtime(0x18)?;
        self.wait_banner(since, self.config.reset_timeout)
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
        self.drain_pending()?;
        if self.unsynced {
            self.resync()?;
        }
        self.garbage.clear();
        let id = self.send_line("$H")?;
        // No $G resync on timeout: GRBL reads no line while homing.
        match self.wait_answer_with(id, timeout, false, false) {
            Ok(()) => {
                self.alarm = None;
                Ok(())
            }
            Err(HalError::Timeout { .. }) if self.port.is_some() => {
                let aborted = self.soft_reset();
                Err(self.timeout(
                    match aborted {
                        Ok(()) => "the homing cycle ($H) to finish; aborted it with a soft reset: the machine is not homed".to_string(),
                        Err(e) => format!("the homing cycle ($H) to finish; the soft reset to abort it failed too: {e}"),
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
        self.command_with(&line, self.config.response_timeout, true)?;
        Ok(())
    }

    fn status(&mut self) -> HalResult<SliderStatus> {
        let deadline = Instant::now() + self.config.response_timeout;
        self.query_status(deadline)
    }

    fn wait_idle(&mut self, timeout: Duration) -> HalResult<SliderStatus> {
        let deadline = Instant::now() + timeout;
        loop {
            let probe = deadline.min(Instant::now() + self.config.response_timeout);
            let s = match self.query_status(probe) {
                Err(HalError::Timeout { .. }) if Instant::now() >= deadline => {
                    return Err(self.timeout("the controller to become idle", timeout));
                }
                r => r?,
            };
            match s.state {
                SliderState::Idle => return Ok(s),
                SliderState::Alarm => return Err(self.alarm_error(self.alarm.unwrap_or(0))),
                _ => {}
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

    fn resume(&mut self) -> HalResult<()> {
        // GRBL ignores '~' until the hold deceleration is complete.
        let deadline = Instant::now() + self.config.response_timeout;
        self.wait_hold_complete(deadline)?;
        self.realtime(b'~')
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
                let deadline = Instant::now() + self.config.response_timeout;
                self.wait_hold_complete(deadline)?;
                self.soft_reset()
            }
            SliderState::Home => self.soft_reset(),
            _ => Ok(()),
        }
    }

    fn settings(&mut self) -> HalResult<SliderSettings> {
        self.settings_acc.clear();
        self.command("$$")?;
        let s = std::mem::take(&mut self.settings_acc);
        if s.is_empty() {
            return Err(self.bad("`$$` listed no settings"));
        }
        Ok(s)
    }
}
