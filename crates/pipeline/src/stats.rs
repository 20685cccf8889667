//! Per-stage counters, live while a pipeline runs.
//!
//! Each node thread owns an `Arc<StageCounters>` and bumps plain atomics (no locks on the hot
//! path); the progress bar and the final report read them through [`StageStats`] snapshots. A
//! snapshot is not atomic across fields (e.g. `output` may be read a moment after `input`), which
//! is fine for progress display and exact once the threads have been joined.

use std::sync::atomic::{AtomicU64, AtomicU8, Ordering};
use std::time::Duration;

use serde::{Deserialize, Serialize};

/// Where a node is in its life.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum StageState {
    /// The thread is running (or about to).
    Running,
    /// Upstream ended normally and `finish()` (or the source's `run()`) returned `Ok`.
    Finished,
    /// The run was cancelled, or ended early because another node failed; no `finish()`.
    Cancelled,
    /// This node returned an error or panicked.
    Failed,
}

impl StageState {
    fn from_u8(v: u8) -> Self {
        match v {
            1 => Self::Finished,
            2 => Self::Cancelled,
            3 => Self::Failed,
            _ => Self::Running,
        }
    }

    fn to_u8(self) -> u8 {
        match self {
            Self::Running => 0,
            Self::Finished => 1,
            Self::Cancelled => 2,
            Self::Failed => 3,
        }
    }
}

/// A snapshot of one node's counters.
///
/// * `input`: items received (always 0 for the source).
/// * `output`: items emitted (for the last node: items collected into the report).
/// * `dropped`: items the node reported discarding through [`Emitter::dropped`](super::Emitter::dropped).
/// * `mean_latency_ms`, `max_latency_ms`: for a stage, time spent inside `process()` per item;
///   for the source, time between consecutive emits (from `run()` start for the first). Both
///   exclude time spent blocked in `emit()` under backpressure, which is `blocked_ms` (total).
///   `finish()` is not counted as an item.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StageStats {
    pub name: String,
    pub state: StageState,
    pub input: u64,
    pub output: u64,
    pub dropped: u64,
    pub mean_latency_ms: f64,
    pub max_latency_ms: f64,
    pub blocked_ms: f64,
}

/// The live atomics behind [`StageStats`].
#[derive(Debug)]
pub(crate) struct StageCounters {
    name: String,
    state: AtomicU8,
    input: AtomicU64,
    output: AtomicU64,
    dropped: AtomicU64,
    latency_samples: AtomicU64,
    latency_total_ns: AtomicU64,
    latency_max_ns: AtomicU64,
    blocked_ns: AtomicU64,
}

fn nanos(d: Duration) -> u64 {
    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX)
}

impl StageCounters {
    pub(crate) fn new(name: &str) -> Self {
        Self {
            name: name.to_owned(),
            state: AtomicU8::new(StageState::Running.to_u8()),
            input: AtomicU64::new(0),
            output: AtomicU64::new(0),
            dropped: AtomicU64::new(0),
            latency_samples: AtomicU64::new(0),
            latency_total_ns: AtomicU64::new(0),
            latency_max_ns: AtomicU64::new(0),
            blocked_ns: AtomicU64::new(0),
        }
    }

    pub(crate) fn name(&self) -> &str {
        &self.name
    }

    pub(crate) fn add_input(&self) {
        self.input.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn add_output(&self) {
        self.output.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn add_dropped(&self, n: u64) {
        self.dropped.fetch_add(n, Ordering::Relaxed);
    }

    pub(crate) fn add_blocked(&self, d: Duration) {
        self.blocked_ns.fetch_add(nanos(d), Ordering::Relaxed);
    }

    pub(crate) fn add_latency(&self, d: Duration) {
        let ns = nanos(d);
        self.latency_samples.fetch_add(1, Ordering::Relaxed);
        self.latency_total_ns.fetch_add(ns, Ordering::Relaxed);
        self.latency_max_ns.fetch_max(ns, Ordering::Relaxed);
    }

    pub(crate) fn set_state(&self, s: StageState) {
        self.state.store(s.to_u8(), Ordering::Release);
    }

    pub(crate) fn snapshot(&self) -> StageStats {
        let samples = self.latency_samples.load(Ordering::Relaxed);
        let total = self.latency_total_ns.load(Ordering::Relaxed);
        let ms = |ns: u64| ns as f64 / 1e6;
        StageStats {
            name: self.name.clone(),
            state: StageState::from_u8(self.state.load(Ordering::Acquire)),
            input: self.input.load(Ordering::Relaxed),
            output: self.output.load(Ordering::Relaxed),
            dropped: self.dropped.load(Ordering::Relaxed),
            mean_latency_ms: if samples == 0 {
                0.0
            } else {
                ms(total) / samples as f64
            },
            max_latency_ms: ms(self.latency_max_ns.load(Ordering::Relaxed)),
            blocked_ms: ms(self.blocked_ns.load(Ordering::Relaxed)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn snapshot_computes_mean_and_max_in_ms() {
        let c = StageCounters::new("x");
        c.add_latency(Duration::from_millis(2));
        c.add_latency(Duration::from_millis(4));
        c.add_blocked(Duration::from_micros(1500));
        c.add_input();
        c.add_output();
        c.add_dropped(3);
        c.set_state(StageState::Finished);
        let s = c.snapshot();
        assert_eq!(s.name, "x");
        assert_eq!(s.state, StageState::Finished);
        assert_eq!((s.input, s.output, s.dropped), (1, 1, 3));
        assert!((s.mean_latency_ms - 3.0).abs() < 1e-9);
        assert!((s.max_latency_ms - 4.0).abs() < 1e-9);
        assert!((s.blocked_ms - 1.5).abs() < 1e-9);
    }

    #[test]
    fn no_samples_means_zero_latency() {
        let s = StageCounters::new("y").snapshot();
        assert_eq!(s.mean_latency_ms, 0.0);
        assert_eq!(s.state, StageState::Running);
    }
}
