//! The `model.bezier` pipeline stage: takes the scan grid, passes it on, builds the Bezier
//! network and emits it after the grid, then writes the foot model for CAD (`footscan::cad`:
//! the closed solid in the foot frame, STL, STEP, glTF) into the scan directory. In a scan the
//! files are written on the scan's model job after the results ([`crate::scan::model_job`]),
//! on the foot `measure.foot` measured.

use super::out_file;
use crate::cad::{
    write_foot_model, write_measured_foot_model, CadError, ModelFiles, ModelSummary,
    DEFAULT_GLB_CELL_MM, DEFAULT_STEP_CELL_MM,
};
use crate::pipeline::{BoxError, Emitter, Stage};
use crate::scan::item::Item;
use crate::scan::model_job::{ModelProgress, ModelState};
use crate::scan::ScanCounters;
use crate::scandata::{ScanDir, ScanGrid};
use crate::surface::build_scan_model;
use crate::surface::BezierNetwork;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelParams {
    /// Mesh files, plain names inside the scan directory; "" to skip one.
    #[serde(default = "default_stl")]
    pub stl: String,
    #[serde(default)]
    pub ply: String,
    #[serde(default)]
    pub obj: String,
    /// The faceted STEP solid; "" to skip it.
    #[serde(default = "default_step")]
    pub step: String,
    /// The same solid as an IGES B-rep solid; "" (the default) to skip it.
    #[serde(default)]
    pub iges: String,
    /// glTF binary for the dashboard's 3D view, Blender and the web; "" to skip it.
    #[serde(default = "default_glb")]
    pub glb: String,
    /// Cell of the .glb solid (mm): coarser than the STL's so the viewer loads it at once.
    #[serde(default = "default_glb_cell")]
    pub glb_cell_mm: f64,
    /// Cell of the grid the mesh is sampled on (mm), in the foot frame.
    #[serde(default = "default_cell")]
    pub cell_mm: f64,
    /// Cell of the STEP solid (mm).
    #[serde(default = "default_step_cell")]
    pub step_cell_mm: f64,
}

fn default_step() -> String {
    ScanDir::MODEL_STEP.into()
}

fn default_glb() -> String {
    ScanDir::MODEL_GLB.into()
}

fn default_glb_cell() -> f64 {
    DEFAULT_GLB_CELL_MM
}

fn default_step_cell() -> f64 {
    DEFAULT_STEP_CELL_MM
}

fn default_stl() -> String {
    ScanDir::MODEL_STL.into()
}

fn default_cell() -> f64 {
    0.5
}

/// An optional output file: "" skips it.
fn optional(out_dir: &Path, key: &str, f: &str) -> Result<Option<PathBuf>, BoxError> {
    if f.is_empty() {
        return Ok(None);
    }
    out_file(out_dir, key, f).map(Some)
}

pub struct ModelStage {
    files: ModelFiles,
    /// The scan's shared state: with it the files are written on its model job.
    counters: Option<Arc<ScanCounters>>,
}

impl ModelStage {
    /// The stage of `p`, writing into `out_dir`; checks the cell and the file names.
    pub fn new(p: ModelParams, out_dir: &Path) -> Result<Self, BoxError> {
        crate::cad::check_cell("cell_mm", p.cell_mm, None)?;
        crate::cad::check_cell("step_cell_mm", p.step_cell_mm, None)?;
        crate::cad::check_cell("glb_cell_mm", p.glb_cell_mm, None)?;
        Ok(ModelStage {
            files: ModelFiles {
                stl: optional(out_dir, "stl", &p.stl)?,
                ply: optional(out_dir, "ply", &p.ply)?,
                obj: optional(out_dir, "obj", &p.obj)?,
                step: optional(out_dir, "step", &p.step)?,
                iges: optional(out_dir, "iges", &p.iges)?,
                glb: optional(out_dir, "glb", &p.glb)?,
                cell_mm: p.cell_mm,
                step_cell_mm: p.step_cell_mm,
                glb_cell_mm: p.glb_cell_mm,
            },
            counters: None,
        })
    }

    /// Write the files on `counters`' model job, after the results.
    pub fn with_counters(mut self, counters: Arc<ScanCounters>) -> Self {
        counters.early.model_comes();
        self.counters = Some(counters);
        self
    }
}

const CELL_NAMES: [&str; 3] = ["cell_mm", "step_cell_mm", "glb_cell_mm"];

/// Log what was written, or that there was no foot to model.
fn logged(r: Result<ModelSummary, CadError>) -> Result<ModelSummary, CadError> {
    match r {
        Ok(s) => {
            tracing::info!(
                length_mm = s.extent_mm[0][1] - s.extent_mm[0][0],
                measured_length_mm = s.foot_length_mm,
                triangles = s.triangles,
                pieces = s.components,
                mesh_ms = s.mesh_ms,
                "foot model written"
            );
            for w in &s.warnings {
                tracing::warn!("model: {w}");
            }
            Ok(s)
        }
        // No foot to put a frame on (an empty glass, a plate): the network still goes on.
        Err(CadError::Measure(e)) => {
            tracing::warn!("foot model not written: {}", footscan_util::Chain(&e));
            Err(CadError::Measure(e))
        }
        Err(e) => Err(e),
    }
}

/// The model job's work: wait for the foot `measure.foot` measures (measure it here if no
/// stage shares it), then build and write the solid; the outcome goes to the job's progress.
fn files_job(
    counters: &ScanCounters,
    grid: &ScanGrid,
    net: &Arc<BezierNetwork>,
    build_ms: f64,
    files: &ModelFiles,
) {
    let job = &counters.model;
    let t = std::time::Instant::now();
    let shared = job.foot.wait().filter(|f| Arc::ptr_eq(&f.net, net));
    if job.abandoned() {
        job.set_progress(ModelProgress {
            state: ModelState::Abandoned,
            reason: Some("the scan ended before the model was written".into()),
            ..ModelProgress::building()
        });
        return;
    }
    let measured_again = shared.is_none();
    let r = match &shared {
        Some(f) => write_measured_foot_model(
            grid,
            net,
            build_ms,
            files,
            CELL_NAMES,
            &f.map,
            &f.measurements,
            t,
        ),
        None => write_foot_model(grid, net, build_ms, files, CELL_NAMES),
    };
    let name = |p: &std::path::PathBuf| {
        p.file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
    };
    let progress = match logged(r) {
        Ok(s) => ModelProgress {
            state: ModelState::Written,
            reason: None,
            files: s.files.iter().map(name).collect(),
            triangles: Some(s.triangles),
            measured_again,
        },
        Err(CadError::Measure(e)) => ModelProgress {
            state: ModelState::NotWritten,
            reason: Some(format!("no foot to model: {}", footscan_util::Chain(&e))),
            measured_again,
            ..ModelProgress::building()
        },
        Err(e) => ModelProgress {
            state: ModelState::Failed,
            reason: Some(format!("model.bezier: {}", footscan_util::Chain(&e))),
            measured_again,
            ..ModelProgress::building()
        },
    };
    job.set_progress(progress);
}

impl Stage<Item> for ModelStage {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Item::Grid(grid) = &item else {
            let _ = out.emit(item);
            return Ok(());
        };
        let grid = grid.clone();
        // The grid first: the sinks and the measurements need no model to start.
        let _ = out.emit(item);
        let (net, build_ms) = build_scan_model(&grid)?;
        tracing::info!(
            segments = net.segments().len(),
            skipped = net.skipped(),
            build_ms,
            "plantar model built"
        );
        let net = Arc::new(net);
        let _ = out.emit(Item::Model(net.clone()));
        let Some(counters) = self.counters.clone() else {
            // Outside a scan: the files now, as before.
            return match logged(write_foot_model(
                &grid,
                &net,
                build_ms,
                &self.files,
                CELL_NAMES,
            )) {
                Ok(_) | Err(CadError::Measure(_)) => Ok(()),
                Err(e) => Err(e.into()),
            };
        };
        let files = self.files.clone();
        let c = counters.clone();
        counters
            .model
            .start(move || files_job(&c, &grid, &net, build_ms, &files))
            .map_err(|e| format!("model.bezier: cannot start the model's thread: {e}"))?;
        Ok(())
    }
}
