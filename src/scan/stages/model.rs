//! The `model.bezier` pipeline stage: takes the scan grid, passes it on, writes the model's
//! mesh files into the scan directory and emits the model after the grid.

use super::export::{model_scan, MeshFiles};
use crate::pipeline::{BoxError, Emitter, Node, Registry, Stage};
use crate::scan::item::Item;
use crate::scan::{params, ScanContext};
use serde::Deserialize;
use std::path::PathBuf;
use std::sync::Arc;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelParams {
    /// Mesh files, plain names inside the scan directory; "" to skip one.
    #[serde(default = "default_stl")]
    stl: String,
    #[serde(default)]
    ply: String,
    #[serde(default)]
    obj: String,
    /// Cell of the (x, y) grid the mesh is sampled on (mm).
    #[serde(default = "default_cell")]
    cell_mm: f64,
}

fn default_stl() -> String {
    "model.stl".into()
}

fn default_cell() -> f64 {
    0.5
}

fn file_in(ctx: &ScanContext, key: &str, f: &str) -> Result<Option<PathBuf>, BoxError> {
    if f.is_empty() {
        return Ok(None);
    }
    let p = std::path::Path::new(f);
    if p.is_absolute() || f.contains("..") || p.components().count() != 1 {
        return Err(
            format!("{key} = {f:?}: must be a plain name inside the scan directory").into(),
        );
    }
    Ok(Some(ctx.out_dir.join(p)))
}

pub struct ModelStage {
    files: MeshFiles,
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

pub fn register_stages(r: &mut Registry<Item, ScanContext>) {
    r.register(
        "model.bezier",
        "Bezier-network plantar model from the grid; writes its closed mesh (stl, ply, obj, cell_mm)",
        |p, ctx: &ScanContext| {
            let p: ModelParams = params(p)?;
            if !(p.cell_mm >= 0.05 && p.cell_mm <= 10.0) {
                return Err(format!("cell_mm = {}: valid range is [0.05, 10]", p.cell_mm).into());
            }
            Ok(Node::stage(ModelStage {
                files: MeshFiles {
                    stl: file_in(ctx, "stl", &p.stl)?,
                    ply: file_in(ctx, "ply", &p.ply)?,
                    obj: file_in(ctx, "obj", &p.obj)?,
                    cell_mm: p.cell_mm,
                },
            }))
        },
    );
}
