//! Run-wide control shared by every node thread: the cancel flag, a wake-up signal that
//! unblocks every `select!`, and the slot holding the first failure.
//!
//! Cancelling drops the only `Sender` of a zero-message channel, so every thread waiting in
//! `select!` on its `Receiver` (blocked in `emit()` or waiting for input) wakes at once, with
//! no polling. The first failure is recorded before the run is cancelled, under one lock, and a
//! failing node keeps its channel ends open until it has recorded its failure, so an error
//! another node hits *because of* the failure can never replace the original cause.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};

use crossbeam_channel::{Receiver, Sender};

use super::error::BoxError;

#[derive(Debug)]
pub(crate) struct RunControl {
    cancelled: AtomicBool,
    wake: Mutex<Option<Sender<()>>>,
    signal: Receiver<()>,
    failure: Mutex<Option<(String, BoxError)>>,
}

fn lock<X>(m: &Mutex<X>) -> MutexGuard<'_, X> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

impl RunControl {
    pub(crate) fn new() -> Arc<Self> {
        let (tx, rx) = crossbeam_channel::bounded(0);
        Arc::new(Self {
            cancelled: AtomicBool::new(false),
            wake: Mutex::new(Some(tx)),
            signal: rx,
            failure: Mutex::new(None),
        })
    }

    pub(crate) fn is_cancelled(&self) -> bool {
        self.cancelled.load(Ordering::SeqCst)
    }

    /// A receiver that becomes ready (disconnected) when the run is cancelled.
    pub(crate) fn signal(&self) -> Receiver<()> {
        self.signal.clone()
    }

    pub(crate) fn cancel(&self) {
        self.cancelled.store(true, Ordering::SeqCst);
        drop(lock(&self.wake).take());
    }

    /// Record `err` as the run's failure and cancel the run, unless the run was already
    /// cancelled or failed, in which case `err` is a consequence and is handed back.
    pub(crate) fn fail(&self, stage: &str, err: BoxError) -> Result<(), BoxError> {
        let mut slot = lock(&self.failure);
        if slot.is_some() || self.is_cancelled() {
            return Err(err);
        }
        *slot = Some((stage.to_owned(), err));
        self.cancel();
        Ok(())
    }

    pub(crate) fn take_failure(&self) -> Option<(String, BoxError)> {
        lock(&self.failure).take()
    }
}

/// Cancels a running pipeline from any thread (e.g. a Ctrl-C handler or the HTTP API).
///
/// After [`cancel`](Self::cancel) the source stops at its next emit or `is_cancelled()` check,
/// every thread stops without calling `finish()`, and [`Running::wait`](super::Running::wait)
/// returns `Ok` with `cancelled: true`. Cancelling twice, or after the run ended, is harmless.
#[derive(Debug, Clone)]
pub struct CancelHandle {
    pub(crate) ctl: Arc<RunControl>,
}

impl CancelHandle {
    pub fn cancel(&self) {
        self.ctl.cancel();
    }

    /// Whether the run has been cancelled (by this handle or because a node failed).
    pub fn is_cancelled(&self) -> bool {
        self.ctl.is_cancelled()
    }
}
