//! Sinks: files written from the finished scan grid. Each passes on every item (the grid and
//! whatever it does not handle) so sinks and model stages chain in any order after accumulate.

use crate::io::{render_heightmap, write_ply_points, HeightMapLabel};
use crate::pipeline::{BoxError, Emitter, Stage};
use crate::scan::item::Item;
use crate::scan::summary::{summarize, TruthSource};
use footscan_geom::P3;
use std::path::PathBuf;
use std::sync::Arc;

pub struct PlySink {
    pub path: PathBuf,
}

impl Stage<Item> for PlySink {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Item::Grid(grid) = &item else {
            let _ = out.emit(item);
            return Ok(());
        };
        let (pts, q): (Vec<P3>, Vec<f32>) =
            grid.valid().map(|(_, _, p, l)| (*p, l.quality)).unzip();
        write_ply_points(&self.path, &pts, &q)
            .map_err(|e| format!("writing {}: {e}", self.path.display()))?;
        let _ = out.emit(item);
        Ok(())
    }
}

/// Writes heightmap.png from the grid, titled with `label` (the side the operator chose, the
/// subject). Placed after `measure.foot`, it writes the map again with the measured side when
/// the measurement arrives.
pub struct HeightMapSink {
    pub path: PathBuf,
    pub cell_mm: f64,
    pub label: HeightMapLabel,
    /// The grid's valid points, kept for a title with the measured side.
    pub points: Option<Vec<P3>>,
}

impl HeightMapSink {
    fn write(&self, pts: &[P3]) -> Result<(), BoxError> {
        render_heightmap(pts, self.cell_mm, &self.label)
            .save(&self.path)
            .map_err(|e| format!("writing {}: {e}", self.path.display()).into())
    }
}

impl Stage<Item> for HeightMapSink {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        match &item {
            Item::Grid(grid) => {
                let pts: Vec<P3> = grid.valid().map(|(_, _, p, _)| *p).collect();
                self.write(&pts)?;
                self.points = Some(pts);
            }
            Item::Foot(m) => {
                self.label.measured = Some(m.side);
                if let Some(pts) = self.points.take() {
                    self.write(&pts)?;
                }
            }
            _ => {}
        }
        let _ = out.emit(item);
        Ok(())
    }
}

/// Emits the scan summary (point count and, for simulated scans, error against ground truth).
pub struct SummarySink {
    pub truth: Option<Arc<dyn TruthSource>>,
}

impl Stage<Item> for SummarySink {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Item::Grid(grid) = &item else {
            let _ = out.emit(item);
            return Ok(());
        };
        let summary = summarize(grid, self.truth.as_deref());
        let _ = out.emit(item);
        let _ = out.emit(Item::Summary(Box::new(summary)));
        Ok(())
    }
}

/// Saves the grid as grid.bin so `footscan model` and `footscan measure` can reuse a scan.
pub struct GridSink {
    pub path: PathBuf,
}

impl Stage<Item> for GridSink {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        if let Item::Grid(grid) = &item {
            grid.save(&self.path)
                .map_err(|e| format!("writing {}: {e}", self.path.display()))?;
        }
        let _ = out.emit(item);
        Ok(())
    }
}
