//! Measurement of a scan: [`measure_grid`] (what the `measure.foot` pipeline stage calls) and
//! [`measure_scan_dir`] for a saved scan directory. Both take the footprint from the scan grid ([`rasterize_grid`]) and
//! the heights from the plantar model where it has them: the Bezier network only keeps
//! segments whose 4 x 4 grid points all have a return, so its own footprint stops up to a
//! segment (1.5 mm) short of the outline, which would shorten every length and width.

use super::picture::render_plantar;
use super::{
    compare_with_truth, grid_truncation, measure_foot, measure_foot_with, rasterize_grid,
    MeasureError, Measurements, Planar, TruthComparison,
};
use crate::geom::HeightMap;
use crate::scandata::{ScanDir, ScanDirError, ScanGrid};
use crate::surface::BezierNetwork;
use std::path::{Path, PathBuf};

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
    scan_heightmap_with(grid, model, cell_mm, Ahead::default())
}

/// Parts of a scan's height map computed before it is measured (a scan computes them while
/// the frames come and while the model is built: `scan::early`, the `measure.foot` stage).
/// Each must be exactly what [`measure_grid`] would compute itself.
#[derive(Debug, Default)]
pub struct Ahead {
    /// [`rasterize_grid`] of the grid on the measured cell.
    pub footprint: Option<Result<HeightMap, MeasureError>>,
    /// [`Planar::of`] that footprint: what its outline alone decides.
    pub planar: Option<Result<Planar, MeasureError>>,
    /// The model's [`BezierNetwork::eval_heightmap`] on the measured cell.
    pub model_map: Option<HeightMap>,
}

/// A footprint and its [`Planar`] measurement (None when the footprint failed).
pub type Footprint = (
    Result<HeightMap, MeasureError>,
    Option<Result<Planar, MeasureError>>,
);

/// The footprint of `grid` and its [`Planar`] measurement: what a scan computes from the
/// grid while the model is built.
pub fn footprint_ahead(grid: &ScanGrid, cell_mm: f64) -> Footprint {
    let map = rasterize_grid(grid, cell_mm);
    let planar = map.as_ref().ok().map(Planar::of);
    (map, planar)
}

/// [`scan_heightmap`] with what was computed `ahead`.
fn scan_heightmap_with(
    grid: &ScanGrid,
    model: Option<&BezierNetwork>,
    cell_mm: f64,
    ahead: Ahead,
) -> Result<(HeightMap, &'static str), MeasureError> {
    let Ahead {
        footprint,
        model_map,
        ..
    } = ahead;
    let Some(net) = model else {
        let map = footprint.unwrap_or_else(|| rasterize_grid(grid, cell_mm))?;
        return Ok((map, "scan grid"));
    };
    // The footprint and the model's heights are independent: side by side, since the
    // results of a scan wait on them (issue 34 item 2).
    let (map, mm) = std::thread::scope(|s| {
        let fp = match footprint {
            Some(done) => Ok(done),
            None => Err(s.spawn(|| rasterize_grid(grid, cell_mm))),
        };
        let mm = model_map.unwrap_or_else(|| net.eval_heightmap(cell_mm));
        let map = fp.unwrap_or_else(|h| h.join().unwrap_or_else(|p| std::panic::resume_unwind(p)));
        (map, mm)
    });
    let mut map = map?;
    // Both maps sit on multiples of the cell (rasterize_grid's origin and the model's
    // lattice), so the model's cell of (i, j) is (i, j) moved by whole cells: no rounding per
    // cell (the results wait on this).
    let shift = |a: f64, b: f64| {
        let d = (a - b) / cell_mm;
        debug_assert!(
            (d - d.round()).abs() < 1e-6,
            "maps off the cell lattice: {d}"
        );
        d.round() as i64
    };
    let (di, dj) = (shift(map.x0, mm.x0), shift(map.y0, mm.y0));
    for j in 0..map.ny {
        let b = j as i64 + dj;
        if b < 0 || b >= mm.ny as i64 {
            continue;
        }
        let row = &mm.z[b as usize * mm.nx..(b as usize + 1) * mm.nx];
        let out = &mut map.z[j * map.nx..(j + 1) * map.nx];
        for (i, z) in out.iter_mut().enumerate() {
            let a = i as i64 + di;
            if z.is_finite() && a >= 0 && a < mm.nx as i64 && row[a as usize].is_finite() {
                *z = row[a as usize];
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
    measure_grid_with(grid, model, cell_mm, Ahead::default())
}

/// [`measure_grid`] with parts of the height map computed `ahead`.
pub fn measure_grid_with(
    grid: &ScanGrid,
    model: Option<&BezierNetwork>,
    cell_mm: f64,
    mut ahead: Ahead,
) -> Result<(HeightMap, Measurements), MeasureError> {
    let planar = ahead.planar.take();
    let (map, heights) = scan_heightmap_with(grid, model, cell_mm, ahead)?;
    // The model's heights went only into cells the footprint has: its valid cells, and so
    // its regions and outline, are the footprint's.
    let mut m = match planar {
        Some(p) => measure_foot_with(&map, p?)?,
        None => measure_foot(&map)?,
    };
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
    footscan_util::write_atomic(json, &text).map_err(io(json))?;
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
/// `use_model` is false), write `json` and `png` (default dir/measurements.json and
/// dir/plantar.png; nothing else is written), and compare with dir/truth.json when there is
/// one.
pub fn measure_scan_dir(
    dir: &Path,
    json: Option<&Path>,
    png: Option<&Path>,
    cell_mm: f64,
    use_model: bool,
) -> Result<MeasureOutput, MeasureError> {
    let scan = ScanDir::new(dir);
    let grid_path = scan.grid_path();
    let grid = scan.load_grid().map_err(|source| MeasureError::Io {
        path: grid_path.clone(),
        source,
    })?;
    let model = if use_model {
        let (net, _) = crate::surface::build_scan_model(&grid).map_err(|e| {
            MeasureError::Model(format!(
                "{}: {}",
                grid_path.display(),
                footscan_util::Chain(&e)
            ))
        })?;
        Some(net)
    } else {
        None
    };
    let (map, m) = measure_grid(&grid, model.as_ref(), cell_mm)?;
    let json = json.map_or_else(|| scan.measurements_path(), Path::to_path_buf);
    let png = png.map_or_else(|| scan.plantar_path(), Path::to_path_buf);
    write_measurements(&m, &map, &json, &png)?;
    let truth_path = scan.truth_path();
    // Through the scan directory, so a compacted scan's truth.json.gz is read too.
    let truth = scan.read_stored(ScanDir::TRUTH).and_then(|b| {
        String::from_utf8(b).map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))
    });
    let comparison = match truth {
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

impl ScanDir {
    /// measurements.json as the scanner's [`Measurements`], or None when the foot was not
    /// measured. Here rather than in `scandata` because measurements are this module's type
    /// and scandata sits below it.
    pub fn load_measurements(&self) -> Result<Option<Measurements>, ScanDirError> {
        self.load_json(Self::MEASUREMENTS, "the scanner's measurements")
    }
}
