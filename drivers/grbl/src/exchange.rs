//! Exchanges with the controller: send a line and wait for its answer under a named
//! [`WaitPolicy`], ask for a status report, stream a program.
//!
//! This is where the link (bytes and lines) meets the answer tracker (which line an answer
//! belongs to): every wait reads lines from the link, hands each to the tracker, and checks
//! whether the outcome it waits for has arrived. The policy decides what a silent deadline
//! means: give up, keep waiting while the machine moves (a motion line is answered only when
//! the planner has room), and whether to queue a `$G` that tells a late answer from a lost
//! one, so one dropped `ok` never shifts the answers to later lines.

use crate::codes::{alarm_message, error_message};
use crate::slider::GrblSlider;
use crate::tracker::{Answer, LineKind, Outcome, Poll, Routed};
use crate::wait::{Patience, Resync, WaitPolicy};
use footscan_hal::{HalError, HalResult, SliderState, SliderStatus, Timestamp};
use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// Times a `?` is asked again after a corrupted report before giving up with `BadData`.
const STATUS_RETRIES: u32 = 3;

/// The midpoint of a query and its answer: the best estimate of when a report was taken.
fn midpoint(a: Timestamp, b: Timestamp) -> Timestamp {
    Timestamp {
        nanos: a.nanos + (b.nanos.saturating_sub(a.nanos)) / 2,
    }
}

impl GrblSlider {
    // ----- errors ------------------------------------------------------------------------

    pub(crate) fn timeout(&self, what: impl Into<String>, after: Duration) -> HalError {
        HalError::Timeout {
            device: self.port_name().to_string(),
            what: what.into(),
            after,
        }
    }

    pub(crate) fn bad(&self, detail: impl Into<String>) -> HalError {
        HalError::BadData {
            device: self.port_name().to_string(),
            detail: detail.into(),
        }
    }

    pub(crate) fn alarm_error(&self, code: u32) -> HalError {
        HalError::Alarm {
            device: self.port_name().to_string(),
            code,
            message: alarm_message(code).to_string(),
        }
    }

    /// A link error; a port that failed is gone, and so are the answers to its lines.
    fn link_failed(&mut self, e: HalError) -> HalError {
        if !self.link.is_open() {
            self.tracker.forget_in_flight();
        }
        e
    }

    // ----- lines in, lines out -----------------------------------------------------------

    fn route(&mut self, line: &str, at: Timestamp) {
        let dev = self.link.device();
        match self.tracker.on_line(line, at) {
            Routed::Alarm(code) => tracing::warn!("{dev}: ALARM:{code}: {}", alarm_message(code)),
            Routed::Garbage(shown) => tracing::warn!("{dev}: unexpected line {shown:?}"),
            Routed::Unsolicited => tracing::debug!("{dev}: unsolicited {line:?}"),
            Routed::Resynced { lost } if lost > 0 => {
                tracing::warn!("{dev}: $G resync: {lost} answer(s) never arrived")
            }
            _ => {}
        }
    }

    /// Route the next line, reading until one is complete or `deadline` passes.
    /// Returns false at the deadline.
    pub(crate) fn pump(&mut self, deadline: Instant) -> HalResult<bool> {
        match self.link.read_line(deadline) {
            Ok(Some((line, at))) => {
                self.route(&line, at);
                Ok(true)
            }
            Ok(None) => Ok(false),
            Err(e) => Err(self.link_failed(e)),
        }
    }

    /// Route everything that has already arrived, without waiting.
    pub(crate) fn drain_pending(&mut self) -> HalResult<()> {
        loop {
            while let Some((line, at)) = self.link.next_line().map_err(|e| self.link_failed(e))? {
                self.route(&line, at);
            }
            let more = self.link.read_some(Instant::now());
            if !more.map_err(|e| self.link_failed(e))? {
                return Ok(());
            }
        }
    }

    pub(crate) fn realtime(&mut self, byte: u8) -> HalResult<()> {
        self.link.write(&[byte]).map_err(|e| self.link_failed(e))
    }

    /// Send one line (no line end) and register it for an answer.
    pub(crate) fn send_line(&mut self, line: &str, kind: LineKind) -> HalResult<u64> {
        let (id, bytes) =
            self.tracker
                .send(line, kind)
                .map_err(|detail| HalError::InvalidArgument {
                    device: self.port_name().to_string(),
                    detail,
                })?;
        if let Err(e) = self.link.write(&bytes) {
            self.tracker.unsend(id);
            return Err(self.link_failed(e));
        }
        Ok(id)
    }

    // ----- answers -----------------------------------------------------------------------

    /// Wait for the answer to line `id` as `policy` says.
    pub(crate) fn wait_answer(&mut self, id: u64, policy: WaitPolicy) -> HalResult<()> {
        let mut deadline = Instant::now() + policy.timeout;
        let mut sync_sent = false;
        // A line waiting for the motion to end is answered a moment after the state says so:
        // once the motion is seen to have ended, it gets one more full timeout.
        let mut moved = false;
        loop {
            for a in self.tracker.skip_older(id) {
                if let Outcome::Error(c) = a.outcome {
                    tracing::warn!(
                        "{}: unawaited `{}` failed: error:{c}: {}",
                        self.port_name(),
                        a.line,
                        error_message(c)
                    );
                }
            }
            match self.tracker.poll(id) {
                Poll::Answered(a) => return self.outcome(a, policy.timeout),
                Poll::Missing => return Err(self.bad(format!("answer to line #{id} went missing"))),
                Poll::Pending => {}
            }
            if self.pump(deadline)? {
                continue;
            }
            let resync = policy.resync == Resync::OnTimeout && !sync_sent && self.link.is_open();
            let moving = policy.patience == Patience::WhileMoving && self.moving()?;
            if !moving && std::mem::take(&mut moved) {
                deadline = Instant::now() + policy.timeout;
                continue;
            }
            if moving {
                moved = true;
                if resync {
                    // The answer may be lost while the machine runs (a scan move is seconds
                    // long): the `$G` behind the line finds out without waiting for the end.
                    sync_sent = true;
                    self.send_line("$G", LineKind::Sync)?;
                }
                deadline = Instant::now() + policy.timeout;
                continue;
            }
            if resync {
                sync_sent = true;
                self.send_line("$G", LineKind::Sync)?;
                deadline = Instant::now() + self.config.response_timeout;
                continue;
            }
            // Its answer may still come, or never: resync before the next command.
            self.tracker.mark_unsynced();
            let line = self.tracker.line_of(id).unwrap_or_default().to_string();
            let garbage: Vec<&str> = self.tracker.garbage().collect();
            if !garbage.is_empty() {
                return Err(self.bad(format!(
                    "no answer to `{line}` within {:?}; received instead: {}",
                    policy.timeout,
                    garbage.join(" | ")
                )));
            }
            return Err(self.timeout(format!("an answer to `{line}`"), policy.timeout));
        }
    }

    /// Whether the controller reports motion. A live controller answers `?` within
    /// milliseconds; half the response timeout keeps a dead one's total under 1.5x that
    /// timeout.
    fn moving(&mut self) -> HalResult<bool> {
        let probe = Instant::now() + self.config.response_timeout / 2;
        Ok(matches!(
            self.query_status(probe)?.state,
            SliderState::Run | SliderState::Jog | SliderState::Home
        ))
    }

    fn outcome(&self, a: Answer, timeout: Duration) -> HalResult<()> {
        let line = a.line;
        match a.outcome {
            Outcome::Ok => Ok(()),
            Outcome::Error(code) => Err(HalError::Rejected {
                device: self.port_name().to_string(),
                code,
                message: format!("{} (`{line}`)", error_message(code)),
            }),
            Outcome::LostToAlarm(c) => Err(self.alarm_error(c)),
            Outcome::LostToReset => Err(HalError::Disconnected {
                device: self.port_name().to_string(),
                reason: format!("the controller reset while `{line}` was pending"),
            }),
            Outcome::Lost => Err(self.timeout(
                format!(
                    "an answer to `{line}` (lost: an ok/error for the lines up to it never arrived; answer counting resynchronised with $G)"
                ),
                timeout,
            )),
        }
    }

    /// Send `$G` and wait for its answer: GRBL answers lines in order, so any line sent
    /// before it and still unanswered when its `[GC:...]` arrives has lost its answer.
    fn resync(&mut self) -> HalResult<()> {
        let id = self.send_line("$G", LineKind::Sync)?;
        let t = self.config.response_timeout;
        self.wait_answer(id, WaitPolicy::alone(t))
            .map_err(|e| match e {
                HalError::Timeout { .. } => self.timeout(
                    "an answer to `$G` (resynchronising the answer counting after a lost or late answer)",
                    t,
                ),
                e => e,
            })
    }

    /// Before a new line: route what has arrived, resync if the counting may be off, and
    /// forget the noise that belonged to earlier exchanges.
    pub(crate) fn prepare_to_send(&mut self) -> HalResult<()> {
        self.drain_pending()?;
        if self.tracker.unsynced() {
            self.resync()?;
        }
        self.tracker.clear_garbage();
        Ok(())
    }

    /// Send a line and wait for its `ok`; returns the feedback lines that arrived meanwhile
    /// (`[...]`, startup lines).
    pub fn command(&mut self, line: &str) -> HalResult<Vec<String>> {
        self.command_with(line, WaitPolicy::command(self.config.response_timeout))
    }

    pub(crate) fn command_with(
        &mut self,
        line: &str,
        policy: WaitPolicy,
    ) -> HalResult<Vec<String>> {
        self.prepare_to_send()?;
        self.tracker.clear_collected();
        let id = self.send_line(line, LineKind::Command)?;
        self.wait_answer(id, policy)?;
        Ok(self.tracker.take_feedback())
    }

    // ----- status ------------------------------------------------------------------------

    /// Send `?` and wait until `deadline` for the report it triggers.
    /// A corrupted report (line noise) is asked for again, up to [`STATUS_RETRIES`] times.
    pub(crate) fn query_status(&mut self, deadline: Instant) -> HalResult<SliderStatus> {
        self.drain_pending()?;
        let start = Instant::now();
        let mut asked = 0;
        let sent = loop {
            let before = self.tracker.reports();
            let corrupt_before = self.tracker.stats.corrupt_reports;
            let sent = Timestamp::now();
            self.realtime(b'?')?;
            asked += 1;
            while self.tracker.reports() == before
                && self.tracker.stats.corrupt_reports == corrupt_before
            {
                if !self.pump(deadline)? {
                    return Err(self.timeout("a status report", start.elapsed()));
                }
            }
            if self.tracker.reports() != before {
                break sent;
            }
            if asked > STATUS_RETRIES {
                let last = self.tracker.garbage().last().unwrap_or_default();
                return Err(self.bad(format!(
                    "{asked} status reports in a row were corrupted; the last: {last:?}"
                )));
            }
            tracing::debug!(
                "{}: corrupted status report, asking again",
                self.port_name()
            );
        };
        let (r, at) = self.tracker.last_report().expect("report recorded");
        let x = r.machine_x(self.tracker.wco());
        let (state, feed, at) = (r.state, r.feed.unwrap_or(0.0), *at);
        Ok(SliderStatus {
            state,
            x_mm: x.ok_or_else(|| self.bad("status report without X"))?,
            feed_mm_min: feed,
            timestamp: midpoint(sent, at),
            uncertainty_s: at.secs_after(sent).max(0.0) / 2.0,
        })
    }

    /// Wait for a banner after `since` banners (a soft reset).
    pub(crate) fn wait_banner(&mut self, since: u64, timeout: Duration) -> HalResult<()> {
        let deadline = Instant::now() + timeout;
        while self.tracker.banners() == since {
            if !self.pump(deadline)? {
                return Err(self.timeout("the GRBL banner after a soft reset", timeout));
            }
        }
        Ok(())
    }

    // ----- streaming ---------------------------------------------------------------------

    /// Stream g-code lines with GRBL's character-counting flow control: as many lines are in
    /// flight as fit in the controller's RX buffer. Returns when every line is accepted (not
    /// executed); the first `error:N` stops the stream with [`HalError::Rejected`] naming the
    /// line (lines already sent after it still run, as with any GRBL streamer).
    pub fn stream<I, S>(&mut self, lines: I) -> HalResult<usize>
    where
        I: IntoIterator<Item = S>,
        S: AsRef<str>,
    {
        self.prepare_to_send()?;
        let timeout = self.config.response_timeout;
        let policy = WaitPolicy::motion(timeout);
        let mut sent: VecDeque<(u64, usize)> = VecDeque::new();
        let mut count = 0;
        for (i, l) in lines.into_iter().enumerate() {
            let l = l.as_ref().trim();
            if l.is_empty() {
                continue;
            }
            if l.len() + 1 > self.tracker.stream_budget() {
                return Err(HalError::InvalidArgument {
                    device: self.port_name().to_string(),
                    detail: format!("line {} longer than the RX buffer: {l:?}", i + 1),
                });
            }
            while !self.tracker.has_room(l) {
                match sent.pop_front() {
                    Some((id, idx)) => {
                        self.wait_answer(id, policy).map_err(|e| annotate(e, idx))?
                    }
                    // Only a resync `$G` is left in flight: wait for its answer.
                    None => {
                        if !self.pump(Instant::now() + timeout)? {
                            return Err(self.timeout("room in the controller's RX buffer", timeout));
                        }
                    }
                }
            }
            let id = self.send_line(l, LineKind::Command)?;
            sent.push_back((id, i));
            count += 1;
        }
        while let Some((id, idx)) = sent.pop_front() {
            self.wait_answer(id, policy).map_err(|e| annotate(e, idx))?;
        }
        Ok(count)
    }
}

/// Name the program line (1-based) a rejection belongs to.
fn annotate(e: HalError, idx: usize) -> HalError {
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
