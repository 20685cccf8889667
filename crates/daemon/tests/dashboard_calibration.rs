//! The calibration wizard in a real browser: footscand on the simulator backend, Debian's
//! headless Chromium driven over the DevTools protocol (`--remote-debugging-pipe`: JSON
//! messages on fds 3 and 4, no extra crate). The guided calibration is started with the
//! simulator's operator scripted to put the 21 mm spacers where 14 mm are asked; the page is
//! then worked as an operator would: "Target in place" at each step, the failed check shown
//! with what was expected and what was seen, "Repeat step", "Keep step", until the calibration
//! is complete and its parameters shown; then the "Daily check" button, its one step confirmed,
//! PASS shown. Screenshots at target/dashboard-calibration-*.png for people to look at.

#[path = "daemon_support/chromium.rs"]
mod chromium;

use chromium::Browser;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const TOKEN: &str = "dashboard-calibration-token-0123456789";

struct Kill(Child);
impl Drop for Kill {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn manifest() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn target_dir() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR"))
        .parent()
        .expect("CARGO_TARGET_TMPDIR is inside the target directory")
        .to_path_buf()
}

/// footscand on config/sim.toml with its archive in `dir`; (process, base URL).
fn start_daemon(dir: &Path) -> (Kill, String) {
    let read = |name: &str| -> toml::Table {
        let p = manifest().join("config").join(name);
        std::fs::read_to_string(&p).unwrap().parse().unwrap()
    };
    // A lighter plan than the built-in one (4 frames a plate, the staircase every 2 mm): the
    // wizard's steps are the same, its real-time passes shorter.
    let mut sim = read("sim.toml");
    let light: toml::Table = "plan = \"plan.toml\"\nverify_step_mm = 2.0\n"
        .parse()
        .unwrap();
    sim.insert("calibration".into(), light.into());
    std::fs::write(
        dir.join("plan.toml"),
        "frames_per_height = 4\nstair_step_mm = 2.0\n",
    )
    .unwrap();
    std::fs::write(dir.join("sim.toml"), toml::to_string(&sim).unwrap()).unwrap();
    let mut d = read("footscand.toml");
    let daemon = d["daemon"].as_table_mut().unwrap();
    daemon.insert(
        "archive".into(),
        dir.join("archive").display().to_string().into(),
    );
    daemon.insert("scanner_config".into(), "sim.toml".into());
    daemon.remove("token");
    daemon.remove("calibration");
    let cfg = dir.join("footscand.toml");
    std::fs::write(&cfg, toml::to_string(&d).unwrap()).unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_footscand"))
        .arg("--config")
        .arg(&cfg)
        .args(["--bind", "127.0.0.1:0"])
        .env("FOOTSCAND_TOKEN", TOKEN)
        .env("RUST_LOG", "warn")
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("starting footscand");
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let line = lines.next().expect("an address line").unwrap();
    let base = line
        .strip_prefix("footscand listening on ")
        .unwrap_or_else(|| panic!("unexpected first line: {line:?}"))
        .trim()
        .to_string();
    std::thread::spawn(move || for _ in lines.map_while(Result::ok) {});
    (Kill(child), base)
}

fn post(base: &str, path: &str, body: &str) -> Value {
    let r = reqwest::blocking::Client::new()
        .post(format!("{base}{path}"))
        .bearer_auth(TOKEN)
        .header("content-type", "application/json")
        .body(body.to_string())
        .send()
        .unwrap();
    let status = r.status();
    let text = r.text().unwrap();
    assert!(status.is_success(), "POST {path}: {status}: {text}");
    serde_json::from_str(&text).unwrap()
}

/// What the card shows (read from the DOM, as the operator sees it).
const CARD: &str = r#"(() => {
  const t = (id) => (document.getElementById(id) || {}).textContent || '';
  const on = (id) => { const b = document.getElementById(id); return !!b && !b.disabled; };
  return {
    step: t('cal-step'), instruction: t('cal-instruction'), seen: t('cal-seen'),
    seenClass: document.getElementById('cal-seen').className,
    confirm: on('cal-confirm'), confirmLabel: t('cal-confirm'), repeat: on('cal-repeat'),
    start: on('cal-start'), verify: on('cal-verify'),
    result: t('cal-result'), status: t('cal-status'), warning: t('cal-warning'),
    error: document.getElementById('error').hidden ? '' : t('error-text'),
  };
})()"#;

/// Work the wizard until the job ends: confirm each step, repeat a failed one (screenshot
/// of the first place, the failed check and the first kept review). Returns (confirms,
/// repeats).
fn operate(
    b: &mut Browser,
    shots: &mut Vec<(String, image::RgbImage)>,
    limit: Duration,
) -> (usize, usize) {
    let t0 = Instant::now();
    while b.eval(CARD)["start"] == true {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the job did not start"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let (mut confirms, mut repeats) = (0, 0);
    let mut last_step = String::new();
    loop {
        assert!(
            t0.elapsed() < limit,
            "the wizard did not finish in {limit:?}: {}",
            b.eval(CARD)
        );
        let c = b.eval(CARD);
        assert_eq!(c["error"], "", "the page shows an error: {c}");
        if c["start"] == true && !c["result"].as_str().unwrap().is_empty() {
            return (confirms, repeats);
        }
        let key = format!("{} {} {}", c["step"], c["seenClass"], c["confirmLabel"]);
        if key == last_step {
            std::thread::sleep(Duration::from_millis(100));
            continue;
        }
        if c["repeat"] == true && c["seenClass"] == "fail" {
            println!("dashboard: {} -> {}", c["step"], c["seen"]);
            if !shots.iter().any(|(n, _)| n == "failed") {
                let img =
                    b.screenshot(&target_dir().join("dashboard-calibration-failed.png"), None);
                shots.push(("failed".into(), img));
            }
            last_step = key;
            b.click("cal-repeat");
            repeats += 1;
        } else if c["confirm"] == true {
            if c["confirmLabel"] == "Target in place" && !shots.iter().any(|(n, _)| n == "place") {
                let img = b.screenshot(&target_dir().join("dashboard-calibration-place.png"), None);
                shots.push(("place".into(), img));
            }
            last_step = key;
            b.click("cal-confirm");
            confirms += 1;
        } else {
            std::thread::sleep(Duration::from_millis(100));
        }
    }
}

#[test]
fn guided_calibration_and_daily_check_in_the_dashboard() {
    let tmp = tempfile::tempdir().unwrap();
    let (_daemon, base) = start_daemon(tmp.path());
    let mut b = Browser::launch(&tmp.path().join("profile"), 1280, 1600);
    b.page("Page.enable", json!({}));
    b.page(
        "Page.navigate",
        json!({"url": format!("{base}/#token={TOKEN}")}),
    );
    let t0 = Instant::now();
    while b.eval("document.readyState === 'complete' && !!document.getElementById('cal-start') && typeof calPoll === 'function'") != true {
        assert!(t0.elapsed() < Duration::from_secs(30), "the page did not load");
        std::thread::sleep(Duration::from_millis(100));
    }
    std::thread::sleep(Duration::from_millis(500));
    let c = b.eval(CARD);
    assert!(
        c["status"].as_str().unwrap().contains("No calibration yet"),
        "{c}"
    );
    assert!(
        c["warning"].as_str().unwrap().contains("no daily check"),
        "{c}"
    );

    // The guided calibration with the simulator's operator making the spacer mistake; the
    // page picks the running job up and the operator works it from there.
    post(
        &base,
        "/api/calibrations",
        r#"{"guided": true, "confirmed_by": "dashboard test",
            "sim_mistakes": [{"asked": "plate:14", "placed": "plate:21"}]}"#,
    );
    b.eval("calPoll()");
    let mut shots = Vec::new();
    let t1 = Instant::now();
    let (confirms, repeats) = operate(&mut b, &mut shots, Duration::from_secs(300));
    let c = b.eval(CARD);
    println!(
        "dashboard calibration: {:.1} s, {confirms} confirms, {repeats} repeats; {}",
        t1.elapsed().as_secs_f64(),
        c["result"]
    );
    assert_eq!(repeats, 1, "the wrong plate repeated once");
    assert_eq!(confirms, 21, "11 placements and 10 kept steps");
    let result = c["result"].as_str().unwrap();
    assert!(result.contains("complete"), "{c}");
    assert!(result.contains("confirmed by dashboard test"), "{c}");
    let d_mm: f64 = b
        .eval("Number(document.querySelector('#cal-params tr:nth-child(2) td').textContent)")
        .as_f64()
        .unwrap();
    assert!((d_mm - 250.0).abs() < 5.0, "D shown {d_mm}");
    let img = b.screenshot(&target_dir().join("dashboard-calibration-done.png"), None);
    shots.push(("done".into(), img));

    // The daily check from its button.
    b.click("cal-verify");
    let (confirms, repeats) = operate(&mut b, &mut shots, Duration::from_secs(120));
    assert_eq!((confirms, repeats), (2, 0), "one step placed and kept");
    let c = b.eval(CARD);
    println!("dashboard daily check: {}", c["result"]);
    assert!(c["result"].as_str().unwrap().contains("PASS"), "{c}");
    let rows = b.eval("document.querySelectorAll('#cal-steps tbody tr').length");
    assert_eq!(rows, 8, "one row per gauge step");
    b.eval("calRefreshStatus()");
    std::thread::sleep(Duration::from_millis(300));
    let c = b.eval(CARD);
    assert_eq!(
        c["warning"], "",
        "the passing check clears the warning: {c}"
    );
    assert!(c["status"].as_str().unwrap().contains("min old"), "{c}");
    let img = b.screenshot(&target_dir().join("dashboard-calibration-check.png"), None);
    shots.push(("check".into(), img));

    // The screenshots are of the page, not blank: the failed check's red text and the PASS
    // badge's green are on them.
    let count = |img: &image::RgbImage, rgb: [u8; 3]| {
        img.pixels()
            .filter(|p| (0..3).all(|k| (p.0[k] as i32 - rgb[k] as i32).abs() < 40))
            .count()
    };
    for (name, img) in &shots {
        let red = count(img, [0xa4, 0x16, 0x1a]);
        let green = count(img, [0x17, 0x66, 0x3a]);
        println!(
            "{name}: {}x{}, red {red} px, green {green} px",
            img.width(),
            img.height()
        );
        if name == "failed" {
            assert!(red > 100, "the failed check is shown in red");
        }
        if name == "check" {
            assert!(green > 100, "the PASS badge is green");
        }
    }
}
