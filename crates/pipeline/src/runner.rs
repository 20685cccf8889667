//! Running a built [`Pipeline`]: one named thread per node, bounded channels between them,
//! cancellation, first-error-wins failure reporting, and the final [`RunReport`].
//!
//! Each node thread runs inside `catch_unwind`, so a panicking stage becomes that stage's error
//! instead of a hung or half-joined run. Threads never poll: they block in `select!` on their
//! input (or output) channel and on the run's cancel signal.

use std::any::Any;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use crossbeam_channel::{select, Receiver};
use tracing::{debug, info_span, warn, Span};

use super::control::{CancelHandle, RunControl};
use super::emitter::{Cancelled, Emitter, Msg, Output};
use super::error::{BoxError, BuildError};
use super::node::{Node, Source, Stage};
use super::stats::{StageCounters, StageState, StageStats};

/// A validated chain of named nodes: a source followed by zero or more stages.
pub struct Pipeline<T> {
    capacity: usize,
    nodes: Vec<(String, Node<T>)>,
}

impl<T> std::fmt::Debug for Pipeline<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Pipeline")
            .field("capacity", &self.capacity)
            .field("stages", &self.names())
            .finish()
    }
}

/// A node returned `Err` (other than [`Cancelled`]) or panicked.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// The first node to fail, its error, and every node's counters at the end of the run.
    #[error("stage `{stage}` failed")]
    Stage {
        stage: String,
        source: BoxError,
        stats: Vec<StageStats>,
    },
}

/// The error recorded for a node that panicked; downcast a failure's `source` to find it.
#[derive(Debug, Clone, thiserror::Error)]
#[error("panicked: {message}")]
pub struct Panicked {
    pub message: String,
}

/// The result of a run that ended normally or was cancelled.
#[derive(Debug)]
pub struct RunReport<T> {
    pub stages: Vec<StageStats>,
    pub elapsed: Duration,
    /// Items emitted by the last node (sinks normally emit nothing or a small summary).
    pub outputs: Vec<T>,
    /// True when the last node did not reach a normal end (the run was cancelled); `outputs`
    /// are then partial.
    pub cancelled: bool,
}

impl<T> Pipeline<T> {
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// Node names in chain order.
    pub fn names(&self) -> Vec<&str> {
        self.nodes.iter().map(|(n, _)| n.as_str()).collect()
    }
}

impl<T: Send + 'static> Pipeline<T> {
    /// Check and assemble a chain: `capacity ≥ 1`, at least one node, the first node a source
    /// and no other. `capacity` is the size of each bounded queue between two nodes.
    pub fn new(capacity: usize, nodes: Vec<(String, Node<T>)>) -> Result<Self, BuildError> {
        if capacity == 0 {
            return Err(BuildError::Capacity(capacity));
        }
        match nodes.first() {
            None => return Err(BuildError::Empty),
            Some((name, node)) if !node.is_source() => {
                return Err(BuildError::FirstNotSource {
                    stage: name.clone(),
                })
            }
            Some(_) => {}
        }
        if let Some((index, (name, _))) = nodes
            .iter()
            .enumerate()
            .skip(1)
            .find(|(_, (_, n))| n.is_source())
        {
            return Err(BuildError::SourceNotFirst {
                index,
                stage: name.clone(),
            });
        }
        Ok(Self { capacity, nodes })
    }

    /// Run to the end on the calling thread's behalf: `self.start().wait()`.
    pub fn run(self) -> Result<RunReport<T>, PipelineError> {
        self.start().wait()
    }

    /// Spawn one thread per node (named after the node) and return at once. Each thread enters
    /// a `stage` span whose parent is the caller's current span (e.g. the scan's).
    ///
    /// If a thread cannot be spawned, that node is reported as failed by [`Running::wait`].
    pub fn start(self) -> Running<T> {
        let ctl = RunControl::new();
        let parent = Span::current();
        let started = Instant::now();
        let count = self.nodes.len();
        let mut counters = Vec::with_capacity(count);
        let mut threads = Vec::with_capacity(count);
        let mut input: Option<Receiver<Msg<T>>> = None;
        for (i, (name, node)) in self.nodes.into_iter().enumerate() {
            let stage_counters = Arc::new(StageCounters::new(&name));
            counters.push(stage_counters.clone());
            let (out, next_input) = if i + 1 < count {
                let (tx, rx) = crossbeam_channel::bounded(self.capacity);
                (Output::Channel(tx), Some(rx))
            } else {
                (Output::Collect(Vec::new()), None)
            };
            let emitter = Emitter::new(out, ctl.clone(), stage_counters.clone());
            let (thread_ctl, node_input) = (ctl.clone(), input.take());
            let span = info_span!(parent: &parent, "stage", name = %name);
            let spawned = thread::Builder::new()
                .name(name.clone())
                .spawn(move || span.in_scope(|| run_node(node, node_input, emitter, &thread_ctl)));
            let handle = match spawned {
                Ok(h) => Some(h),
                Err(e) => {
                    let err = format!("cannot spawn thread: {e}").into();
                    if ctl.fail(&name, err).is_ok() {
                        stage_counters.set_state(StageState::Failed);
                    } else {
                        stage_counters.set_state(StageState::Cancelled);
                    }
                    None
                }
            };
            threads.push((name, handle));
            input = next_input;
        }
        Running {
            ctl,
            counters,
            threads,
            started,
        }
    }
}

/// A pipeline whose threads are running. Dropping it without [`wait`](Self::wait) cancels the
/// run and joins the threads (so it blocks until every source honours the cancel).
pub struct Running<T> {
    ctl: Arc<RunControl>,
    counters: Vec<Arc<StageCounters>>,
    threads: Vec<(String, Option<JoinHandle<NodeExit<T>>>)>,
    started: Instant,
}

struct NodeExit<T> {
    state: StageState,
    outputs: Vec<T>,
}

impl<T> Running<T> {
    /// A live snapshot of every node's counters, in chain order.
    pub fn stats(&self) -> Vec<StageStats> {
        self.counters.iter().map(|c| c.snapshot()).collect()
    }

    pub fn cancel_handle(&self) -> CancelHandle {
        CancelHandle {
            ctl: self.ctl.clone(),
        }
    }

    /// Same as `self.cancel_handle().cancel()`.
    pub fn cancel(&self) {
        self.ctl.cancel();
    }

    /// Whether every node thread has ended (so [`wait`](Self::wait) will not block).
    pub fn is_finished(&self) -> bool {
        self.threads
            .iter()
            .filter_map(|(_, h)| h.as_ref())
            .all(JoinHandle::is_finished)
    }

    /// Join every thread and report. Cancellation is `Ok` with `cancelled: true`; a node error
    /// or panic is `Err(PipelineError::Stage)` naming the first node that failed.
    pub fn wait(mut self) -> Result<RunReport<T>, PipelineError> {
        let threads = std::mem::take(&mut self.threads);
        let mut last = None;
        for (name, handle) in threads {
            last = match handle.map(JoinHandle::join) {
                Some(Ok(exit)) => Some(exit),
                Some(Err(payload)) => {
                    // Only reachable if the runtime itself panicked outside catch_unwind.
                    let err = Box::new(Panicked {
                        message: panic_message(payload.as_ref()),
                    });
                    let _ = self.ctl.fail(&name, err);
                    None
                }
                None => None,
            };
        }
        let elapsed = self.started.elapsed();
        let stages = self.stats();
        if let Some((stage, source)) = self.ctl.take_failure() {
            return Err(PipelineError::Stage {
                stage,
                source,
                stats: stages,
            });
        }
        let (cancelled, outputs) = match last {
            Some(exit) => (exit.state != StageState::Finished, exit.outputs),
            None => (true, Vec::new()),
        };
        Ok(RunReport {
            stages,
            elapsed,
            outputs,
            cancelled,
        })
    }
}

impl<T> Drop for Running<T> {
    fn drop(&mut self) {
        if self.threads.is_empty() {
            return;
        }
        self.ctl.cancel();
        for (_, handle) in self.threads.drain(..) {
            if let Some(h) = handle {
                let _ = h.join();
            }
        }
    }
}

/// How a node's loop ended when it did not return an error.
enum Ending {
    Finished,
    Cancelled,
}

fn run_node<T>(
    mut node: Node<T>,
    input: Option<Receiver<Msg<T>>>,
    mut out: Emitter<T>,
    ctl: &RunControl,
) -> NodeExit<T> {
    debug!("stage started");
    // `input` and `out` (the channel ends) must outlive the failure report below: dropping the
    // receiver first would let the upstream see a closed channel, fail, and win the race to
    // report, masking this node's real error.
    let result = catch_unwind(AssertUnwindSafe(|| match (&mut node, input.as_ref()) {
        (Node::Source(source), _) => drive_source(source.as_mut(), &mut out),
        (Node::Stage(stage), Some(rx)) => drive_stage(stage.as_mut(), rx, &mut out),
        (Node::Stage(_), None) => Err("internal error: stage has no input".into()),
    }));
    let error: Option<BoxError> = match result {
        Ok(Ok(Ending::Finished)) => None,
        Ok(Ok(Ending::Cancelled)) => Some(Box::new(Cancelled)),
        Ok(Err(e)) => Some(e),
        Err(payload) => Some(Box::new(Panicked {
            message: panic_message(payload.as_ref()),
        })),
    };
    let state = match error {
        None => StageState::Finished,
        Some(e) if e.is::<Cancelled>() => StageState::Cancelled,
        Some(e) => match ctl.fail(out.counters.name(), e) {
            Ok(()) => StageState::Failed,
            Err(e) => {
                warn!(error = %e, "stage error after the run was cancelled; ignored");
                StageState::Cancelled
            }
        },
    };
    out.counters.set_state(state);
    let s = out.counters.snapshot();
    debug!(
        state = ?state,
        input = s.input,
        output = s.output,
        dropped = s.dropped,
        "stage ended"
    );
    drop(input);
    drop(node);
    NodeExit {
        state,
        outputs: out.into_outputs(),
    }
}

fn drive_source<T>(source: &mut dyn Source<T>, out: &mut Emitter<T>) -> Result<Ending, BoxError> {
    out.start_source_clock();
    source.run(out)?;
    Ok(match out.end() {
        Ok(()) => Ending::Finished,
        Err(Cancelled) => Ending::Cancelled,
    })
}

fn drive_stage<T>(
    stage: &mut dyn Stage<T>,
    input: &Receiver<Msg<T>>,
    out: &mut Emitter<T>,
) -> Result<Ending, BoxError> {
    let signal = out.signal().clone();
    loop {
        if out.is_cancelled() {
            return Ok(Ending::Cancelled);
        }
        let msg = select! {
            recv(input) -> msg => msg.ok(),
            recv(signal) -> _ => return Ok(Ending::Cancelled),
        };
        match msg {
            Some(Msg::Item(item)) => {
                out.counters.add_input();
                out.take_blocked();
                let t0 = Instant::now();
                stage.process(item, out)?;
                let busy = t0.elapsed().saturating_sub(out.take_blocked());
                out.counters.add_latency(busy);
            }
            Some(Msg::End) => {
                stage.finish(out)?;
                return Ok(match out.end() {
                    Ok(()) => Ending::Finished,
                    Err(Cancelled) => Ending::Cancelled,
                });
            }
            // Upstream stopped without `End`: it failed or the run was cancelled.
            None => return Ok(Ending::Cancelled),
        }
    }
}

fn panic_message(payload: &(dyn Any + Send)) -> String {
    if let Some(s) = payload.downcast_ref::<&str>() {
        (*s).to_owned()
    } else if let Some(s) = payload.downcast_ref::<String>() {
        s.clone()
    } else {
        "non-string panic payload".to_owned()
    }
}

#[cfg(test)]
mod tests {
    use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
    use std::sync::mpsc;

    use super::*;
    use crate::{FnSource, FnStage};

    /// Generous bound that only catches hangs, never slowness.
    const HANG: Duration = Duration::from_secs(60);

    fn wait_bounded<T: Send + 'static>(running: Running<T>) -> Result<RunReport<T>, PipelineError> {
        let (tx, rx) = mpsc::channel();
        thread::spawn(move || {
            let _ = tx.send(running.wait());
        });
        rx.recv_timeout(HANG)
            .expect("pipeline did not end: deadlock or missed cancel")
    }

    fn node(name: &str, node: Node<u64>) -> (String, Node<u64>) {
        (name.to_owned(), node)
    }

    fn count_to(n: u64) -> Node<u64> {
        Node::source(FnSource(move |out: &mut Emitter<u64>| {
            for i in 0..n {
                out.emit(i)?;
            }
            Ok(())
        }))
    }

    fn endless() -> Node<u64> {
        Node::source(FnSource(|out: &mut Emitter<u64>| {
            for i in 0.. {
                out.emit(i)?;
            }
            Ok(())
        }))
    }

    fn map(mut f: impl FnMut(u64) -> u64 + Send + 'static) -> Node<u64> {
        Node::stage(FnStage(move |x: u64, out: &mut Emitter<u64>| {
            out.emit(f(x))?;
            Ok(())
        }))
    }

    fn sink() -> Node<u64> {
        Node::stage(FnStage(|_: u64, _: &mut Emitter<u64>| Ok(())))
    }

    fn states(stats: &[StageStats]) -> Vec<StageState> {
        stats.iter().map(|s| s.state).collect()
    }

    /// The error and its causes, `outer: cause`, as the edges print them.
    fn chain(e: &dyn std::error::Error) -> String {
        let mut s = e.to_string();
        let mut c = e.source();
        while let Some(x) = c {
            s = format!("{s}: {x}");
            c = x.source();
        }
        s
    }

    fn stage_error(
        r: Result<RunReport<u64>, PipelineError>,
    ) -> (String, BoxError, Vec<StageStats>, String) {
        match r {
            Ok(rep) => panic!("expected a failure, got {rep:?}"),
            Err(e) => {
                let shown = chain(&e);
                let PipelineError::Stage {
                    stage,
                    source,
                    stats,
                } = e;
                (stage, source, stats, shown)
            }
        }
    }

    /// Records `finish()` calls and signals once it has seen `notify_at` items.
    struct Watcher {
        seen: u64,
        notify_at: u64,
        notify: mpsc::Sender<()>,
        finished: Arc<AtomicBool>,
    }

    impl Stage<u64> for Watcher {
        fn process(&mut self, _: u64, _: &mut Emitter<u64>) -> Result<(), BoxError> {
            self.seen += 1;
            if self.seen == self.notify_at {
                let _ = self.notify.send(());
            }
            Ok(())
        }
        fn finish(&mut self, _: &mut Emitter<u64>) -> Result<(), BoxError> {
            self.finished.store(true, Ordering::SeqCst);
            Err("finish must not run on a cancelled or failed run".into())
        }
    }

    #[test]
    fn order_is_preserved_through_three_stages() {
        let n = 10_000;
        let mut expected_next = 0;
        let check = Node::stage(FnStage(move |x: u64, out: &mut Emitter<u64>| {
            if x != (expected_next + 1) * 2 {
                return Err(format!("out of order: {x} after {expected_next}").into());
            }
            expected_next += 1;
            out.emit(x)?;
            Ok(())
        }));
        let p = Pipeline::new(
            3,
            vec![
                node("src", count_to(n)),
                node("inc", map(|x| x + 1)),
                node("double", map(|x| x * 2)),
                node("check", check),
            ],
        )
        .unwrap();
        let report = wait_bounded(p.start()).unwrap();
        let expected: Vec<u64> = (0..n).map(|x| (x + 1) * 2).collect();
        assert_eq!(report.outputs, expected);
        assert!(!report.cancelled);
        assert_eq!(states(&report.stages), vec![StageState::Finished; 4]);
        assert_eq!(report.stages[0].input, 0);
        assert_eq!(report.stages[0].output, n);
        for s in &report.stages[1..] {
            assert_eq!((s.input, s.output, s.dropped), (n, n, 0), "{}", s.name);
            assert!(s.max_latency_ms >= s.mean_latency_ms);
        }
    }

    #[test]
    fn backpressure_bounds_items_in_flight() {
        let capacity = 2;
        let produced = Arc::new(AtomicU64::new(0));
        let consumed = Arc::new(AtomicU64::new(0));
        let max_in_flight = Arc::new(AtomicU64::new(0));
        let (p2, c2, m2) = (produced.clone(), consumed.clone(), max_in_flight.clone());
        let source = Node::source(FnSource(move |out: &mut Emitter<u64>| {
            for i in 0..300 {
                // Counted as in flight from the moment it is handed to emit().
                let ahead = p2.fetch_add(1, Ordering::SeqCst) + 1 - c2.load(Ordering::SeqCst);
                m2.fetch_max(ahead, Ordering::SeqCst);
                out.emit(i)?;
            }
            Ok(())
        }));
        let c3 = consumed.clone();
        let slow_sink = Node::stage(FnStage(move |_: u64, _: &mut Emitter<u64>| {
            thread::sleep(Duration::from_millis(1));
            c3.fetch_add(1, Ordering::SeqCst);
            Ok(())
        }));
        let p = Pipeline::new(
            capacity,
            vec![
                node("src", source),
                node("pass", map(|x| x)),
                node("slow", slow_sink),
            ],
        )
        .unwrap();
        let report = wait_bounded(p.start()).unwrap();
        assert_eq!(consumed.load(Ordering::SeqCst), 300);
        // Two queues of `capacity`, plus one item held by each of the three nodes.
        let bound = capacity as u64 * 2 + 3;
        let max = max_in_flight.load(Ordering::SeqCst);
        assert!(max <= bound, "source ran {max} items ahead (bound {bound})");
        assert!(report.stages[0].blocked_ms > 0.0, "{:?}", report.stages[0]);
        assert_eq!(
            report.stages[2].blocked_ms, 0.0,
            "the last node never blocks"
        );
    }

    #[test]
    fn cancel_mid_run_stops_every_thread_without_finish() {
        let (notify, noticed) = mpsc::channel();
        let finished = Arc::new(AtomicBool::new(false));
        let watcher = Watcher {
            seen: 0,
            notify_at: 100,
            notify,
            finished: finished.clone(),
        };
        let p = Pipeline::new(
            4,
            vec![
                node("src", endless()),
                node("pass", map(|x| x)),
                node("watch", Node::stage(watcher)),
            ],
        )
        .unwrap();
        let running = p.start();
        let handle = running.cancel_handle();
        noticed
            .recv_timeout(HANG)
            .expect("sink never saw 100 items");
        thread::spawn(move || handle.cancel()).join().unwrap();
        let report = wait_bounded(running).unwrap();
        assert!(report.cancelled);
        assert!(
            !finished.load(Ordering::SeqCst),
            "finish() ran after cancel"
        );
        assert_eq!(states(&report.stages), vec![StageState::Cancelled; 3]);
        assert!(report.stages[2].input >= 100);
    }

    #[test]
    fn cancel_reaches_a_source_that_only_polls() {
        let (started, is_started) = mpsc::channel();
        let source = Node::source(FnSource(move |out: &mut Emitter<u64>| {
            let _ = started.send(());
            while !out.is_cancelled() {
                thread::sleep(Duration::from_millis(1));
            }
            Ok(())
        }));
        let running = Pipeline::new(1, vec![node("src", source), node("sink", sink())])
            .unwrap()
            .start();
        is_started.recv_timeout(HANG).unwrap();
        running.cancel();
        let report = wait_bounded(running).unwrap();
        assert!(report.cancelled);
        assert_eq!(states(&report.stages), vec![StageState::Cancelled; 2]);
    }

    #[test]
    fn first_error_wins_and_upstream_is_released() {
        // The source turns Cancelled into its own error, and the sink's finish() would report
        // a truncated stream: neither may mask the middle stage's failure.
        let source = Node::source(FnSource(|out: &mut Emitter<u64>| {
            for i in 0..1_000_000 {
                out.emit(i).map_err(|_| "source: output closed")?;
            }
            Ok(())
        }));
        let failing = Node::stage(FnStage(|x: u64, out: &mut Emitter<u64>| {
            if x == 100 {
                return Err(format!("bad item {x}").into());
            }
            out.emit(x)?;
            Ok(())
        }));
        let (notify, _noticed) = mpsc::channel();
        let finished = Arc::new(AtomicBool::new(false));
        let watcher = Watcher {
            seen: 0,
            notify_at: u64::MAX,
            notify,
            finished: finished.clone(),
        };
        let p = Pipeline::new(
            2,
            vec![
                node("src", source),
                node("detect.cog", failing),
                node("sink", Node::stage(watcher)),
            ],
        )
        .unwrap();
        let (stage, source, stats, shown) = stage_error(wait_bounded(p.start()));
        assert_eq!(stage, "detect.cog");
        assert_eq!(source.to_string(), "bad item 100");
        assert_eq!(shown, "stage `detect.cog` failed: bad item 100");
        assert!(!finished.load(Ordering::SeqCst));
        assert_eq!(
            states(&stats),
            vec![
                StageState::Cancelled,
                StageState::Failed,
                StageState::Cancelled
            ]
        );
        assert_eq!(stats[1].input, 101);
        // Items still queued when the run failed are discarded, not processed.
        assert!(stats[2].input <= 100);
        assert!(stats[0].output < 1_000_000);
    }

    #[test]
    fn failing_sink_unblocks_a_source_blocked_in_emit() {
        let failing_sink = Node::stage(FnStage(|x: u64, _: &mut Emitter<u64>| {
            if x == 3 {
                return Err("disk full".into());
            }
            Ok(())
        }));
        let p = Pipeline::new(
            1,
            vec![
                node("src", endless()),
                node("pass", map(|x| x)),
                node("sink.ply", failing_sink),
            ],
        )
        .unwrap();
        let (stage, _, stats, shown) = stage_error(wait_bounded(p.start()));
        assert_eq!(stage, "sink.ply");
        assert_eq!(shown, "stage `sink.ply` failed: disk full");
        assert_eq!(stats[2].state, StageState::Failed);
    }

    #[test]
    fn panic_is_reported_as_that_stages_error() {
        let panicky = Node::stage(FnStage(|x: u64, out: &mut Emitter<u64>| {
            if x == 5 {
                panic!("boom at item {x}");
            }
            out.emit(x)?;
            Ok(())
        }));
        let p = Pipeline::new(
            2,
            vec![
                node("src", endless()),
                node("panicky", panicky),
                node("sink", sink()),
            ],
        )
        .unwrap();
        let (stage, source, stats, shown) = stage_error(wait_bounded(p.start()));
        assert_eq!(stage, "panicky");
        let panicked = source.downcast_ref::<Panicked>().expect("a Panicked error");
        assert_eq!(panicked.message, "boom at item 5");
        assert_eq!(shown, "stage `panicky` failed: panicked: boom at item 5");
        assert_eq!(stats[1].state, StageState::Failed);
    }

    #[test]
    fn panic_in_source_is_reported() {
        let source = Node::source(FnSource(|out: &mut Emitter<u64>| {
            out.emit(1)?;
            panic!("camera vanished");
        }));
        let p = Pipeline::new(2, vec![node("acquire", source), node("sink", sink())]).unwrap();
        let (stage, _, _, shown) = stage_error(wait_bounded(p.start()));
        assert_eq!(stage, "acquire");
        assert_eq!(shown, "stage `acquire` failed: panicked: camera vanished");
    }

    #[test]
    fn dropped_items_are_counted() {
        let evens = Node::stage(FnStage(|x: u64, out: &mut Emitter<u64>| {
            if x % 2 == 1 {
                out.dropped(1);
            } else {
                out.emit(x)?;
            }
            Ok(())
        }));
        let p = Pipeline::new(8, vec![node("src", count_to(1000)), node("evens", evens)]).unwrap();
        let report = wait_bounded(p.start()).unwrap();
        let s = &report.stages[1];
        assert_eq!((s.input, s.output, s.dropped), (1000, 500, 500));
        assert_eq!(report.outputs.len(), 500);
        assert!(report.outputs.iter().all(|x| x % 2 == 0));
    }

    #[test]
    fn finish_runs_once_at_end_of_stream_and_can_emit() {
        struct Sum {
            total: u64,
            finishes: Arc<AtomicU64>,
        }
        impl Stage<u64> for Sum {
            fn process(&mut self, x: u64, _: &mut Emitter<u64>) -> Result<(), BoxError> {
                self.total += x;
                Ok(())
            }
            fn finish(&mut self, out: &mut Emitter<u64>) -> Result<(), BoxError> {
                self.finishes.fetch_add(1, Ordering::SeqCst);
                out.emit(self.total)?;
                Ok(())
            }
        }
        let finishes = Arc::new(AtomicU64::new(0));
        let sum = Sum {
            total: 0,
            finishes: finishes.clone(),
        };
        let p = Pipeline::new(
            2,
            vec![
                node("src", count_to(100)),
                node("sum", Node::stage(sum)),
                node("pass", map(|x| x)),
            ],
        )
        .unwrap();
        let report = wait_bounded(p.start()).unwrap();
        assert_eq!(report.outputs, vec![4950]);
        assert_eq!(finishes.load(Ordering::SeqCst), 1);
        assert!(!report.cancelled);
    }

    #[test]
    fn source_alone_is_collected() {
        let p = Pipeline::new(1, vec![node("src", count_to(5))]).unwrap();
        let report = wait_bounded(p.start()).unwrap();
        assert_eq!(report.outputs, vec![0, 1, 2, 3, 4]);
        assert_eq!(report.stages[0].output, 5);
    }

    #[test]
    fn stats_are_live_while_running() {
        let (release, released) = mpsc::channel::<()>();
        let source = Node::source(FnSource(move |out: &mut Emitter<u64>| {
            for i in 0..10 {
                out.emit(i)?;
            }
            let _ = released.recv();
            Ok(())
        }));
        let (notify, noticed) = mpsc::channel();
        let watcher = Watcher {
            seen: 0,
            notify_at: 10,
            notify,
            finished: Arc::new(AtomicBool::new(false)),
        };
        let running = Pipeline::new(
            16,
            vec![node("src", source), node("watch", Node::stage(watcher))],
        )
        .unwrap()
        .start();
        noticed.recv_timeout(HANG).unwrap();
        let live = running.stats();
        assert_eq!(states(&live), vec![StageState::Running; 2]);
        assert_eq!((live[0].output, live[1].input), (10, 10));
        drop(release);
        // Watcher::finish fails on purpose, proving finish() runs on a normal end.
        let (stage, ..) = stage_error(wait_bounded(running));
        assert_eq!(stage, "watch");
    }

    #[test]
    fn dropping_running_cancels_and_joins() {
        let running = Pipeline::new(2, vec![node("src", endless()), node("sink", sink())])
            .unwrap()
            .start();
        let (done, is_done) = mpsc::channel();
        thread::spawn(move || {
            drop(running);
            let _ = done.send(());
        });
        is_done
            .recv_timeout(HANG)
            .expect("drop did not end the run");
    }

    #[test]
    fn chain_shape_is_checked() {
        let err =
            Pipeline::new(2, vec![node("a", count_to(1)), node("b", count_to(1))]).unwrap_err();
        assert!(matches!(err, BuildError::SourceNotFirst { index: 1, ref stage } if stage == "b"));
        let err = Pipeline::new(2, vec![node("s", sink())]).unwrap_err();
        assert!(matches!(err, BuildError::FirstNotSource { ref stage } if stage == "s"));
        assert!(matches!(
            Pipeline::<u64>::new(2, vec![]),
            Err(BuildError::Empty)
        ));
        let err = Pipeline::new(0, vec![node("a", count_to(1))]).unwrap_err();
        assert!(matches!(err, BuildError::Capacity(0)));
    }
}
