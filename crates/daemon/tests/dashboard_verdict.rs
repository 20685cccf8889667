//! The quality gate's verdicts on the dashboard, in Debian's headless Chromium: footscand
//! scans twice into one archive (a short simulated scan with 5 % of the frames dropped, then
//! one with 20 mm of the travel lost), and the page must show the first amber ("complete with
//! warnings") and the second red with "rescan" in words, not green. The screenshot is kept at
//! target/dashboard-verdict.png for people to look at.

mod daemon_support;

use daemon_support::{chromium, command, short_scanner_config, Footscand, Opts};
use std::path::Path;
use std::time::Duration;

const WIN_W: u32 = 1280;
/// Tall enough for the archive table below the result panel (and, since issue 35, the 3D
/// view above its pictures; since issue 38, the insole card below the last's).
const WIN_H: u32 = 3600;
/// style.css: --warn (amber) and --bad (red).
const AMBER: [u8; 3] = [0xe0, 0xa8, 0x00];
const RED: [u8; 3] = [0xa4, 0x16, 0x1a];

/// Start footscand on `archive` scanning the short simulated travel with `noise` added to
/// [sim.noise]; gaps up to 6 mm bridged (three frames in a row dropped at 1 mm steps still
/// bridge, so the 5 % scan is never a rescan by chance).
fn daemon(dir: &Path, archive: &Path, noise: &str) -> Footscand {
    let o = Opts {
        archive: Some(archive.to_owned()),
        ..Opts::default()
    };
    let (cmd, archive) = command(dir, &o);
    let cfg = short_scanner_config("")
        .replace("whole_foot = false", "whole_foot = false\nbridge_mm = 6.0")
        .replace("speckle = 0.15", &format!("speckle = 0.15\n{noise}"));
    assert!(cfg.contains(noise) && cfg.contains("bridge_mm = 6.0"));
    std::fs::write(dir.join("scanner.toml"), cfg).unwrap();
    Footscand::spawn(cmd, archive, None)
}

/// One scan to its end; (id, status, reason).
fn scan(d: &Footscand, subject: &str) -> (String, String, String) {
    let id = d.start_scan(subject);
    d.wait_scan_end(Duration::from_secs(240));
    let r = d.record(&id);
    let out = (
        id,
        r["status"].as_str().unwrap().to_string(),
        r["reason"].as_str().unwrap_or("").to_string(),
    );
    println!("scan {}: {} ({})", out.0, out.1, out.2);
    out
}

/// The dashboard in Chromium at this test's window size with `extra`; its stdout.
fn run_chromium(url: &str, profile: &Path, extra: &str) -> Vec<u8> {
    let flags = ["--hide-scrollbars", "--virtual-time-budget=5000", extra];
    chromium::run(
        url,
        profile,
        (WIN_W, WIN_H),
        &flags,
        Duration::from_secs(120),
    )
}

/// The start tag (from `<` to `>`) of the first element whose start tag holds `needle`.
fn tag_with<'a>(html: &'a str, needle: &str) -> Option<&'a str> {
    let at = html.find(needle)?;
    let start = html[..at].rfind('<')?;
    Some(&html[start..at + html[at..].find('>')?])
}

/// The text of the element starting at the first start tag holding `needle`, tags removed,
/// up to its end tag `</name>`.
fn text_with(html: &str, needle: &str, name: &str) -> Option<String> {
    let at = html.find(needle)?;
    let open_end = at + html[at..].find('>')? + 1;
    let close = open_end + html[open_end..].find(&format!("</{name}>"))?;
    let mut text = String::new();
    let mut in_tag = false;
    for c in html[open_end..close].chars() {
        match c {
            '<' => in_tag = true,
            '>' => in_tag = false,
            c if !in_tag => text.push(c),
            _ => {}
        }
    }
    Some(text.replace("&amp;", "&"))
}

/// The archive table's row of scan `id` (from `<tr` to `</tr>`).
fn row<'a>(html: &'a str, id: &str) -> &'a str {
    let at = html
        .find(&format!("<tr data-scan-id=\"{id}\""))
        .unwrap_or_else(|| panic!("scan {id} is not in the archive table"));
    &html[at..at + html[at..].find("</tr>").unwrap()]
}

fn near(p: [u8; 3], c: [u8; 3]) -> bool {
    (0..3).all(|k| (p[k] as i32 - c[k] as i32).abs() <= 12)
}

#[test]
fn dashboard_shows_warnings_amber_and_rescan_red() {
    chromium::require();
    let tmp = tempfile::tempdir().unwrap();
    let archive = tmp.path().join("archive");

    let mut d = daemon(tmp.path(), &archive, "drop_rate = 0.05");
    let (warned, status, reason) = scan(&d, "p-warn");
    assert_eq!(status, "complete with warnings", "{reason}");
    assert!(reason.contains("frames dropped") && reason.contains("bridged"));
    d.terminate(Duration::from_secs(20));
    let d = daemon(tmp.path(), &archive, "drop_x_mm = [[150.0, 170.0]]");
    let (failed, status, reason) = scan(&d, "p-gap");
    assert_eq!(status, "rescan", "{reason}");
    assert!(reason.contains("mm of the foot not scanned"), "{reason}");

    // 1. The DOM: both rows with their verdict badges; the result panel (the newest scan)
    //    red, saying rescan before the patient leaves, with the reason.
    let dom = run_chromium(&d.url("/"), &tmp.path().join("p1"), "--dump-dom");
    let dom = String::from_utf8(dom).unwrap();
    std::fs::write(
        chromium::target_png("dashboard-verdict.png").with_extension("html"),
        &dom,
    )
    .unwrap();
    let badge = |id: &str| {
        let r = row(&dom, id);
        let t = tag_with(r, "class=\"badge").expect("a badge in the row");
        (
            t.to_string(),
            text_with(r, "class=\"badge", "span").unwrap(),
        )
    };
    let (w_tag, w_text) = badge(&warned);
    assert!(
        w_tag.contains("st-complete-with-warnings") && w_text == "complete with warnings",
        "{w_tag} {w_text}"
    );
    let (f_tag, f_text) = badge(&failed);
    assert!(
        f_tag.contains("st-rescan") && f_text.contains("rescan"),
        "{f_tag} {f_text}"
    );
    let result = tag_with(&dom, "id=\"result-id\"").unwrap();
    let said = text_with(&dom, "id=\"result-id\"", "span").unwrap();
    println!("result panel: {said}");
    assert!(result.contains("st-rescan"), "{result}");
    assert!(
        said.contains("failed: rescan before the patient leaves"),
        "{said}"
    );
    let warn = text_with(&dom, "id=\"result-warnings\"", "p").unwrap();
    assert!(warn.contains("mm of the foot not scanned"), "{warn}");

    // 2. The screenshot: amber and red where the verdicts are, and no green badge (the page
    //    has no complete scan to show).
    let png = chromium::target_png("dashboard-verdict.png");
    let _ = std::fs::remove_file(&png);
    run_chromium(
        &d.url("/"),
        &tmp.path().join("p2"),
        &format!("--screenshot={}", png.display()),
    );
    let img = image::open(&png).expect("the screenshot decodes").to_rgb8();
    let count = |c: [u8; 3]| img.pixels().filter(|p| near(p.0, c)).count();
    let (amber, red, green) = (count(AMBER), count(RED), count([0x17, 0x66, 0x3a]));
    println!(
        "screenshot {}: {amber} amber, {red} red, {green} green pixels",
        png.display()
    );
    assert!(amber > 200, "no amber badge on the page ({amber} pixels)");
    assert!(red > 200, "no red verdict on the page ({red} pixels)");
}
