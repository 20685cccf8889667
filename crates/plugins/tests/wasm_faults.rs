//! A wasm stage's faults stay inside it: every way a module can misbehave (trap, endless loop,
//! unbounded memory, NaN, wrong row count, garbage codes) is an error naming the module and
//! what it did, and a new instance of the same compiled module works afterwards. Modules that
//! cannot be used (not wasm, imports, wrong exports, wrong ABI, refused parameters) are
//! refused when loaded. The modules are written in WAT here and compiled by the `wat` crate.

use footscan_plugins::wasm::{Pixels, RowOut, WasmKind, WasmLimits, WasmPlugin};
use footscan_plugins::PluginError;
use std::path::PathBuf;

/// A module with a bump allocator and `body` as footscan_detect's body (locals $px $w $h
/// $bpp $out; must leave an i32).
fn detector_wat(body: &str) -> String {
    format!(
        r#"(module
  (memory (export "memory") 1)
  (global $top (mut i32) (i32.const 1024))
  (func (export "footscan_abi") (result i32) i32.const 1)
  (func (export "footscan_alloc") (param $n i32) (result i32) (local $p i32) (local $end i32)
    (local.set $p (global.get $top))
    (local.set $end (i32.add (local.get $p) (local.get $n)))
    (if (i32.gt_u (local.get $end) (i32.mul (memory.size) (i32.const 65536)))
      (then
        (if (i32.eq
              (memory.grow (i32.add (i32.shr_u (i32.sub (local.get $end)
                 (i32.mul (memory.size) (i32.const 65536))) (i32.const 16)) (i32.const 1)))
              (i32.const -1))
          (then (return (i32.const 0))))))
    (global.set $top (local.get $end))
    (local.get $p))
  (func (export "footscan_detect") (param $px i32) (param $w i32) (param $h i32) (param $bpp i32)
        (param $out i32) (result i32) (local $r i32)
    {body}))"#
    )
}

/// Every row rejected as below threshold (code 1) with intensity 0: a well-behaved module.
const REJECT_ALL: &str = r#"
    (block $done (loop $rows
      (br_if $done (i32.ge_u (local.get $r) (local.get $h)))
      (i32.store (i32.add (local.get $out) (i32.add (i32.mul (local.get $r) (i32.const 24)) (i32.const 20)))
                 (i32.const 1))
      (local.set $r (i32.add (local.get $r) (i32.const 1)))
      (br $rows)))
    (local.get $h)"#;

struct Dir(tempfile::TempDir);

impl Dir {
    fn new() -> Self {
        Dir(tempfile::tempdir().unwrap())
    }
    fn module(&self, name: &str, wat: &str) -> PathBuf {
        let p = self.0.path().join(name);
        std::fs::write(&p, wat::parse_str(wat).expect("valid WAT")).unwrap();
        p
    }
}

fn small_limits() -> WasmLimits {
    WasmLimits {
        fuel_per_call: 50_000_000,
        memory_bytes: 4 << 20,
    }
}

/// Run a 64x8 grey frame through the module at `path`.
fn run(path: &std::path::Path) -> Result<Vec<RowOut>, PluginError> {
    let plugin = WasmPlugin::load(path)?;
    assert_eq!(plugin.kind(), WasmKind::Detector);
    let mut d = plugin.detector(small_limits(), &[])?;
    let px = vec![7u8; 64 * 8];
    let mut out = vec![
        RowOut {
            col: 0.0,
            intensity: 0.0,
            width: 0.0,
            quality: 0.0,
            reject: 0
        };
        8
    ];
    d.detect(64, 8, Pixels::Gray8(&px), &mut out)?;
    Ok(out)
}

fn fault(path: &std::path::Path) -> String {
    let e = run(path).expect_err("the module misbehaves");
    assert!(matches!(e, PluginError::Fault { .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.contains(&path.display().to_string()),
        "names the module: {text}"
    );
    text
}

fn refused(path: &std::path::Path) -> String {
    let e = run(path).expect_err("the module is refused");
    assert!(matches!(e, PluginError::Load { .. }), "{e}");
    let text = e.to_string();
    assert!(
        text.contains(&path.display().to_string()),
        "names the module: {text}"
    );
    text
}

#[test]
fn a_well_behaved_module_runs_on_grey8_and_grey16_frames_repeatedly() {
    let dir = Dir::new();
    let p = dir.module("ok.wasm", &detector_wat(REJECT_ALL));
    let out = run(&p).unwrap();
    assert!(out.iter().all(|r| r.reject == 1 && r.col.is_nan()));
    let mut d = WasmPlugin::load(&p)
        .unwrap()
        .detector(small_limits(), &[])
        .unwrap();
    let mut rows = vec![out[0]; 16];
    for _ in 0..3 {
        d.detect(32, 16, Pixels::Gray16(&[9u16; 32 * 16]), &mut rows)
            .unwrap();
        d.detect(32, 16, Pixels::Gray8(&[9u8; 32 * 16]), &mut rows)
            .unwrap();
    }
    assert!(rows.iter().all(|r| r.reject == 1));
}

#[test]
fn a_trap_is_a_fault_naming_the_module_and_the_next_instance_works() {
    let dir = Dir::new();
    let p = dir.module("trap.wasm", &detector_wat("unreachable"));
    let text = fault(&p);
    assert!(text.contains("footscan_detect: trapped"), "{text}");
    assert!(text.contains("unreachable"), "{text}");
    // The module itself is fine to instantiate again (the next scan).
    let ok = dir.module("ok.wasm", &detector_wat(REJECT_ALL));
    assert!(run(&ok).is_ok());
    assert!(WasmPlugin::load(&p)
        .unwrap()
        .detector(small_limits(), &[])
        .is_ok());
}

#[test]
fn an_endless_loop_runs_out_of_fuel() {
    let dir = Dir::new();
    let p = dir.module(
        "loop.wasm",
        &detector_wat("(loop $l (br $l)) (i32.const 0)"),
    );
    let text = fault(&p);
    assert!(text.contains("ran out of fuel"), "{text}");
    assert!(text.contains("50000000"), "names the limit: {text}");
}

#[test]
fn unbounded_allocation_stops_at_the_memory_limit() {
    let dir = Dir::new();
    let p = dir.module(
        "grow.wasm",
        &detector_wat("(loop $l (drop (memory.grow (i32.const 16))) (br $l)) (i32.const 0)"),
    );
    let text = fault(&p);
    assert!(
        text.contains("memory past the limit of 4194304 bytes"),
        "{text}"
    );
}

#[test]
fn a_nan_column_on_an_accepted_row_is_a_fault() {
    let dir = Dir::new();
    let p = dir.module(
        "nan.wasm",
        &detector_wat(&format!(
            "(f64.store (i32.add (local.get $out) (i32.const 72)) (f64.const nan)) {REJECT_ALL_BUT_3}"
        )),
    );
    let text = fault(&p);
    assert!(text.contains("returned column NaN for row 3"), "{text}");
}

/// Every row rejected but row 3, which is left accepted (code 0).
const REJECT_ALL_BUT_3: &str = r#"
    (block $done (loop $rows
      (br_if $done (i32.ge_u (local.get $r) (local.get $h)))
      (i32.store (i32.add (local.get $out) (i32.add (i32.mul (local.get $r) (i32.const 24)) (i32.const 20)))
                 (i32.ne (local.get $r) (i32.const 3)))
      (local.set $r (i32.add (local.get $r) (i32.const 1)))
      (br $rows)))
    (local.get $h)"#;

#[test]
fn too_few_or_too_many_rows_are_faults() {
    let dir = Dir::new();
    let few = dir.module(
        "few.wasm",
        &detector_wat("(i32.sub (local.get $h) (i32.const 1))"),
    );
    assert!(fault(&few).contains("returned 7 rows for a frame of 8 rows"));
    let many = dir.module(
        "many.wasm",
        &detector_wat("(i32.add (local.get $h) (i32.const 1))"),
    );
    assert!(fault(&many).contains("returned 9 rows for a frame of 8 rows"));
    let err = dir.module("err.wasm", &detector_wat("(i32.const -5)"));
    assert!(fault(&err).contains("error code -5"));
}

#[test]
fn garbage_reject_codes_and_columns_out_of_the_frame_are_faults() {
    let dir = Dir::new();
    let p = dir.module(
        "code.wasm",
        &detector_wat(
            "(i32.store (i32.add (local.get $out) (i32.const 20)) (i32.const 99)) (local.get $h)",
        ),
    );
    assert!(fault(&p).contains("reject code 99 for row 0"));
    let p = dir.module(
        "far.wasm",
        &detector_wat(&format!(
            "(f64.store (i32.add (local.get $out) (i32.const 72)) (f64.const 64.5)) {REJECT_ALL_BUT_3}"
        )),
    );
    assert!(fault(&p).contains("returned column 64.5 for row 3"));
}

#[test]
fn files_that_are_not_usable_modules_are_refused_at_load() {
    let dir = Dir::new();
    let missing = dir.0.path().join("missing.wasm");
    assert!(refused(&missing).contains("cannot read it"));
    let text = dir.0.path().join("text.wasm");
    std::fs::write(&text, "hello").unwrap();
    assert!(refused(&text).contains("not a WebAssembly binary"));

    let imports = dir.module(
        "wasi.wasm",
        &detector_wat(REJECT_ALL).replacen(
            "(module",
            r#"(module (import "wasi_snapshot_preview1" "fd_write" (func (param i32 i32 i32 i32) (result i32)))"#,
            1,
        ),
    );
    let t = refused(&imports);
    assert!(
        t.contains("imports wasi_snapshot_preview1::fd_write, which footscan does not grant"),
        "{t}"
    );

    let wrong = dir.module(
        "wrongsig.wasm",
        &detector_wat("(f32.const 0)").replace(
            "(param $out i32) (result i32)",
            "(param $out i32) (result f32)",
        ),
    );
    let t = refused(&wrong);
    assert!(
        t.contains("exports footscan_detect as (i32, i32, i32, i32, i32) -> (f32)"),
        "{t}"
    );

    let none = dir.module(
        "nostage.wasm",
        r#"(module (memory (export "memory") 1)
             (func (export "footscan_abi") (result i32) i32.const 1)
             (func (export "footscan_alloc") (param i32) (result i32) i32.const 1024))"#,
    );
    assert!(refused(&none).contains("exports no stage function"));

    let abi2 = dir.module(
        "abi2.wasm",
        &detector_wat(REJECT_ALL).replace("(result i32) i32.const 1)", "(result i32) i32.const 2)"),
    );
    assert!(refused(&abi2).contains("footscan_abi() returned 2"));
}

#[test]
fn parameters_go_to_footscan_param_and_refusals_name_the_key() {
    let dir = Dir::new();
    // Accepts `k` (1 byte, 'k') only when 0 < value < 10.
    let wat = detector_wat(REJECT_ALL).replacen(
        "(func (export \"footscan_detect\")",
        r#"(func (export "footscan_param") (param $k i32) (param $n i32) (param $v f64) (result i32)
             (if (i32.or (i32.ne (local.get $n) (i32.const 1))
                         (i32.ne (i32.load8_u (local.get $k)) (i32.const 107)))
               (then (return (i32.const 1))))
             (if (i32.and (f64.gt (local.get $v) (f64.const 0)) (f64.lt (local.get $v) (f64.const 10)))
               (then (return (i32.const 0))))
             (i32.const 2))
           (func (export "footscan_detect")"#,
        1,
    );
    let p = dir.module("param.wasm", &wat);
    let plugin = WasmPlugin::load(&p).unwrap();
    assert!(plugin
        .detector(small_limits(), &[("k".into(), 3.0)])
        .is_ok());
    let e = plugin
        .detector(small_limits(), &[("k".into(), 30.0)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("args.k = 30 is out of its range"), "{e}");
    let e = plugin
        .detector(small_limits(), &[("q".into(), 1.0)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("does not know the parameter args.q"), "{e}");
    let e = WasmPlugin::load(&dir.module("ok.wasm", &detector_wat(REJECT_ALL)))
        .unwrap()
        .detector(small_limits(), &[("k".into(), 1.0)])
        .unwrap_err()
        .to_string();
    assert!(e.contains("exports no footscan_param"), "{e}");
}
