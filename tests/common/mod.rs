//! Scaffolding shared by the root package's test binaries (`mod common;` in each).
//!
//! A whole simulated scan runs in real time (15-60 s), and several binaries only need the
//! default one (config/sim.toml: the simulator's 250 mm right foot) to read or to copy: they
//! share one, made by the CLI under the target's temporary directory and made again when the
//! CLI binary or config/sim.toml changes (docs/method.md 14g has the time it saves).
// Each binary uses a part of this module; the rest would be dead code there.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// What the shared scan depends on: the CLI binary (its size and modification time: cargo
/// rewrites it whenever any of the scanner's code changes) and config/sim.toml's text.
fn made_by() -> String {
    let exe = Path::new(env!("CARGO_BIN_EXE_footscan"));
    let meta = std::fs::metadata(exe).unwrap_or_else(|e| panic!("{}: {e}", exe.display()));
    let mtime = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    let config = std::fs::read_to_string(repo().join("config/sim.toml"))
        .expect("config/sim.toml is readable");
    format!("{} {} {mtime}\n{config}", exe.display(), meta.len())
}

/// The default simulated scan's directory, shared by every test binary of the package: read
/// it, never write into it (copy it with [`copy_default_scan`] to change it).
///
/// Made once per change of the CLI or config/sim.toml, under a file lock so that two binaries
/// run at once do not both scan. Only a scan whose status is "complete" is kept for the next
/// binary: one with dropped frames (a loaded machine) serves this binary only, as its own scan
/// did before, and the next binary scans again.
pub fn default_scan() -> &'static Path {
    static SCAN: OnceLock<PathBuf> = OnceLock::new();
    SCAN.get_or_init(|| {
        let tmp = Path::new(env!("CARGO_TARGET_TMPDIR"));
        let dir = tmp.join("shared-sim-scan");
        // Which CLI binary and config made the scan in `dir`: written beside it (not in it,
        // which holds the scan's files only) after a complete scan.
        let made_by_file = tmp.join("shared-sim-scan.made-by");
        let lock = std::fs::File::create(tmp.join("shared-sim-scan.lock")).unwrap();
        lock.lock().unwrap();
        let key = made_by();
        if std::fs::read_to_string(&made_by_file).ok().as_deref() == Some(key.as_str()) {
            return dir;
        }
        let _ = std::fs::remove_file(&made_by_file);
        let _ = std::fs::remove_dir_all(&dir);
        let out = Command::new(env!("CARGO_BIN_EXE_footscan"))
            .current_dir(repo())
            .args(["scan", "--config", "config/sim.toml", "--out"])
            .arg(&dir)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "the default simulated scan failed: {}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        if summary(&dir)["status"] == "complete" {
            std::fs::write(&made_by_file, key).unwrap();
        }
        dir
    })
}

/// scan.json of the scan in `dir` (the scan's summary: status, frames, points, truth, ...).
pub fn summary(dir: &Path) -> serde_json::Value {
    let p = dir.join("scan.json");
    let text = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_slice(&text).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// A copy of the default simulated scan in `to` (made if absent), for a test that writes
/// into its scan directory.
pub fn copy_default_scan(to: &Path) {
    copy_dir(default_scan(), to);
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for e in std::fs::read_dir(from).unwrap() {
        let e = e.unwrap();
        let target = to.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &target);
        } else {
            std::fs::copy(e.path(), &target).unwrap();
        }
    }
}
