//! The `model.bezier` pipeline stage: takes the scan grid, passes it on, writes the model's
//! mesh files into the scan directory and emits the model after the grid.

use super::out_file;
use crate::pipeline::{BoxError, Emitter, Stage};
use crate::scan::item::Item;
use crate::surface::{model_scan, MeshFiles};
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
    /// Cell of the (x, y) grid the mesh is sampled on (mm).
    #[serde(default = "default_cell")]
    pub cell_mm: f64,
}

fn default_stl() -> String {
    "model.stl".into()
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
    files: MeshFiles,
}

impl ModelStage {
    /// The stage of `p`, writing into `out_dir`; checks the cell and the file names.
    pub fn new(p: ModelParams, out_dir: &Path) -> Result<Self, BoxError> {
        if !(p.cell_mm >= 0.05 && p.cell_mm <= 10.0) {
            return Err(format!("cell_mm = {}: valid range is [0.05, 10]", p.cell_mm).into());
        }
        Ok(ModelStage {
            files: MeshFiles {
                stl: optional(out_dir, "stl", &p.stl)?,
                ply: optional(out_dir, "ply", &p.ply)?,
                obj: optional(out_dir, "obj", &p.obj)?,
                cell_mm: p.cell_mm,
            },
        })
    }
}

impl Stage<Item> for ModelStage {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Item::Grid(grid) = &item else {
            let _ = out.emit(item);
            return Ok(());
        };
        let (net, summary) = model_scan(grid, &self.files)?;
        tracing::info!(
            segments = summary.segments,
            skipped = summary.skipped,
            build_ms = summary.build_ms,
            max_jump_deg = summary.continuity.max_deg,
            "plantar model built"
        );
        let _ = out.emit(item);
        let _ = out.emit(Item::Model(Arc::new(net)));
        Ok(())
    }
}
