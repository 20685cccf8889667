//! The plantar model's height map computed while the scan runs (issue 34 item 2): the
//! measurements after the last frame then wait only for the model's last columns.
//!
//! `accumulate` hands every frame's points here; a thread of its own builds each column of
//! the Bezier network's segments once its four frames have come ([`Segment::interpolating`],
//! the network's own construction) and fills their heights ([`HeightFill`]). `measure.foot`
//! asks for the map with the finished network; [`HeightFill::finish`] checks the segments
//! against it, so a grid changed after the frames came (gaps bridged) costs time, never a
//! different height.

use crate::geom::HeightMap;
use crate::surface::network::{period, segments_along};
use crate::surface::{BezierNetwork, HeightFill, Segment};
use footscan_geom::P3;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{channel, Sender};
use std::sync::Mutex;
use std::thread::JoinHandle;

/// Requested by `measure.foot` (with its cell) before the frames flow, fed by `accumulate`;
/// filled only when `model.bezier` is in the pipeline to send the network it is checked
/// against (without it the map would be filled for nothing).
#[derive(Debug, Default)]
pub struct EarlyHeights {
    cell_mm: Mutex<Option<f64>>,
    model: AtomicBool,
    worker: Mutex<Option<Worker>>,
}

#[derive(Debug)]
struct Worker {
    frames: Sender<Vec<P3>>,
    thread: JoinHandle<HeightFill>,
}

impl EarlyHeights {
    /// Ask for the model's heights on cells of `cell_mm`.
    pub fn request(&self, cell_mm: f64) {
        *self.cell_mm.lock().unwrap() = Some(cell_mm);
    }

    /// Say that a model stage will send the network down the pipeline.
    pub fn model_comes(&self) {
        self.model.store(true, Ordering::Relaxed);
    }

    /// One frame's points, in scan order (the first starts the thread when heights were
    /// asked for). A frame with another row count than the first is ignored here:
    /// [`HeightFill::finish`] then finds the segments differ.
    pub fn push(&self, points: &[P3]) {
        if !self.model.load(Ordering::Relaxed) {
            return;
        }
        let Some(cell) = *self.cell_mm.lock().unwrap() else {
            return;
        };
        let mut w = self.worker.lock().unwrap();
        if w.is_none() {
            let (tx, rx) = channel::<Vec<P3>>();
            let rows = points.len();
            let spawned = std::thread::Builder::new()
                .name("model.heights".into())
                .spawn(move || {
                    // Below the scan's own stages: a frame is never dropped for it.
                    let _ = footscan_util::priority::lower_this_thread(5);
                    let mut cols = Columns::new(rows, cell);
                    for f in rx {
                        cols.push(f);
                    }
                    cols.fill
                });
            match spawned {
                Ok(thread) => *w = Some(Worker { frames: tx, thread }),
                Err(e) => {
                    tracing::debug!("model.heights not started ({e}): measured after the scan");
                    *self.cell_mm.lock().unwrap() = None;
                    return;
                }
            }
        }
        if let Some(w) = w.as_ref() {
            let _ = w.frames.send(points.to_vec());
        }
    }

    /// The height map of `net` on the requested cell (its cells exactly
    /// [`BezierNetwork::eval_heightmap`]'s: [`HeightFill::finish`]), or None when none was
    /// asked for or no frame came.
    pub fn finish(&self, net: &BezierNetwork) -> Option<HeightMap> {
        let w = self.worker.lock().unwrap().take()?;
        let t = std::time::Instant::now();
        drop(w.frames);
        let fill = w.thread.join().ok()?;
        let joined_ms = t.elapsed().as_secs_f64() * 1e3;
        let (given, all) = (fill.len(), net.segments().len());
        let map = fill.finish(net);
        tracing::debug!(
            joined_ms,
            finished_ms = t.elapsed().as_secs_f64() * 1e3,
            given,
            all,
            "model heights"
        );
        Some(map)
    }
}

/// The frames of the segment column being waited for, and the filled heights.
struct Columns {
    rows: usize,
    /// Frames from the first of column `next` on.
    frames: VecDeque<Vec<P3>>,
    next: usize,
    fill: HeightFill,
    col: Vec<Segment>,
}

impl Columns {
    fn new(rows: usize, cell: f64) -> Self {
        Columns {
            rows,
            frames: VecDeque::with_capacity(4),
            next: 0,
            fill: HeightFill::new(cell),
            col: Vec::new(),
        }
    }

    fn push(&mut self, frame: Vec<P3>) {
        if frame.len() != self.rows || self.rows < 2 {
            return;
        }
        self.frames.push_back(frame);
        // Column a spans frames 3a..=3a+3; it is final (period 3) once they have all come.
        if self.frames.len() < 4 {
            return;
        }
        let (a, f) = (self.next, &self.frames);
        self.col.clear();
        self.col
            .extend((0..segments_along(self.rows)).filter_map(|b| {
                Segment::interpolating(|i, j| f[i - 3 * a][j], a, b, 3, period(self.rows, b))
            }));
        self.fill.add(&self.col);
        // The column's last frame is the next one's first.
        self.frames.drain(..3);
        self.next += 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::surface::PointGrid;

    /// Frames of a smooth sole-like surface: `nu` frames of `nv` rows, NaN off an ellipse.
    fn frames(nu: usize, nv: usize) -> Vec<Vec<P3>> {
        (0..nu)
            .map(|i| {
                let x = i as f64 * 0.5;
                (0..nv)
                    .map(|j| {
                        let y = j as f64 * 0.3 - 12.0;
                        let inside = ((x - 15.0) / 14.0).powi(2) + (y / 11.0).powi(2) < 1.0;
                        let z = 2.0 + 0.01 * (x - 15.0).powi(2) + 0.02 * y * y;
                        if inside {
                            P3::new(x + 0.01 * (y * 0.4).sin(), y, z)
                        } else {
                            P3::from([f64::NAN; 3])
                        }
                    })
                    .collect()
            })
            .collect()
    }

    /// The heights filled while the frames come are the finished network's, bit for bit,
    /// and all but the last column were filled before the end.
    #[test]
    fn heights_filled_while_the_frames_come_are_the_networks() {
        let fr = frames(50, 81);
        let early = EarlyHeights::default();
        // Nothing asked for, or asked for with no model to come: nothing kept.
        early.push(&fr[0]);
        assert!(early.worker.lock().unwrap().is_none());
        early.request(0.1);
        early.push(&fr[0]);
        assert!(early.worker.lock().unwrap().is_none());
        early.model_comes();
        let mut cols = Columns::new(81, 0.1);
        for f in &fr {
            early.push(f);
            cols.push(f.clone());
        }
        let grid = PointGrid::new(50, 81, fr.concat());
        let net = BezierNetwork::build(&grid).unwrap();
        let whole = net.eval_heightmap_on(0.1, 1);
        // 50 frames: columns 0..=15 are final before the end, column 16 (period 1) is not.
        let before_end = net.segments().iter().filter(|s| s.a < 16).count();
        assert_eq!(cols.fill.len(), before_end);
        assert!(before_end > 0 && before_end < net.segments().len());
        let got = early.finish(&net).expect("heights were asked for");
        assert!(crate::surface::network::tests::same_heights(&got, &whole));
        assert!(whole.valid_count() > 1000);
    }
}
