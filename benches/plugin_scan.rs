//! Whole simulated scans at the simulated camera's rate (config/sim.toml: 50 frames/s, 80 to
//! 240 mm, 0.5 mm a frame) with a plugin detector in place of the built-in one: frames
//! acquired, frames dropped (the pipeline's bounded channels were full), the detect stage's
//! mean and largest latency. The target (issue 33): no frame dropped with either kind.
//!
//! `cargo bench --profile dev --bench plugin_scan` (needs clang, lld and target/venv-plugins:
//! scripts/setup.sh). A bench, not a test: whether a stage keeps up depends on the machine's
//! load, which a test cannot assert on.

use footscan::scan::{run_scan, LoadedConfig, ScanOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn config(detect_stage: &str) -> LoadedConfig {
    let path = repo().join("config/sim.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace(
            "stage = \"detect.bezier-plus\"\nthreshold = 30             # DN (8-bit; x257 for Gray16)\nsmooth_rows = 1.5          # 0 = per-row estimates only",
            detect_stage,
        )
        .replace("start_mm = 0.0 ", "start_mm = 80.0 ")
        .replace("end_mm = 320.0 ", "end_mm = 240.0 ");
    assert!(
        text.contains(detect_stage),
        "config/sim.toml changed its detect stage"
    );
    // Detection is what is measured: no model, measurements or files after accumulate (a
    // stage that finds no line would fail the model).
    let cut = text
        .find("[[pipeline.stages]]\nstage = \"model.bezier\"")
        .expect("config/sim.toml has its model stage after accumulate");
    let text = text[..cut].to_string() + "[[pipeline.stages]]\nstage = \"sink.summary\"\n";
    LoadedConfig::parse(&path, text).unwrap()
}

fn main() {
    // `cargo bench` passes --bench; `cargo test --all-targets` runs this binary without it,
    // and four whole scans in real time that assert nothing do not belong
    // in the test suite (the plugin stages' tests are tests/plugin_wasm.rs, plugin_exec.rs).
    if !std::env::args().any(|a| a == "--bench") {
        println!(
            "plugin_scan: a benchmark; run it with `cargo bench --profile dev --bench plugin_scan`"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let wasm = dir.path().join("cog.wasm");
    let ok = Command::new("clang")
        .args([
            "--target=wasm32",
            "-O2",
            "-msimd128",
            "-nostdlib",
            "-Wl,--no-entry",
        ])
        // The examples' shared footscan_abi.h (also for copies built from a temporary dir).
        .arg("-I")
        .arg(repo().join("examples/plugins"))
        .arg("-o")
        .arg(&wasm)
        .arg(repo().join("examples/plugins/cog-wasm/cog.c"))
        .status()
        .expect("clang runs (scripts/setup.sh)");
    assert!(ok.success());
    let py = repo().join("target/venv-plugins/bin/python");
    let null = dir.path().join("null.py");
    std::fs::write(
        &null,
        format!(
            "import sys\nsys.path.insert(0, {:?})\nimport numpy as np\n\
             from footscan_stage import ROW, run_detector\n\
             def detect(frame, args):\n    out = np.zeros(frame.shape[0], dtype=ROW)\n    out['reject'] = 1\n    return out\n\
             sys.exit(run_detector(detect))\n",
            repo().join("examples/plugins/python").display().to_string()
        ),
    )
    .unwrap();
    let q = |p: &Path| format!("{:?}", p.display().to_string());
    let stages = [
        (
            "built-in detect.cog",
            "stage = \"detect.cog\"\nthreshold = 30\nambiguity = 1.5\nskip_spikes = false"
                .to_string(),
        ),
        (
            "wasm cog.c",
            format!(
                "stage = \"wasm\"\nmodule = {}\nargs = {{ threshold = 30 }}",
                q(&wasm)
            ),
        ),
        (
            "exec Python cog_stage.py",
            format!(
                "stage = \"exec\"\ncommand = [{}, {}]\nargs = {{ threshold = 30 }}",
                q(&py),
                q(&repo().join("examples/plugins/python/cog_stage.py"))
            ),
        ),
        (
            "exec Python, returns at once",
            format!("stage = \"exec\"\ncommand = [{}, {}]", q(&py), q(&null)),
        ),
    ];
    println!(
        "{:32} {:>7} {:>8} {:>12} {:>12}",
        "detector", "frames", "dropped", "mean ms", "max ms"
    );
    for (i, (name, stage)) in stages.iter().enumerate() {
        let out = dir.path().join(format!("scan{i}"));
        let s = match run_scan(&config(stage), &ScanOptions::new(&out), |_| {}) {
            Ok(s) => s,
            Err(e) => {
                println!("{name:32} failed: {}", footscan_util::chain(&e));
                continue;
            }
        };
        let det = s
            .stages
            .iter()
            .find(|r| r.name.starts_with("detect") || r.name == "wasm" || r.name == "exec")
            .expect("a detect stage report");
        println!(
            "{name:32} {:>7} {:>8} {:>12.2} {:>12.2}",
            s.frames, s.dropped_frames, det.mean_latency_ms, det.max_latency_ms
        );
    }
}
