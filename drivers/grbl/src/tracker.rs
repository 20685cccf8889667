//! The answer tracker: which sent line each received line answers, as a pure state machine.
//!
//! GRBL answers every line it reads with exactly one `ok` or `error:N`, in the order it read
//! them, and says nothing else about which line an answer belongs to. Status reports, alarms,
//! feedback and banners arrive interleaved with those answers at any time. Getting the
//! pairing right is the whole difficulty of a GRBL driver, and it is easy to get subtly wrong
//! (one dropped `ok` shifts every later answer by one line), so it lives here without any I/O:
//! the caller registers what it sends and hands over what it receives, line by line, and the
//! tests drive it with byte strings instead of a serial port.
//!
//! What it keeps:
//! - the in-flight queue of sent lines, oldest first, with the bytes each occupies in the
//!   controller's RX buffer (character counting: a streamer may keep as many lines in flight
//!   as fit in that buffer);
//! - the outcome of each line: `ok`, `error:N`, lost to an `ALARM:N` or a reset (GRBL drops
//!   its input then, so those lines will never be answered), or lost outright;
//! - the `$G` resync: after a timeout the caller queues a `$G` marked as a sync. GRBL answers
//!   it in order with a `[GC:...]` line, so any line sent before it and still unanswered when
//!   that line arrives has lost its answer (dropped or mangled on the wire) and is marked so;
//!   later answers then pair with their own lines again;
//! - what the controller said about itself on the way: alarm, banner (reset), last status
//!   report with its arrival time, work offset, `$N=` settings, feedback lines, and the
//!   garbage it sent (counted in [`GrblStats`]).

use crate::message::{parse_line, Message, StatusReport};
use footscan_hal::{SliderSettings, SliderState, Timestamp};
use std::collections::VecDeque;

/// Longest line GRBL accepts (its line buffer is 80 bytes including the terminator).
pub(crate) const MAX_LINE: usize = 79;

/// Garbage lines kept for error messages.
const GARBAGE_KEPT: usize = 8;

/// Feedback lines kept per command (a runaway controller cannot grow it without bound).
const FEEDBACK_KEPT: usize = 256;

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
    /// Successful [`GrblSlider::reconnect`](crate::GrblSlider::reconnect)s.
    pub reconnects: u64,
}

/// How a sent line ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Outcome {
    Ok,
    Error(u32),
    /// The controller alarmed: never answered (GRBL discards its input), or a `$H` answered
    /// after the alarm its cycle raised.
    LostToAlarm(u32),
    /// Never answered: the controller reset.
    LostToReset,
    /// No `ok`/`error:N` arrived for it before the `[GC:...]` of a later `$G` sync: the
    /// controller's answer was dropped or arrived mangled.
    Lost,
}

/// A sent line and how it ended.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Answer {
    pub id: u64,
    pub outcome: Outcome,
    pub line: String,
}

/// Where the wait for one line stands.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum Poll {
    Answered(Answer),
    /// Still in flight.
    Pending,
    /// Neither answered nor in flight (never sent, or forgotten with the port).
    Missing,
}

/// Whether a line is an ordinary command, a `$G` sent to resynchronise the counting, or a
/// homing cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum LineKind {
    Command,
    Sync,
    /// `$H`: a failed cycle raises `ALARM:N` while GRBL is still executing the line, and GRBL
    /// answers the line with its `ok` after the alarm (then resets). Counting it lost at the
    /// alarm would pair that late `ok` with the next line sent.
    Homing,
}

/// What a received line was, for the caller's log.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Routed {
    /// `ok`/`error:N` paired with the oldest line in flight.
    Answer(u64, Outcome),
    /// `ok`/`error:N` with nothing in flight.
    Unsolicited,
    Alarm(u32),
    Report,
    Banner,
    /// `[GC:...]` of a sync `$G`, and how many earlier lines it found unanswered.
    Resynced {
        lost: usize,
    },
    Feedback,
    Setting,
    Garbage(String),
}

#[derive(Clone, Debug)]
struct InFlight {
    id: u64,
    /// Bytes it occupies in the controller's RX buffer (line + '\n').
    len: usize,
    line: String,
    kind: LineKind,
    /// An `ALARM:N` arrived while this `$H` executed: its answer still comes, and means
    /// the alarm.
    alarmed: Option<u32>,
}

/// What the controller has told about itself.
#[derive(Clone, Debug, Default)]
struct Seen {
    /// The alarm it is in (0: locked without an `ALARM:N` code).
    alarm: Option<u32>,
    banner: Option<String>,
    /// Banners since creation: a waiter compares counts to see a (new) reset.
    banners: u64,
    /// Status reports since creation: a waiter compares counts to see a new one.
    reports: u64,
    last_report: Option<(StatusReport, Timestamp)>,
    /// The last `WCO:` (GRBL sends it only every 10 to 30 reports).
    wco: Option<Vec<f64>>,
}

/// The answer tracker (see the module docs).
#[derive(Clone, Debug)]
pub(crate) struct Tracker {
    next_id: u64,
    in_flight: VecDeque<InFlight>,
    /// Outcomes not yet taken by a waiter, oldest first.
    answered: VecDeque<Answer>,
    rx_buffer: usize,
    /// The pairing may be off (noise while lines were in flight, or a wait that gave up):
    /// the caller resyncs before its next command.
    unsynced: bool,
    seen: Seen,
    settings: SliderSettings,
    feedback: Vec<String>,
    garbage: VecDeque<String>,
    pub stats: GrblStats,
}

impl Tracker {
    pub fn new(rx_buffer: usize) -> Self {
        Tracker {
            next_id: 0,
            in_flight: VecDeque::new(),
            answered: VecDeque::new(),
            rx_buffer,
            unsynced: false,
            seen: Seen::default(),
            settings: SliderSettings::new(),
            feedback: Vec::new(),
            garbage: VecDeque::new(),
            stats: GrblStats::default(),
        }
    }

    /// A fresh port: nothing in flight, nothing known about the controller but the counters
    /// (banners, reports, stats) that waiters and callers compare across it.
    pub fn reopen(&mut self, rx_buffer: usize) {
        self.in_flight.clear();
        self.answered.clear();
        self.rx_buffer = rx_buffer;
        self.unsynced = false;
        self.seen.alarm = None;
        self.seen.banner = None;
        self.seen.last_report = None;
        self.garbage.clear();
    }

    /// The port is gone: no line in flight will ever be answered.
    pub fn forget_in_flight(&mut self) {
        self.in_flight.clear();
    }

    // ----- sending -----------------------------------------------------------------------

    /// Register a line about to be written and return its id and the bytes to write. Register
    /// before writing: its answer may be read by the same call that notices it.
    pub fn send(&mut self, line: &str, kind: LineKind) -> Result<(u64, Vec<u8>), String> {
        let line = line.trim();
        if line.len() > MAX_LINE || line.contains(['\n', '\r']) {
            return Err(format!(
                "not a single GRBL line of at most {MAX_LINE} characters: {line:?}"
            ));
        }
        let mut bytes = Vec::with_capacity(line.len() + 1);
        bytes.extend_from_slice(line.as_bytes());
        bytes.push(b'\n');
        let id = self.next_id;
        self.next_id += 1;
        self.in_flight.push_back(InFlight {
            id,
            len: bytes.len(),
            line: line.to_string(),
            kind,
            alarmed: None,
        });
        if kind == LineKind::Sync {
            self.stats.resyncs += 1;
        }
        Ok((id, bytes))
    }

    /// Withdraw a line whose write failed (it never reached the controller).
    pub fn unsend(&mut self, id: u64) {
        self.in_flight.retain(|f| f.id != id);
    }

    /// Bytes of the controller's RX buffer taken by lines not yet answered.
    pub fn in_flight_bytes(&self) -> usize {
        self.in_flight.iter().map(|f| f.len).sum()
    }

    /// The budget a streamer keeps in flight: the RX buffer less one byte, so a realtime
    /// command always finds room.
    pub fn stream_budget(&self) -> usize {
        self.rx_buffer.saturating_sub(1).max(1)
    }

    /// Whether `line` (plus its '\n') fits in the budget next to the lines in flight.
    pub fn has_room(&self, line: &str) -> bool {
        // line + '\n' <= budget - in flight
        self.in_flight_bytes() + line.trim().len() < self.stream_budget()
    }

    pub fn is_in_flight(&self, id: u64) -> bool {
        self.in_flight.iter().any(|f| f.id == id)
    }

    /// The text of a line still in flight.
    pub fn line_of(&self, id: u64) -> Option<&str> {
        self.in_flight
            .iter()
            .find(|f| f.id == id)
            .map(|f| f.line.as_str())
    }

    // ----- answers -----------------------------------------------------------------------

    /// Drop the outcomes of lines sent before `id` that nobody waits for any more (a sync
    /// `$G`, a line whose wait gave up); returned so the caller can log their errors.
    pub fn skip_older(&mut self, id: u64) -> Vec<Answer> {
        let mut skipped = Vec::new();
        while self.answered.front().is_some_and(|a| a.id < id) {
            skipped.extend(self.answered.pop_front());
        }
        skipped
    }

    /// Take the outcome of line `id` if it has one (after [`Tracker::skip_older`]).
    pub fn poll(&mut self, id: u64) -> Poll {
        if let Some(i) = self.answered.iter().position(|a| a.id == id) {
            return Poll::Answered(self.answered.remove(i).expect("index"));
        }
        if self.is_in_flight(id) {
            Poll::Pending
        } else {
            Poll::Missing
        }
    }

    /// Whether the pairing of answers may be off, so the next command resyncs first.
    pub fn unsynced(&self) -> bool {
        self.unsynced
    }

    /// A wait gave up on a line: its answer may still come, or never.
    pub fn mark_unsynced(&mut self) {
        self.unsynced = true;
    }

    fn lose_in_flight(&mut self, outcome: Outcome) {
        for f in self.in_flight.drain(..) {
            self.answered.push_back(Answer {
                id: f.id,
                outcome,
                line: f.line,
            });
        }
    }

    // ----- receiving ---------------------------------------------------------------------

    /// Route one received line (without its terminator), which arrived at `at`.
    pub fn on_line(&mut self, line: &str, at: Timestamp) -> Routed {
        match parse_line(line) {
            Message::Ok => self.answer(Outcome::Ok),
            Message::Error(c) => self.answer(Outcome::Error(c)),
            Message::Alarm(code) => {
                self.seen.alarm = Some(code);
                match self.in_flight.front_mut() {
                    // The cycle's line is answered after its alarm; nothing is sent behind it.
                    Some(f) if f.kind == LineKind::Homing => f.alarmed = Some(code),
                    _ => self.lose_in_flight(Outcome::LostToAlarm(code)),
                }
                Routed::Alarm(code)
            }
            Message::Status(r) => {
                self.seen.reports += 1;
                if let Some(w) = &r.wco {
                    self.seen.wco = Some(w.clone());
                }
                if r.state == SliderState::Alarm {
                    self.seen.alarm.get_or_insert(0);
                } else {
                    self.seen.alarm = None;
                }
                self.seen.last_report = Some((r, at));
                Routed::Report
            }
            Message::Banner(b) => {
                self.seen.banners += 1;
                self.seen.banner = Some(b);
                self.seen.wco = None;
                self.lose_in_flight(Outcome::LostToReset);
                Routed::Banner
            }
            Message::Feedback(f) => {
                let mut routed = Routed::Feedback;
                if f.starts_with("GC:") {
                    if let Some(lost) = self.resync_marker() {
                        routed = Routed::Resynced { lost };
                    }
                }
                if f == "MSG:'$H'|'$X' to unlock" {
                    self.seen.alarm.get_or_insert(0);
                } else if f == "MSG:Caution: Unlocked" {
                    self.seen.alarm = None;
                } else if let Some(opt) = f.strip_prefix("OPT:") {
                    // [OPT:V,15,128]: options, planner blocks, RX buffer bytes.
                    if let Some(n) = opt.split(',').nth(2).and_then(|n| n.trim().parse().ok()) {
                        self.rx_buffer = n;
                    }
                }
                self.keep_feedback(format!("[{f}]"));
                routed
            }
            Message::Setting(k, v) => {
                self.settings.insert(k, v);
                Routed::Setting
            }
            Message::Other(o) => {
                self.keep_feedback(o);
                Routed::Feedback
            }
            Message::Garbage(g) => {
                // A mangled status report is asked again by the caller; anything else may
                // have been a mangled `ok`, so the pairing is resynchronised before the next
                // command.
                let shown: String = g.chars().take(80).collect();
                self.stats.garbage_lines += 1;
                if g.starts_with('<') {
                    self.stats.corrupt_reports += 1;
                } else if !self.in_flight.is_empty() {
                    self.unsynced = true;
                }
                if self.garbage.len() >= GARBAGE_KEPT {
                    self.garbage.pop_front();
                }
                self.garbage.push_back(shown.clone());
                Routed::Garbage(shown)
            }
        }
    }

    fn answer(&mut self, outcome: Outcome) -> Routed {
        match self.in_flight.pop_front() {
            Some(f) => {
                let outcome = f.alarmed.map_or(outcome, Outcome::LostToAlarm);
                self.answered.push_back(Answer {
                    id: f.id,
                    outcome,
                    line: f.line,
                });
                Routed::Answer(f.id, outcome)
            }
            None => Routed::Unsolicited,
        }
    }

    /// A `[GC:...]` arrived. If a sync `$G` is in flight, it answers that one (GRBL answers
    /// in order), so every line before it that is still unanswered lost its answer.
    fn resync_marker(&mut self) -> Option<usize> {
        let i = self
            .in_flight
            .iter()
            .position(|l| l.kind == LineKind::Sync)?;
        for l in self.in_flight.drain(..i).collect::<Vec<_>>() {
            self.stats.lost_answers += 1;
            self.answered.push_back(Answer {
                id: l.id,
                outcome: Outcome::Lost,
                line: l.line,
            });
        }
        self.unsynced = false;
        Some(i)
    }

    fn keep_feedback(&mut self, line: String) {
        if self.feedback.len() < FEEDBACK_KEPT {
            self.feedback.push(line);
        }
    }

    // ----- what the controller said ------------------------------------------------------

    pub fn alarm(&self) -> Option<u32> {
        self.seen.alarm
    }
    /// After a successful `$H` or `$X`.
    pub fn clear_alarm(&mut self) {
        self.seen.alarm = None;
    }
    pub fn banner(&self) -> Option<&str> {
        self.seen.banner.as_deref()
    }
    pub fn banners(&self) -> u64 {
        self.seen.banners
    }
    pub fn reports(&self) -> u64 {
        self.seen.reports
    }
    pub fn last_report(&self) -> Option<&(StatusReport, Timestamp)> {
        self.seen.last_report.as_ref()
    }
    pub fn wco(&self) -> Option<&[f64]> {
        self.seen.wco.as_deref()
    }
    pub fn rx_buffer(&self) -> usize {
        self.rx_buffer
    }
    /// The garbage lines received since [`Tracker::clear_garbage`], last ones only.
    pub fn garbage(&self) -> impl Iterator<Item = &str> {
        self.garbage.iter().map(String::as_str)
    }
    pub fn clear_garbage(&mut self) {
        self.garbage.clear();
    }
    /// Forget feedback and settings collected so far (a new command starts).
    pub fn clear_collected(&mut self) {
        self.feedback.clear();
        self.settings.clear();
    }
    /// Feedback lines (`[...]`, startup lines) since [`Tracker::clear_collected`].
    pub fn take_feedback(&mut self) -> Vec<String> {
        std::mem::take(&mut self.feedback)
    }
    /// `$N=value` lines since [`Tracker::clear_collected`].
    pub fn take_settings(&mut self) -> SliderSettings {
        std::mem::take(&mut self.settings)
    }
}

#[cfg(test)]
mod tests;
