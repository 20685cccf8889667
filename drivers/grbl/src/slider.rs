//! [`GrblSlider`]: the [`Slider`] implementation over a serial port.

use crate::codes::{alarm_message, error_message};
use crate::message::{banner_version, parse_line, Message, StatusReport};
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
    /// Status polling period of `wait_idle`.
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
}

#[derive(Clone, Debug)]
struct InFlight {
    id: u64,
    /// Bytes it occupies in the controller's RX buffer (line + '\n').
    len: usize,
    line: String,
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
                let shown: String = g.chars().take(80).collect();
                return Err(self.bad(format!("unexpected line from the controller: {shown:?}")));
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
        let mut deadline = Instant::now() + timeout;
        loop {
            while let Some(&(aid, _, _)) = self.answered.front() {
                if aid > id {
                    break;
                }
                let (aid, outcome, line) = self.answered.pop_front().expect("front");
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
                return Err(self.timeout(format!("an answer to `{line}`"), timeout));
            }
        }
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
        self.feedback.clear();
        let id = self.send_line(line)?;
        self.wait_answer(id, timeout, patient)?;
        Ok(std::mem::take(&mut self.feedback))
    }

    fn realtime(&mut self, byte: u8) -> HalResult<()> {
        self.write_raw(&[byte])
    }

    /// Send `?` and wait until `deadline` for the report it triggers.
    fn query_status(&mut self, deadline: Instant) -> HalResult<SliderStatus> {
        self.drain_pending()?;
        let before = self.reports;
        let sent = Timestamp::now();
        self.realtime(b'?')?;
        let start = Instant::now();
        while self.reports == before {
            if !self.pump(deadline)? {
                return Err(self.timeout("a status report", start.elapsed()));
            }
        }
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
                let (id, idx) = sent.pop_front().expect("in flight implies sent");
                self.wait_answer(id, timeout, true)
                    .map_err(|e| self.annotate(e, idx))?;
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
        self.port = None;
        self.rx.clear();
        self.in_flight.clear();
        self.answered.clear();
        self.alarm = None;
        self.banner = None;
        self.last_report = None;
        self.jogging = false;
        self.rx_buffer = self.config.rx_buffer;
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
        let since = self.banners;
        self.realtime(0x18)?;
        // Wait for the banner, tolerating noise before it (boot loaders, line garbage).
        let timeout = self.config.reset_timeout;
        let deadline = Instant::now() + timeout;
        let mut noise: Vec<String> = Vec::new();
        while self.banners == since {
            match self.pump(deadline) {
                Ok(true) => {}
                Ok(false) if noise.is_empty() => {
                    return Err(self.timeout("the GRBL banner after a soft reset", timeout));
                }
                Ok(false) => {
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
                Ok(_) | Err(HalError::Rejected { .. }) => break,
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

    fn home(&mut self, timeout: Duration) -> HalResult<()> {
        self.command_with("$H", timeout, false)?;
        self.alarm = None;
        Ok(())
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
            SliderState::Jog => {
                self.realtime(0x85)?;
                self.jogging = false;
                // Wait for the jog deceleration; nothing stays queued after a jog cancel.
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
