//! footscand over real HTTP on 127.0.0.1: a scan from POST to downloaded artifacts, request
//! validation, the bearer token, and the curl examples of docs/API.md.

mod daemon_support;

use daemon_support::*;
use std::path::Path;
use std::time::{Duration, Instant};

/// (a) Start a simulated scan, follow the events to the end, download and check every artifact.
#[test]
fn scan_over_http_end_to_end() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    assert_eq!(d.get_json("/api/health")["ok"], true);
    let st = d.get_json("/api/status");
    assert_eq!(st["backend"], "sim");
    assert!(st["scan"].is_null());
    assert_eq!(d.get("/api/preview.png").status(), 404, "no frame yet");

    let t0 = Instant::now();
    let id = d.start_scan("e2e-subject_1");
    let events = d.follow(&id);
    let wall = t0.elapsed().as_secs_f64();
    let (last_name, last) = events.last().unwrap();
    assert_eq!(last_name, "state");
    assert_eq!(last["state"], "complete", "{last}");
    let progress: Vec<&Value> = events
        .iter()
        .filter(|(n, v)| n == "progress" && v["id"] == id.as_str())
        .map(|(_, v)| v)
        .collect();
    assert!(progress.len() >= 3, "{} progress events", progress.len());
    for w in progress.windows(2) {
        assert!(
            w[1]["frames"].as_u64() >= w[0]["frames"].as_u64(),
            "frames go back"
        );
    }
    let fin = progress.last().unwrap();
    assert_eq!(fin["state"], "complete");

    let list = d.get_json("/api/scans");
    assert_eq!(list[0]["id"], id.as_str());
    let rec = d.record(&id);
    assert_eq!(rec["status"], "complete");
    assert_eq!(rec["subject"], "e2e-subject_1");
    assert_eq!(rec["side"], "right");
    assert!(rec["reason"].is_null());
    assert!(rec["finished"].is_string());
    let summary = &rec["summary"];
    let frames = rec["frames"].as_u64().unwrap();
    let points = rec["points"].as_u64().unwrap();
    assert!(frames > 100, "{frames} frames");
    assert!(points > 10_000, "{points} points");
    assert_eq!(summary["frames"], frames);
    assert_eq!(summary["dropped_frames"], 0);
    assert!(
        rec["measurements"].is_object(),
        "measurements.json is listed"
    );

    let arts = rec["artifacts"].as_array().unwrap();
    let names: Vec<&str> = arts.iter().map(|a| a["name"].as_str().unwrap()).collect();
    for want in [
        "points.ply",
        "model.stl",
        "scan.json",
        "measurements.json",
        "heightmap.png",
        "plantar.png",
        "calibration.toml",
        "record.json",
    ] {
        assert!(names.contains(&want), "{want} missing from {names:?}");
    }
    for a in arts {
        let name = a["name"].as_str().unwrap();
        let r = d.get(&format!("/api/scans/{id}/files/{name}"));
        assert_eq!(r.status(), 200);
        assert_eq!(
            r.headers()["content-type"],
            a["content_type"].as_str().unwrap()
        );
        let cd = r.headers()["content-disposition"]
            .to_str()
            .unwrap()
            .to_string();
        assert!(cd.starts_with("attachment;") && cd.contains(name), "{cd}");
        let bytes = r.bytes().unwrap();
        assert_eq!(bytes.len() as u64, a["bytes"].as_u64().unwrap(), "{name}");
        let on_disk = daemon_support::archived_file(&d.archive, &id, name);
        assert!(
            bytes[..] == on_disk[..],
            "{name} differs from the archived file"
        );
        check_artifact(name, &bytes, points);
    }
    // The preview now shows the last frame.
    let p = d.get("/api/preview.png?width=160");
    assert_eq!(p.status(), 200);
    assert!(p.headers().contains_key("x-frame-seq"));
    let img = image::load_from_memory(&p.bytes().unwrap()).unwrap();
    assert_eq!(img.width(), 160);
    let line = d.get_json("/api/preview/line");
    assert_eq!(
        line["cols"].as_array().unwrap().len() as u64,
        line["height"].as_u64().unwrap()
    );
    assert!(line["cols"]
        .as_array()
        .unwrap()
        .iter()
        .any(|c| c.is_number()));

    println!(
        "end-to-end: scan {:.2} s (summary), {wall:.2} s from POST to the last event; frames {frames}, \
         dropped {}, points {points}, truth RMS {} mm; {} progress events",
        summary["seconds"].as_f64().unwrap(),
        summary["dropped_frames"],
        summary["truth"]["rms_mm"],
        progress.len()
    );
}

fn check_artifact(name: &str, b: &[u8], points: u64) {
    match name.rsplit_once('.').map(|x| x.1) {
        Some("ply") => {
            let end = b
                .windows(11)
                .position(|w| w == b"end_header\n")
                .expect("PLY header ends");
            let head = std::str::from_utf8(&b[..end]).unwrap();
            assert!(head.starts_with("ply\n"), "{head}");
            let n: u64 = head
                .lines()
                .find_map(|l| l.strip_prefix("element vertex "))
                .expect("vertex count")
                .trim()
                .parse()
                .unwrap();
            assert_eq!(n, points, "PLY vertices = points of the record");
            let props = head.lines().filter(|l| l.starts_with("property")).count();
            assert!(props >= 3, "{head}");
            assert!(b.len() > end + 11 + n as usize * 12, "PLY body too short");
        }
        Some("stl") => {
            if b.starts_with(b"solid") && b.windows(8).any(|w| w == b"endsolid") {
                return; // ASCII STL
            }
            let n = u32::from_le_bytes(b[80..84].try_into().unwrap()) as usize;
            assert!(n > 100, "{n} triangles");
            assert_eq!(b.len(), 84 + 50 * n, "binary STL size");
        }
        Some("obj") => {
            let t = std::str::from_utf8(b).unwrap();
            assert!(
                t.lines().any(|l| l.starts_with("v ")) && t.lines().any(|l| l.starts_with("f "))
            );
        }
        Some("json") => {
            serde_json::from_slice::<Value>(b).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
        Some("png") => {
            let img = image::load_from_memory(b).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(img.width() > 10 && img.height() > 10);
        }
        Some("toml") => {
            toml::from_str::<toml::Table>(std::str::from_utf8(b).unwrap()).unwrap();
        }
        _ => assert!(!b.is_empty(), "{name} is empty"),
    }
}

fn assert_json_error(status: u16, body: &str, want: std::ops::RangeInclusive<u16>, what: &str) {
    assert!(
        want.contains(&status),
        "{what}: status {status}, body {body}"
    );
    let v: Value = serde_json::from_str(body).unwrap_or_else(|e| panic!("{what}: {e}: {body:?}"));
    let msg = v["error"]
        .as_str()
        .unwrap_or_else(|| panic!("{what}: no error in {v}"));
    assert!(!msg.is_empty());
}

/// (c) Bad ids, names and bodies are refused with 4xx and a JSON error; nothing escapes the
/// archive.
#[test]
fn requests_are_validated() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("secret"), b"do not serve").unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    for target in [
        "/api/scans/../etc",
        "/api/scans/%2e%2e",
        "/api/scans/%2e%2e%2f%2e%2e%2fsecret",
        "/api/scans/..%2Fsecret/files/x",
        "/api/scans/20261121T221503Z-3f2a/files/..%2F..%2Fsecret",
        "/api/scans/20261121T221503Z-3f2a/files/%2e%2e",
        "/api/scans/20261121T221503Z-3f2a/files/.reserve",
        "/api/scans/20261121T221503Z-3f2a",
        "/api/scans/20261121t221503z-3f2a",
        "/api/nothing",
        "/api/preview.png?width=5",
        "/api/preview.png?width=abc",
        "/api/scans/%ff",
        "/api/scans/%ff/files/x",
        "/api/preview.png?width=1&width=2",
    ] {
        let (s, body) = raw_get(&d.base, target);
        assert_json_error(s, &body, 400..=404, target);
        assert!(!body.contains("do not serve"), "{target} leaked the file");
    }
    let long = "x".repeat(65);
    let notes = "n".repeat(2001);
    let big = format!(
        r#"{{"subject": "a", "side": "left", "notes": "{}"}}"#,
        "n".repeat(20_000)
    );
    for (body, want, what) in [
        (
            r#"{"subject": "a", "side": "middle"}"#.to_string(),
            400..=400,
            "wrong side",
        ),
        (
            format!(r#"{{"subject": "{long}", "side": "left"}}"#),
            400..=400,
            "long subject",
        ),
        (
            r#"{"subject": "", "side": "left"}"#.to_string(),
            400..=400,
            "empty subject",
        ),
        (
            r#"{"subject": "../x", "side": "left"}"#.to_string(),
            400..=400,
            "subject with /",
        ),
        (
            format!(r#"{{"subject": "a", "side": "left", "notes": "{notes}"}}"#),
            400..=400,
            "long notes",
        ),
        (
            r#"{"subject": "a", "side": "left", "extra": 1}"#.to_string(),
            400..=400,
            "unknown field",
        ),
        (r#"{"subject": "a""#.to_string(), 400..=400, "broken JSON"),
        (
            r#"{"side": "left"}"#.to_string(),
            400..=400,
            "missing subject",
        ),
        (big, 413..=413, "oversize body"),
    ] {
        let r = d
            .client
            .post(d.url("/api/scans"))
            .header("content-type", "application/json")
            .body(body)
            .send()
            .unwrap();
        let s = r.status().as_u16();
        assert_json_error(s, &r.text().unwrap(), want, what);
    }
    let r = d
        .client
        .post(d.url("/api/scans"))
        .body(r#"{"subject": "a", "side": "left"}"#)
        .send()
        .unwrap();
    let s = r.status().as_u16();
    assert_json_error(s, &r.text().unwrap(), 415..=415, "no content type");
    let (s, v) = d.post("/api/calibrations", r#"{"method": "magic"}"#);
    assert_json_error(s, &v.to_string(), 400..=400, "unknown calibration method");
    let (s, v) = d.post("/api/scans/20261121T221503Z-3f2a/cancel", "{}");
    assert_json_error(s, &v.to_string(), 404..=404, "cancel unknown scan");
    let r = d.client.delete(d.url("/api/scans")).send().unwrap();
    let s = r.status().as_u16();
    assert_json_error(s, &r.text().unwrap(), 405..=405, "DELETE");

    // One job at a time: a second scan while one runs is a conflict; then cancel it.
    let id = d.start_scan("busy");
    let (s, v) = d.post("/api/scans", r#"{"subject": "b", "side": "left"}"#);
    assert_json_error(s, &v.to_string(), 409..=409, "second scan");
    let (s, v) = d.post("/api/calibrations", r#"{"method": "insystem"}"#);
    assert_json_error(s, &v.to_string(), 409..=409, "calibration during a scan");
    let (s, v) = d.post(&format!("/api/scans/{id}/cancel"), "");
    assert_eq!(s, 202, "{v}");
    assert_eq!(v["state"], "cancelling");
    let end = d.wait_scan_end(Duration::from_secs(60));
    assert_eq!(end["state"], "cancelled");
    assert_eq!(end["reason"], "cancelled by the operator");
    let rec = d.record(&id);
    assert_eq!(rec["status"], "cancelled");
    assert_eq!(rec["reason"], "cancelled by the operator");
    let (s, v) = d.post(&format!("/api/scans/{id}/cancel"), "");
    assert_json_error(s, &v.to_string(), 409..=409, "cancel a finished scan");
    assert!(!d.archive.join("secret").exists());
}

/// (b) A non-loopback bind needs a token; with one, every request but health needs it.
#[test]
fn bearer_token_guards_a_network_bind() {
    let tmp = tempfile::tempdir().unwrap();
    let (mut cmd, _) = command(
        tmp.path(),
        &Opts {
            bind: "0.0.0.0:0",
            ..Opts::default()
        },
    );
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "started without a token: {err}");
    assert!(
        err.contains("token") && err.contains("FOOTSCAND_TOKEN"),
        "{err}"
    );
    assert!(out.stdout.is_empty(), "it must not listen");

    const TOKEN: &str = "s3cret-token-for-tests";
    for via_env in [false, true] {
        let dir = tmp.path().join(format!("env-{via_env}"));
        std::fs::create_dir_all(&dir).unwrap();
        let mut d = if via_env {
            let (mut cmd, archive) = command(
                &dir,
                &Opts {
                    bind: "0.0.0.0:0",
                    daemon_extra: "allow_plain_http = true\n",
                    ..Opts::default()
                },
            );
            cmd.env("FOOTSCAND_TOKEN", TOKEN);
            Footscand::spawn(cmd, archive, Some(TOKEN))
        } else {
            Footscand::start(
                &dir,
                Opts {
                    bind: "0.0.0.0:0",
                    token: Some(TOKEN),
                    daemon_extra: "allow_plain_http = true\n",
                    ..Opts::default()
                },
            )
        };
        d.base = d.base.replace("0.0.0.0", "127.0.0.1");
        let c = &d.client;
        let status = |r: reqwest::blocking::RequestBuilder| r.send().unwrap().status().as_u16();
        assert_eq!(status(c.get(d.url("/api/health"))), 200);
        assert_eq!(
            status(c.get(d.url("/"))),
            200,
            "the dashboard page asks for the token"
        );
        for path in [
            "/api/status",
            "/api/scans",
            "/api/preview/line",
            "/api/events",
        ] {
            let r = c.get(d.url(path)).send().unwrap();
            assert_eq!(r.status(), 401, "{path} without a token");
            assert!(r.text().unwrap().contains("\"error\""));
            assert_eq!(
                status(c.get(d.url(path)).bearer_auth("wrong-token-wrong-token")),
                401
            );
        }
        assert_eq!(status(c.get(d.url("/api/status")).bearer_auth(TOKEN)), 200);
        assert_eq!(
            status(c.get(d.url(&format!("/api/status?access_token={TOKEN}")))),
            200
        );
        assert_eq!(status(c.get(d.url("/api/status?access_token=nope"))), 401);
        let r = c
            .post(d.url("/api/scans"))
            .header("content-type", "application/json")
            .body(r#"{"subject": "a", "side": "left"}"#)
            .send()
            .unwrap();
        assert_eq!(r.status(), 401, "POST without a token");
        let s = d.terminate(Duration::from_secs(30));
        assert!(s.success(), "{s:?}");
    }
}

/// (g) Every ```sh block of docs/API.md runs against a live daemon: exit code 0 and every
/// JSON line of its output parses.
#[test]
fn api_doc_curl_examples_run() {
    let doc_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/API.md");
    let doc = std::fs::read_to_string(&doc_path).unwrap();
    let mut blocks = Vec::new();
    let mut cur: Option<String> = None;
    for line in doc.lines() {
        match (&mut cur, line.trim_end()) {
            (None, "```sh") => cur = Some(String::new()),
            (Some(b), "```") => {
                blocks.push(std::mem::take(b));
                cur = None;
            }
            (Some(b), l) => {
                b.push_str(l);
                b.push('\n');
            }
            _ => {}
        }
    }
    assert!(
        blocks.len() >= 12,
        "{} sh blocks in docs/API.md",
        blocks.len()
    );
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(tmp.path(), Opts::default());
    // A finished scan for the examples that name one.
    let id = d.start_scan("doc-example");
    d.wait_scan_end(Duration::from_secs(120));
    let work = tmp.path().join("curl");
    std::fs::create_dir_all(&work).unwrap();
    let mut ran = 0;
    for b in &blocks {
        if !b.contains("curl") {
            continue;
        }
        // A scan the examples started must end before the next one can start.
        if b.contains("/api/calibrations") {
            d.wait_scan_end(Duration::from_secs(120));
        }
        let out = std::process::Command::new("sh")
            .arg("-c")
            .arg(format!("set -e\n{b}"))
            .current_dir(&work)
            .env("FS", &d.base)
            .env("ID", &id)
            .env("TOKEN", "unused-on-loopback")
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{b}\nexit {:?}\n{stdout}\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
        );
        // The output: JSON values (one or more), or an event stream whose data is JSON.
        let json: String = stdout
            .lines()
            .filter(|l| !l.starts_with("event: ") && !l.starts_with(':'))
            .map(|l| l.strip_prefix("data: ").unwrap_or(l))
            .collect::<Vec<_>>()
            .join("\n");
        let mut values = 0;
        for v in serde_json::Deserializer::from_str(&json).into_iter::<Value>() {
            v.unwrap_or_else(|e| panic!("{b}: output is not JSON: {e}: {json}"));
            values += 1;
        }
        assert!(values > 0 || json.trim().is_empty(), "{b}: {json}");
        ran += 1;
    }
    println!("ran {ran} curl examples from docs/API.md");
    assert!(ran >= 12);
}
