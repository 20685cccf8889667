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

/// WebGL without a GPU: ANGLE on SwiftShader, which Chromium only falls back to when told.
pub const WEBGL: [&str; 2] = ["--use-angle=swiftshader", "--enable-unsafe-swiftshader"];

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

/// Chromium driven over the DevTools protocol (`--remote-debugging-pipe`: JSON messages ended
/// by NUL on fds 3 and 4, no extra crate), one page attached: for tests that work the page
/// (type, click) rather than only load it.
pub struct Browser {
    child: std::process::Child,
    tx: std::fs::File,
    rx: std::io::BufReader<std::fs::File>,
    next_id: u64,
    session: String,
}

impl Drop for Browser {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn pipe() -> (std::os::fd::OwnedFd, std::os::fd::OwnedFd) {
    use std::os::fd::FromRawFd;
    let mut fds = [0; 2];
    // SAFETY: pipe2 fills two new descriptors, owned from here on.
    assert_eq!(unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) }, 0);
    unsafe {
        (
            std::os::fd::OwnedFd::from_raw_fd(fds[0]),
            std::os::fd::OwnedFd::from_raw_fd(fds[1]),
        )
    }
}

impl Browser {
    /// Headless Chromium with a fresh `profile`, one blank page of `width` x `height` CSS px.
    pub fn launch(profile: &Path, width: u32, height: u32) -> Browser {
        Browser::launch_with(profile, width, height, &[])
    }

    /// [`Browser::launch`] with `extra` flags, e.g. [`WEBGL`]. A Chromium that dies before
    /// its first answer (seen once in CI on a loaded machine: the pipe broken at the first
    /// command, its stderr not kept) is started again on a fresh profile, at most three
    /// times; then the panic carries each try's exit status and stderr.
    pub fn launch_with(profile: &Path, width: u32, height: u32, extra: &[&str]) -> Browser {
        require();
        let mut tries = Vec::new();
        for attempt in 0..3 {
            let dir = match attempt {
                0 => profile.to_path_buf(),
                n => profile.join(format!("retry{n}")),
            };
            match Browser::try_launch(&dir, width, height, extra) {
                Ok(b) => {
                    if attempt > 0 {
                        println!(
                            "chromium started on try {}: {}",
                            attempt + 1,
                            tries.join("; ")
                        );
                    }
                    return b;
                }
                Err(e) => tries.push(format!("try {}: {e}", attempt + 1)),
            }
        }
        panic!("chromium did not start:\n{}", tries.join("\n"));
    }

    fn try_launch(
        profile: &Path,
        width: u32,
        height: u32,
        extra: &[&str],
    ) -> Result<Browser, String> {
        use serde_json::json;
        use std::os::fd::IntoRawFd;
        use std::os::unix::process::CommandExt;
        std::fs::create_dir_all(profile).map_err(|e| format!("{}: {e}", profile.display()))?;
        let err_path = profile.join("chromium-stderr.log");
        let err_file =
            std::fs::File::create(&err_path).map_err(|e| format!("{}: {e}", err_path.display()))?;
        let (cmd_r, cmd_w) = pipe(); // we write commands, Chromium reads fd 3
        let (ev_r, ev_w) = pipe(); // Chromium writes fd 4, we read
        let (a, b) = (cmd_r.into_raw_fd(), ev_w.into_raw_fd());
        let mut cmd = Command::new(CHROMIUM);
        cmd.args(HEADLESS)
            .args(extra)
            .args(["--remote-debugging-pipe", "about:blank"])
            .arg(format!("--user-data-dir={}", profile.display()))
            .arg(format!("--window-size={width},{height}"))
            .stdout(Stdio::null())
            .stderr(err_file);
        // SAFETY: only async-signal-safe dup2 calls between fork and exec.
        unsafe {
            cmd.pre_exec(move || {
                if libc::dup2(a, 3) < 0 || libc::dup2(b, 4) < 0 {
                    return Err(std::io::Error::last_os_error());
                }
                Ok(())
            });
        }
        let child = cmd
            .spawn()
            .unwrap_or_else(|e| panic!("starting {CHROMIUM}: {e}"));
        // SAFETY: the raw descriptors came from into_raw_fd above; the child has its copies.
        unsafe {
            libc::close(a);
            libc::close(b);
        }
        let mut br = Browser {
            child,
            tx: std::fs::File::from(cmd_w),
            rx: std::io::BufReader::new(std::fs::File::from(ev_r)),
            next_id: 0,
            session: String::new(),
        };
        let first = br.try_call(None, "Target.createTarget", json!({"url": "about:blank"}));
        let t = match first {
            Ok(t) => t,
            Err(e) => {
                let _ = br.child.kill();
                let status = br.child.wait().map(|s| s.to_string()).unwrap_or_default();
                let stderr = std::fs::read_to_string(&err_path).unwrap_or_default();
                let tail: Vec<&str> = stderr.lines().rev().take(20).collect();
                return Err(format!(
                    "{e} ({status}); stderr's last lines:\n{}",
                    tail.into_iter().rev().collect::<Vec<_>>().join("\n")
                ));
            }
        };
        let target = t["targetId"].as_str().unwrap().to_string();
        let s = br.call(
            None,
            "Target.attachToTarget",
            json!({"targetId": target, "flatten": true}),
        );
        br.session = s["sessionId"].as_str().unwrap().to_string();
        br.page(
            "Emulation.setDeviceMetricsOverride",
            json!({"width": width, "height": height, "deviceScaleFactor": 1, "mobile": false}),
        );
        Ok(br)
    }

    /// One DevTools command (on the page's session when `session` is given); its result.
    pub fn call(
        &mut self,
        session: Option<&str>,
        method: &str,
        params: serde_json::Value,
    ) -> serde_json::Value {
        self.try_call(session, method, params)
            .unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Browser::call`], its failures returned.
    fn try_call(
        &mut self,
        session: Option<&str>,
        method: &str,
        params: serde_json::Value,
    ) -> Result<serde_json::Value, String> {
        use std::io::{BufRead, Write};
        self.next_id += 1;
        let id = self.next_id;
        let mut msg = serde_json::json!({"id": id, "method": method, "params": params});
        if let Some(s) = session {
            msg["sessionId"] = s.into();
        }
        let mut bytes = serde_json::to_vec(&msg).unwrap();
        bytes.push(0);
        self.tx
            .write_all(&bytes)
            .map_err(|e| format!("sending {method} to chromium: {e}"))?;
        loop {
            let mut buf = Vec::new();
            let n = self
                .rx
                .read_until(0, &mut buf)
                .map_err(|e| format!("reading chromium's answer to {method}: {e}"))?;
            if n == 0 {
                return Err(format!("chromium closed the DevTools pipe during {method}"));
            }
            buf.pop();
            let v: serde_json::Value = serde_json::from_slice(&buf)
                .map_err(|e| format!("chromium's answer to {method}: {e}"))?;
            if v["id"] == id {
                if !v["error"].is_null() {
                    return Err(format!("{method}: {}", v["error"]));
                }
                return Ok(v["result"].clone());
            }
        }
    }

    /// A command on the page.
    pub fn page(&mut self, method: &str, params: serde_json::Value) -> serde_json::Value {
        let s = self.session.clone();
        self.call(Some(&s), method, params)
    }

    /// Load `url` and wait (at most `limit`) until `ready` (a JS expression) is true.
    pub fn open(&mut self, url: &str, ready: &str, limit: Duration) {
        self.page("Page.enable", serde_json::json!({}));
        self.page("Page.navigate", serde_json::json!({ "url": url }));
        self.wait_for(
            &format!("document.readyState === 'complete' && !!({ready})"),
            limit,
        );
    }

    /// Evaluate `expr` in the page (promises awaited); its value. Panics on an exception.
    pub fn eval(&mut self, expr: &str) -> serde_json::Value {
        let r = self.page(
            "Runtime.evaluate",
            serde_json::json!({"expression": expr, "returnByValue": true, "awaitPromise": true}),
        );
        assert!(
            r["exceptionDetails"].is_null(),
            "{expr}: {}",
            r["exceptionDetails"]
        );
        r["result"]["value"].clone()
    }

    /// Poll `expr` until it is true (at most `limit`, else panic naming it).
    pub fn wait_for(&mut self, expr: &str, limit: Duration) {
        let t0 = Instant::now();
        while self.eval(&format!(
            "(() => {{ try {{ return !!({expr}); }} catch (_) {{ return false; }} }})()"
        )) != true
        {
            assert!(
                t0.elapsed() < limit,
                "the page did not reach {expr} in {limit:?}"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Click the element with this id.
    pub fn click(&mut self, id: &str) {
        let found = self.eval(&format!(
            "(() => {{ const e = document.getElementById({id:?}); if (e) e.click(); return !!e; }})()"
        ));
        assert_eq!(found, true, "no element #{id} to click");
    }

    /// A PNG of the page as shown into `path`, decoded; with `element`, of that element only
    /// (its box, scrolled or not).
    pub fn screenshot(&mut self, path: &Path, element: Option<&str>) -> image::RgbImage {
        use base64::Engine;
        let mut params = serde_json::json!({"format": "png"});
        if let Some(id) = element {
            let r = self.eval(&format!(
                "(() => {{ const r = document.getElementById({id:?}).getBoundingClientRect(); \
                 return [r.left + scrollX, r.top + scrollY, r.width, r.height]; }})()"
            ));
            let b: Vec<f64> = serde_json::from_value(r).unwrap();
            params["clip"] = serde_json::json!({"x": b[0], "y": b[1], "width": b[2],
                "height": b[3], "scale": 1});
            params["captureBeyondViewport"] = true.into();
        }
        let r = self.page("Page.captureScreenshot", params);
        let png = base64::engine::general_purpose::STANDARD
            .decode(r["data"].as_str().unwrap())
            .unwrap();
        std::fs::write(path, &png).unwrap();
        println!("screenshot {}", path.display());
        image::load_from_memory(&png).unwrap().to_rgb8()
    }
}
