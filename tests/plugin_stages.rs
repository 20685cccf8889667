//! Per-scan and sink plugin stages of both kinds in simulated scans: the extent of the point
//! set from a wasm module (examples/plugins/extent-wasm) and from a Python process
//! (examples/plugins/python/extent_stage.py) lands in scan.json and agrees with the grid;
//! a wasm sink granted the scan directory read-only reads points.ply; a Python sink posts the
//! summary to a local HTTP server this test runs. An optional stage that fails is skipped with
//! its reason kept in scan.json; a required one fails the scan naming the plugin.

use footscan::scan::{run_scan, LoadedConfig, ScanOptions};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::mpsc;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn python() -> String {
    if let Ok(p) = std::env::var("FOOTSCAN_PLUGIN_PYTHON") {
        return p;
    }
    let p = repo().join("target/venv-plugins/bin/python");
    assert!(
        p.exists(),
        "{} is missing: run scripts/setup.sh (it makes the numpy venv the process stages use)",
        p.display()
    );
    p.display().to_string()
}

/// Build a C example (or `src` text) into `dir` the way docs/plugins.md says.
fn build_c(src: &Path, dir: &Path) -> PathBuf {
    let out = dir.join(src.file_stem().unwrap()).with_extension("wasm");
    let o = Command::new("clang")
        .args(["--target=wasm32", "-O2", "-nostdlib", "-Wl,--no-entry"])
        // The examples' shared footscan_abi.h (also for copies built from a temporary dir).
        .arg("-I")
        .arg(repo().join("examples/plugins"))
        .arg("-o")
        .arg(&out)
        .arg(src)
        .output()
        .expect("clang runs (scripts/setup.sh installs clang and lld)");
    assert!(
        o.status.success(),
        "clang could not build {}: {}",
        src.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    out
}

/// Scans run one at a time: the simulated slider runs in real time.
static SCANS: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// config/sim.toml from 80 to 150 mm with `stages` after accumulate (no model or measure).
fn config(stages: &str) -> LoadedConfig {
    let path = repo().join("config/sim.toml");
    let text = std::fs::read_to_string(&path).unwrap();
    let cut = text
        .find("[[pipeline.stages]]\nstage = \"model.bezier\"")
        .expect("config/sim.toml has its model stage after accumulate");
    let text = text[..cut]
        .replace("start_mm = 0.0 ", "start_mm = 80.0 ")
        .replace("end_mm = 320.0 ", "end_mm = 150.0 ")
        + stages;
    LoadedConfig::parse(&path, text).unwrap()
}

fn py_stage(script: &str, place: &str, extra: &str) -> String {
    format!(
        "[[pipeline.stages]]\nstage = \"exec\"\nplace = \"{place}\"\ncommand = [{:?}, {:?}]\n{extra}\n",
        python(),
        repo().join("examples/plugins/python").join(script).display().to_string()
    )
}

fn wasm_stage(module: &Path, extra: &str) -> String {
    format!(
        "[[pipeline.stages]]\nstage = \"wasm\"\nmodule = {:?}\n{extra}\n",
        module.display().to_string()
    )
}

/// An HTTP server on a free local port that answers one POST with 200 and hands over its body.
fn http_server() -> (String, mpsc::Receiver<String>) {
    let l = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://127.0.0.1:{}/scans", l.local_addr().unwrap().port());
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let (s, _) = l.accept().unwrap();
        let mut r = BufReader::new(s.try_clone().unwrap());
        let (mut len, mut line) = (0usize, String::new());
        let mut first = String::new();
        r.read_line(&mut first).unwrap();
        loop {
            line.clear();
            r.read_line(&mut line).unwrap();
            if line.trim().is_empty() {
                break;
            }
            if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
                len = v.trim().parse().unwrap();
            }
        }
        let mut body = vec![0; len];
        r.read_exact(&mut body).unwrap();
        (&s).write_all(
            b"HTTP/1.1 200 OK\r\nContent-Length: 8\r\nConnection: close\r\n\r\nreceived",
        )
        .unwrap();
        let _ = tx.send(format!(
            "{}{}",
            first.trim(),
            String::from_utf8(body).unwrap()
        ));
    });
    (url, rx)
}

fn scan_json(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("scan.json")).expect("scan.json")).unwrap()
}

#[test]
fn per_scan_and_sink_stages_of_both_kinds_in_one_simulated_scan() {
    let _one = SCANS.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let extent = build_c(
        &repo().join("examples/plugins/extent-wasm/extent.c"),
        dir.path(),
    );
    let plysink = build_c(
        &repo().join("examples/plugins/plysink-wasm/plysink.c"),
        dir.path(),
    );
    let (url, posted) = http_server();
    let stages = wasm_stage(&extent, "")
        + &py_stage("extent_stage.py", "scan", "")
        + "[[pipeline.stages]]\nstage = \"sink.ply\"\n[[pipeline.stages]]\nstage = \"sink.grid\"\n\
           [[pipeline.stages]]\nstage = \"sink.summary\"\n"
        + &wasm_stage(&plysink, "grant = \"scan\"")
        + &py_stage(
            "post_summary.py",
            "sink",
            &format!("args = {{ url = {url:?} }}"),
        );
    let out = dir.path().join("scan");
    let s = run_scan(&config(&stages), &ScanOptions::new(&out), |_| {}).expect("the scan runs");
    let j = scan_json(&out);
    let plugins = j["plugins"]
        .as_array()
        .expect("scan.json lists the plugin stages");
    assert_eq!(plugins.len(), 4, "{plugins:#?}");
    for p in plugins {
        assert_eq!(p["status"], "ok", "{p}");
    }
    let (w, x) = (&plugins[0]["values"], &plugins[1]["values"]);
    assert_eq!(plugins[0]["stage"], "wasm");
    assert_eq!(plugins[1]["stage"], "exec");

    // The extent against the grid the scan saved, computed here.
    let grid = footscan::scan::ScanGrid::load(&out.join("grid.bin")).unwrap();
    let pts: Vec<footscan_geom::P3> = grid.valid().map(|(_, _, p, _)| *p).collect();
    assert_eq!(pts.len(), s.points);
    let fold = |k: usize, f: fn(f64, f64) -> f64, z: f64| pts.iter().map(|p| p[k]).fold(z, f);
    let (x0, x1) = (
        fold(0, f64::min, f64::INFINITY),
        fold(0, f64::max, f64::NEG_INFINITY),
    );
    let (y0, y1) = (
        fold(1, f64::min, f64::INFINITY),
        fold(1, f64::max, f64::NEG_INFINITY),
    );
    let truth = [
        ("points", s.points as f64),
        ("x_min_mm", x0),
        ("x_max_mm", x1),
        ("length_mm", x1 - x0),
        ("width_mm", y1 - y0),
        ("z_max_mm", fold(2, f64::max, f64::NEG_INFINITY)),
    ];
    for (k, v) in truth {
        let (a, b) = (w[k].as_f64().unwrap(), x[k].as_f64().unwrap());
        // The C example prints 6 decimals; numpy's repr is exact.
        assert!((a - v).abs() <= 1e-6, "{k}: wasm {a}, grid {v}");
        assert!((b - v).abs() <= 1e-9, "{k}: python {b}, grid {v}");
    }
    assert!(x1 - x0 > 50.0, "the scan covers the foot: {x0}..{x1}");

    // The wasm sink read points.ply through its read-only grant.
    let report = std::fs::read_to_string(out.join("plysink-report.txt")).unwrap();
    assert!(
        report.starts_with(&format!("points.ply {} vertices", s.points))
            && report.contains(": agree"),
        "{report}"
    );
    assert_eq!(plugins[2]["report"], "plysink-report.txt");

    // The Python sink posted the summary to the local endpoint.
    let got = posted
        .recv_timeout(std::time::Duration::from_secs(10))
        .expect("the sink posted");
    let (req, body) = got.split_at(got.find('{').unwrap());
    assert!(req.starts_with("POST /scans"), "{req}");
    let b: serde_json::Value = serde_json::from_str(body).unwrap();
    assert_eq!(b["points"], s.points);
    assert_eq!(b["scan_dir"], "scan");
    assert_eq!(b["plugins"].as_array().unwrap().len(), 3, "{b}");
    let report = std::fs::read_to_string(out.join("post_summary-report.txt")).unwrap();
    assert!(report.contains("HTTP 200 received"), "{report}");
}

#[test]
fn an_optional_stage_that_fails_is_skipped_and_a_required_one_fails_the_scan() {
    let _one = SCANS.lock().unwrap_or_else(|p| p.into_inner());
    let dir = tempfile::tempdir().unwrap();
    let src = std::fs::read_to_string(repo().join("examples/plugins/extent-wasm/extent.c"))
        .unwrap()
        .replace("    if (len % 24) return -1;", "    __builtin_trap();");
    let trap_src = dir.path().join("trapping.c");
    std::fs::write(&trap_src, src).unwrap();
    let trap = build_c(&trap_src, dir.path());
    // A port nobody listens on: the post is refused.
    let closed = {
        let l = TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let stages = wasm_stage(&trap, "required = false")
        + "[[pipeline.stages]]\nstage = \"sink.summary\"\n"
        + &py_stage(
            "post_summary.py",
            "sink",
            &format!("args = {{ url = \"http://127.0.0.1:{closed}/scans\" }}\nrequired = false"),
        );
    let out = dir.path().join("optional");
    let s = run_scan(&config(&stages), &ScanOptions::new(&out), |_| {})
        .expect("optional stages do not fail the scan");
    assert!(s.points > 10_000, "{} points", s.points);
    let j = scan_json(&out);
    assert_ne!(j["status"], "failed", "{j}");
    let p = j["plugins"].as_array().unwrap();
    assert_eq!(p.len(), 2, "{p:#?}");
    assert_eq!(p[0]["status"], "skipped");
    let why = p[0]["reason"].as_str().unwrap();
    assert!(
        why.contains("trapping.wasm") && why.contains("trapped"),
        "{why}"
    );
    assert_eq!(p[1]["status"], "skipped");
    let why = p[1]["reason"].as_str().unwrap();
    assert!(
        why.contains("post_summary.py") && why.contains("refused"),
        "{why}"
    );
    assert!(!out.join("post_summary-report.txt").exists());

    // The same module, required (the default): the scan fails naming it.
    let out = dir.path().join("required");
    let e = run_scan(
        &config(&(wasm_stage(&trap, "") + "[[pipeline.stages]]\nstage = \"sink.summary\"\n")),
        &ScanOptions::new(&out),
        |_| {},
    )
    .expect_err("a required stage that fails fails the scan");
    let e = footscan_util::chain(&e);
    assert!(
        e.contains("stage `wasm` failed") && e.contains("trapping.wasm") && e.contains("trapped"),
        "{e}"
    );
    let j = scan_json(&out);
    assert_eq!(j["status"], "failed");
    assert!(
        j["reason"].as_str().unwrap().contains("trapping.wasm"),
        "{j}"
    );
}

#[test]
fn a_module_asking_for_files_without_a_grant_is_refused_at_start() {
    let dir = tempfile::tempdir().unwrap();
    let plysink = build_c(
        &repo().join("examples/plugins/plysink-wasm/plysink.c"),
        dir.path(),
    );
    let stages =
        "[[pipeline.stages]]\nstage = \"sink.summary\"\n".to_string() + &wasm_stage(&plysink, "");
    let e = run_scan(
        &config(&stages),
        &ScanOptions::new(dir.path().join("scan")),
        |_| {},
    )
    .expect_err("refused");
    let e = footscan_util::chain(&e);
    assert!(
        e.contains("plysink.wasm")
            && e.contains("imports wasi_snapshot_preview1::path_open")
            && e.contains("grants this stage no directory"),
        "{e}"
    );
    // A per-frame detector may be neither optional nor granted.
    let cog = build_c(&repo().join("examples/plugins/cog-wasm/cog.c"), dir.path());
    for (extra, want) in [
        ("required = false", "cannot be skipped"),
        ("grant = \"scan\"", "gets no directory"),
    ] {
        let text = std::fs::read_to_string(repo().join("config/sim.toml")).unwrap().replace(
            "stage = \"detect.bezier-plus\"\nthreshold = 30             # DN (8-bit; x257 for Gray16)\nsmooth_rows = 1.5          # 0 = per-row estimates only",
            &format!("stage = \"wasm\"\nmodule = {:?}\nargs = {{ threshold = 30 }}\n{extra}", cog.display().to_string()),
        );
        let cfg = LoadedConfig::parse(&repo().join("config/sim.toml"), text).unwrap();
        let e = run_scan(&cfg, &ScanOptions::new(dir.path().join("scan2")), |_| {})
            .expect_err("refused");
        let e = footscan_util::chain(&e);
        assert!(e.contains(want), "{extra}: {e}");
    }
}
