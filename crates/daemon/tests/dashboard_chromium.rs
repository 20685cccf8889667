//! The dashboard in a real browser: the footscand binary on a temporary archive runs a short
//! simulated scan over HTTP, then Debian's headless Chromium loads the page from it. The dumped
//! DOM must list the scan and show the API's measurements; the screenshot (kept at
//! target/dashboard.png for people to look at) must show the page's header, the laser frame and
//! the height map's colour map where the layout puts them.

#[path = "daemon_support/chromium.rs"]
mod chromium;

use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Window of the screenshot; the layout's three columns are laid out for this width.
const WIN_W: u32 = 1280;
const WIN_H: u32 = 900;

/// The daemon, killed when dropped (the test may fail anywhere).
struct Daemon {
    child: Child,
    base: String,
}

impl Drop for Daemon {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn manifest() -> PathBuf {
    // The repository root (config/, target/), two levels above this crate.
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The dashboard in Chromium at this test's window size. The page's requests all finish in
/// virtual time: an idle dashboard holds no open event stream (it follows events only while a
/// scan runs), so the budget can expire.
fn run_chromium(url: &str, profile: &Path, extra: &[&str]) -> Vec<u8> {
    let mut flags = vec!["--virtual-time-budget=5000"];
    flags.extend_from_slice(extra);
    chromium::run(
        url,
        profile,
        (WIN_W, WIN_H),
        &flags,
        Duration::from_secs(120),
    )
}

/// Bearer token the daemon is started with: the page must carry it on every request.
const TOKEN: &str = "dashboard-test-token-0123456789";

impl Daemon {
    fn start(config: &Path) -> Daemon {
        let mut child = Command::new(env!("CARGO_BIN_EXE_footscand"))
            .arg("--config")
            .arg(config)
            .args(["--bind", "127.0.0.1:0"])
            .env("FOOTSCAND_TOKEN", TOKEN)
            .env("RUST_LOG", "warn")
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("starting footscand");
        let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
        let first = lines.next();
        let mut daemon = Daemon {
            child,
            base: String::new(),
        };
        let line = match first {
            Some(Ok(l)) => l,
            other => panic!("footscand printed no address line: {other:?}"),
        };
        daemon.base = line
            .strip_prefix("footscand listening on ")
            .unwrap_or_else(|| panic!("unexpected first line from footscand: {line:?}"))
            .trim()
            .to_string();
        // Keep draining stdout so the daemon never blocks on a full pipe.
        std::thread::spawn(move || for _ in lines.map_while(Result::ok) {});
        daemon
    }

    fn request(&self, method: reqwest::Method, path: &str) -> reqwest::blocking::RequestBuilder {
        reqwest::blocking::Client::new()
            .request(method, format!("{}{path}", self.base))
            .bearer_auth(TOKEN)
            .timeout(Duration::from_secs(30))
    }

    fn get_json(&self, path: &str) -> Value {
        let r = self
            .request(reqwest::Method::GET, path)
            .send()
            .unwrap_or_else(|e| panic!("GET {path}: {e}"));
        let status = r.status();
        let text = r.text().unwrap();
        assert!(status.is_success(), "GET {path}: {status}: {text}");
        serde_json::from_str(&text).unwrap_or_else(|e| panic!("GET {path}: not JSON ({e}): {text}"))
    }

    fn get_bytes(&self, path: &str) -> Vec<u8> {
        let r = self
            .request(reqwest::Method::GET, path)
            .send()
            .unwrap_or_else(|e| panic!("GET {path}: {e}"));
        assert!(r.status().is_success(), "GET {path}: {}", r.status());
        r.bytes().unwrap().to_vec()
    }
}

/// Every start tag that contains `needle` (e.g. `data-key="x"`), from `<` to `>`.
fn tags_with<'a>(html: &'a str, needle: &str) -> Vec<&'a str> {
    let mut tags = Vec::new();
    let mut from = 0;
    while let Some(i) = html[from..].find(needle) {
        let at = from + i;
        if let (Some(start), Some(len)) = (html[..at].rfind('<'), html[at..].find('>')) {
            tags.push(&html[start..at + len]);
        }
        from = at + needle.len();
    }
    tags
}

/// The attribute `name` of a start tag.
fn attr(tag: &str, name: &str) -> Option<String> {
    let key = format!(" {name}=\"");
    let v0 = tag.find(&key)? + key.len();
    let v1 = v0 + tag[v0..].find('"')?;
    Some(unescape(&tag[v0..v1]))
}

/// The attribute `name` of the first tag that contains `needle`.
fn attr_of_tag_with(html: &str, needle: &str, name: &str) -> Option<String> {
    attr(tags_with(html, needle).first()?, name)
}

/// The text inside the first element that contains `needle` in its start tag.
fn text_of_tag_with(html: &str, needle: &str) -> Option<String> {
    let at = html.find(needle)?;
    let open_end = at + html[at..].find('>')? + 1;
    let close = open_end + html[open_end..].find('<')?;
    Some(unescape(&html[open_end..close]))
}

fn unescape(s: &str) -> String {
    s.replace("&quot;", "\"")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&")
}

/// The five stops of the height-map colour ramp (crates/scanner/src/io/heightmap.rs).
const RAMP: [[u8; 3]; 5] = [
    [68, 1, 84],
    [59, 82, 139],
    [33, 145, 140],
    [94, 201, 98],
    [253, 231, 37],
];

fn dist(a: [u8; 3], b: [u8; 3]) -> i32 {
    (0..3)
        .map(|k| (a[k] as i32 - b[k] as i32).abs())
        .max()
        .unwrap()
}

struct Region {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

impl Region {
    fn pixels<'a>(&'a self, img: &'a image::RgbImage) -> impl Iterator<Item = [u8; 3]> + 'a {
        (self.y0..self.y1).flat_map(move |y| (self.x0..self.x1).map(move |x| img.get_pixel(x, y).0))
    }
    fn fraction(&self, img: &image::RgbImage, f: impl Fn([u8; 3]) -> bool) -> f64 {
        let n = ((self.x1 - self.x0) * (self.y1 - self.y0)) as f64;
        self.pixels(img).filter(|p| f(*p)).count() as f64 / n
    }
}

/// Copies of config/footscand.toml and config/sim.toml in `dir`, the archive in `dir`, and a
/// scan short enough for a test: 1.5 mm per frame (about 220 frames, a few seconds) with the
/// emulated slider allowed the faster feed, and the height map on 1 mm cells (the single
/// empty cells between frames are filled; 0.5 mm cells would be striped).
fn write_configs(dir: &Path) -> PathBuf {
    let read = |name: &str| {
        let p = manifest().join("config").join(name);
        let text = std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        text.parse::<toml::Table>()
            .unwrap_or_else(|e| panic!("{}: {e}", p.display()))
    };
    let mut sim = read("sim.toml");
    let step = 1.5;
    let fps = sim["camera"]["fps"].as_float().unwrap();
    sim["scan"]["step_mm"] = toml::Value::Float(step);
    let feed = step * fps * 60.0;
    sim["sim"]["slider"]["max_rate_mm_min"] = toml::Value::Float(feed.max(3000.0));
    let stages = sim["pipeline"]["stages"].as_array_mut().unwrap();
    let hm = stages
        .iter_mut()
        .find(|s| s["stage"].as_str() == Some("sink.heightmap"))
        .expect("config/sim.toml has a sink.heightmap stage");
    hm["cell_mm"] = toml::Value::Float(1.0);
    std::fs::write(dir.join("sim.toml"), toml::to_string(&sim).unwrap()).unwrap();

    let mut d = read("footscand.toml");
    let daemon = d["daemon"].as_table_mut().unwrap();
    daemon.insert(
        "archive".into(),
        dir.join("archive").display().to_string().into(),
    );
    daemon.insert("scanner_config".into(), "sim.toml".into());
    daemon.remove("token"); // the test's token comes from FOOTSCAND_TOKEN
    daemon.remove("calibration"); // simulated scans use the simulator's true model
    let path = dir.join("footscand.toml");
    std::fs::write(&path, toml::to_string(&d).unwrap()).unwrap();
    path
}

/// The number in a cell's text ("1,234.5 mm" -> 1234.5).
fn number_in(text: &str) -> f64 {
    let t: String = text
        .chars()
        .take_while(|c| c.is_ascii_digit() || matches!(c, '.' | ',' | '-'))
        .filter(|c| *c != ',')
        .collect();
    t.parse()
        .unwrap_or_else(|e| panic!("no number at the start of {text:?}: {e}"))
}

#[test]
fn dashboard_in_headless_chromium_shows_the_scan() {
    chromium::require();
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_configs(tmp.path());
    let d = Daemon::start(&cfg);
    println!("footscand at {}", d.base);

    // A short simulated scan over HTTP, followed to its end.
    let body = r#"{"subject": "chromium-01", "side": "right", "notes": "dashboard test"}"#;
    let r = d
        .request(reqwest::Method::POST, "/api/scans")
        .header("Content-Type", "application/json")
        .body(body)
        .send()
        .expect("POST /api/scans");
    let status = r.status();
    let text = r.text().unwrap();
    assert_eq!(status.as_u16(), 202, "POST /api/scans: {text}");
    let id = serde_json::from_str::<Value>(&text).unwrap()["id"]
        .as_str()
        .expect("POST /api/scans returns an id")
        .to_string();
    let t0 = Instant::now();
    let rec = loop {
        let rec = d.get_json(&format!("/api/scans/{id}"));
        if rec["status"] != "running" {
            break rec;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(300),
            "scan {id} still running after 300 s: {rec}"
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    println!(
        "scan {id}: {} in {:.1} s, {} frames, {} points",
        rec["status"],
        t0.elapsed().as_secs_f64(),
        rec["frames"],
        rec["points"]
    );
    assert_eq!(
        rec["status"], "complete",
        "scan {id} did not complete: {rec}"
    );
    let m = rec["measurements"].clone();
    assert!(m.is_object(), "scan {id} has no measurements: {rec}");
    let hm = image::load_from_memory(&d.get_bytes(&format!("/api/scans/{id}/files/heightmap.png")))
        .expect("heightmap.png decodes")
        .to_rgb8();
    println!("heightmap.png {}x{}", hm.width(), hm.height());
    let line = d.get_json("/api/preview/line");
    let line_rows = line["cols"]
        .as_array()
        .map_or(0, |c| c.iter().filter(|v| v.is_number()).count());
    let preview = image::load_from_memory(&d.get_bytes("/api/preview.png?width=480"))
        .expect("preview.png decodes")
        .to_luma8();
    let preview_mean =
        preview.pixels().map(|p| p.0[0] as f64).sum::<f64>() / preview.pixels().len() as f64;
    println!(
        "last frame {}: line on {line_rows} rows, preview {}x{} mean grey {preview_mean:.1}",
        line["seq"],
        preview.width(),
        preview.height()
    );

    // The page with the token in its fragment, as an operator opens it.
    let url = format!("{}/#token={TOKEN}", d.base);

    // 1. The DOM after the page's requests: the scan in the archive list, the result panel on
    //    it, the measurements the API gave, images and links that carry the token, no error.
    let dom = run_chromium(&url, &tmp.path().join("profile-dom"), &["--dump-dom"]);
    let dom = String::from_utf8(dom).expect("the DOM is UTF-8");
    std::fs::write(
        chromium::target_png("dashboard.png").with_extension("html"),
        &dom,
    )
    .unwrap();
    let error_hidden = attr_of_tag_with(&dom, "id=\"error\"", "hidden");
    assert!(
        error_hidden.is_some(),
        "the page shows an error: {:?}",
        text_of_tag_with(&dom, "id=\"error-text\"")
    );
    let row = tags_with(&dom, &format!("data-scan-id=\"{id}\""))
        .into_iter()
        .find(|t| t.starts_with("<tr"));
    assert_eq!(
        row.and_then(|t| attr(t, "data-status")).as_deref(),
        Some("complete"),
        "scan {id} is not listed as complete in the archive table"
    );
    assert_eq!(
        attr_of_tag_with(&dom, "id=\"result\"", "data-scan-id").as_deref(),
        Some(id.as_str()),
        "the result panel does not show scan {id}"
    );
    // key, decimals shown
    let shown = [
        ("foot_length_mm", 1),
        ("ball_width_mm", 1),
        ("midfoot_width_mm", 1),
        ("heel_width_mm", 1),
        ("arch_height_mm", 1),
        ("arch_index", 3),
        ("axis_angle_deg", 1),
        ("contact_area_mm2", 0),
    ];
    for (key, decimals) in shown {
        let api = m[key]
            .as_f64()
            .unwrap_or_else(|| panic!("measurements.{key} missing from the API: {m}"));
        let needle = format!("data-key=\"{key}\"");
        let value: f64 = attr_of_tag_with(&dom, &needle, "data-value")
            .unwrap_or_else(|| panic!("measurements table has no {key} cell"))
            .parse()
            .unwrap();
        assert_eq!(value, api, "{key}: page {value}, API {api}");
        let text = text_of_tag_with(&dom, &needle).unwrap();
        let tol = 0.5 * 10f64.powi(-decimals) + 1e-9;
        assert!(
            (number_in(&text) - api).abs() <= tol,
            "{key}: the page shows {text:?}, the API says {api}"
        );
        println!("{key}: API {api}, page {text:?}");
    }
    for name in ["heightmap.png", "plantar.png"] {
        let src = format!("/api/scans/{id}/files/{name}?access_token={TOKEN}");
        assert!(dom.contains(&src), "no <img> or link with {src}");
    }

    // 2. The screenshot: laid out as designed at 1280 px.
    let shot = chromium::target_png("dashboard.png");
    let _ = std::fs::remove_file(&shot);
    run_chromium(
        &url,
        &tmp.path().join("profile-shot"),
        &[&format!("--screenshot={}", shot.display())],
    );
    println!("screenshot: {}", shot.display());
    let img = image::open(&shot)
        .expect("the screenshot decodes")
        .to_rgb8();
    assert_eq!((img.width(), img.height()), (WIN_W, WIN_H));

    // Not blank: many colours, the page background around the cards.
    let distinct: std::collections::HashSet<[u8; 3]> = img.pixels().map(|p| p.0).collect();
    let page = Region {
        x0: 0,
        y0: 0,
        x1: WIN_W,
        y1: WIN_H,
    };
    let bg = page.fraction(&img, |p| p == [0xee, 0xf1, 0xf5]);
    println!(
        "{} distinct colours, page background on {:.1} %",
        distinct.len(),
        100.0 * bg
    );
    assert!(
        distinct.len() > 500,
        "screenshot nearly blank: {} colours",
        distinct.len()
    );
    assert!(
        bg > 0.03 && bg < 0.6,
        "page background on {:.1} % of the screenshot",
        100.0 * bg
    );

    // The header band in its colour (style.css --head) across the top.
    let header = Region {
        x0: 0,
        y0: 0,
        x1: WIN_W,
        y1: 40,
    };
    let head = header.fraction(&img, |p| p == [0x17, 0x32, 0x4d]);
    println!("header colour on {:.1} % of the top 40 rows", 100.0 * head);
    assert!(
        head > 0.7,
        "header band: its colour on only {:.1} %",
        100.0 * head
    );

    // The height map and the plantar view (both drawn with the colour ramp) in the result
    // column, at x >= 788 (style.css: 12 px padding, columns 300 and 456 px, 10 px gaps);
    // every stop of the ramp shows there (their colour bars hold the whole ramp) and the ramp
    // shows nowhere else.
    let result = Region {
        x0: 788,
        y0: 46,
        x1: WIN_W,
        y1: WIN_H,
    };
    let elsewhere = Region {
        x0: 0,
        y0: 46,
        x1: 780,
        y1: WIN_H,
    };
    for (k, stop) in RAMP.iter().enumerate() {
        let near = |p: [u8; 3]| dist(p, *stop) <= 16;
        let inside = result.pixels(&img).filter(|p| near(*p)).count();
        let outside = elsewhere.pixels(&img).filter(|p| near(*p)).count();
        println!("ramp stop {k} {stop:?}: {inside} px in the result column, {outside} elsewhere");
        assert!(
            inside >= 20,
            "ramp stop {stop:?}: {inside} px in the result column"
        );
        assert!(
            outside < 50,
            "ramp stop {stop:?} outside the result column: {outside} px"
        );
    }
    let purple = result.fraction(&img, |p| dist(p, RAMP[0]) <= 16);
    println!(
        "sole (lowest ramp colour) on {:.1} % of the result column",
        100.0 * purple
    );
    assert!(
        purple > 0.03,
        "the sole's colour on only {:.1} %",
        100.0 * purple
    );

    // The live laser frame drawn on its canvas (second column): the same mean grey level as
    // the API's preview (the empty canvas is a flat #111), the detected line over it when
    // the frame has one.
    let frame = Region {
        x0: 345,
        y0: 110,
        x1: 755,
        y1: 420,
    };
    let greys: Vec<f64> = frame
        .pixels(&img)
        .filter(|p| p[0] == p[1] && p[1] == p[2])
        .map(|p| p[0] as f64)
        .collect();
    let canvas_mean = greys.iter().sum::<f64>() / greys.len().max(1) as f64;
    let flat = frame.fraction(&img, |p| p == [0x11, 0x11, 0x11]);
    // The overlay is translucent red over grey: red well above green and blue.
    let overlay = frame.fraction(&img, |p| {
        p[0] >= 100 && p[0] as u32 > 2 * p[1] as u32 && p[0] as u32 > 3 * p[2] as u32 / 2
    });
    println!(
        "laser frame: canvas mean grey {canvas_mean:.1} (API preview {preview_mean:.1}), \
         empty-canvas colour on {:.1} %, line overlay on {:.2} %",
        100.0 * flat,
        100.0 * overlay
    );
    assert!(
        (canvas_mean - preview_mean).abs() < 3.0 && flat < 0.5,
        "the canvas does not show the preview frame: mean grey {canvas_mean:.1} against \
         {preview_mean:.1}, {:.1} % empty",
        100.0 * flat
    );
    if line_rows > 100 {
        assert!(
            overlay > 0.0005,
            "the detected line ({line_rows} rows) is not drawn"
        );
    }
}
