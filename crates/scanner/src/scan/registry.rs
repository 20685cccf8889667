//! The one list of scan stages by name, with their parameters: what `[[pipeline.stages]]`
//! may name and what `footscan stages` prints.

use super::stages::{
    out_file, Accumulate, Acquire, AdjustParams, AdjustStage, Detect, GridSink, HeightMapSink,
    MeasureParams, MeasureStage, ModelParams, ModelStage, PlySink, SummarySink, Triangulate,
};
#[cfg(feature = "plugins")]
use super::stages::{PluginDetector, PluginInfo, PluginRunner, PluginScanStage, PluginSinkStage};
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
    /// A directory the module may open files in (WASI, preopened as fd 3): "scan" for the
    /// scan's own directory, else a path. Read-only for sinks; none for per-frame stages.
    grant: Option<PathBuf>,
    /// false: a failing per-scan or sink stage is skipped (recorded in scan.json).
    required: Option<bool>,
    /// A sink's report file in the scan directory.
    report: Option<String>,
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
    /// "frame" (a detector, the default), "scan" or "sink".
    place: Option<String>,
    /// false: a failing per-scan or sink stage is skipped (recorded in scan.json).
    required: Option<bool>,
    /// A sink's report file in the scan directory.
    report: Option<String>,
}

/// An `exec` stage's `args` as the `key=value` words of its `hello`: numbers, booleans (1/0)
/// and strings without spaces (a sink's URL).
#[cfg(feature = "plugins")]
fn exec_args(args: &toml::Table) -> Result<Vec<(String, String)>, BoxError> {
    args.iter()
        .map(|(k, v)| match v {
            toml::Value::Integer(i) => Ok((k.clone(), i.to_string())),
            toml::Value::Float(f) => Ok((k.clone(), f.to_string())),
            toml::Value::Boolean(b) => Ok((k.clone(), u8::from(*b).to_string())),
            toml::Value::String(t) if !t.is_empty() && !t.contains(char::is_whitespace) => {
                Ok((k.clone(), t.clone()))
            }
            other => Err(format!(
                "args.{k}: a process stage takes numbers, booleans or strings without spaces, found {other}"
            )
            .into()),
        })
        .collect()
}

/// What a per-frame stage cannot have: it is the scan's detector, so it is never optional,
/// and it gets no directory.
#[cfg(feature = "plugins")]
fn frame_stage_only(
    required: Option<bool>,
    grant: bool,
    report: &Option<String>,
) -> Result<(), BoxError> {
    if required == Some(false) {
        return Err("required = false: a per-frame detector is where the scan's points come from, so it cannot be skipped; only per-scan and sink stages can be optional".into());
    }
    if grant {
        return Err("grant: a per-frame detector gets no directory; grants are for per-scan and sink stages".into());
    }
    if report.is_some() {
        return Err("report: only a sink writes a report".into());
    }
    Ok(())
}

/// A sink's report file (default `<stem>-report.txt` of the plugin) in the scan directory.
#[cfg(feature = "plugins")]
fn report_file(
    ctx: &ScanContext,
    report: Option<String>,
    plugin: &str,
) -> Result<PathBuf, BoxError> {
    let stem: String = std::path::Path::new(plugin)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
        .chars()
        .filter(|c| c.is_ascii_alphanumeric() || *c == '_' || *c == '-')
        .take(40)
        .collect();
    let default = format!(
        "{}-report.txt",
        if stem.is_empty() { "sink" } else { &stem }
    );
    out_file(&ctx.out_dir, "report", &report.unwrap_or(default))
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
            Ok(Node::stage(
                ModelStage::new(p, &ctx.out_dir)?.with_counters(ctx.counters.clone()),
            ))
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
        "a WebAssembly module's stage, sandboxed (module = file.wasm, args = { .. }, fuel_per_frame, memory_mb, grant, required, report); where it sits follows its exports: footscan_detect per frame in place of detect.*, footscan_scan per scan, footscan_sink a sink: docs/plugins.md",
        |p, ctx: &ScanContext| {
            let p: WasmParams = params(p)?;
            let limits = wasm_limits(&p)?;
            let args = plugin_args(&p.args)?;
            let plugin = footscan_plugins::wasm::WasmPlugin::load(&p.module)?;
            let info = || PluginInfo {
                stage: "wasm",
                plugin: plugin.path().display().to_string(),
                required: p.required.unwrap_or(true),
                counters: ctx.counters.clone(),
            };
            let grant = |writable: bool| {
                p.grant.as_ref().map(|g| footscan_plugins::wasi::Grant {
                    dir: if g == std::path::Path::new("scan") {
                        ctx.out_dir.clone()
                    } else {
                        g.clone()
                    },
                    writable,
                })
            };
            use footscan_plugins::wasm::WasmKind;
            match plugin.kind() {
                WasmKind::Detector => {
                    frame_stage_only(p.required, p.grant.is_some(), &p.report)?;
                    Ok(Node::stage(
                        Detect::plugin("wasm", PluginDetector::new(plugin.detector(limits, &args)?))
                            .with_tap(ctx.tap.clone())
                            .with_counters(ctx.counters.clone()),
                    ))
                }
                WasmKind::Scan => {
                    if p.report.is_some() {
                        return Err("report: only a sink writes a report".into());
                    }
                    let runner = plugin.runner(limits, &args, grant(true).as_ref())?;
                    Ok(Node::stage(PluginScanStage::new(info(), PluginRunner::Wasm(runner))))
                }
                WasmKind::Sink => {
                    let runner = plugin.runner(limits, &args, grant(false).as_ref())?;
                    let report = report_file(ctx, p.report.clone(), &p.module.display().to_string())?;
                    Ok(Node::stage(PluginSinkStage::new(
                        info(),
                        PluginRunner::Wasm(runner),
                        ctx.out_dir.clone(),
                        report,
                    )))
                }
            }
        },
    );
    r.register(
        "exec",
        "an external process's stage (command = [program, args..], args = { .. }, place = frame/scan/sink, frame_timeout_ms, max_restarts, required, report): per frame in place of detect.* (frames through shared memory), per scan (the points in, values out) or a sink (the summary in, a report out); restarted on a crash: docs/plugins.md",
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
            use footscan_plugins::exec::{ExecDetector, ExecRole};
            let role = match p.place.as_deref().unwrap_or("frame") {
                "frame" => ExecRole::Detector,
                "scan" => ExecRole::Scan,
                "sink" => ExecRole::Sink,
                other => {
                    return Err(format!(
                        "place = {other:?}: valid places are \"frame\" (a detector, the default), \"scan\" and \"sink\""
                    )
                    .into())
                }
            };
            let info = PluginInfo {
                stage: "exec",
                plugin: format!("`{}`", p.command.join(" ")),
                required: p.required.unwrap_or(true),
                counters: ctx.counters.clone(),
            };
            match role {
                ExecRole::Detector => {
                    frame_stage_only(p.required, false, &p.report)?;
                    let exec = ExecDetector::start(&p.command, &plugin_args(&p.args)?, limits)?;
                    Ok(Node::stage(
                        Detect::plugin("exec", PluginDetector::exec(exec))
                            .with_tap(ctx.tap.clone())
                            .with_counters(ctx.counters.clone()),
                    ))
                }
                ExecRole::Scan => {
                    if p.report.is_some() {
                        return Err("report: only a sink writes a report".into());
                    }
                    let exec = ExecDetector::start_as(role, &p.command, &exec_args(&p.args)?, limits)?;
                    Ok(Node::stage(PluginScanStage::new(info, PluginRunner::Exec(exec))))
                }
                ExecRole::Sink => {
                    let exec = ExecDetector::start_as(role, &p.command, &exec_args(&p.args)?, limits)?;
                    let name = p.command.last().cloned().unwrap_or_default();
                    let report = report_file(ctx, p.report.clone(), &name)?;
                    Ok(Node::stage(PluginSinkStage::new(
                        info,
                        PluginRunner::Exec(exec),
                        ctx.out_dir.clone(),
                        report,
                    )))
                }
            }
        },
    );
}
