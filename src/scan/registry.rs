//! The scan stages by name, with their parameters.

use super::stages::{
    Accumulate, Acquire, GridSink, HeightMapSink, PlySink, SummarySink, Triangulate,
};
use super::{item::Item, Devices, ScanCounters, ScanPlan, TruthSource};
use crate::calib::Calibration;
use crate::pipeline::{BoxError, Node, Registry};
use serde::de::DeserializeOwned;
use serde::Deserialize;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// What stage factories may use besides their own parameters.
pub struct ScanContext {
    pub out_dir: PathBuf,
    pub plan: ScanPlan,
    pub devices: Mutex<Option<Devices>>,
    pub calibration: Option<Calibration>,
    pub truth: Option<Arc<dyn TruthSource>>,
    pub counters: Arc<ScanCounters>,
    /// Live preview of the detect stage's frames and lines (the daemon's).
    pub tap: Option<Arc<dyn super::stages::FrameTap>>,
}

/// A stage's parameters as its typed, `deny_unknown_fields` struct; serde's message names the
/// offending key, which the config layer turns into a line and column.
pub fn params<P: DeserializeOwned>(t: &toml::Table) -> Result<P, BoxError> {
    P::deserialize(toml::Value::Table(t.clone())).map_err(|e| e.message().trim().to_string().into())
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NoParams {}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TriangulateParams {
    /// A calibration TOML; default: the one the scan was started with.
    calibration: Option<PathBuf>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileParams {
    file: Option<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct HeightMapParams {
    file: Option<String>,
    cell_mm: Option<f64>,
}

fn file_in(ctx: &ScanContext, file: Option<String>, default: &str) -> Result<PathBuf, BoxError> {
    let f = file.unwrap_or_else(|| default.to_string());
    let p = std::path::Path::new(&f);
    if p.is_absolute() || f.contains("..") {
        return Err(format!("file = {f:?}: must be a plain name inside the scan directory").into());
    }
    Ok(ctx.out_dir.join(p))
}

/// Every stage a scan pipeline may name.
pub fn registry() -> Registry<Item, ScanContext> {
    let mut r = Registry::new();
    r.register(
        "acquire",
        "frames from the camera with the slider X at each capture time (source)",
        |p, ctx: &ScanContext| {
            params::<NoParams>(p)?;
            let devices = ctx
                .devices
                .lock()
                .unwrap()
                .take()
                .ok_or("no camera and slider left: only one acquire stage may run")?;
            Ok(Node::source(Acquire::new(
                devices,
                ctx.plan.clone(),
                ctx.counters.clone(),
            )))
        },
    );
    crate::detect::register_stages(&mut r);
    r.register(
        "triangulate",
        "3D point per row from the calibration (calibration = file, optional)",
        |p, ctx: &ScanContext| {
            let p: TriangulateParams = params(p)?;
            let cal = match p.calibration {
                Some(path) => Calibration::load(&path)?,
                None => ctx.calibration.clone().ok_or(
                    "no calibration: pass --calibration FILE or set calibration = \"FILE\" on this stage",
                )?,
            };
            Ok(Node::stage(Triangulate::new(cal.triangulator())))
        },
    );
    r.register(
        "accumulate",
        "collects frames into the scan grid (frame x row)",
        |p, _ctx: &ScanContext| {
            params::<NoParams>(p)?;
            Ok(Node::stage(Accumulate::default()))
        },
    );
    crate::surface::register_stages(&mut r);
    crate::measure::register_stages(&mut r);
    r.register(
        "sink.ply",
        "writes the point cloud as binary PLY (file, default points.ply)",
        |p, ctx: &ScanContext| {
            let p: FileParams = params(p)?;
            Ok(Node::stage(PlySink {
                path: file_in(ctx, p.file, "points.ply")?,
            }))
        },
    );
    r.register(
        "sink.heightmap",
        "writes the sole height map as PNG with a colour scale (file, cell_mm)",
        |p, ctx: &ScanContext| {
            let p: HeightMapParams = params(p)?;
            let cell_mm = p.cell_mm.unwrap_or(0.5);
            if !(cell_mm > 0.01 && cell_mm <= 10.0) {
                return Err(format!("cell_mm = {cell_mm}: valid range is (0.01, 10]").into());
            }
            Ok(Node::stage(HeightMapSink {
                path: file_in(ctx, p.file, "heightmap.png")?,
                cell_mm,
            }))
        },
    );
    r.register(
        "sink.grid",
        "saves the scan grid as grid.bin for later model and measure runs (file)",
        |p, ctx: &ScanContext| {
            let p: FileParams = params(p)?;
            Ok(Node::stage(GridSink {
                path: file_in(ctx, p.file, "grid.bin")?,
            }))
        },
    );
    r.register(
        "sink.summary",
        "scan summary with the error against ground truth for simulated scans",
        |p, ctx: &ScanContext| {
            params::<NoParams>(p)?;
            Ok(Node::stage(SummarySink {
                truth: ctx.truth.clone(),
            }))
        },
    );
    r
}
