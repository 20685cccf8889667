//! The one list of scan stages by name, with their parameters: what `[[pipeline.stages]]`
//! may name and what `footscan stages` prints.

#[cfg(feature = "plugins")]
use super::stages::PluginDetector;
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

/// A `wasm` stage: a WebAssembly module (docs/plugins.md).
#[cfg(feature = "plugins")]
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WasmParams {
    /// The .wasm file (relative to the working directory).
    module: PathBuf,
    /// Numbers (or booleans, as 0/1) handed to the module's `footscan_param`.
    #[serde(default)]
    args: toml::Table,
    /// Fuel (about one unit per wasm instruction) for one frame.
    fuel_per_frame: Option<u64>,
    /// Largest memory the module may grow to, MiB.
    memory_mb: Option<u64>,
}

/// An `exec` stage: an external process (docs/plugins.md).
#[cfg(feature = "plugins")]
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ExecParams {
    /// The program and its arguments.
    command: Vec<String>,
    /// Numbers (or booleans, as 0/1) sent in `hello`.
    #[serde(default)]
    args: toml::Table,
    /// Longest wait for one frame's answer, ms.
    frame_timeout_ms: Option<u64>,
    /// Restarts per scan after a crash or a hang.
    max_restarts: Option<u32>,
}

/// A plugin's `args`: what `footscan_param` or `hello` takes.
#[cfg(feature = "plugins")]
fn plugin_args(args: &toml::Table) -> Result<Vec<(String, f64)>, BoxError> {
    args.iter()
        .map(|(k, v)| match v {
            toml::Value::Integer(i) => Ok((k.clone(), *i as f64)),
            toml::Value::Float(f) => Ok((k.clone(), *f)),
            toml::Value::Boolean(b) => Ok((k.clone(), f64::from(u8::from(*b)))),
            other => Err(format!(
                "args.{k}: a plugin stage takes numbers or booleans, found a {}",
                other.type_str()
            )
            .into()),
        })
        .collect()
}

#[cfg(feature = "plugins")]
fn wasm_limits(p: &WasmParams) -> Result<footscan_plugins::wasm::WasmLimits, BoxError> {
    let d = footscan_plugins::wasm::WasmLimits::default();
    let fuel = p.fuel_per_frame.unwrap_or(d.fuel_per_call);
    if fuel == 0 {
        return Err("fuel_per_frame = 0: it must be at least 1 (default 2000000000)".into());
    }
    let mb = p.memory_mb.unwrap_or((d.memory_bytes >> 20) as u64);
    if !(1..=4096).contains(&mb) {
        return Err(format!("memory_mb = {mb}: valid range is 1..=4096 (a wasm32 memory)").into());
    }
    Ok(footscan_plugins::wasm::WasmLimits {
        fuel_per_call: fuel,
        memory_bytes: (mb as usize) << 20,
    })
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
    #[cfg(feature = "plugins")]
    plugin_stages(&mut r);
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

/// The `wasm` and `exec` stages (docs/plugins.md).
#[cfg(feature = "plugins")]
fn plugin_stages(r: &mut Registry<Item, ScanContext>) {
    r.register(
        "wasm",
        "a WebAssembly module's stage, sandboxed (module = file.wasm, args = { .. }, fuel_per_frame, memory_mb); one exporting footscan_detect sits per frame in place of detect.*: docs/plugins.md",
        |p, ctx: &ScanContext| {
            let p: WasmParams = params(p)?;
            let limits = wasm_limits(&p)?;
            let args = plugin_args(&p.args)?;
            let plugin = footscan_plugins::wasm::WasmPlugin::load(&p.module)?;
            match plugin.kind() {
                footscan_plugins::wasm::WasmKind::Detector => Ok(Node::stage(
                    Detect::plugin("wasm", PluginDetector::new(plugin.detector(limits, &args)?))
                        .with_tap(ctx.tap.clone())
                        .with_counters(ctx.counters.clone()),
                )),
            }
        },
    );
    r.register(
        "exec",
        "an external process's stage (command = [program, args..], args = { .. }, frame_timeout_ms, max_restarts): per frame in place of detect.*, frames through shared memory, restarted on a crash: docs/plugins.md",
        |p, ctx: &ScanContext| {
            let p: ExecParams = params(p)?;
            let d = footscan_plugins::exec::ExecLimits::default();
            let timeout = p.frame_timeout_ms.unwrap_or(d.frame_timeout.as_millis() as u64);
            if !(1..=600_000).contains(&timeout) {
                return Err(format!("frame_timeout_ms = {timeout}: valid range is 1..=600000").into());
            }
            let limits = footscan_plugins::exec::ExecLimits {
                frame_timeout: std::time::Duration::from_millis(timeout),
                max_restarts: p.max_restarts.unwrap_or(d.max_restarts),
                ..d
            };
            let exec = footscan_plugins::exec::ExecDetector::start(
                &p.command,
                &plugin_args(&p.args)?,
                limits,
            )?;
            Ok(Node::stage(
                Detect::plugin("exec", PluginDetector::exec(exec))
                    .with_tap(ctx.tap.clone())
                    .with_counters(ctx.counters.clone()),
            ))
        },
    );
}
