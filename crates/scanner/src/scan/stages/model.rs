//! The `model.bezier` pipeline stage: takes the scan grid, passes it on, builds the Bezier
//! network, writes the foot model for CAD (`footscan::cad`: the closed solid in the foot
//! frame, STL and STEP) into the scan directory and emits the network after the grid.

use super::out_file;
use crate::cad::{
    write_foot_model, CadError, ModelFiles, DEFAULT_GLB_CELL_MM, DEFAULT_STEP_CELL_MM,
};
use crate::pipeline::{BoxError, Emitter, Stage};
use crate::scan::item::Item;
use crate::surface::build_scan_model;
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
    "model.step".into()
}

fn default_glb() -> String {
    "model.glb".into()
}

fn default_glb_cell() -> f64 {
    DEFAULT_GLB_CELL_MM
}

fn default_step_cell() -> f64 {
    DEFAULT_STEP_CELL_MM
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
    files: ModelFiles,
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
        })
    }
}

impl Stage<Item> for ModelStage {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Item::Grid(grid) = &item else {
            let _ = out.emit(item);
            return Ok(());
        };
        let (net, build_ms) = build_scan_model(grid)?;
        tracing::info!(
            segments = net.segments().len(),
            skipped = net.skipped(),
            build_ms,
            "plantar model built"
        );
        match write_foot_model(
            grid,
            &net,
            build_ms,
            &self.files,
            ["cell_mm", "step_cell_mm", "glb_cell_mm"],
        ) {
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
            }
            // No foot to put a frame on (an empty glass, a plate): the network still goes on.
            Err(CadError::Measure(e)) => {
                tracing::warn!("foot model not written: {}", footscan_util::Chain(&e))
            }
            Err(e) => return Err(e.into()),
        }
        let _ = out.emit(item);
        let _ = out.emit(Item::Model(Arc::new(net)));
        Ok(())
    }
}
