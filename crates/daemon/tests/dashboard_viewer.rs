//! The dashboard's 3D view (issue 35 item 2) in Debian's headless Chromium, WebGL on
//! SwiftShader: after one short simulated scan the page opens on that scan's result without a
//! click, loads its model.glb with three.js from the daemon itself (no CDN), and the canvas
//! shows the foot: from the top its image spans the foot's length against its width, from
//! the side its length against its height (the extents read from the .glb's own accessors),
//! with the red landmarks drawn. Screenshots: target/dashboard-viewer-{top,side}.png.

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
    let id = d.start_scan("viewer");
    d.wait_scan_end(Duration::from_secs(240));
    let glb = std::fs::read(d.archive.join(&id).join("model.glb")).expect("the scan's model.glb");
    let ext = glb_extent(&glb);
    println!(
        "model.glb: {} bytes, extent {:.1} x {:.1} x {:.1} mm",
        glb.len(),
        ext[0] * 1e3,
        ext[1] * 1e3,
        ext[2] * 1e3
    );

    let mut b = Browser::launch_with(&tmp.path().join("profile"), 1280, 1800, &WEBGL);
    // No click: the page opens on the newest finished scan, and the view follows it.
    b.open(
        &format!("{}/#token={TOKEN}", d.base),
        &format!("window.footscanViewer && footscanViewer.ready && footscanViewer.id === {id:?}"),
        Duration::from_secs(60),
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

    // The progress line never reads more frames than planned.
    let detail = b.eval("document.getElementById('progress-detail').textContent");
    let text = detail.as_str().unwrap_or("");
    println!("progress: {text}");
    if let Some((a, rest)) = text.split_once(" / ") {
        let n = |s: &str| -> u64 { s.trim().replace(',', "").parse().unwrap_or(0) };
        let planned = rest.split_whitespace().next().unwrap_or("0");
        assert!(n(a.rsplit(' ').next().unwrap()) <= n(planned), "{text}");
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
