//! Shared by the footscand tests: start the real binary on 127.0.0.1:0 with a short simulated
//! scan, talk to it over HTTP, follow its event stream.
#![allow(dead_code)]

pub mod chromium;

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

pub use serde_json::Value;

/// The default simulated scanner with a short travel (60..200 mm at 1 mm a frame: ~140
/// frames over the heel and arch, a few seconds), plus `faults` as [sim.faults] keys. A
/// partial scan by design: `quality.whole_foot = false`, so the quality gate notes the foot
/// cut by the range instead of asking for a rescan (docs/method.md section 3.3).
pub fn short_scanner_config(faults: &str) -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/sim.toml");
    let text = std::fs::read_to_string(path).unwrap();
    let mut out = String::new();
    for line in text.lines() {
        let key = line.split('=').next().unwrap_or("").trim();
        let line = match key {
            "start_mm" if line.contains("first frame") => "start_mm = 60.0".to_string(),
            "end_mm" if line.contains("last") => "end_mm = 200.0".to_string(),
            "step_mm" if line.contains("advance") => "step_mm = 1.0".to_string(),
            _ => line.to_string(),
        };
        out.push_str(&line);
        out.push('\n');
    }
    assert!(out.contains("start_mm = 60.0") && out.contains("end_mm = 200.0"));
    out = out.replace(
        "[pipeline]\n",
        "[quality]\nwhole_foot = false\n\n[pipeline]\n",
    );
    assert!(out.contains("whole_foot = false"));
    if !faults.is_empty() {
        out = out.replace(
            "[sim.optics]",
            &format!("[sim.faults]\n{faults}\n\n[sim.optics]"),
        );
    }
    out
}

pub struct Opts<'a> {
    pub faults: &'a str,
    pub token: Option<&'a str>,
    pub bind: &'a str,
    /// Archive directory; default: `archive` in the test's directory.
    pub archive: Option<PathBuf>,
    /// More [daemon] lines, e.g. `tls = "self-signed"`.
    pub daemon_extra: &'a str,
    /// More scanner config sections, appended (e.g. [`light_calibration`]'s).
    pub scanner_extra: &'a str,
}

/// The daemon's options with a lighter calibration plan than the built-in one (4 frames per
/// plate instead of 16, the staircase every 2 mm instead of 0.25, the daily check's every 2
/// instead of 1), written into `dir` as plan.toml and named by the scanner config: the
/// guided procedure's steps and checks are the same, its real-time passes 3-8 times shorter.
pub fn light_calibration(dir: &Path) -> Opts<'static> {
    std::fs::write(
        dir.join("plan.toml"),
        "frames_per_height = 4\nstair_step_mm = 2.0\n",
    )
    .unwrap();
    Opts {
        scanner_extra: "\n[calibration]\nplan = \"plan.toml\"\nverify_step_mm = 2.0\n",
        ..Opts::default()
    }
}

impl Default for Opts<'_> {
    fn default() -> Self {
        Opts {
            faults: "",
            token: None,
            bind: "127.0.0.1:0",
            archive: None,
            daemon_extra: "",
            scanner_extra: "",
        }
    }
}

pub struct Footscand {
    pub child: Child,
    pub base: String,
    pub archive: PathBuf,
    pub client: reqwest::blocking::Client,
    pub token: Option<String>,
    stderr: std::sync::Arc<std::sync::Mutex<String>>,
}

/// Write the configs into `dir` and the command that starts the daemon on them.
pub fn command(dir: &Path, o: &Opts) -> (Command, PathBuf) {
    std::fs::write(
        dir.join("scanner.toml"),
        short_scanner_config(o.faults) + o.scanner_extra,
    )
    .unwrap();
    let archive = o.archive.clone().unwrap_or_else(|| dir.join("archive"));
    let mut cfg = format!(
        "[daemon]\narchive = {:?}\nscanner_config = \"scanner.toml\"\n",
        archive.to_str().unwrap()
    );
    if let Some(t) = o.token {
        cfg.push_str(&format!("token = {t:?}\n"));
    }
    cfg.push_str(o.daemon_extra);
    let path = dir.join("footscand.toml");
    std::fs::write(&path, cfg).unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_footscand"));
    cmd.arg("--config")
        .arg(&path)
        .arg("--bind")
        .arg(o.bind)
        .env_remove("FOOTSCAND_TOKEN")
        .env("RUST_LOG", "info")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    (cmd, archive)
}

impl Footscand {
    pub fn start(dir: &Path, o: Opts) -> Footscand {
        let (cmd, archive) = command(dir, &o);
        Footscand::spawn(cmd, archive, o.token)
    }

    /// Run `cmd` and wait for the address line.
    pub fn spawn(mut cmd: Command, archive: PathBuf, token: Option<&str>) -> Footscand {
        let mut child = cmd.spawn().expect("footscand starts");
        let stderr = std::sync::Arc::new(std::sync::Mutex::new(String::new()));
        let err_pipe = child.stderr.take().unwrap();
        let sink = stderr.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(err_pipe).lines().map_while(Result::ok) {
                eprintln!("[footscand] {line}");
                sink.lock().unwrap().push_str(&line);
                sink.lock().unwrap().push('\n');
            }
        });
        let mut out = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        out.read_line(&mut line)
            .expect("footscand prints its address");
        let base = line
            .trim()
            .strip_prefix("footscand listening on ")
            .unwrap_or_else(|| panic!("unexpected first line {line:?}"))
            .to_string();
        std::thread::spawn(move || {
            let mut rest = String::new();
            let _ = out.read_to_string(&mut rest);
        });
        Footscand {
            child,
            base,
            archive,
            client: reqwest::blocking::Client::builder()
                .timeout(Duration::from_secs(120))
                .build()
                .unwrap(),
            token: token.map(str::to_string),
            stderr,
        }
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    pub fn get(&self, path: &str) -> reqwest::blocking::Response {
        let mut r = self.client.get(self.url(path));
        if let Some(t) = &self.token {
            r = r.bearer_auth(t);
        }
        r.send().unwrap_or_else(|e| panic!("GET {path}: {e}"))
    }

    pub fn get_json(&self, path: &str) -> Value {
        let r = self.get(path);
        let status = r.status();
        let text = r.text().unwrap();
        assert_eq!(status, 200, "GET {path}: {text}");
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("GET {path}: {e}: {text}"))
    }

    pub fn post(&self, path: &str, body: &str) -> (u16, Value) {
        let r = self
            .client
            .post(self.url(path))
            .header("content-type", "application/json")
            .body(body.to_string());
        self.send_json("POST", path, r)
    }

    pub fn delete(&self, path: &str) -> (u16, Value) {
        self.send_json("DELETE", path, self.client.delete(self.url(path)))
    }

    /// Send a request with the token, if any; its status and JSON body.
    fn send_json(
        &self,
        method: &str,
        path: &str,
        mut r: reqwest::blocking::RequestBuilder,
    ) -> (u16, Value) {
        if let Some(t) = &self.token {
            r = r.bearer_auth(t);
        }
        let r = r.send().unwrap();
        let status = r.status().as_u16();
        let text = r.text().unwrap();
        let v = serde_json::from_str(&text)
            .unwrap_or_else(|e| panic!("{method} {path}: not JSON ({e}): {text:?}"));
        (status, v)
    }

    /// Start a scan; its id.
    pub fn start_scan(&self, subject: &str) -> String {
        let (s, v) = self.post(
            "/api/scans",
            &format!(r#"{{"subject": "{subject}", "side": "right", "notes": "test"}}"#),
        );
        assert_eq!(s, 202, "{v}");
        v["id"].as_str().unwrap().to_string()
    }

    /// Follow /api/events until scan `id` ends; every (event, data) seen, in order.
    pub fn follow(&self, id: &str) -> Vec<(String, Value)> {
        let mut r = self.client.get(self.url("/api/events"));
        if let Some(t) = &self.token {
            r = r.bearer_auth(t);
        }
        let resp = r.send().unwrap();
        assert_eq!(resp.status(), 200);
        assert!(resp.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/event-stream"));
        let mut events = Vec::new();
        let mut name = String::new();
        for line in BufReader::new(resp).lines() {
            let line = line.expect("event stream readable");
            if let Some(n) = line.strip_prefix("event: ") {
                name = n.to_string();
            } else if let Some(d) = line.strip_prefix("data: ") {
                let v: Value = serde_json::from_str(d).unwrap_or_else(|e| panic!("{e}: {d}"));
                let end = v["id"] == id
                    && (name == "state" || name == "progress")
                    && v["state"] != "running";
                events.push((name.clone(), v));
                if end && name == "state" {
                    break;
                }
            }
        }
        events
    }

    /// Poll GET `path` every 100 ms until `done` holds for its JSON (or `limit`: a failed
    /// assertion naming the path and its last answer); that answer.
    pub fn wait_json(&self, path: &str, limit: Duration, done: impl Fn(&Value) -> bool) -> Value {
        let t0 = Instant::now();
        loop {
            let v = self.get_json(path);
            if done(&v) {
                return v;
            }
            assert!(
                t0.elapsed() < limit,
                "GET {path}: still not done after {limit:?}: {v}"
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Poll /api/status until the scan is no longer running (or `limit`); the final scan.
    pub fn wait_scan_end(&self, limit: Duration) -> Value {
        self.wait_json("/api/status", limit, |s| s["scan"]["state"] != "running")["scan"].clone()
    }

    /// The record of scan `id` (with artifacts, summary, measurements).
    pub fn record(&self, id: &str) -> Value {
        self.get_json(&format!("/api/scans/{id}"))
    }

    pub fn download(&self, id: &str, name: &str) -> Vec<u8> {
        let r = self.get(&format!("/api/scans/{id}/files/{name}"));
        assert_eq!(r.status(), 200, "{id}/{name}");
        r.bytes().unwrap().to_vec()
    }

    /// Wait for the scan's job of kind `noun` ("last", "insole") to end; its record.
    pub fn wait_job(&self, id: &str, noun: &str, limit: Duration) -> Value {
        self.wait_json(&format!("/api/scans/{id}/{noun}"), limit, |j| {
            j["state"] != "running"
        })
    }

    /// File `name` made by the scan's job of kind `noun`: its content type and bytes.
    pub fn job_file(&self, id: &str, noun: &str, name: &str) -> (String, Vec<u8>) {
        let r = self.get(&format!("/api/scans/{id}/{noun}/{name}"));
        assert_eq!(r.status(), 200, "{name}");
        (
            r.headers()["content-type"].to_str().unwrap().to_string(),
            r.bytes().unwrap().to_vec(),
        )
    }

    pub fn stderr(&self) -> String {
        self.stderr.lock().unwrap().clone()
    }

    /// SIGTERM and wait for the exit status (with a limit).
    pub fn terminate(&mut self, limit: Duration) -> std::process::ExitStatus {
        let pid = self.child.id() as libc::pid_t;
        // SAFETY: kill(2) on our own child's pid.
        unsafe { libc::kill(pid, libc::SIGTERM) };
        let t0 = Instant::now();
        loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                return s;
            }
            assert!(
                t0.elapsed() < limit,
                "footscand did not exit within {limit:?}"
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Footscand {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// A raw HTTP/1.1 request on a fresh connection: (status, body).
pub fn raw_get(base: &str, target: &str) -> (u16, String) {
    use std::io::Write;
    let addr = base.strip_prefix("http://").unwrap();
    let mut s = std::net::TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(
        s,
        "GET {target} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut resp = String::new();
    s.read_to_string(&mut resp).unwrap();
    let status = resp
        .split_whitespace()
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0);
    let body = resp
        .split_once("\r\n\r\n")
        .map(|(_, b)| b.to_string())
        .unwrap_or_default();
    (status, body)
}

/// Percentile of `v` (sorted in place), p in 0..=100.
/// The bytes of file `name` of scan `id` in `archive` as archived: the file itself, or, once
/// the daemon has put the scan into compact form (`[archive] compact`, on by default), its
/// compact form decoded and checked (footscan::scandata::ScanDir::read_file).
pub fn archived_file(archive: &Path, id: &str, name: &str) -> Vec<u8> {
    footscan::scandata::ScanDir::new(archive.join(id))
        .read_file(name)
        .unwrap_or_else(|e| panic!("{id}/{name}: {e}"))
}

pub fn percentile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[((v.len() - 1) as f64 * p / 100.0).round() as usize]
}

/// A JSON array of strings (a job's files).
pub fn strings(v: &Value) -> Vec<&str> {
    v.as_array()
        .unwrap_or_else(|| panic!("not an array: {v}"))
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect()
}

/// The triangles of a binary STL, its length checked against their count.
pub fn stl_triangles(stl: &[u8]) -> usize {
    let tris = u32::from_le_bytes(stl[80..84].try_into().unwrap()) as usize;
    assert_eq!(stl.len(), 84 + 50 * tris);
    tris
}

/// Record scan `id`'s job of kind `noun` as running, as a daemon stopped during it leaves it
/// (the daemon must be stopped).
pub fn mark_job_running(archive: &Path, id: &str, noun: &str) {
    let job_file = archive.join(id).join(format!("{noun}-job.json"));
    let mut job: Value = serde_json::from_slice(&std::fs::read(&job_file).unwrap()).unwrap();
    job["state"] = "running".into();
    std::fs::write(&job_file, job.to_string()).unwrap();
}

/// The dashboard in Chromium (profile in `dir`) with scan `id`'s Result card showing its
/// job of kind `noun` done (the card's `render<Noun>` and `#<noun>-state`).
pub fn open_job_card(
    d: &Footscand,
    dir: &Path,
    id: &str,
    noun: &str,
    limit: Duration,
) -> chromium::Browser {
    let mut b = chromium::Browser::launch(&dir.join("profile"), 1280, 2400);
    let render = format!("render{}{}", noun[..1].to_uppercase(), &noun[1..]);
    b.open(
        &format!("{}/", d.base),
        &format!("typeof {render} === 'function'"),
        limit,
    );
    b.eval(&format!("loadResult({id:?})"));
    b.wait_for(
        &format!(
            "(() => {{ const e = document.getElementById('{noun}-state'); \
             return !!e && e.dataset.state === 'done'; }})()"
        ),
        limit,
    );
    b
}
