//! The printable report (crates/scanner/src/report.rs) read back with Debian's poppler-utils: a simulated
//! scan's `footscan report` PDF is an A4 page whose calibration bar is 100 mm (283.46 pt) in
//! the PDF itself and 100.0 +- 0.5 mm when rendered (pdftoppm at 254 dpi: 10 px a mm), and
//! whose heel-to-toe line is the measured foot length at 1:1.

use std::path::Path;
use std::process::Command;

mod common;

fn tool(name: &str) -> String {
    let p = format!("/usr/bin/{name}");
    assert!(
        Path::new(&p).is_file(),
        "{p} is missing: this test needs Debian's poppler-utils; run scripts/setup.sh"
    );
    p
}

fn run(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap_or_else(|e| panic!("{cmd:?}: {e}"));
    assert!(
        out.status.success(),
        "{cmd:?}: {}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The extent (first, last) of pixels near `rgb` along x and y.
fn extent(img: &image::RgbImage, rgb: [u8; 3]) -> Option<([u32; 2], [u32; 2])> {
    let near = |p: [u8; 3]| (0..3).all(|k| (p[k] as i32 - rgb[k] as i32).abs() <= 40);
    let mut e: Option<([u32; 2], [u32; 2])> = None;
    for (x, y, p) in img.enumerate_pixels() {
        if near(p.0) {
            let (ex, ey) = e.get_or_insert(([x, x], [y, y]));
            ex[0] = ex[0].min(x);
            ex[1] = ex[1].max(x);
            ey[0] = ey[0].min(y);
            ey[1] = ey[1].max(y);
        }
    }
    e
}

#[test]
fn report_pdf_is_printed_at_one_to_one() {
    let (pdftoppm, pdfinfo, pdftotext) = (tool("pdftoppm"), tool("pdfinfo"), tool("pdftotext"));
    // The package's shared default scan (tests/common), read only.
    let tmp = tempfile::tempdir().unwrap();
    let dir = common::default_scan();
    let s = common::summary(dir);
    assert_eq!(s["status"], "complete", "{}", s["reason"]);
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("measurements.json")).unwrap()).unwrap();
    let length = m["foot_length_mm"].as_f64().unwrap();

    let pdf = tmp.path().join("report.pdf");
    let said = run(Command::new(env!("CARGO_BIN_EXE_footscan"))
        .args(["report", "--scan"])
        .arg(dir)
        .arg("--out")
        .arg(&pdf));
    println!("{}", said.trim());

    // The page: A4, one page.
    let info = run(Command::new(&pdfinfo).arg(&pdf));
    assert!(info.contains("Pages:           1"), "{info}");
    assert!(info.contains("595.276 x 841.89 pts (A4)"), "{info}");
    // The bar in PDF units: a filled rectangle 2.5 mm x 100 mm = 7.09 x 283.46 pt.
    let bytes = std::fs::read(&pdf).unwrap();
    let content = String::from_utf8_lossy(&bytes);
    let bar: Vec<Vec<f64>> = content
        .lines()
        .filter_map(|l| l.strip_suffix(" re"))
        .map(|l| l.split(' ').map(|v| v.parse::<f64>().unwrap()).collect())
        .filter(|v: &Vec<f64>| v[3] > 100.0)
        .collect();
    assert_eq!(bar.len(), 1, "one long rectangle: {bar:?}");
    println!("bar in the PDF: {:?} pt", bar[0]);
    assert!((bar[0][3] - 283.4646).abs() < 0.01, "{:?}", bar[0]);
    // The words that go with it, and the measurements with their definitions.
    let words = run(Command::new(&pdftotext).arg(&pdf).arg("-"));
    for w in [
        "is 100 mm long",
        "check the bar with a ruler",
        &format!("Foot length: {length:.1} mm"),
        "Ball width, MT1-MT5",
        "EU 40",
        "Mondopoint 250",
        "Arch index",
        "right foot",
    ] {
        assert!(words.contains(w), "{w:?} not in the report:\n{words}");
    }

    // Both feet (the same scan twice: the layout, not the foot, is under test): A3
    // landscape with the comparison and the same bar.
    let both = tmp.path().join("both.pdf");
    run(Command::new(env!("CARGO_BIN_EXE_footscan"))
        .args(["report", "--left"])
        .arg(dir)
        .arg("--right")
        .arg(dir)
        .arg("--out")
        .arg(&both));
    let info = run(Command::new(&pdfinfo).arg(&both));
    assert!(info.contains("1190.55 x 841.89 pts (A3)"), "{info}");
    let words = run(Command::new(&pdftotext).arg(&both).arg("-"));
    for w in [
        "Foot length (mm)",
        "is 100 mm long",
        "Ball width MT1-MT5 (mm)",
    ] {
        assert!(
            words.contains(w),
            "{w:?} not in the two feet's report:\n{words}"
        );
    }

    // Rendered at 254 dpi (10 px a mm): the bar's length and the foot's length in pixels.
    let png = tmp.path().join("page");
    run(Command::new(&pdftoppm)
        .args(["-r", "254", "-png", "-singlefile"])
        .arg(&pdf)
        .arg(&png));
    let img = image::open(png.with_extension("png")).unwrap().to_rgb8();
    // 210 x 297 mm at 10 px a mm (pdftoppm rounds the page up by a pixel).
    assert!(
        img.width().abs_diff(2100) <= 1 && img.height().abs_diff(2970) <= 1,
        "{} x {} px",
        img.width(),
        img.height()
    );
    let (bx, by) = extent(&img, [0, 0, 204]).expect("the blue bar is on the page");
    let bar_mm = (by[1] - by[0] + 1) as f64 / 10.0;
    let (lx, ly) = extent(&img, [217, 0, 0]).expect("the red length line is on the page");
    // The line ends in 2 mm squares at the heel point and the end of the length.
    let line_mm = (ly[1] - ly[0] + 1) as f64 / 10.0 - 2.0;
    println!(
        "rendered: bar {bar_mm:.1} mm ({} px wide), heel to toe {line_mm:.1} mm (measured {length:.1} mm, {} px wide)",
        bx[1] - bx[0] + 1,
        lx[1] - lx[0] + 1
    );
    assert!((bar_mm - 100.0).abs() <= 0.5, "bar {bar_mm} mm");
    assert!(
        (line_mm - length).abs() <= 0.5,
        "{line_mm} mm on paper for {length} mm"
    );
}
