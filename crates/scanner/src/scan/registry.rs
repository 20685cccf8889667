//! The one list of scan stages by name, with their parameters: what `[[pipeline.stages]]`
//! may name and what `footscan stages` prints.

use super::stages::{
    out_file, Accumulate, Acquire, AdjustParams, AdjustStage, Detect, GridSink, HeightMapSink,
    MeasureParams, MeasureStage, ModelParams, ModelStage, PlySink, SummarySink, Triangulate,
};
use super::{item::Item, Devices, ScanCounters, ScanPlan, TruthSource};
use crate::calib::Calibration;
use crate::detect::{build, DetectParams, DETECTORS};
use crate::pipeline::{BoxError, Node, Registry};
use crate::scandata::ScanDir;
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
    /// What heightmap.png is titled with: the side the operator chose, the subject.
    pub label: crate::io::HeightMapLabel,
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

/// `file` of a sink's table, or its default, inside the scan directory.
fn file_in(ctx: &ScanContext, file: Option<String>, default: &str) -> Result<PathBuf, BoxError> {
    out_file(
        &ctx.out_dir,
        "file",
        &file.unwrap_or_else(|| default.to_string()),
    )
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
    for d in &DETECTORS {
        r.register(d.stage, d.description, move |p, ctx: &ScanContext| {
            let p: DetectParams = params(p)?;
            let det = build(d.name, &p)?;
            Ok(Node::stage(
                Detect::new(d.stage, det)
                    .with_tap(ctx.tap.clone())
                    .with_counters(ctx.counters.clone()),
            ))
        });
    }
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
        "collects frames into the scan grid (frame x row), bridging small gaps of dropped frames ([quality] bridge_mm)",
        |p, ctx: &ScanContext| {
            params::<NoParams>(p)?;
            Ok(Node::stage(Accumulate::with_gate(
                ctx.counters.clone(),
                ctx.plan.step_mm,
                ctx.plan.quality.bridge_mm,
            )))
        },
    );
    r.register(
        "model.bezier",
        "Bezier-network plantar model from the grid; writes the foot model for CAD, one closed solid in the foot frame (stl, ply, obj, step, cell_mm, step_cell_mm)",
        |p, ctx: &ScanContext| {
            let p: ModelParams = params(p)?;
            Ok(Node::stage(ModelStage::new(p, &ctx.out_dir)?))
        },
    );
    r.register(
        "measure.foot",
        "foot measurements of docs/method.md section 8 from the grid (and model): measurements.json, plantar.png (json, png, cell_mm, use_model, required)",
        |p, ctx: &ScanContext| {
            let p: MeasureParams = params(p)?;
            Ok(Node::stage(
                MeasureStage::new(p, &ctx.out_dir)?.with_counters(ctx.counters.clone()),
            ))
        },
    );
    r.register(
        "last.adjust",
        "a last's bottom adjusted to the measured foot (after measure.foot): bottom.igs, bottom.step, last_adjusted.stl, deviation.png, adjust.json (last = file, units, length_mm, fade_mm)",
        |p, ctx: &ScanContext| {
            let p: AdjustParams = params(p)?;
            Ok(Node::stage(AdjustStage::new(p, &ctx.out_dir)?))
        },
    );
    r.register(
        "sink.ply",
        "writes the point cloud as binary PLY (file, default points.ply)",
        |p, ctx: &ScanContext| {
            let p: FileParams = params(p)?;
            Ok(Node::stage(PlySink {
                path: file_in(ctx, p.file, ScanDir::POINTS)?,
            }))
        },
    );
    r.register(
        "sink.heightmap",
        "writes the sole height map as PNG with a colour scale, titled with side, view and subject (file, cell_mm)",
        |p, ctx: &ScanContext| {
            let p: HeightMapParams = params(p)?;
            let cell_mm = p.cell_mm.unwrap_or(0.5);
            if !(cell_mm > 0.01 && cell_mm <= 10.0) {
                return Err(format!("cell_mm = {cell_mm}: valid range is (0.01, 10]").into());
            }
            Ok(Node::stage(HeightMapSink {
                path: file_in(ctx, p.file, ScanDir::HEIGHTMAP)?,
                cell_mm,
                label: ctx.label.clone(),
                points: None,
            }))
        },
    );
    r.register(
        "sink.grid",
        "saves the scan grid as grid.bin for later model and measure runs (file)",
        |p, ctx: &ScanContext| {
            let p: FileParams = params(p)?;
            Ok(Node::stage(GridSink {
                path: file_in(ctx, p.file, ScanDir::GRID)?,
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
