//! `measure.foot`: measures the foot at the end of the stream from the grid and, when one
//! comes down the pipeline, the plantar model; the measurements go on down the pipeline for
//! the last stages (`last.adjust`).

use super::out_file;
use crate::measure::{footprint_ahead, measure_grid_with, write_measurements, Ahead, Footprint};
use crate::pipeline::{BoxError, Emitter, Stage};
use crate::scan::item::Item;
use crate::scan::model_job::MeasuredFoot;
use crate::scandata::{ScanDir, ScanGrid};
use crate::surface::BezierNetwork;
use serde::Deserialize;
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeasureParams {
    #[serde(default = "default_json")]
    pub json: String,
    #[serde(default = "default_png")]
    pub png: String,
    #[serde(default = "default_cell")]
    pub cell_mm: f64,
    /// Heights from the model when one comes down the pipeline.
    #[serde(default = "yes")]
    pub use_model: bool,
    /// A foot that cannot be measured fails the scan; false: a warning in the log.
    #[serde(default = "yes")]
    pub required: bool,
}

fn default_json() -> String {
    ScanDir::MEASUREMENTS.into()
}
fn default_png() -> String {
    ScanDir::PLANTAR.into()
}
fn default_cell() -> f64 {
    crate::measure::DEFAULT_CELL_MM
}
fn yes() -> bool {
    true
}

/// `measure.foot`: keeps the grid (and the model, which comes after it) and measures once
/// both have come (without a model, at the end of the stream); passes every item on.
pub struct MeasureStage {
    json: PathBuf,
    png: PathBuf,
    cell_mm: f64,
    use_model: bool,
    required: bool,
    grid: Option<Arc<ScanGrid>>,
    model: Option<Arc<BezierNetwork>>,
    counters: Option<Arc<crate::scan::ScanCounters>>,
    /// Measured already (when the model came): the end of the stream has nothing to do.
    measured: bool,
    /// The footprint, rasterised from the grid and measured as far as its outline goes while
    /// the model is built.
    footprint: Option<std::thread::JoinHandle<Footprint>>,
}

impl MeasureStage {
    /// The stage of `p`, writing into `out_dir`; checks the cell and the file names.
    pub fn new(p: MeasureParams, out_dir: &std::path::Path) -> Result<Self, BoxError> {
        if !(p.cell_mm >= 0.05 && p.cell_mm <= 1.0) {
            return Err(format!("cell_mm = {}: valid range is [0.05, 1]", p.cell_mm).into());
        }
        Ok(MeasureStage {
            json: out_file(out_dir, "json", &p.json)?,
            png: out_file(out_dir, "png", &p.png)?,
            cell_mm: p.cell_mm,
            use_model: p.use_model,
            required: p.required,
            grid: None,
            model: None,
            counters: None,
            measured: false,
            footprint: None,
        })
    }

    /// Tell the quality gate the measured foot's side (checked against the operator's), and
    /// hand the measured foot to the model job when it is measured the way the model's
    /// frame needs (with the model, on the default cell): the foot is then measured once.
    pub fn with_counters(mut self, counters: Arc<crate::scan::ScanCounters>) -> Self {
        if self.shares() {
            counters.model.foot.expect();
        }
        if self.use_model {
            counters.early.request(self.cell_mm);
        }
        self.counters = Some(counters);
        self
    }

    fn shares(&self) -> bool {
        self.use_model && self.cell_mm == crate::measure::DEFAULT_CELL_MM
    }

    /// Hand the model job the measured foot (None: it measures, or says why it cannot).
    fn publish(&self, foot: Option<Arc<MeasuredFoot>>) {
        if let Some(c) = &self.counters {
            if self.shares() {
                c.model.foot.publish(foot);
            }
        }
    }
}

impl Drop for MeasureStage {
    /// A stage that ends without measuring (the scan failed or was cancelled) must not leave
    /// the model job waiting.
    fn drop(&mut self) {
        self.publish(None);
    }
}

impl Stage<Item> for MeasureStage {
    /// Measures as soon as the model has come after the grid, else at the end of the
    /// stream: the results do not wait for the stages after the model to end. The footprint
    /// is rasterised from the grid's arrival on, beside the model's construction.
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        match &item {
            Item::Grid(g) => {
                self.grid = Some(g.clone());
                let (g, cell) = (g.clone(), self.cell_mm);
                self.footprint = std::thread::Builder::new()
                    .name("measure.footprint".into())
                    .spawn(move || footprint_ahead(&g, cell))
                    .ok();
            }
            Item::Model(n) if self.use_model => self.model = Some(n.clone()),
            _ => {}
        }
        let ready = matches!(item, Item::Model(_)) && self.use_model && self.grid.is_some();
        let _ = out.emit(item);
        if ready {
            self.measure(out)?;
        }
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        if self.measured {
            return Ok(());
        }
        self.measure(out)
    }
}

impl MeasureStage {
    fn measure(&mut self, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        self.measured = true;
        let Some(grid) = self.grid.take() else {
            return Err("measure.foot received no scan grid: put it after accumulate".into());
        };
        let model = self.model.clone();
        // The model's heights filled while the frames came, when accumulate fed them.
        let t = std::time::Instant::now();
        let ms = |t: std::time::Instant| t.elapsed().as_secs_f64() * 1e3;
        let (footprint, planar) = match self.footprint.take().and_then(|h| h.join().ok()) {
            Some((f, p)) => (Some(f), p),
            None => (None, None),
        };
        let ahead = Ahead {
            model_map: match (&self.counters, &model) {
                (Some(c), Some(net)) => c.early.finish(net),
                _ => None,
            },
            footprint,
            planar,
        };
        let early_ms = ms(t);
        let had_early = ahead.model_map.is_some();
        let result = measure_grid_with(&grid, model.as_deref(), self.cell_mm, ahead);
        let measured_ms = ms(t);
        let result = result.and_then(|(map, m)| {
            let Some(net) = model else {
                return write_measurements(&m, &map, &self.json, &self.png).map(|_| m);
            };
            let foot = Arc::new(MeasuredFoot {
                net,
                map,
                measurements: m.clone(),
            });
            // The model job starts on it while the files below are written.
            self.publish(Some(foot.clone()));
            write_measurements(&m, &foot.map, &self.json, &self.png).map(|_| m)
        });
        if result.is_err() {
            self.publish(None);
        }
        tracing::debug!(
            early_heights = had_early,
            heights_ready_ms = early_ms,
            measured_ms,
            written_ms = ms(t),
            "measure.foot timing"
        );
        match result {
            Ok(m) => {
                tracing::info!(
                    length_mm = m.foot_length_mm,
                    ball_width_mm = m.ball_width_mm,
                    arch_index = m.arch_index,
                    "foot measured"
                );
                for w in &m.warnings {
                    tracing::warn!("{w}");
                }
                if let Some(c) = &self.counters {
                    c.set_foot_side(m.side);
                    c.set_measure_warnings(m.warnings.clone());
                }
                let _ = out.emit(Item::Foot(Arc::new(m)));
                Ok(())
            }
            Err(e) if !self.required => {
                tracing::warn!("foot not measured: {}", footscan_util::Chain(&e));
                Ok(())
            }
            Err(e) => Err(format!("measure.foot: {}", footscan_util::Chain(&e)).into()),
        }
    }
}
