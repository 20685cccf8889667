//! Measurement of a scan: the `measure.foot` pipeline stage and [`measure_scan_dir`] for a
//! saved scan directory. Both take the footprint from the scan grid ([`rasterize_grid`]) and
//! the heights from the plantar model where it has them: the Bezier network only keeps
//! segments whose 4 x 4 grid points all have a return, so its own footprint stops up to a
//! segment (1.5 mm) short of the outline, which would shorten every length and width.

use super::{
    compare_with_truth, grid_truncation, measure_foot, rasterize_grid, MeasureError, Measurements,
    TruthComparison,
};
use crate::geom::HeightMap;
use crate::io::render_plantar;
use crate::pipeline::{BoxError, Emitter, Node, Registry, Stage};
use crate::scan::item::Item;
use crate::scan::{params, ScanContext, ScanGrid};
use crate::surface::BezierNetwork;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Default cell of the measured height map (mm): outline vertices are within half a cell of
/// the footprint's edge, and extreme points on flat stretches of the outline need it fine.
pub const DEFAULT_CELL_MM: f64 = 0.1;

/// The height map of a scan: footprint from `grid`, heights from `model` where it covers a
/// cell, else from the grid. Also says which heights were used.
pub fn scan_heightmap(
    grid: &ScanGrid,
    model: Option<&BezierNetwork>,
    cell_mm: f64,
) -> Result<(HeightMap, &'static str), MeasureError> {
    let mut map = rasterize_grid(grid, cell_mm)?;
    let Some(net) = model else {
        return Ok((map, "scan grid"));
    };
    let mm = net.eval_heightmap(cell_mm);
    for j in 0..map.ny {
        for i in 0..map.nx {
            if !map.get(i, j).is_finite() {
                continue;
            }
            if let Some((a, b)) = mm.cell_of(map.x(i), map.y(j)) {
                let z = mm.get(a, b);
                if z.is_finite() {
                    map.set(i, j, z);
                }
            }
        }
    }
    Ok((map, "bezier model (footprint from the scan grid)"))
}

/// Measure a scan grid (with its model, if any); warnings note a cut-off footprint.
pub fn measure_grid(
    grid: &ScanGrid,
    model: Option<&BezierNetwork>,
    cell_mm: f64,
) -> Result<(HeightMap, Measurements), MeasureError> {
    let (map, heights) = scan_heightmap(grid, model, cell_mm)?;
    let mut m = measure_foot(&map)?;
    m.heights_from = heights.to_string();
    m.warnings.extend(grid_truncation(grid));
    Ok((map, m))
}

/// Write `m` as JSON to `json` and its drawing over `map` as PNG to `png` (atomically).
pub fn write_measurements(
    m: &Measurements,
    map: &HeightMap,
    json: &Path,
    png: &Path,
) -> Result<(), MeasureError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| MeasureError::Io { path, source }
    };
    let text = serde_json::to_vec_pretty(m).expect("measurements serialise");
    crate::io::write_atomic(json, &text).map_err(io(json))?;
    render_plantar(map, m).save(png).map_err(io(png))?;
    Ok(())
}

/// What [`measure_scan_dir`] did.
#[derive(Debug)]
pub struct MeasureOutput {
    pub measurements: Measurements,
    pub json: PathBuf,
    pub png: PathBuf,
    /// Against the scan's truth.json, for simulated scans.
    pub comparison: Option<TruthComparison>,
}

/// Measure the saved scan in `dir` (grid.bin; the Bezier model is rebuilt from it unless
/// `use_model` is false), write `json` (default dir/measurements.json) and dir/plantar.png,
/// and compare with dir/truth.json when there is one.
pub fn measure_scan_dir(
    dir: &Path,
    json: Option<&Path>,
    cell_mm: f64,
    use_model: bool,
) -> Result<MeasureOutput, MeasureError> {
    let grid_path = dir.join("grid.bin");
    let grid = ScanGrid::load(&grid_path).map_err(|source| MeasureError::Io {
        path: grid_path.clone(),
        source,
    })?;
    let model = if use_model {
        let (net, _) = crate::surface::build_scan_model(&grid)
            .map_err(|e| MeasureError::Model(format!("{}: {e}", grid_path.display())))?;
        Some(net)
    } else {
        None
    };
    let (map, m) = measure_grid(&grid, model.as_ref(), cell_mm)?;
    let json = json.map_or_else(|| dir.join("measurements.json"), Path::to_path_buf);
    let png = dir.join("plantar.png");
    write_measurements(&m, &map, &json, &png)?;
    let truth_path = dir.join("truth.json");
    let comparison = match std::fs::read_to_string(&truth_path) {
        Ok(t) => Some(compare_with_truth(&m, &t).map_err(|e| MeasureError::Io {
            path: truth_path.clone(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidData, e),
        })?),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(source) => {
            return Err(MeasureError::Io {
                path: truth_path,
                source,
            })
        }
    };
    Ok(MeasureOutput {
        measurements: m,
        json,
        png,
        comparison,
    })
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeasureParams {
    #[serde(default = "default_json")]
    json: String,
    #[serde(default = "default_png")]
    png: String,
    #[serde(default = "default_cell")]
    cell_mm: f64,
    /// Heights from the model when one comes down the pipeline.
    #[serde(default = "yes")]
    use_model: bool,
    /// A foot that cannot be measured fails the scan; false: a warning in the log.
    #[serde(default = "yes")]
    required: bool,
}

fn default_json() -> String {
    "measurements.json".into()
}
fn default_png() -> String {
    "plantar.png".into()
}
fn default_cell() -> f64 {
    DEFAULT_CELL_MM
}
fn yes() -> bool {
    true
}

/// `measure.foot`: keeps the grid (and the model, which comes after it) and measures at the
/// end of the stream; passes every item on.
pub struct MeasureStage {
    json: PathBuf,
    png: PathBuf,
    cell_mm: f64,
    use_model: bool,
    required: bool,
    grid: Option<Arc<ScanGrid>>,
    model: Option<Arc<BezierNetwork>>,
}

impl Stage<Item> for MeasureStage {
    fn process(&mut self, item: Item, out: &mut Emitter<Item>) -> Result<(), BoxError> {
        match &item {
            Item::Grid(g) => self.grid = Some(g.clone()),
            Item::Model(n) if self.use_model => self.model = Some(n.clone()),
            _ => {}
        }
        let _ = out.emit(item);
        Ok(())
    }

    fn finish(&mut self, _out: &mut Emitter<Item>) -> Result<(), BoxError> {
        let Some(grid) = self.grid.take() else {
            return Err("measure.foot received no scan grid: put it after accumulate".into());
        };
        let result = measure_grid(&grid, self.model.as_deref(), self.cell_mm)
            .and_then(|(map, m)| write_measurements(&m, &map, &self.json, &self.png).map(|_| m));
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
                Ok(())
            }
            Err(e) if !self.required => {
                tracing::warn!("foot not measured: {e}");
                Ok(())
            }
            Err(e) => Err(format!("measure.foot: {e}").into()),
        }
    }
}

fn file_in(ctx: &ScanContext, key: &str, f: &str) -> Result<PathBuf, BoxError> {
    let p = Path::new(f);
    if f.is_empty() || p.is_absolute() || p.components().count() != 1 || f.contains("..") {
        return Err(
            format!("{key} = {f:?}: must be a plain name inside the scan directory").into(),
        );
    }
    Ok(ctx.out_dir.join(p))
}

pub fn register_stages(r: &mut Registry<Item, ScanContext>) {
    r.register(
        "measure.foot",
        "foot measurements of SPEC 8 from the grid (and model): measurements.json, plantar.png (json, png, cell_mm, use_model, required)",
        |p, ctx: &ScanContext| {
            let p: MeasureParams = params(p)?;
            if !(p.cell_mm >= 0.05 && p.cell_mm <= 1.0) {
                return Err(format!("cell_mm = {}: valid range is [0.05, 1]", p.cell_mm).into());
            }
            Ok(Node::stage(MeasureStage {
                json: file_in(ctx, "json", &p.json)?,
                png: file_in(ctx, "png", &p.png)?,
                cell_mm: p.cell_mm,
                use_model: p.use_model,
                required: p.required,
                grid: None,
                model: None,
            }))
        },
    );
}
