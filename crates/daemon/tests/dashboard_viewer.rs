//! The dashboard's 3D view (issue 35 item 2) in Debian's headless Chromium, WebGL on
//! SwiftShader: after one short simulated scan the page opens on that scan's result without a
//! click, loads its model.glb with three.js from the daemon itself (no CDN), and the canvas
//! shows the foot: from the top its image spans the foot's length against its width, from
//! the side its length against its height (the extents read from the .glb's own accessors),
//! with the red landmarks drawn. Screenshots: target/dashboard-viewer-{top,side}.png.
//! The page, open while the scan runs, never shows more frames than planned (every text of
//! its progress line recorded); the time from opening the page to the foot drawn is printed.

mod daemon_support;

use daemon_support::chromium::{self, Browser, WEBGL};
use daemon_support::{Footscand, Opts};
use std::time::Duration;

const TOKEN: &str = "viewer-test-token-0123456789";
/// view.js: BACKGROUND and LANDMARK.
const BACKGROUND: [u8; 3] = [0xf7, 0xf7, 0xf5];
const LANDMARK: [u8; 3] = [0xd0, 0x10, 0x10];

/// The foot's extent (x, y, z in glTF metres) from the .glb's POSITION accessor of node
/// "foot" (min/max are required there by the glTF specification).
fn glb_extent(bytes: &[u8]) -> [f64; 3] {
    let jl = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + jl]).unwrap();
    let node = doc["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|n| n["name"] == "foot")
        .expect("a node named foot");
    let mesh = &doc["meshes"][node["mesh"].as_u64().unwrap() as usize];
    let acc = &doc["accessors"][mesh["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap() as usize];
    let f = |k: &str, d: usize| acc[k][d].as_f64().unwrap();
    [0, 1, 2].map(|d| f("max", d) - f("min", d))
}

/// Pixels unlike the background: their bounding box (w, h) and share of the image; and the
/// landmark-red pixels.
fn coverage(img: &image::RgbImage) -> (u32, u32, f64, usize) {
    let (mut x0, mut y0, mut x1, mut y1, mut n, mut red) = (u32::MAX, u32::MAX, 0, 0, 0usize, 0);
    let (w, h) = img.dimensions();
    for (x, y, p) in img.enumerate_pixels() {
        // The figure's frame is not the view.
        if x < 4 || y < 4 || x + 4 >= w || y + 4 >= h {
            continue;
        }
        let d = (0..3)
            .map(|c| (p[c] as i32 - BACKGROUND[c] as i32).abs())
            .max()
            .unwrap();
        let [r, g, b] = p.0.map(i32::from);
        // The foot's shades of skin, not the red landmarks and length line or the blue
        // ball-width line drawn over it.
        let skin = r >= g && g >= b - 8 && r - g < 70;
        if d > 24 && skin {
            n += 1;
            x0 = x0.min(x);
            y0 = y0.min(y);
            x1 = x1.max(x);
            y1 = y1.max(y);
        }
        if (0..3).all(|c| (p[c] as i32 - LANDMARK[c] as i32).abs() < 40) {
            red += 1;
        }
    }
    assert!(n > 0, "the canvas shows nothing but the background");
    let share = n as f64 / (img.width() * img.height()) as f64;
    (x1 - x0 + 1, y1 - y0 + 1, share, red)
}

#[test]
fn the_foot_in_3d_from_the_top_and_the_side() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Footscand::start(
        tmp.path(),
        Opts {
            token: Some(TOKEN),
            ..Opts::default()
        },
    );
    // The page open before the scan starts: its progress line watched all through the scan
    // (every text it shows, from a MutationObserver), beside the event stream's counts.
    let mut b = Browser::launch_with(&tmp.path().join("profile"), 1280, 1800, &WEBGL);
    b.open(
        &format!("{}/#token={TOKEN}", d.base),
        "document.getElementById('progress-detail') && window.footscanViewer",
        Duration::from_secs(60),
    );
    b.eval(
        "(() => { const e = document.getElementById('progress-detail'); window.seenProgress = []; \
         new MutationObserver(() => seenProgress.push(e.textContent)).observe(e, \
         { childList: true, characterData: true, subtree: true }); })()",
    );
    let id = d.start_scan("viewer");
    let events = d.follow(&id);
    let (mut raw_max, mut planned) = (0, 0);
    for (_, v) in events
        .iter()
        .filter(|(n, v)| n == "progress" && v["id"] == id.as_str())
    {
        raw_max = raw_max.max(v["frames"].as_u64().unwrap_or(0));
        planned = planned.max(v["expected_frames"].as_u64().unwrap_or(0));
    }
    let seen = b.eval("window.seenProgress");
    let seen: Vec<&str> = seen
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    let n = |s: &str| -> u64 { s.trim().replace(',', "").parse().unwrap_or(u64::MAX) };
    let counts: Vec<(u64, u64)> = seen
        .iter()
        .filter_map(|t| {
            let (a, rest) = t.split_once(" / ")?;
            let shown = n(a.rsplit(' ').next().unwrap());
            Some((shown, n(rest.split_whitespace().next()?)))
        })
        .collect();
    println!(
        "progress: {} texts shown, {} with a count against the plan, the last {:?}; the event \
         stream's largest count {raw_max} of {planned} planned",
        seen.len(),
        counts.len(),
        seen.last()
    );
    assert!(
        counts.len() >= 3,
        "the page showed no running count: {seen:?}"
    );
    for (shown, plan) in &counts {
        assert!(
            shown <= plan,
            "the page read {shown} of {plan} planned frames"
        );
        assert_eq!(*plan, planned, "the page's plan is the daemon's");
    }
    let glb = daemon_support::archived_file(&d.archive, &id, "model.glb");
    let ext = glb_extent(&glb);
    println!(
        "model.glb: {} bytes, extent {:.1} x {:.1} x {:.1} mm",
        glb.len(),
        ext[0] * 1e3,
        ext[1] * 1e3,
        ext[2] * 1e3
    );

    // No click: the page opened anew shows the newest finished scan, and the view follows it.
    // (Another URL, so the page loads anew rather than moving to its own fragment.)
    b.open(
        &format!("{}/?again#token={TOKEN}", d.base),
        &format!("window.footscanViewer && footscanViewer.ready && footscanViewer.id === {id:?}"),
        Duration::from_secs(60),
    );
    let at = b.eval("[footscanViewer.readyAt, footscanViewer.loadMs]");
    println!(
        "the foot drawn {:.0} ms after the page's navigation started (model.glb fetched and \
         parsed in {:.0} ms)",
        at[0].as_f64().unwrap(),
        at[1].as_f64().unwrap()
    );
    let result = b.eval(
        "({ id: document.getElementById('result').dataset.scanId, \
           empty: document.getElementById('result-empty').hidden })",
    );
    assert_eq!(result["id"], id.as_str(), "{result}");
    assert_eq!(
        result["empty"], true,
        "'No finished scan yet' still shown: {result}"
    );
    let st = b.eval(
        "({ms: footscanViewer.loadMs, tri: footscanViewer.triangles, \
          marks: footscanViewer.landmarks, lines: footscanViewer.lines, err: footscanViewer.error})",
    );
    println!("viewer: {st}");
    assert!(st["err"].is_null(), "{st}");
    assert!(st["tri"].as_f64().unwrap() > 1000.0, "{st}");
    for m in ["heel_point", "toe_tip", "mt1_head", "mt5_head"] {
        assert!(
            st["marks"].as_array().unwrap().iter().any(|v| v == m),
            "{m}: {st}"
        );
    }
    for l in ["length", "ball_width"] {
        assert!(
            st["lines"].as_array().unwrap().iter().any(|v| v == l),
            "{l}: {st}"
        );
    }

    // From the top: the image spans length against width; from the side, against height.
    // The camera frames the whole foot: its image spans 40 to 95 % of the canvas's width.
    for (view, across, tol, min_share) in [("top", 2usize, 0.2, 0.10), ("side", 1, 0.3, 0.01)] {
        b.eval(&format!("footscanViewer.setView({view:?})"));
        std::thread::sleep(Duration::from_millis(300));
        let path = chromium::target_png(&format!("dashboard-viewer-{view}.png"));
        let img = b.screenshot(&path, Some("viewer"));
        let (w, h, share, red) = coverage(&img);
        let want = ext[0] / ext[across];
        let got = w as f64 / h as f64;
        println!(
            "{view}: foot {w} x {h} px ({:.1} % of the canvas), aspect {got:.2} (model {want:.2}), {red} landmark pixels",
            100.0 * share
        );
        assert!(
            (got / want - 1.0).abs() < tol,
            "{view}: the foot's image is {w} x {h} px, aspect {got:.2}; the model's is {want:.2}"
        );
        assert!(
            share > min_share,
            "{view}: the foot covers {share:.3} of the view"
        );
        let span = w as f64 / img.width() as f64;
        assert!(
            (0.4..0.95).contains(&span),
            "{view}: the foot spans {span:.2} of the canvas's width"
        );
        assert!(red > 10, "{view}: no landmark drawn");
    }
}

/// The target measured, not asserted (a study: `cargo test -p footscand --test
/// dashboard_viewer -- --ignored --nocapture`): the default simulated scan (config/sim.toml
/// as shipped, 641 frames over 0-320 mm), its model.glb's size, and how long after the page's
/// navigation start the view has drawn its foot, in three page loads.
#[test]
#[ignore]
fn the_default_scan_in_3d_timed() {
    let tmp = tempfile::tempdir().unwrap();
    let (cmd, archive) = daemon_support::command(
        tmp.path(),
        &Opts {
            token: Some(TOKEN),
            ..Opts::default()
        },
    );
    let sim = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/sim.toml"),
    )
    .unwrap();
    std::fs::write(tmp.path().join("scanner.toml"), sim).unwrap();
    let d = Footscand::spawn(cmd, archive, Some(TOKEN));
    let id = d.start_scan("default");
    let end = d.wait_scan_end(Duration::from_secs(600));
    println!("scan: {} frames, {}", end["frames"], end["state"]);
    let glb = daemon_support::archived_file(&d.archive, &id, "model.glb");
    println!("default scan model.glb: {} bytes", glb.len());
    let mut b = Browser::launch_with(&tmp.path().join("profile"), 1280, 1800, &WEBGL);
    for run in 0..3 {
        b.open(
            &format!("{}/?run={run}#token={TOKEN}", d.base),
            &format!(
                "window.footscanViewer && footscanViewer.ready && footscanViewer.id === {id:?}"
            ),
            Duration::from_secs(60),
        );
        let at =
            b.eval("[footscanViewer.readyAt, footscanViewer.loadMs, footscanViewer.triangles]");
        println!(
            "run {run}: foot drawn {:.0} ms after navigation start; model.glb fetched and parsed \
             in {:.0} ms; {} triangles",
            at[0].as_f64().unwrap(),
            at[1].as_f64().unwrap(),
            at[2]
        );
    }
}
