//! The detectors on real frames of other scanners (MANIFEST.csv under $FOOTSCAN_DATA/frames or
//! ../shared/data/frames, read in place). Without ground truth: a line on a flat board is
//! straight, and a laser-off frame holds no line. The bounds are what the default detector
//! (bezier-plus, automatic threshold, the manifest's channel) meets today; where it falls short
//! of the targets (every visible row found, the straightest of all detectors) the figure is
//! asserted as it stands so a regression shows.

use footscan_bench::real::{all_detectors, default_data_dir, run, table};

#[test]
fn default_detector_on_real_flat_boards_and_laser_off_frames() {
    let dir = default_data_dir();
    if !dir.join("MANIFEST.csv").is_file() {
        eprintln!("skipped: no real frames at {}", dir.display());
        return;
    }
    let (rows, spreads) = run(&dir, &all_detectors()).unwrap();
    println!("{}", table(&rows, &spreads));
    let mut regions = 0;
    for r in rows
        .iter()
        .filter(|r| r.detector == "bezier-plus" && r.region != "off")
    {
        regions += 1;
        let peers: Vec<_> = rows
            .iter()
            .filter(|p| p.frame == r.frame && p.region == r.region && p.background == r.background)
            .collect();
        let best = peers
            .iter()
            .map(|p| p.resid_px)
            .filter(|v| v.is_finite())
            .fold(f64::INFINITY, f64::min);
        // Straightness: within 35 % of the straightest detector (target 5 %; 28 % on the
        // ciclop board 290:470 without its laser-off frame, where steger is straighter: 34 %
        // before the window was clipped at a textured board's level), below 0.7 px.
        assert!(
            r.resid_px <= 1.35 * best && r.resid_px < 0.7,
            "{} {}: bezier-plus {:.4} px, best {best:.4}",
            r.frame,
            r.region,
            r.resid_px
        );
        // Rows found where the line is visible: the 98 % target (worst 98.2 %, with the
        // line's continuity deciding ambiguous rows).
        let floor = 98.0;
        assert!(
            r.found_pct >= floor,
            "{} {}: {:.1} % of visible rows",
            r.frame,
            r.region,
            r.found_pct
        );
    }
    assert!(regions >= 10, "{regions} flat regions");
    // Laser-off frames: no row of a colour-difference channel holds a line (the target; a lone
    // row is a speck, not a line); the plain red channel of textured scenes does not separate
    // (reported, not asserted).
    for r in rows
        .iter()
        .filter(|r| r.region == "off" && r.channel.contains('-'))
    {
        assert_eq!(r.found, 0, "{} {}: {} rows", r.frame, r.detector, r.found);
    }
    for s in spreads.iter().filter(|s| s.detector == "bezier-plus") {
        assert!(s.spread_px < 1.0, "{s:?}");
    }
}
