//! Per-frame processing: detection, triangulation, accumulation into the scan grid.

#[cfg(feature = "plugins")]
use super::plugin::PluginDetector;
use super::FrameTap;
use crate::calib::Triangulator;
use crate::detect::{Detector, Image, LinePeak, Prep};
use crate::pipeline::{BoxError, Emitter, Stage};
use crate::scan::item::{unexpected, AcquiredFrame, FrameLines, FramePoints, Item};
use crate::scan::{ScanCounters, ScanGrid};
use footscan_geom::P3;
use footscan_hal::Frame;
use std::sync::Arc;

/// What finds the line: a built-in detector, or a wasm module's, which may fail.
enum Finder {
    Builtin(Box<dyn Detector>),
    #[cfg(feature = "plugins")]
    Plugin(Box<PluginDetector>),
}

pub struct Detect {
    name: &'static str,
    detector: Finder,
    tap: Option<Arc<dyn FrameTap>>,
    /// The laser-off background, subtracted from every frame once a laser-off frame came.
    prep: Prep,
    background: bool,
    counters: Option<Arc<ScanCounters>>,
}

impl Detect {
    pub fn new(name: &'static str, detector: Box<dyn Detector>) -> Self {
        Self::with_finder(name, Finder::Builtin(detector))
    }

    /// The `wasm` and `exec` stages: the plugin's detector in place of a built-in one.
    #[cfg(feature = "plugins")]
    pub fn plugin(name: &'static str, detector: PluginDetector) -> Self {
        Self::with_finder(name, Finder::Plugin(Box::new(detector)))
    }

    fn with_finder(name: &'static str, detector: Finder) -> Self {
        Detect {
            name,
            detector,
            tap: None,
            prep: Prep::new(None),
            background: false,
            counters: None,
        }
    }

    /// Show every frame and its line to `tap` (a live preview).
    pub fn with_tap(mut self, tap: Option<Arc<dyn FrameTap>>) -> Self {
        self.tap = tap;
        self
    }

    /// Count the laser-off frames and the rows found in them into `counters`.
    pub fn with_counters(mut self, counters: Arc<ScanCounters>) -> Self {
        self.counters = Some(counters);
        self
    }

    /// A laser-off frame: the rows the detector finds in it as it is are false detections
    /// (counted); the first one becomes the background. Nothing goes downstream.
    fn laser_off(&mut self, af: AcquiredFrame) -> Result<(), BoxError> {
        let mut lines = vec![LinePeak::NONE; af.frame.height as usize];
        self.find(&af.frame, &mut lines)?;
        let found = lines.iter().filter(|l| l.is_valid()).count() as u64;
        if found > 0 {
            tracing::warn!(
                seq = af.meta.seq,
                rows = found,
                "line found in a laser-off frame"
            );
        }
        if let Some(c) = &self.counters {
            c.add_laser_off(found);
        }
        if !self.background {
            let name = format!("laser-off frame {}", af.meta.seq);
            self.prep.set_background(&Image::Gray(af.frame), &name)?;
            self.background = true;
        }
        Ok(())
    }
}

fn find(d: &mut Finder, frame: &Frame, lines: &mut [LinePeak]) -> Result<(), BoxError> {
    match d {
        Finder::Builtin(d) => {
            d.detect(frame, lines);
            Ok(())
        }
        #[cfg(feature = "plugins")]
        Finder::Plugin(d) => d.detect(frame, lines),
    }
}

impl Detect {
    fn find(&mut self, frame: &Frame, lines: &mut [LinePeak]) -> Result<(), BoxError> {
        find(&mut self.detector, frame, lines)
    }
}

impl Stage<Item> for Detect {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Item::Frame(af) = item else {
            return Err(unexpected(self.name, &item, "frames"));
        };
        if af.laser_off {
            return self.laser_off(af);
        }
        let mut lines = vec![LinePeak::NONE; af.frame.height as usize];
        let (meta, img) = (af.meta, Image::Gray(af.frame));
        let seen = self.prep.prepare(&img, "scan frame")?;
        find(&mut self.detector, seen, &mut lines)?;
        let Image::Gray(frame) = img else {
            unreachable!("made grey above")
        };
        if let Some(tap) = &self.tap {
            tap.frame(&meta, &frame, &lines);
        }
        drop(frame); // hand the buffer back to the camera's pool before blocking downstream
        let _ = out.emit(Item::Lines(FrameLines { meta, lines }));
        Ok(())
    }
}

pub struct Triangulate {
    tri: Triangulator,
}

impl Triangulate {
    pub fn new(tri: Triangulator) -> Self {
        Triangulate { tri }
    }
}

impl Stage<Item> for Triangulate {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Item::Lines(fl) = item else {
            return Err(unexpected("triangulate", &item, "lines"));
        };
        let x = fl.meta.x_mm;
        let points = fl
            .lines
            .iter()
            .enumerate()
            .map(|(r, l)| {
                l.is_valid()
                    .then(|| self.tri.point(x, l.col, r as f64))
                    .flatten()
                    .unwrap_or(P3::from([f64::NAN; 3]))
            })
            .collect();
        let _ = out.emit(Item::Points(FramePoints {
            meta: fl.meta,
            lines: fl.lines,
            points,
        }));
        Ok(())
    }
}

/// Collects frames into the scan grid and emits it once the scan ends, with the gaps of
/// dropped frames bridged and the quality gate's facts handed to `counters`
/// (docs/method.md section 3.3): every sink and model after it sees the bridged grid.
#[derive(Default)]
pub struct Accumulate {
    grid: Option<ScanGrid>,
    gate: Option<(Arc<ScanCounters>, f64, f64)>,
}

impl Accumulate {
    /// Bridge gaps up to `bridge_mm` at the nominal `step_mm` and record the facts.
    pub fn with_gate(counters: Arc<ScanCounters>, step_mm: f64, bridge_mm: f64) -> Self {
        Accumulate {
            grid: None,
            gate: Some((counters, step_mm, bridge_mm)),
        }
    }
}

impl Stage<Item> for Accumulate {
    fn process(&mut self, item: Item, _out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Item::Points(fp) = item else {
            return Err(unexpected("accumulate", &item, "points"));
        };
        if let Some((counters, ..)) = &self.gate {
            counters.early.push(&fp.points);
        }
        self.grid
            .get_or_insert_with(|| ScanGrid::new(fp.points.len()))
            .push(fp);
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let mut grid = self
            .grid
            .take()
            .ok_or("the scan produced no frames: nothing to accumulate")?;
        if let Some((counters, step_mm, bridge_mm)) = &self.gate {
            let mut q = crate::scan::quality::bridge_gaps(&mut grid, *step_mm, *bridge_mm);
            crate::scan::quality::inspect(&grid, &mut q);
            if q.bridged_frames > 0 {
                tracing::info!(
                    frames = q.bridged_frames,
                    largest_gap_mm = q.largest_gap_mm,
                    "gaps of dropped frames bridged"
                );
            }
            counters.set_quality(q);
        }
        let _ = out.emit(Item::Grid(Arc::new(grid)));
        Ok(())
    }
}
