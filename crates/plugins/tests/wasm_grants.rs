//! Per-scan and sink modules and their directory grants: a module that imports the file
//! system without a grant, or anything else at all, is refused at start naming the file and
//! the reason; a granted module reaches exactly its directory (the kernel refuses `..`,
//! absolute paths and symlinks out of it), read-only for sinks.

use footscan_plugins::wasi::Grant;
use footscan_plugins::wasm::{WasmKind, WasmLimits, WasmPlugin};
use footscan_plugins::PluginError;
use std::path::{Path, PathBuf};

/// A sink that opens the path it is given (its input) with `oflags` and `rights`, and reports
/// the WASI errno (4 bytes) and, when it opened, up to 64 bytes read from the file.
fn opener_wat(oflags: u32, rights: u64) -> String {
    format!(
        r#"(module
  (import "wasi_snapshot_preview1" "path_open"
    (func $open (param i32 i32 i32 i32 i32 i64 i64 i32 i32) (result i32)))
  (import "wasi_snapshot_preview1" "fd_read" (func $read (param i32 i32 i32 i32) (result i32)))
  (import "wasi_snapshot_preview1" "fd_write" (func $write (param i32 i32 i32 i32) (result i32)))
  (memory (export "memory") 4)
  (global $top (mut i32) (i32.const 4096))
  (func (export "footscan_abi") (result i32) i32.const 1)
  (func (export "footscan_alloc") (param $n i32) (result i32) (local $p i32)
    (local.set $p (global.get $top))
    (global.set $top (i32.add (local.get $p) (local.get $n)))
    (local.get $p))
  (func (export "footscan_sink") (param $in i32) (param $len i32) (param $out i32) (param $cap i32)
        (result i32) (local $e i32)
    (local.set $e (call $open (i32.const 3) (i32.const 0) (local.get $in) (local.get $len)
       (i32.const {oflags}) (i64.const {rights}) (i64.const 0) (i32.const 0) (i32.const 64)))
    (i32.store (local.get $out) (local.get $e))
    (if (i32.ne (local.get $e) (i32.const 0)) (then (return (i32.const 4))))
    ;; iovec at 128: 64 bytes at out+4; nread at 72
    (i32.store (i32.const 128) (i32.add (local.get $out) (i32.const 4)))
    (i32.store (i32.const 132) (i32.const 64))
    (if (i32.and (i32.const {rights}) (i32.const 64))
      (then
        ;; a write: the input itself, then report errno only
        (i32.store (i32.const 128) (local.get $in))
        (i32.store (i32.const 132) (local.get $len))
        (i32.store (local.get $out)
          (call $write (i32.load (i32.const 64)) (i32.const 128) (i32.const 1) (i32.const 72)))
        (return (i32.const 4))))
    (drop (call $read (i32.load (i32.const 64)) (i32.const 128) (i32.const 1) (i32.const 72)))
    (i32.add (i32.const 4) (i32.load (i32.const 72)))))"#
    )
}

struct Env {
    tmp: tempfile::TempDir,
}

impl Env {
    fn new() -> Self {
        let tmp = tempfile::tempdir().unwrap();
        let grant = tmp.path().join("scan");
        std::fs::create_dir(&grant).unwrap();
        std::fs::write(grant.join("a.txt"), "inside").unwrap();
        std::fs::write(tmp.path().join("secret.txt"), "outside").unwrap();
        std::os::unix::fs::symlink(tmp.path().join("secret.txt"), grant.join("link.txt")).unwrap();
        Env { tmp }
    }
    fn grant(&self, writable: bool) -> Grant {
        Grant {
            dir: self.tmp.path().join("scan"),
            writable,
        }
    }
    fn module(&self, name: &str, wat: &str) -> PathBuf {
        let p = self.tmp.path().join(name);
        std::fs::write(&p, wat::parse_str(wat).expect("valid WAT")).unwrap();
        p
    }
}

fn limits() -> WasmLimits {
    WasmLimits {
        fuel_per_call: 10_000_000,
        memory_bytes: 16 << 20,
    }
}

/// The errno and what was read, opening `path` through the module at `m` under `grant`.
fn open(m: &Path, grant: &Grant, path: &str) -> (i32, String) {
    let p = WasmPlugin::load(m).unwrap();
    assert_eq!(p.kind(), WasmKind::Sink);
    let mut r = p.runner(limits(), &[], Some(grant)).unwrap();
    let rep = r.run(path.as_bytes()).unwrap();
    (
        i32::from_le_bytes(rep[..4].try_into().unwrap()),
        String::from_utf8_lossy(&rep[4..]).into_owned(),
    )
}

#[test]
fn a_module_importing_files_without_a_grant_is_refused_by_name() {
    let env = Env::new();
    let m = env.module("reader.wasm", &opener_wat(0, 2));
    let p = WasmPlugin::load(&m).unwrap();
    assert!(p.wants_files());
    let e = p.runner(limits(), &[], None).expect_err("no grant");
    assert!(matches!(e, PluginError::Load { .. }), "{e}");
    let t = e.to_string();
    assert!(t.contains(&m.display().to_string()), "{t}");
    assert!(
        t.contains("imports wasi_snapshot_preview1::path_open")
            && t.contains("grants this stage no directory"),
        "{t}"
    );
    // Granted, it starts.
    assert!(p.runner(limits(), &[], Some(&env.grant(false))).is_ok());
}

#[test]
fn imports_beyond_the_files_of_a_grant_are_refused_at_load() {
    let env = Env::new();
    for (import, sig) in [
        (
            "\"wasi_snapshot_preview1\" \"sock_accept\"",
            "(param i32 i32 i32) (result i32)",
        ),
        (
            "\"wasi_snapshot_preview1\" \"clock_time_get\"",
            "(param i32 i64 i32) (result i32)",
        ),
        ("\"env\" \"host_call\"", "(param i32) (result i32)"),
    ] {
        let m = env.module(
            "net.wasm",
            &opener_wat(0, 2).replacen(
                "(memory",
                &format!("(import {import} (func {sig}))\n  (memory"),
                1,
            ),
        );
        let e = WasmPlugin::load(&m).expect_err("refused");
        let t = e.to_string();
        let name = import.replace("\" \"", "::").replace('"', "");
        assert!(t.contains(&m.display().to_string()), "{t}");
        assert!(
            t.contains(&format!("imports {name}, which footscan does not grant")),
            "{t}"
        );
    }
}

#[test]
fn a_granted_sink_reads_its_directory_and_nothing_outside_it() {
    let env = Env::new();
    let m = env.module("reader.wasm", &opener_wat(0, 2));
    let g = env.grant(false);
    assert_eq!(open(&m, &g, "a.txt"), (0, "inside".to_string()));
    // WASI errno 76 (notcapable) for a path out of the grant, 44 (noent) for a missing file.
    assert_eq!(open(&m, &g, "../secret.txt").0, 76);
    assert_eq!(open(&m, &g, "nope.txt").0, 44);
    let abs = env.tmp.path().join("secret.txt");
    assert_ne!(open(&m, &g, abs.to_str().unwrap()).0, 0);
    let (e, text) = open(&m, &g, "link.txt");
    assert_ne!(e, 0, "a symlink out of the grant was followed: {text}");
}

#[test]
fn a_sinks_grant_is_read_only_and_a_per_scan_grant_writable() {
    let env = Env::new();
    // oflags CREAT|TRUNC, rights fd_read|fd_write.
    let m = env.module("writer.wasm", &opener_wat(9, 66));
    assert_eq!(open(&m, &env.grant(false), "out.txt").0, 76);
    assert!(!env.tmp.path().join("scan/out.txt").exists());
    let m2 = env.module("writer2.wasm", &opener_wat(9, 66));
    // A sink's runner with a writable grant stands in for a per-scan stage's.
    assert_eq!(open(&m2, &env.grant(true), "out.txt").0, 0);
    assert_eq!(
        std::fs::read_to_string(env.tmp.path().join("scan/out.txt")).unwrap(),
        "out.txt"
    );
    assert_eq!(open(&m2, &env.grant(true), "../escape.txt").0, 76);
    assert!(!env.tmp.path().join("escape.txt").exists());
}

#[test]
fn a_per_scan_module_reports_values_and_faults_name_it() {
    let env = Env::new();
    // Reports "n <bytes/24>" for inputs under 10 points; traps on longer ones.
    let m = env.module(
        "count.wasm",
        r#"(module
  (memory (export "memory") 4)
  (global $top (mut i32) (i32.const 4096))
  (func (export "footscan_abi") (result i32) i32.const 1)
  (func (export "footscan_alloc") (param $n i32) (result i32) (local $p i32)
    (local.set $p (global.get $top))
    (global.set $top (i32.add (local.get $p) (local.get $n)))
    (local.get $p))
  (func (export "footscan_scan") (param $in i32) (param $len i32) (param $out i32) (param $cap i32)
        (result i32)
    (if (i32.ge_u (local.get $len) (i32.const 240)) (then unreachable))
    (i32.store8 (local.get $out) (i32.const 110))
    (i32.store8 (i32.add (local.get $out) (i32.const 1)) (i32.const 32))
    (i32.store8 (i32.add (local.get $out) (i32.const 2))
      (i32.add (i32.const 48) (i32.div_u (local.get $len) (i32.const 24))))
    (i32.const 3)))"#,
    );
    let p = WasmPlugin::load(&m).unwrap();
    assert_eq!(p.kind(), WasmKind::Scan);
    assert!(!p.wants_files());
    let mut r = p.runner(limits(), &[], None).unwrap();
    let rep = r.run(&[0u8; 24 * 7]).unwrap();
    assert_eq!(
        footscan_plugins::parse_values(&rep).unwrap(),
        vec![("n".to_string(), 7.0)]
    );
    let e = r.run(&[0u8; 24 * 12]).expect_err("traps");
    assert!(matches!(e, PluginError::Fault { .. }));
    let t = e.to_string();
    assert!(
        t.contains("count.wasm") && t.contains("footscan_scan") && t.contains("trapped"),
        "{t}"
    );
    // A detector's runner is refused: it is not a per-frame module.
    assert!(p.detector(limits(), &[]).is_err());
}

#[test]
fn reported_values_are_checked_line_by_line() {
    use footscan_plugins::parse_values;
    assert_eq!(
        parse_values(b"# extent\nlength_mm 251.5\n\nwidth_mm 98\n").unwrap(),
        vec![("length_mm".into(), 251.5), ("width_mm".into(), 98.0)]
    );
    assert!(parse_values(b"Length 1")
        .unwrap_err()
        .contains("keys are 1-64 of a-z"));
    assert!(parse_values(b"a nan")
        .unwrap_err()
        .contains("finite numbers"));
    assert!(parse_values(b"a 1 2").unwrap_err().contains("`key value`"));
    assert!(parse_values(b"a 1\na 2").unwrap_err().contains("twice"));
    assert!(parse_values(&[0xff, 0x20]).unwrap_err().contains("UTF-8"));
}
