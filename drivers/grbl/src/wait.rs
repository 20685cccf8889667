//! The named wait policies: how long and how hard to wait for the answer to one line. A file
//! of its own because the slider (slider.rs) chooses a policy per command and the exchanges
//! (exchange.rs, `impl GrblSlider`) carry it out; the policy belongs to neither.

use std::time::Duration;

/// What a silent deadline means while waiting for a line's answer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Patience {
    /// Give up at the deadline.
    Fixed,
    /// Start the deadline again while the controller reports motion (`Run`, `Jog`, `Home`):
    /// a line waiting for planner room is answered only when a block completes.
    WhileMoving,
}

/// Whether a timeout is followed by a `$G` sync.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Resync {
    /// For `$H` (GRBL reads no line while homing) and for the `$G` of a resync itself.
    Never,
    /// Queue a sync `$G` behind the line and wait for it to settle the line's fate: GRBL
    /// answers in order, so a late answer still comes first and a lost one is marked lost by
    /// the `[GC:...]` (during a long move, without waiting for the motion to end).
    OnTimeout,
}

/// How long and how hard to wait for the answer to one line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct WaitPolicy {
    pub timeout: Duration,
    pub patience: Patience,
    pub resync: Resync,
}

impl WaitPolicy {
    /// A line GRBL answers at once (`$I`, `$$`, `$X`, `G4 P0`).
    pub fn command(timeout: Duration) -> Self {
        WaitPolicy {
            timeout,
            patience: Patience::Fixed,
            resync: Resync::OnTimeout,
        }
    }
    /// A motion line (`G1`, `$J=`), answered when the planner takes it.
    pub fn motion(timeout: Duration) -> Self {
        WaitPolicy {
            timeout,
            patience: Patience::WhileMoving,
            resync: Resync::OnTimeout,
        }
    }
    /// A line nothing may be queued behind: `$H`, or the `$G` of a resync.
    pub fn alone(timeout: Duration) -> Self {
        WaitPolicy {
            timeout,
            patience: Patience::Fixed,
            resync: Resync::Never,
        }
    }
}
