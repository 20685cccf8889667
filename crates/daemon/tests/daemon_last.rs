//! footscand returns an adjusted last with a scan: a scanner config whose pipeline ends in
//! `last.adjust` (a real last, read at test time), a whole-foot scan over HTTP, and the last's
//! files listed with their content types and downloadable beside the scan's; the dashboard
//! shows deviation.png when the scan has one (tests/dashboard_chromium.rs covers the page).

mod daemon_support;

use daemon_support::*;
use std::path::PathBuf;
use std::time::Duration;

fn lasts_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    base.join("lasts")
}

#[test]
fn a_scan_with_last_adjust_offers_the_adjusted_last() {
    let dir = tempfile::tempdir().unwrap();
    let (cmd, archive) = command(dir.path(), &Opts::default());
    // The whole foot (0..320 mm at 1 mm a frame) so it is measured whole, then the last.
    let last = lasts_dir().join("Last_Flat_RoundTip.stl");
    assert!(
        last.is_file(),
        "{} missing (set FOOTSCAN_DATA)",
        last.display()
    );
    let cfg = short_scanner_config("")
        .replace("start_mm = 60.0", "start_mm = 0.0")
        .replace("end_mm = 200.0", "end_mm = 320.0")
        + &format!(
            "\n[[pipeline.stages]]\nstage = \"last.adjust\"\nlast = {:?}\nlength_mm = 262.0\n",
            last.display().to_string()
        );
    std::fs::write(dir.path().join("scanner.toml"), cfg).unwrap();
    let d = Footscand::spawn(cmd, archive, None);
    let id = d.start_scan("last-01");
    let end = d.wait_scan_end(Duration::from_secs(120));
    assert_eq!(end["state"], "complete", "{end}\n{}", d.stderr());
    let rec = d.record(&id);
    let arts = rec["artifacts"].as_array().unwrap();
    let kind = |n: &str| {
        arts.iter()
            .find(|a| a["name"] == n)
            .unwrap_or_else(|| panic!("{n} not listed: {arts:?}"))["content_type"]
            .as_str()
            .unwrap()
            .to_string()
    };
    assert_eq!(kind("deviation.png"), "image/png");
    assert_eq!(kind("bottom.igs"), "model/iges");
    assert_eq!(kind("bottom.step"), "model/step");
    assert_eq!(kind("last_adjusted.stl"), "model/stl");
    let r: Value = serde_json::from_slice(&d.download(&id, "adjust.json")).unwrap();
    let after = &r["after"];
    println!("adjust.json after: {after}");
    assert!(after["outline_rms_mm"].as_f64().unwrap() <= 0.3);
    assert!(after["height_rms_mm"].as_f64().unwrap() <= 0.3);
    let png = d.download(&id, "deviation.png");
    assert_eq!(&png[1..4], b"PNG");
    let igs = d.download(&id, "bottom.igs");
    assert!(
        String::from_utf8_lossy(&igs).contains("128"),
        "IGES with a B-spline surface"
    );
}
