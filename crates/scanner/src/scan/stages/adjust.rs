//! `last.adjust`: a last's bottom adjusted to the scanned foot at the end of the scan (the
//! bottom as IGES and STEP, the deformed last as STL, the deviation heat map and adjust.json
//! in the scan directory). The last file is read and checked when the pipeline is built, so a
//! missing or broken last stops the scan (and footscand) before anything moves.

use crate::lastfit::{adjust_last, foot_plantar, AdjustScanOptions, LastSource};
use crate::measure::Measurements;
use crate::pipeline::{BoxError, Emitter, Stage};
use crate::scan::item::Item;
use crate::scandata::ScanGrid;
use footscan_geom::mesh::Units;
use footscan_last::adjust::last::LastOptions;
use footscan_last::adjust::output::write_into;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AdjustParams {
    /// The last: a mesh file (STL, OBJ or PLY; a closed mesh) or the directory of a scan of a
    /// last bottom (its grid.bin; the bottom is adjusted, there is no whole last to deform).
    pub last: PathBuf,
    /// Units of the last file: "auto" (from its size), "mm" or "m".
    #[serde(default = "default_units")]
    pub units: String,
    /// Scale the last to this length (mm), for unitless files.
    pub length_mm: Option<f64>,
    /// Height over which the deformation of the whole last fades out (mm).
    #[serde(default = "default_fade")]
    pub fade_mm: f64,
}

fn default_units() -> String {
    "auto".into()
}
fn default_fade() -> f64 {
    30.0
}

/// Keeps the grid and the measurements; adjusts at the end of the stream.
pub struct AdjustStage {
    last: LastSource,
    out_dir: PathBuf,
    opts: AdjustScanOptions,
    grid: Option<Arc<ScanGrid>>,
    foot: Option<Arc<Measurements>>,
}

impl AdjustStage {
    pub fn new(p: AdjustParams, out_dir: &Path) -> Result<Self, BoxError> {
        let units: Units = p.units.parse().map_err(|e| format!("units: {e}"))?;
        if let Some(l) = p.length_mm {
            if !(l > 50.0 && l < 500.0) {
                return Err(format!("length_mm = {l}: a last is 50-500 mm long").into());
            }
        }
        let opts = LastOptions {
            units,
            length_mm: p.length_mm,
            ..LastOptions::default()
        };
        let adjust_opts =
            AdjustScanOptions::with_fade_mm(p.fade_mm).map_err(|e| format!("fade_mm: {e}"))?;
        let last = LastSource::load(&p.last, &opts, adjust_opts.adjust.cell_mm)
            .map_err(|e| e.to_string())?;
        Ok(AdjustStage {
            last,
            out_dir: out_dir.to_path_buf(),
            opts: adjust_opts,
            grid: None,
            foot: None,
        })
    }
}

impl Stage<Item> for AdjustStage {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        match &item {
            Item::Grid(g) => self.grid = Some(g.clone()),
            Item::Foot(m) => self.foot = Some(m.clone()),
            _ => {}
        }
        let _ = out.emit(item);
        Ok(())
    }

    fn finish(&mut self, _out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let (Some(grid), Some(m)) = (self.grid.take(), self.foot.take()) else {
            return Err(
                "last.adjust received no measured foot: put it after accumulate and measure.foot"
                    .into(),
            );
        };
        let source = self.out_dir.display().to_string();
        let foot = foot_plantar(&source, &grid, &m, self.opts.adjust.cell_mm)
            .map_err(|e| format!("last.adjust: {e}"))?;
        let done =
            adjust_last(&foot, &self.last, &self.opts).map_err(|e| format!("last.adjust: {e}"))?;
        write_into(
            &self.out_dir,
            &done.adjustment,
            &done.surface,
            done.whole_last(&self.last),
            &done.report,
        )
        .map_err(|e| format!("last.adjust: {e}"))?;
        let (b, a) = (done.adjustment.before, done.adjustment.after);
        tracing::info!(
            last = %self.last.path().display(),
            eps = done.adjustment.eps,
            zeta = done.adjustment.zeta,
            height_rms_before_mm = b.height_rms_mm,
            height_rms_after_mm = a.height_rms_mm,
            outline_rms_after_mm = a.outline_rms_mm,
            adjust_ms = done.adjust_ms,
            "last bottom adjusted"
        );
        Ok(())
    }
}
