//! The [`Emitter`]: how a node passes items downstream.
//!
//! It hides whether the next hop is a bounded channel or the run's output collection, counts
//! outputs and drops, and times backpressure: a send that finds the channel full waits in a
//! `select!` on both the channel and the run's cancel signal, so a blocked producer always wakes
//! when the run is cancelled or a downstream node fails.

use std::sync::Arc;
use std::time::{Duration, Instant};

use crossbeam_channel::{select, Receiver, Sender, TrySendError};

use super::control::RunControl;
use super::stats::StageCounters;

/// `emit` failed because the run was cancelled or a node failed. Stop work and return; it
/// converts into [`BoxError`](super::BoxError) and is treated as a clean stop, not a failure.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("the pipeline run was cancelled")]
pub struct Cancelled;

/// What travels on a channel: an item, or the upstream's normal end of stream. A channel that
/// disconnects without `End` means the upstream stopped early (cancel or failure).
pub(crate) enum Msg<T> {
    Item(T),
    End,
}

pub(crate) enum Output<T> {
    Channel(Sender<Msg<T>>),
    /// The last node: items are collected into [`RunReport::outputs`](super::RunReport).
    Collect(Vec<T>),
}

/// Passed to [`Source::run`](super::Source::run), [`Stage::process`](super::Stage::process)
/// and [`Stage::finish`](super::Stage::finish) to send items to the next node.
///
/// Items emitted by the *last* node are collected in memory and returned in
/// [`RunReport::outputs`](super::RunReport::outputs); sinks therefore normally emit nothing, or
/// one small summary item.
pub struct Emitter<T> {
    out: Output<T>,
    ctl: Arc<RunControl>,
    signal: Receiver<()>,
    pub(crate) counters: Arc<StageCounters>,
    /// Time blocked in `emit` since the last [`take_blocked`](Self::take_blocked).
    blocked: Duration,
    /// Sources only: when the previous `emit` returned (latency = time between emits).
    last_emit: Option<Instant>,
}

impl<T> Emitter<T> {
    pub(crate) fn new(out: Output<T>, ctl: Arc<RunControl>, counters: Arc<StageCounters>) -> Self {
        let signal = ctl.signal();
        Self {
            out,
            ctl,
            signal,
            counters,
            blocked: Duration::ZERO,
            last_emit: None,
        }
    }

    /// Send `item` to the next node, blocking while its input queue is full.
    ///
    /// Returns `Err(Cancelled)` (and drops `item`) once the run is cancelled or has failed.
    pub fn emit(&mut self, item: T) -> Result<(), Cancelled> {
        if self.ctl.is_cancelled() {
            return Err(Cancelled);
        }
        if let Some(last) = self.last_emit {
            self.counters.add_latency(last.elapsed());
        }
        self.push(Msg::Item(item))?;
        self.counters.add_output();
        if self.last_emit.is_some() {
            self.last_emit = Some(Instant::now());
        }
        Ok(())
    }

    /// Count `n` items this node discarded (e.g. frames without a laser line).
    pub fn dropped(&mut self, n: u64) {
        self.counters.add_dropped(n);
    }

    /// Whether the run has been cancelled or has failed; long-running work should check this.
    pub fn is_cancelled(&self) -> bool {
        self.ctl.is_cancelled()
    }

    fn push(&mut self, msg: Msg<T>) -> Result<(), Cancelled> {
        match &mut self.out {
            Output::Collect(items) => {
                if let Msg::Item(item) = msg {
                    items.push(item);
                }
                Ok(())
            }
            Output::Channel(tx) => match tx.try_send(msg) {
                Ok(()) => Ok(()),
                Err(TrySendError::Disconnected(_)) => Err(Cancelled),
                Err(TrySendError::Full(msg)) => {
                    let t0 = Instant::now();
                    let sent = select! {
                        send(tx, msg) -> r => r.is_ok(),
                        recv(self.signal) -> _ => false,
                    };
                    let waited = t0.elapsed();
                    self.blocked += waited;
                    self.counters.add_blocked(waited);
                    if sent {
                        Ok(())
                    } else {
                        Err(Cancelled)
                    }
                }
            },
        }
    }

    /// Signal a normal end of stream downstream.
    pub(crate) fn end(&mut self) -> Result<(), Cancelled> {
        if self.ctl.is_cancelled() {
            return Err(Cancelled);
        }
        self.push(Msg::End)
    }

    /// Start the source clock: the first latency sample runs from here to the first emit.
    pub(crate) fn start_source_clock(&mut self) {
        self.last_emit = Some(Instant::now());
    }

    pub(crate) fn take_blocked(&mut self) -> Duration {
        std::mem::take(&mut self.blocked)
    }

    pub(crate) fn signal(&self) -> &Receiver<()> {
        &self.signal
    }

    pub(crate) fn into_outputs(self) -> Vec<T> {
        match self.out {
            Output::Collect(items) => items,
            Output::Channel(_) => Vec::new(),
        }
    }
}
