//! HTTPS (issue 35 item 4), tested with curl and openssl as a clinic's client would be: the
//! self-signed certificate's fingerprint in the log, in /api/tls and on the wire agree; the
//! API, the event stream and a download (the scan's model.glb) work over HTTPS with
//! --cacert; plain HTTP to the TLS port gets a clean JSON 400; a client expecting another
//! certificate refuses the connection; a token on the network without TLS is refused at
//! start unless allow_plain_http says the network is trusted.

mod daemon_support;

use daemon_support::{command, Footscand, Opts};
use std::path::Path;
use std::process::Command;
use std::time::Duration;

const TOKEN: &str = "tls-test-token-0123456789";

/// curl's exit code and stdout.
fn curl(args: &[&str]) -> (i32, String) {
    let out = Command::new("curl")
        .args(["-sS", "--max-time", "20"])
        .args(args)
        .output()
        .expect("curl runs (scripts/setup.sh installs it)");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
    )
}

/// The SHA-256 fingerprint of the certificate the server at `host:port` presents, read by
/// openssl (independently of the daemon's code).
fn wire_fingerprint(addr: &str) -> String {
    let out = Command::new("sh")
        .arg("-c")
        .arg(format!(
            "openssl s_client -connect {addr} </dev/null 2>/dev/null | openssl x509 -noout -fingerprint -sha256"
        ))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    text.trim()
        .split_once('=')
        .unwrap_or_else(|| panic!("openssl printed {text:?}"))
        .1
        .to_string()
}

fn start(dir: &Path, extra: &str) -> Footscand {
    std::fs::create_dir_all(dir).unwrap();
    let mut d = Footscand::start(
        dir,
        Opts {
            bind: "0.0.0.0:0",
            token: Some(TOKEN),
            daemon_extra: extra,
            ..Opts::default()
        },
    );
    d.base = d.base.replace("0.0.0.0", "127.0.0.1");
    d
}

#[test]
fn https_self_signed_and_given_certificates_with_curl() {
    let tmp = tempfile::tempdir().unwrap();
    let auth = format!("Authorization: Bearer {TOKEN}");

    // A token on the network over plain HTTP is refused at start, naming the way out.
    let (mut cmd, _) = command(
        tmp.path(),
        &Opts {
            bind: "0.0.0.0:0",
            token: Some(TOKEN),
            ..Opts::default()
        },
    );
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "started over plain HTTP: {err}");
    assert!(
        err.contains("clear text") && err.contains("allow_plain_http = true"),
        "{err}"
    );
    assert!(out.stdout.is_empty(), "it must not listen");

    // Self-signed: made on first start, its fingerprint in the log, /api/tls and on the wire.
    let d = start(&tmp.path().join("self"), "tls = \"self-signed\"\n");
    assert!(d.base.starts_with("https://127.0.0.1:"), "{}", d.base);
    let addr = d.base.trim_start_matches("https://").to_string();
    let cert = d.archive.join("tls/cert.pem");
    assert!(cert.exists(), "{} not made", cert.display());
    let cacert = cert.to_str().unwrap();
    let (code, body) = curl(&["--cacert", cacert, "-H", &auth, &d.url("/api/tls")]);
    assert_eq!(code, 0, "curl --cacert: {body}");
    let v: serde_json::Value = serde_json::from_str(&body).unwrap();
    assert_eq!(v["https"], true, "{v}");
    let fp = v["certificate"]["fingerprint_sha256"]
        .as_str()
        .unwrap()
        .to_string();
    assert_eq!(wire_fingerprint(&addr), fp);
    let log = d.stderr();
    assert!(log.contains(&format!("SHA-256 fingerprint {fp}")), "{log}");
    println!("self-signed certificate {fp}");

    // The API: status, a scan started and followed on the event stream, its model.glb
    // downloaded over HTTPS byte for byte.
    let (code, body) = curl(&["--cacert", cacert, "-H", &auth, &d.url("/api/status")]);
    assert_eq!(code, 0, "{body}");
    assert!(body.contains("\"devices\""), "{body}");
    let (_, denied) = curl(&[
        "--cacert",
        cacert,
        "-o",
        "/dev/null",
        "-w",
        "%{http_code}",
        &d.url("/api/status"),
    ]);
    assert_eq!(denied, "401", "no token over HTTPS");
    let events = {
        let url = d.url("/api/events");
        let (cacert, auth) = (cacert.to_string(), auth.clone());
        std::thread::spawn(move || {
            let out = Command::new("curl")
                .args(["-sSN", "--max-time", "10", "--cacert", &cacert, "-H", &auth])
                .arg(&url)
                .output()
                .unwrap();
            String::from_utf8_lossy(&out.stdout).into_owned()
        })
    };
    std::thread::sleep(Duration::from_millis(500));
    let (code, body) = curl(&[
        "--cacert",
        cacert,
        "-H",
        &auth,
        "-H",
        "content-type: application/json",
        "-d",
        "{\"subject\":\"tls\",\"side\":\"right\",\"notes\":\"\"}",
        &d.url("/api/scans"),
    ]);
    assert_eq!(code, 0, "{body}");
    let id = serde_json::from_str::<serde_json::Value>(&body).unwrap()["id"]
        .as_str()
        .unwrap_or_else(|| panic!("no id in {body}"))
        .to_string();
    let mut done = false;
    for _ in 0..240 {
        let (_, body) = curl(&["--cacert", cacert, "-H", &auth, &d.url("/api/status")]);
        let v: serde_json::Value = serde_json::from_str(&body).unwrap();
        if v["scan"]["state"] != "running" && d.archive.join(&id).join("record.json").exists() {
            done = true;
            break;
        }
        std::thread::sleep(Duration::from_millis(500));
    }
    assert!(done, "the scan did not end");
    let glb = tmp.path().join("model.glb");
    let (code, body) = curl(&[
        "--cacert",
        cacert,
        "-H",
        &auth,
        "-o",
        glb.to_str().unwrap(),
        "-w",
        "%{http_code} %{content_type}",
        &d.url(&format!("/api/scans/{id}/files/model.glb")),
    ]);
    assert_eq!(code, 0);
    assert_eq!(body, "200 model/gltf-binary");
    assert_eq!(
        std::fs::read(&glb).unwrap(),
        daemon_support::archived_file(&d.archive, &id, "model.glb")
    );
    let stream = events.join().unwrap();
    assert!(
        stream.contains("event:") || stream.contains("data:"),
        "no events over HTTPS: {stream:?}"
    );

    // Plain HTTP to the TLS port: a clean JSON 400 saying to use https.
    let (code, body) = curl(&["-w", " %{http_code}", &format!("http://{addr}/api/status")]);
    assert_eq!(code, 0, "{body}");
    assert!(
        body.contains("HTTPS only") && body.ends_with(" 400"),
        "{body}"
    );
    // A client that does not trust the certificate refuses it (curl: exit 60).
    let (code, _) = curl(&["-H", &auth, &d.url("/api/status")]);
    assert_eq!(code, 60, "curl accepted an untrusted certificate");

    // Given files: the first daemon's certificate and key, copied; a client holding another
    // daemon's certificate refuses this one.
    let given = tmp.path().join("given");
    std::fs::create_dir_all(&given).unwrap();
    for f in ["cert.pem", "key.pem"] {
        std::fs::copy(d.archive.join("tls").join(f), given.join(f)).unwrap();
    }
    drop(d);
    let other = start(&tmp.path().join("other"), "tls = \"self-signed\"\n");
    let other_cert = other.archive.join("tls/cert.pem");
    let g = start(
        &tmp.path().join("files"),
        &format!(
            "tls = {{ cert = {:?}, key = {:?} }}\n",
            given.join("cert.pem").to_str().unwrap(),
            given.join("key.pem").to_str().unwrap()
        ),
    );
    let gaddr = g.base.trim_start_matches("https://").to_string();
    assert_eq!(wire_fingerprint(&gaddr), fp);
    let given_cert = given.join("cert.pem");
    let (code, body) = curl(&[
        "--cacert",
        given_cert.to_str().unwrap(),
        "-H",
        &auth,
        &g.url("/api/health"),
    ]);
    assert_eq!(code, 0, "{body}");
    let (code, _) = curl(&[
        "--cacert",
        other_cert.to_str().unwrap(),
        "-H",
        &auth,
        &g.url("/api/health"),
    ]);
    assert_eq!(code, 60, "curl accepted a certificate it does not trust");
    assert!(!g.archive.join("tls").exists(), "given files: nothing made");
}
