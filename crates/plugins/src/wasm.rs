//! WebAssembly stages: a module compiled once by wasmtime, instantiated per scan, called per
//! frame under a fuel and a memory limit.
//!
//! ABI 1 (docs/plugins.md has the whole contract): the module imports nothing and exports
//! `memory`, `footscan_abi() -> i32` (returns 1), `footscan_alloc(size: i32) -> i32` and,
//! for a per-frame detector, `footscan_detect(px, width, height, bytes_per_px, out) -> i32`
//! (rows written, negative for an error of its own) and optionally
//! `footscan_param(key, key_len, value: f64) -> i32` (0 accepted, 1 unknown key, 2 out of
//! range). Each output row is 24 bytes: f64 column, f32 intensity, f32 width, f32 quality,
//! u32 reject code ([`REJECT_CODES`]).
//!
//! A per-scan stage exports `footscan_scan(input, len, out, out_cap) -> i32` (the scan's
//! points in, a report of `key value` lines out) and a sink `footscan_sink(input, len, out,
//! out_cap) -> i32` (the scan summary as JSON in, a report out); both return the report's
//! length or a negative error code of their own.
//!
//! Why almost no imports: a module that can call nothing of the host cannot reach a file, a
//! socket or a clock, so the sandbox needs no policy. The one exception is the file part of
//! WASI ([`crate::wasi`]) over exactly the directory a per-scan or sink stage's config grants;
//! a module importing it without a grant is refused at start. Why fuel rather than epochs: fuel counts
//! instructions, so a limit means the same on a loaded CI machine as on a quiet one and needs
//! no ticker thread; a loop without end runs out of it on the frame it started.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, OnceLock};
use std::time::SystemTime;

use wasmtime::{
    Config, Engine, ExternType, Instance, Linker, Memory, Module, Store, StoreLimits,
    StoreLimitsBuilder, Trap, TypedFunc,
};

pub use crate::rows::{Pixels, RowOut, REJECT_CODES, ROW_BYTES};
use crate::wasi::{self, Fs, Grant, HasFs};
use crate::PluginError;

/// What a module's store holds: its limits and, when granted, its directory.
pub struct Host {
    limits: StoreLimits,
    fs: Option<Fs>,
    name: String,
}

impl HasFs for Host {
    fn fs(&mut self) -> Option<&mut Fs> {
        self.fs.as_mut()
    }
    fn plugin_name(&self) -> &str {
        &self.name
    }
}

/// Longest report a per-scan or sink module may return, bytes.
pub const REPORT_CAP: usize = 64 << 10;

/// The ABI version this host speaks (`footscan_abi()` must return it).
pub const ABI_VERSION: i32 = 1;
/// Per-call limits of a wasm stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WasmLimits {
    /// Fuel (about one unit per wasm instruction) for one call. The default, 2e9, is about
    /// 100 times what the example cog detector spends on a 1280x1024 frame.
    pub fuel_per_call: u64,
    /// Largest linear memory, bytes. The default, 64 MiB, holds a 16-bit 2048x2048 frame
    /// several times over.
    pub memory_bytes: usize,
}

impl Default for WasmLimits {
    fn default() -> Self {
        Self {
            fuel_per_call: 2_000_000_000,
            memory_bytes: 64 << 20,
        }
    }
}

/// What a module is for, from the functions it exports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WasmKind {
    /// Per frame: a frame's rows in, a line position per row out (`footscan_detect`).
    Detector,
    /// Per scan: the point set in, values (and files in a granted directory) out
    /// (`footscan_scan`).
    Scan,
    /// A sink: the scan summary in and the scan directory read-only, a report out
    /// (`footscan_sink`).
    Sink,
}

impl WasmKind {
    /// Where the stage sits in a scan pipeline (for `footscan stages`).
    pub fn place(self) -> &'static str {
        match self {
            Self::Detector => "per frame (detector: frame rows in, line per row out)",
            Self::Scan => "per scan (the point set in, values out)",
            Self::Sink => "sink (the scan summary and directory in, a report out)",
        }
    }
}

/// One engine per process: compiled modules belong to an engine, so sharing it is what lets
/// a module compiled for one scan be used again by the next.
fn engine() -> &'static Engine {
    static ENGINE: OnceLock<Engine> = OnceLock::new();
    ENGINE.get_or_init(|| {
        let mut c = Config::new();
        c.consume_fuel(true);
        Engine::new(&c).expect("wasmtime accepts a config that only turns fuel on")
    })
}

/// Compiled modules by file, kept while the file's length and modification time stay the
/// same: a daemon compiles a module once, not once per scan.
type Cache = HashMap<PathBuf, (SystemTime, u64, Module)>;

fn cache() -> &'static Mutex<Cache> {
    static CACHE: OnceLock<Mutex<Cache>> = OnceLock::new();
    CACHE.get_or_init(Mutex::default)
}

/// A loaded, checked and compiled module.
#[derive(Clone)]
pub struct WasmPlugin {
    path: PathBuf,
    module: Module,
    kind: WasmKind,
    /// The WASI functions it imports (the file system of a grant).
    wasi: Vec<String>,
}

impl std::fmt::Debug for WasmPlugin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WasmPlugin")
            .field("path", &self.path)
            .field("kind", &self.kind)
            .finish()
    }
}

/// The signature an export must have, as wasm value types.
struct Sig {
    name: &'static str,
    params: &'static [wasmtime::ValType],
    results: &'static [wasmtime::ValType],
}

const I32: wasmtime::ValType = wasmtime::ValType::I32;
const F64: wasmtime::ValType = wasmtime::ValType::F64;

const ABI: Sig = Sig {
    name: "footscan_abi",
    params: &[],
    results: &[I32],
};
const ALLOC: Sig = Sig {
    name: "footscan_alloc",
    params: &[I32],
    results: &[I32],
};
const PARAM: Sig = Sig {
    name: "footscan_param",
    params: &[I32, I32, F64],
    results: &[I32],
};
const DETECT: Sig = Sig {
    name: "footscan_detect",
    params: &[I32, I32, I32, I32, I32],
    results: &[I32],
};
const SCAN: Sig = Sig {
    name: "footscan_scan",
    params: &[I32, I32, I32, I32],
    results: &[I32],
};
const SINK: Sig = Sig {
    name: "footscan_sink",
    params: &[I32, I32, I32, I32],
    results: &[I32],
};

fn sig_text(params: &[wasmtime::ValType], results: &[wasmtime::ValType]) -> String {
    let list = |v: &[wasmtime::ValType]| {
        v.iter()
            .map(|t| t.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!("({}) -> ({})", list(params), list(results))
}

impl WasmPlugin {
    /// Load, check and compile `path` (or take it from the cache).
    pub fn load(path: &Path) -> Result<Self, PluginError> {
        let refuse = |reason: String| PluginError::Load {
            plugin: path.display().to_string(),
            reason,
        };
        let meta = std::fs::metadata(path).map_err(|e| {
            refuse(format!(
                "cannot read it ({e}); `module` must name a .wasm file"
            ))
        })?;
        let stamp = (
            meta.modified().unwrap_or(SystemTime::UNIX_EPOCH),
            meta.len(),
        );
        let cached = cache()
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .get(path)
            .filter(|(t, n, _)| (*t, *n) == stamp)
            .map(|(_, _, m)| m.clone());
        let module = match cached {
            Some(m) => m,
            None => {
                let bytes =
                    std::fs::read(path).map_err(|e| refuse(format!("cannot read it ({e})")))?;
                if !bytes.starts_with(b"\0asm") {
                    return Err(refuse(
                        "is not a WebAssembly binary (no \\0asm header); build a .wasm module (docs/plugins.md)".into(),
                    ));
                }
                let m = Module::new(engine(), &bytes)
                    .map_err(|e| refuse(format!("does not compile: {e}")))?;
                cache()
                    .lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .insert(path.to_path_buf(), (stamp.0, stamp.1, m.clone()));
                m
            }
        };
        let (kind, wasi) = check_module(&module).map_err(refuse)?;
        Ok(Self {
            path: path.to_path_buf(),
            module,
            kind,
            wasi,
        })
    }

    pub fn kind(&self) -> WasmKind {
        self.kind
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Whether the module imports the file system (and so needs a grant).
    pub fn wants_files(&self) -> bool {
        !self.wasi.is_empty()
    }

    /// A store, an instance and the ABI check, with `grant` preopened when given.
    fn instantiate(
        &self,
        limits: WasmLimits,
        grant: Option<&Grant>,
    ) -> Result<(Store<Host>, Instance), PluginError> {
        let name = self.path.display().to_string();
        let refuse = |reason: String| PluginError::Load {
            plugin: name.clone(),
            reason,
        };
        if grant.is_none() && self.wants_files() {
            return Err(refuse(format!(
                "imports {}, which footscan does not grant: the config grants this stage no \
                 directory (a per-frame stage never gets one; a per-scan or sink stage gets one \
                 with grant = \"DIR\", docs/plugins.md)",
                self.wasi
                    .iter()
                    .map(|f| format!("{}::{f}", wasi::MODULE))
                    .collect::<Vec<_>>()
                    .join(", ")
            )));
        }
        let fs = grant.map(Fs::open).transpose().map_err(&refuse)?;
        let limiter = StoreLimitsBuilder::new()
            .memory_size(limits.memory_bytes)
            .trap_on_grow_failure(true)
            .instances(1)
            .build();
        let mut store = Store::new(
            engine(),
            Host {
                limits: limiter,
                fs,
                name: name.clone(),
            },
        );
        store.limiter(|h| &mut h.limits);
        store
            .set_fuel(limits.fuel_per_call)
            .map_err(|e| refuse(format!("cannot set its fuel: {e}")))?;
        let mut linker = Linker::new(engine());
        if self.wants_files() {
            wasi::define(&mut linker)
                .map_err(|e| refuse(format!("cannot be given its file functions: {e}")))?;
        }
        let instance = linker
            .instantiate(&mut store, &self.module)
            .map_err(|e| refuse(format!("cannot be instantiated: {}", describe(&e, limits))))?;
        Ok((store, instance))
    }

    /// A per-scan or sink instance; `grant` is the directory its config grants, if any.
    pub fn runner(
        &self,
        limits: WasmLimits,
        params: &[(String, f64)],
        grant: Option<&Grant>,
    ) -> Result<WasmRunner, PluginError> {
        let export = match self.kind {
            WasmKind::Scan => SCAN.name,
            WasmKind::Sink => SINK.name,
            WasmKind::Detector => {
                return Err(PluginError::Load {
                    plugin: self.path.display().to_string(),
                    reason: "exports footscan_detect: it sits per frame, not per scan or as a sink"
                        .into(),
                })
            }
        };
        let (store, instance) = self.instantiate(limits, grant)?;
        let mut core = Core::new(self, store, &instance, limits, params)?;
        let name = core.name.clone();
        let run =
            typed(&instance, &mut core.store, export).map_err(|reason| PluginError::Load {
                plugin: name,
                reason,
            })?;
        Ok(WasmRunner { core, run, export })
    }

    /// A detector instance with its own memory, `params` given to `footscan_param` in order.
    pub fn detector(
        &self,
        limits: WasmLimits,
        params: &[(String, f64)],
    ) -> Result<WasmDetector, PluginError> {
        if self.kind != WasmKind::Detector {
            return Err(PluginError::Load {
                plugin: self.path.display().to_string(),
                reason: format!(
                    "is a {} stage, not a per-frame detector (it exports no footscan_detect)",
                    self.kind.place()
                ),
            });
        }
        let (store, instance) = self.instantiate(limits, None)?;
        let mut core = Core::new(self, store, &instance, limits, params)?;
        let name = core.name.clone();
        let detect = typed(&instance, &mut core.store, "footscan_detect").map_err(|reason| {
            PluginError::Load {
                plugin: name,
                reason,
            }
        })?;
        Ok(WasmDetector {
            core,
            detect,
            shape: None,
            in_ptr: 0,
            out_ptr: 0,
        })
    }
}

/// What every kind of instance has: its store, memory, allocator and limits.
struct Core {
    name: String,
    store: Store<Host>,
    memory: Memory,
    alloc: TypedFunc<i32, i32>,
    limits: WasmLimits,
}

impl Core {
    /// The common exports, the ABI version and the parameters.
    fn new(
        plugin: &WasmPlugin,
        mut store: Store<Host>,
        instance: &Instance,
        limits: WasmLimits,
        params: &[(String, f64)],
    ) -> Result<Self, PluginError> {
        let name = plugin.path.display().to_string();
        let refuse = |reason: String| PluginError::Load {
            plugin: name.clone(),
            reason,
        };
        let memory = instance
            .get_memory(&mut store, "memory")
            .ok_or_else(|| refuse("exports no memory named `memory`".into()))?;
        let abi: TypedFunc<(), i32> =
            typed(instance, &mut store, "footscan_abi").map_err(&refuse)?;
        let alloc = typed(instance, &mut store, "footscan_alloc").map_err(&refuse)?;
        let param: Option<TypedFunc<(i32, i32, f64), i32>> = instance
            .get_export(&mut store, "footscan_param")
            .is_some()
            .then(|| typed(instance, &mut store, "footscan_param"))
            .transpose()
            .map_err(&refuse)?;
        let mut d = Core {
            name: name.clone(),
            store,
            memory,
            alloc,
            limits,
        };
        let version = d.call("footscan_abi", |s| abi.call(s, ()))?;
        if version != ABI_VERSION {
            return Err(refuse(format!(
                "footscan_abi() returned {version}; this footscan speaks ABI {ABI_VERSION}"
            )));
        }
        for (key, value) in params {
            let Some(param) = &param else {
                return Err(refuse(format!(
                    "args.{key} given, but the module exports no footscan_param and takes no parameters"
                )));
            };
            let ptr = d.alloc(key.len(), "a parameter name")?;
            d.memory.data_mut(&mut d.store)[ptr..ptr + key.len()].copy_from_slice(key.as_bytes());
            let code = d.call("footscan_param", |s| {
                param.call(s, (ptr as i32, key.len() as i32, *value))
            })?;
            match code {
                0 => {}
                1 => return Err(refuse(format!("does not know the parameter args.{key}"))),
                2 => return Err(refuse(format!("args.{key} = {value} is out of its range"))),
                c => {
                    return Err(refuse(format!(
                        "footscan_param refused args.{key} = {value} with code {c}"
                    )))
                }
            }
        }
        Ok(d)
    }

    fn fault(&self, what: String) -> PluginError {
        PluginError::Fault {
            plugin: self.name.clone(),
            what,
        }
    }

    /// Run one export with a full tank of fuel.
    fn call<R>(
        &mut self,
        export: &str,
        f: impl FnOnce(&mut Store<Host>) -> wasmtime::Result<R>,
    ) -> Result<R, PluginError> {
        let fuel = self.limits.fuel_per_call;
        self.store
            .set_fuel(fuel)
            .map_err(|e| self.fault(format!("could not be given fuel: {e}")))?;
        f(&mut self.store)
            .map_err(|e| self.fault(format!("{export}: {}", describe(&e, self.limits))))
    }

    /// `size` bytes from the module's allocator, checked to lie inside its memory.
    fn alloc(&mut self, size: usize, what: &str) -> Result<usize, PluginError> {
        let n = i32::try_from(size)
            .map_err(|_| self.fault(format!("cannot hold {what} of {size} bytes in wasm32")))?;
        let alloc = self.alloc.clone();
        let ptr = self.call("footscan_alloc", |s| alloc.call(s, n))?;
        let len = self.memory.data_size(&self.store);
        let start = ptr as u32 as usize;
        if ptr <= 0 || start + size > len {
            return Err(self.fault(format!(
                "footscan_alloc({size}) for {what} returned {ptr}, not a block inside its {len}-byte memory"
            )));
        }
        Ok(start)
    }
}

fn typed<P, R>(
    instance: &Instance,
    store: &mut Store<Host>,
    name: &str,
) -> Result<TypedFunc<P, R>, String>
where
    P: wasmtime::WasmParams,
    R: wasmtime::WasmResults,
{
    instance
        .get_typed_func::<P, R>(&mut *store, name)
        .map_err(|e| format!("export `{name}`: {e}"))
}

/// The module's kind, or why it is refused: imports (nothing is granted), a missing export or
/// one of the wrong type.
fn check_module(m: &Module) -> Result<(WasmKind, Vec<String>), String> {
    let (files, other): (Vec<_>, Vec<_>) = m
        .imports()
        .partition(|i| i.module() == wasi::MODULE && wasi::PROVIDED.contains(&i.name()));
    if !other.is_empty() {
        return Err(format!(
            "imports {}, which footscan does not grant: a wasm stage gets no network, clock or \
             host function, and of WASI only the files of a granted directory ({}) \
             (build it freestanding, e.g. clang --target=wasm32 -nostdlib)",
            other
                .iter()
                .map(|i| format!("{}::{}", i.module(), i.name()))
                .collect::<Vec<_>>()
                .join(", "),
            wasi::PROVIDED.join(", ")
        ));
    }
    let files: Vec<String> = files.iter().map(|i| i.name().to_string()).collect();
    let exports: HashMap<&str, ExternType> = m.exports().map(|e| (e.name(), e.ty())).collect();
    if !matches!(exports.get("memory"), Some(ExternType::Memory(_))) {
        return Err("exports no memory named `memory`".into());
    }
    let check = |s: &Sig, required: bool| -> Result<bool, String> {
        match exports.get(s.name) {
            None if required => Err(format!(
                "does not export {} {} (ABI {ABI_VERSION}, docs/plugins.md)",
                s.name,
                sig_text(s.params, s.results)
            )),
            None => Ok(false),
            Some(ExternType::Func(f)) => {
                let (p, r): (Vec<_>, Vec<_>) = (f.params().collect(), f.results().collect());
                let same = |a: &[wasmtime::ValType], b: &[wasmtime::ValType]| {
                    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.matches(y))
                };
                if same(&p, s.params) && same(&r, s.results) {
                    Ok(true)
                } else {
                    Err(format!(
                        "exports {} as {}, but ABI {ABI_VERSION} wants {}",
                        s.name,
                        sig_text(&p, &r),
                        sig_text(s.params, s.results)
                    ))
                }
            }
            Some(_) => Err(format!("exports {} but not as a function", s.name)),
        }
    };
    check(&ABI, true)?;
    check(&ALLOC, true)?;
    check(&PARAM, false)?;
    let found: Vec<WasmKind> = [
        (check(&DETECT, false)?, WasmKind::Detector),
        (check(&SCAN, false)?, WasmKind::Scan),
        (check(&SINK, false)?, WasmKind::Sink),
    ]
    .into_iter()
    .filter_map(|(has, k)| has.then_some(k))
    .collect();
    match found.as_slice() {
        [k] => Ok((*k, files)),
        [] => Err(format!(
            "exports no stage function: a per-frame detector exports footscan_detect {}, a \
             per-scan stage footscan_scan {}, a sink footscan_sink {} (docs/plugins.md)",
            sig_text(DETECT.params, DETECT.results),
            sig_text(SCAN.params, SCAN.results),
            sig_text(SINK.params, SINK.results)
        )),
        _ => Err(
            "exports more than one of footscan_detect, footscan_scan and footscan_sink: a module \
             is one stage"
                .into(),
        ),
    }
}

/// Why a call failed, in words a config author can act on.
fn describe(e: &wasmtime::Error, limits: WasmLimits) -> String {
    match e.downcast_ref::<Trap>() {
        Some(Trap::OutOfFuel) => format!(
            "ran out of fuel: more than {} wasm instructions in one call (the stage's fuel_per_call); \
             it loops without end or needs a larger limit",
            limits.fuel_per_call
        ),
        Some(t) => format!("trapped: {t}"),
        None => {
            let text = format!("{e:#}");
            if text.contains("forcing trap when growing memory") {
                format!(
                    "tried to grow its memory past the limit of {} bytes (the stage's memory_mb): {text}",
                    limits.memory_bytes
                )
            } else {
                format!("failed: {text}")
            }
        }
    }
}

/// A per-frame detector instance: its own store and memory, buffers allocated in the module
/// once per frame shape.
pub struct WasmDetector {
    core: Core,
    detect: TypedFunc<(i32, i32, i32, i32, i32), i32>,
    shape: Option<(u32, u32, usize)>,
    in_ptr: usize,
    out_ptr: usize,
}

impl std::fmt::Debug for WasmDetector {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WasmDetector")
            .field("name", &self.core.name)
            .field("limits", &self.core.limits)
            .finish()
    }
}

impl WasmDetector {
    /// Detect the line in every row of a `width` x `height` frame into `out` (one per row).
    pub fn detect(
        &mut self,
        width: u32,
        height: u32,
        px: Pixels<'_>,
        out: &mut [RowOut],
    ) -> Result<(), PluginError> {
        let (w, h, bpp) = (width as usize, height as usize, px.bytes_per_px());
        assert_eq!(px.len(), w * h, "pixels of a {width}x{height} frame");
        assert_eq!(out.len(), h, "one result per row");
        let c = &mut self.core;
        if self.shape != Some((width, height, bpp)) {
            self.in_ptr = c.alloc(w * h * bpp, "the frame")?;
            self.out_ptr = c.alloc(h * ROW_BYTES, "the output rows")?;
            self.shape = Some((width, height, bpp));
        }
        let (in_ptr, out_ptr) = (self.in_ptr, self.out_ptr);
        let mem = c.memory.data_mut(&mut c.store);
        px.write_le(&mut mem[in_ptr..]);
        let detect = self.detect.clone();
        let args = (
            in_ptr as i32,
            width as i32,
            height as i32,
            bpp as i32,
            out_ptr as i32,
        );
        let rows = c.call("footscan_detect", |s| detect.call(s, args))?;
        if rows < 0 {
            return Err(c.fault(format!(
                "footscan_detect returned its error code {rows} on a {width}x{height} frame"
            )));
        }
        if rows as usize != h {
            return Err(c.fault(format!(
                "footscan_detect returned {rows} rows for a frame of {h} rows (it must write one per row)"
            )));
        }
        // Parse straight from the module's memory: it cannot move while borrowed here.
        let bytes = &c.memory.data(&c.store)[out_ptr..out_ptr + h * ROW_BYTES];
        crate::rows::parse(bytes, width, out).map_err(|what| PluginError::Fault {
            plugin: c.name.clone(),
            what: format!("footscan_detect {what}"),
        })
    }
}

/// A per-scan or sink instance: bytes in, a report out.
pub struct WasmRunner {
    core: Core,
    run: TypedFunc<(i32, i32, i32, i32), i32>,
    export: &'static str,
}

impl std::fmt::Debug for WasmRunner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WasmRunner")
            .field("name", &self.core.name)
            .field("export", &self.export)
            .finish()
    }
}

impl WasmRunner {
    /// Hand `input` to the stage's function and return its report.
    pub fn run(&mut self, input: &[u8]) -> Result<Vec<u8>, PluginError> {
        let c = &mut self.core;
        let in_ptr = c.alloc(input.len().max(1), "the input")?;
        let out_ptr = c.alloc(REPORT_CAP, "the report")?;
        c.memory.data_mut(&mut c.store)[in_ptr..in_ptr + input.len()].copy_from_slice(input);
        let run = self.run.clone();
        let args = (
            in_ptr as i32,
            input.len() as i32,
            out_ptr as i32,
            REPORT_CAP as i32,
        );
        let export = self.export;
        let n = c.call(export, |s| run.call(s, args))?;
        if n < 0 {
            return Err(c.fault(format!("{export} returned its error code {n}")));
        }
        if n as usize > REPORT_CAP {
            return Err(c.fault(format!(
                "{export} returned a report of {n} bytes, more than the {REPORT_CAP} it was given"
            )));
        }
        let mem = c.memory.data(&c.store);
        Ok(mem[out_ptr..out_ptr + n as usize].to_vec())
    }
}
