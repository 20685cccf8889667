//! Debian's headless Chromium for the dashboard tests: the flags every run needs (no sandbox as
//! root, none of the background connections this machine's closed network refuses), one run
//! with its stdout, and where screenshots are kept.
// Each test binary includes this file and uses part of it.
#![allow(dead_code)]

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

pub const CHROMIUM: &str = "/usr/bin/chromium";

/// Flags of every headless run (the profile and window size come on top).
pub const HEADLESS: [&str; 7] = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
];

pub fn require() {
    assert!(
        Path::new(CHROMIUM).is_file(),
        "{CHROMIUM} is missing: the dashboard tests need Debian's chromium package; run \
         scripts/setup.sh (it installs chromium and fonts-dejavu-core)"
    );
}

/// Run Chromium on `url` with [`HEADLESS`], a fresh `profile`, a `size` window and `extra`
/// flags, for at most `limit`; its stdout (a DOM dump, say). Panics with Chromium's stderr
/// when it fails or overruns.
pub fn run(
    url: &str,
    profile: &Path,
    size: (u32, u32),
    extra: &[&str],
    limit: Duration,
) -> Vec<u8> {
    require();
    let mut child = Command::new(CHROMIUM)
        .args(HEADLESS)
        .arg(format!("--user-data-dir={}", profile.display()))
        .arg(format!("--window-size={},{}", size.0, size.1))
        .args(extra)
        .arg(url)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("starting {CHROMIUM}: {e}"));
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let out_t = std::thread::spawn(move || {
        let mut v = Vec::new();
        out.read_to_end(&mut v).map(|_| v)
    });
    let err_t = std::thread::spawn(move || {
        let mut s = String::new();
        err.read_to_string(&mut s).map(|_| s)
    });
    let t0 = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            let stderr = err_t.join().unwrap().unwrap_or_default();
            panic!("chromium did not finish within {limit:?} on {url}; stderr:\n{stderr}");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let stdout = out_t.join().unwrap().unwrap();
    let stderr = err_t.join().unwrap().unwrap_or_default();
    println!(
        "chromium {extra:?}: {status} in {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    assert!(
        status.success(),
        "chromium failed ({status}) on {url}; stderr:\n{stderr}"
    );
    stdout
}

/// Where people find a screenshot: `target/NAME`.
pub fn target_png(name: &str) -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR"))
        .parent()
        .expect("CARGO_TARGET_TMPDIR is inside the target directory")
        .join(name)
}
