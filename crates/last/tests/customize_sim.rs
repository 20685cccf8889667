//! Customized lasts from simulated feet (lengths 230, 260, 290 mm, both sides): the foot's
//! measurements against the simulator's analytic truth, every rule met on the output mesh
//! cut independently, the last closed; and the real FIND foot's characteristic points
//! against the landmarks its authors annotated.

use footscan_geom::mesh::TriMesh;
use footscan_last::customize::rules::RuleSet;
use footscan_last::customize::{customize, foot_in_frame, write_outputs, Inputs};
use footscan_sim::foot::{Foot, FootParams, MeshResolution, Side};

fn sim_foot(l: f64, side: Side) -> (TriMesh, footscan_sim::foot::FootMeshTruth) {
    let f = Foot::new(FootParams {
        length_mm: l,
        side,
        ..FootParams::default()
    })
    .unwrap();
    let m = f.mesh(MeshResolution::default());
    (m.tri_mesh(), m.truth)
}

/// The lowest vertex of a mesh within 2 mm of the plane at `x` along the axis.
fn lowest_near(m: &TriMesh, x: f64) -> f64 {
    m.vertices
        .iter()
        .filter(|v| (v.x - x).abs() < 2.0)
        .map(|v| v.z)
        .fold(f64::MAX, f64::min)
}

/// The clinic's input for the default simulated scan (a 250 mm right foot): its plantar
/// figures and the girths a fitter would tape (the simulator's, rounded).
fn scan_of_250_mm_foot() -> (
    footscan_last::customize::clinic::Plantar,
    footscan_last::customize::clinic::TapeGirths,
) {
    use footscan_geom::Side;
    use footscan_last::customize::clinic::{Plantar, TapeGirths};
    let plantar = Plantar {
        side: Side::Right,
        length: 250.0,
        ball_width: 99.99,
        waist_width: 58.42,
        heel_width: 62.5,
        footprint: Vec::new(),
    };
    let girths = TapeGirths::checked(260.0, 248.0, 367.0, 200.5).unwrap();
    (plantar, girths)
}

#[test]
fn simulated_feet() {
    let rules = RuleSet::default_rules();
    let inp = Inputs::default();
    for l in [230.0, 260.0, 290.0] {
        for side in [Side::Right, Side::Left] {
            let (m, truth) = sim_foot(l, side);
            let (foot, frame) = foot_in_frame(m, "sim").unwrap();
            let c = customize(foot, frame, &rules, &inp).unwrap();
            let fm = &c.foot_measures;
            println!(
                "L {l} {side:?}: length {:.3} (truth {:.3}) ball width {:.3} ({:.3}) heel width {:.3} ({:.3}) evals {}",
                fm.length, truth.length_mm, fm.ball_width, truth.ball_width_mm, fm.heel_width, truth.heel_width_mm, c.evaluations
            );
            for r in &c.rules {
                println!(
                    "  {:5} {:16} foot {:7.2} target {:7.2} last {:7.2} err {:+.3}",
                    r.rule, r.quantity, r.foot_mm, r.target_mm, r.last_mm, r.error_mm
                );
            }
            for f in &c.fits {
                println!(
                    "  fit {:16} {:4} pts {:3} ctrl max {:.4} mm",
                    f.curve, f.data_points, f.control_points, f.max_error_mm
                );
            }
            println!("  clearance {}", c.clearance.summary());
            assert!((fm.length - truth.length_mm).abs() < 0.5, "length");
            // Where the rules say the foot must fit (heel seat, midfoot, toe box) it does,
            // within FIT_TOL_MM. Measured before this held: midfoot -0.9 to -1.0 mm (the
            // upper widening widened the plan waist and the waist scale went below 1 to
            // give it back, pressing the arch's wall), toe box -1.15 to -1.48 mm (the back
            // of the hallux rose between two stations, under the ruling between their
            // rings), heel seat -2.3 mm on the 230 mm foot under an older field.
            // A simulated foot stands on the glass from heel to ball: no curve under an arch
            // to raise its last by (the real feet's midfoot is 2-9 mm up,
            // tests/last_customize.rs).
            assert!(c.bottom_curve.is_none(), "bottom curve on a standing foot");
            for name in ["heel seat", "midfoot", "toe box"] {
                let r = c.clearance.region(name).unwrap();
                assert!(r.vertices > 0 && r.met(), "{name} {r:?}");
            }
            assert!(
                c.clearance.must_fit_margin_mm >= -footscan_last::customize::FIT_TOL_MM,
                "{}",
                c.clearance.summary()
            );
            // The toe is round in plan: the last's bottom 2 mm behind its end is under half
            // as wide as at the foot's toe tip (the stretched toes' hull ended square: 33.6 of 56.7 mm on the 230 mm foot).
            let bottom_width = |x: f64| {
                let (lo, hi) = c
                    .last
                    .vertices
                    .iter()
                    .filter(|v| v.z < 3.0 && (v.x - x).abs() < 1.0)
                    .fold((f64::MAX, f64::MIN), |(a, b), v| (a.min(v.y), b.max(v.y)));
                hi - lo
            };
            let end = c.last.bbox().max.x;
            let (at_tip, near_end) = (bottom_width(fm.a.x), bottom_width(end - 2.0));
            println!("  toe: bottom {at_tip:.1} mm wide at the foot's tip, {near_end:.1} mm 2 mm from the end");
            assert!(
                near_end < 0.5 * at_tip,
                "square toe: {near_end:.1} of {at_tip:.1} mm"
            );
            for r in &c.rules {
                assert!(r.met, "{} {} err {}", r.rule, r.quantity, r.error_mm);
            }
            if l == 260.0 {
                let dir = std::path::Path::new("/tmp/customize_sim").join(format!("{side:?}"));
                write_outputs(&c, &inp, &dir).unwrap();
                // The glTF outputs: the last, and the foot inside it in one frame (the foot's
                // box within the last's but for 5 mm), the foot red where it stands out.
                assert!(dir.join("last.glb").is_file());
                let (_, proud) =
                    footscan_geom::mesh::foot_in_last_glb(&c.foot, "foot", &c.last).unwrap();
                let (fb, lb) = (c.foot.bbox(), c.last.bbox());
                println!(
                    "  foot_in_last.glb: the foot stands out of the last by {proud:.2} mm at most"
                );
                for d in 0..3 {
                    assert!(
                        fb.min[d] > lb.min[d] - 5.0 && fb.max[d] < lb.max[d] + 5.0,
                        "axis {d}: foot {:?}..{:?}, last {:?}..{:?}",
                        fb.min,
                        fb.max,
                        lb.min,
                        lb.max
                    );
                }
                let bytes = std::fs::read(dir.join("foot_in_last.glb")).unwrap();
                let jl = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
                let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + jl]).unwrap();
                assert_eq!(doc["nodes"][0]["name"], "foot");
                assert_eq!(doc["nodes"][1]["name"], "last");
                assert_eq!(doc["materials"][1]["alphaMode"], "BLEND");
            }
        }
    }
}

/// A foot whose midfoot does not reach the glass, as a foot scanned without weight on it:
/// the simulated 260 mm foot with its midfoot lifted by a known bump (6 mm at its top). The
/// curve under the arch stays under the bump and rises most of it, the last's bottom follows
/// it, every rule is met and the foot fits where the rules say it must to within 0.45 mm.
/// (With a flat bottom filling the gap the real feet's instep stood 6.6 mm out;
/// docs/method.md 10.5.)
#[test]
fn lifted_midfoot_gets_a_bottom_that_follows_it() {
    let rules = RuleSet::default_rules();
    let inp = Inputs::default();
    let (mut m, _) = sim_foot(260.0, Side::Right);
    let bb = m.bbox();
    let len = bb.max.x - bb.min.x;
    let bump = |t: f64| {
        if (0.25..=0.6).contains(&t) {
            6.0 * (std::f64::consts::PI * (t - 0.25) / 0.35).sin().powi(2)
        } else {
            0.0
        }
    };
    for v in &mut m.vertices {
        v.z += bump((v.x - bb.min.x) / len);
    }
    let (foot, frame) = foot_in_frame(m, "lifted").unwrap();
    let fb = foot.bbox();
    let c = customize(foot, frame, &rules, &inp).unwrap();
    let curve = c
        .bottom_curve
        .as_ref()
        .expect("a curve under the lifted midfoot");
    // The frame's x runs along the foot from its heel point, within a millimetre of the
    // world's here (no yaw). The curve never lifts the foot's sections off the glass (it
    // stays under the bump), and it rises most of the bump's height: on the bump's flanks
    // and top it lags by the smoothing (the lowest within 8 mm, averaged over 8 mm).
    let flen = fb.max.x - fb.min.x;
    let over = curve
        .iter()
        .map(|p| p[1] - bump((p[0] - fb.min.x) / flen))
        .fold(f64::MIN, f64::max);
    let (xr, rise) = curve
        .iter()
        .map(|p| (p[0], p[1]))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .unwrap();
    println!("  lifted midfoot: curve rises {rise:.2} mm at x {xr:.1}, {over:.3} mm over the bump");
    assert!(over < 0.2, "bottom curve {over:.3} mm over the bump");
    assert!(
        rise > 4.0,
        "bottom curve rises {rise:.2} mm under a 6 mm bump"
    );
    let low = lowest_near(&c.last, xr);
    println!("  the last's bottom there: {low:.2} mm");
    assert!((low - rise).abs() < 1.0, "last's bottom at {low:.2} mm");
    for r in &c.rules {
        assert!(r.met, "{} {}: {:+.3} mm", r.rule, r.quantity, r.error_mm);
    }
    println!("  clearance {}", c.clearance.summary());
    // Measured -0.34 mm in the midfoot (the standing foot: -0.05): the curve lags the bump
    // by 1.1 mm at its top, so the laid-flat midfoot still hangs that far over the flat
    // bottom's fill. The must-fit target (FIT_TOL_MM) is not met here yet; this bounds what
    // is.
    assert!(
        c.clearance.must_fit_margin_mm >= -0.45,
        "{}",
        c.clearance.summary()
    );
}

/// The clinic path with a stock last that has toe spring and a raised heel, as shop lasts
/// do: the simulator's 240 mm foot's last raised by a known bottom curve (20 mm at the heel
/// end falling to 0 at 0.3 L, 12 mm toe spring rising from 0.7 L). It is laid flat by the
/// curve it finds, customized for a 250 mm foot (every rule met, as with the flat stock
/// last), and the output raised back: its bottom under the tread stays on the glass, and
/// the heel and toe stand where the stock's curve puts them.
#[test]
fn clinic_stock_last_with_toe_spring_and_heel() {
    use footscan_last::customize::clinic::customize_stock;
    let rules = RuleSet::default_rules();
    let inp = Inputs::default();
    let (m, _) = sim_foot(240.0, Side::Right);
    let (foot, frame) = foot_in_frame(m, "sim").unwrap();
    let flat = customize(foot, frame, &rules, &inp).unwrap().last;
    let bb = flat.bbox();
    let len = bb.max.x - bb.min.x;
    let raise = |x: f64| {
        let t = (x - bb.min.x) / len;
        if t < 0.3 {
            20.0 * (1.0 - t / 0.3)
        } else if t > 0.7 {
            12.0 * ((t - 0.7) / 0.3).powi(2)
        } else {
            0.0
        }
    };
    let mut stock = flat.clone();
    for v in &mut stock.vertices {
        v.z += raise(v.x);
    }
    let (plantar, girths) = scan_of_250_mm_foot();
    let c = customize_stock(stock, "raised stock", &plantar, &girths, &rules, &inp).unwrap();
    for r in &c.rules {
        println!(
            "  {:5} {:16} foot {:7.2} target {:7.2} last {:7.2} err {:+.3}",
            r.rule, r.quantity, r.foot_mm, r.target_mm, r.last_mm, r.error_mm
        );
        assert!(r.met, "{} {}: {:+.3} mm", r.rule, r.quantity, r.error_mm);
    }
    let curve = c
        .bottom_curve
        .as_ref()
        .expect("the stock last was laid flat");
    // The curve found against the one applied, where the sections' lowest points are the
    // bottom (0.2-0.9 L; the ends are extrapolated).
    // The curve is given along the output last (as last.stl was raised by it), whose x
    // maps onto the stock's by their extents.
    let x0 = curve[0][0];
    let ob = c.last.bbox();
    let k = len / (ob.max.x - ob.min.x);
    let on_stock = |x: f64| (x - x0) * k;
    let worst = curve
        .iter()
        .filter(|p| (0.2..=0.9).contains(&(on_stock(p[0]) / len)))
        .map(|p| (p[1] - raise(on_stock(p[0]) + bb.min.x)).abs())
        .fold(0.0, f64::max);
    println!(
        "bottom curve: {} samples, worst {worst:.3} mm off the applied one",
        curve.len()
    );
    assert!(worst < 1.0, "bottom curve off by {worst:.3} mm");
    // The output raised back: lowest point of the last's sections at 0.5 L on the glass,
    // at 0.1 L and 0.95 L raised like the stock's.
    let lb = c.last.bbox();
    let low_at = |t: f64| lowest_near(&c.last, lb.min.x + t * (lb.max.x - lb.min.x));
    let (heel, tread, toe) = (low_at(0.1), low_at(0.5), low_at(0.95));
    println!("last bottom: 0.1 L {heel:.2} mm, 0.5 L {tread:.2} mm, 0.95 L {toe:.2} mm");
    assert!(tread.abs() < 1.0, "tread {tread:.2} mm off the glass");
    assert!(
        (heel - 20.0 * (1.0 - 0.1 / 0.3)).abs() < 2.0,
        "heel {heel:.2}"
    );
    // The toe stands lower than the applied spring (8.33 mm at 0.95 L): the bottom curve is
    // found up to 0.9 L, smoothed over +-5 mm, and carried on straight (docs/method.md
    // 10.7). 6.35 mm with the square-toed stock, 6.26 since the whole-foot path (which made
    // this stock) rounds its toe in plan; the bound was 2.0 mm, 0.02 mm above the first.
    assert!(
        (toe - 12.0 * (0.25f64 / 0.3).powi(2)).abs() < 2.5,
        "toe {toe:.2}"
    );
    c.last.check().expect("closed");
}

/// Flat stock lasts made from the simulator's 238 and 240 mm feet, customized for the
/// default simulated scan's plantar figures and tape girths (250 mm foot): every rule met.
/// Both failed before the stock's chamfer was laid again through its own heel point: the
/// sections' flat band had turned it into a terrace at the outline's 1.5 mm, so the heel
/// point jumped 4.5 mm between Newton steps (bottom length and long-heel girth off by
/// 2-2.5 mm).
#[test]
fn clinic_flat_stock_lasts_shorter_than_the_foot() {
    use footscan_last::customize::clinic::customize_stock;
    let rules = RuleSet::default_rules();
    let inp = Inputs::default();
    let (plantar, girths) = scan_of_250_mm_foot();
    for l in [238.0, 240.0] {
        let (m, _) = sim_foot(l, Side::Right);
        let (foot, frame) = foot_in_frame(m, "sim").unwrap();
        let stock = customize(foot, frame, &rules, &inp).unwrap().last;
        let c = customize_stock(stock, "flat stock", &plantar, &girths, &rules, &inp)
            .unwrap_or_else(|e| panic!("{l} mm stock: {e}"));
        for r in &c.rules {
            println!(
                "  {l} {:5} {:16} target {:7.2} last {:7.2} err {:+.3}",
                r.rule, r.quantity, r.target_mm, r.last_mm, r.error_mm
            );
            assert!(
                r.met,
                "{l}: {} {}: {:+.3} mm",
                r.rule, r.quantity, r.error_mm
            );
        }
    }
}

/// The FIND template foot (../shared/data/feet/find_template, a real scan's remesh, read
/// never copied) ships landmarks as vertex ids (keypoints.csv). Our points against them in
/// the coordinate both definitions fix (crates/last/src/customize/landmarks.rs): the toe tip
/// and heel point along the axis, MT1 and MT5 across it. Measured (2026-11-25): toe tip
/// +0.71 mm, heel point -0.71, MT1 -2.13 (ours is the plan extreme, 2.1 mm further out than
/// the annotated vertex and 19 mm further back, where the first metatarsal head lies at 0.72
/// L), MT5 +0.32.
#[test]
fn find_foot_points_against_its_annotated_landmarks() {
    use footscan_last::customize::landmarks::{pair_with, read_keypoints};
    use footscan_last::customize::measure::measure;
    let d = std::env::var_os("FOOTSCAN_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data")
        })
        .join("feet/find_template");
    assert!(
        d.is_dir(),
        "real foot data missing: {} is not a directory; set FOOTSCAN_DATA to the directory \
         holding feet/find_template",
        d.display()
    );
    let (m, _) = footscan_geom::mesh::TriMesh::load_solid(
        d.join("template_mm.stl"),
        footscan_geom::mesh::Units::Mm,
        None,
    )
    .unwrap();
    let (foot, frame) = foot_in_frame(m, "FIND").unwrap();
    let fm = measure(&foot, None, frame.medial_sign()).unwrap();
    let kp = read_keypoints(
        &d.join("template.obj"),
        &d.join("keypoints.csv"),
        "FIND",
        1000.0,
    )
    .unwrap();
    assert_eq!(kp.len(), 12, "{kp:?}");
    let pairs = pair_with(&fm, &frame, &kp);
    assert_eq!(pairs.len(), 4, "{pairs:?}");
    for (p, bound) in pairs.iter().zip([1.5, 1.5, 3.0, 1.0]) {
        println!(
            "{} - {}: {:+.2} mm ({}; along {:+.2}, across {:+.2})",
            p.ours,
            p.theirs,
            p.error(),
            p.compared,
            p.dx,
            p.dy
        );
        assert!(p.error().abs() <= bound, "{p:?} (bound {bound} mm)");
    }
}

/// A real person's pair from an in-store scanner that scans the foot standing on a flat plate
/// (../shared/data/feet/dupontgu_my_feet: metres, heel to toe along y, the right foot yawed
/// about 20 degrees, each cut about 100 mm up), as scanned and perturbed: vertex noise of 0.3
/// and 0.5 mm along the vertex normals and a further 10 degree yaw. Every rule is met and the
/// foot fits where the rules say it must (heel seat, midfoot, toe box within FIT_TOL_MM; the
/// noisy copies within FIT_TOL_MM plus the noise).
/// Measured (2026-11-27, docs/method.md 10.5): as scanned, left -0.03 / -0.24 / -0.01 and
/// right -0.00 / -0.30 / -0.10 mm; before this round's rounded corners and instep offset
/// below the long-heel plane, midfoot -1.99 and -0.79 mm.
#[test]
fn standing_pair_fits_as_scanned_and_perturbed() {
    let d = std::env::var_os("FOOTSCAN_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| {
            std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data")
        })
        .join("feet/dupontgu_my_feet");
    assert!(
        d.is_dir(),
        "real foot data missing: {} is not a directory; set FOOTSCAN_DATA to the directory \
         holding feet/dupontgu_my_feet",
        d.display()
    );
    let rules = RuleSet::default_rules();
    let inp = Inputs::default();
    let mut lengths = Vec::new();
    // Noise moves single vertices out of the foot's surface by up to 3 sigma; the bound
    // grows by the noise itself. Measured (heel seat / midfoot / toe box): noise 0.3 mm
    // left -0.01 / -0.45 / -0.01, right -0.06 / -0.34 / -0.04; noise 0.5 mm left -0.20 /
    // -0.43 / -0.02 (87 evaluations, 1.7 s), right -0.15 / -0.53 / -0.04; the 10 degree
    // yaw as scanned to 0.01 mm. The midfoot's miss is the waist width scale (0.993-0.996)
    // giving back a plan waist that the hulls holding the foot between stations widened,
    // from both walls (docs/method.md 10.5).
    let bound = |noise: f64| footscan_last::customize::FIT_TOL_MM + noise;
    for side in ["left", "right"] {
        let (m, _) = footscan_geom::mesh::TriMesh::load_solid(
            d.join(format!("{side}_foot.stl")),
            footscan_geom::mesh::Units::Auto,
            None,
        )
        .unwrap();
        for (name, noise, yaw) in [
            ("as scanned", 0.0, 0.0),
            ("noise 0.3", 0.3, 0.0),
            ("noise 0.5", 0.5, 0.0),
            ("yaw 10", 0.0, 10.0),
        ] {
            let p = perturbed(&m, noise, yaw, 7);
            let t = std::time::Instant::now();
            let (foot, frame) = foot_in_frame(p, side).unwrap();
            assert_eq!(
                format!("{:?}", frame.side).to_lowercase(),
                side,
                "{side} {name}"
            );
            let c = customize(foot, frame, &rules, &inp).unwrap();
            let ms = t.elapsed().as_secs_f64() * 1e3;
            let worst = c.rules.iter().map(|r| r.error_mm.abs()).fold(0.0, f64::max);
            println!(
                "{side} {name}: length {:.2}, ball width {:.2}, heel width {:.2}; rules worst \
                 {worst:.3} mm; {}; {ms:.0} ms ({} evaluations)",
                c.foot_measures.length,
                c.foot_measures.ball_width,
                c.foot_measures.heel_width,
                c.clearance.summary(),
                c.evaluations
            );
            for r in &c.rules {
                assert!(r.met, "{side} {name}: {} err {}", r.rule, r.error_mm);
            }
            // A miss is explained, a fit is not.
            let missed = c.clearance.regions.iter().any(|r| !r.met());
            assert_eq!(
                c.clearance.missed_because.is_some(),
                missed,
                "{side} {name}"
            );
            if let Some(why) = &c.clearance.missed_because {
                println!("  must-fit missed: {why}");
            }
            for region in ["heel seat", "midfoot", "toe box"] {
                let r = c.clearance.region(region).unwrap();
                assert!(
                    r.vertices > 0 && r.min_mm >= -bound(noise),
                    "{side} {name}: {region} {r:?}"
                );
            }
            if noise == 0.0 && yaw == 0.0 {
                lengths.push(c.foot_measures.length);
            }
        }
    }
    // One person's pair: the feet are within 1 % of each other's length (274.94 / 275.07).
    assert!(
        (lengths[0] - lengths[1]).abs() < 0.01 * lengths[0],
        "{lengths:?}"
    );
}

/// A copy of a world mesh (mm, z up) with each vertex moved along its normal by a
/// deterministic noise of standard deviation `noise` mm and turned by `yaw` degrees about
/// the vertical through its centroid.
fn perturbed(m: &TriMesh, noise: f64, yaw: f64, seed: u64) -> TriMesh {
    let mut out = m.clone();
    let normals = m.vertex_normals();
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut uniform = move || {
        // xorshift64*
        s ^= s >> 12;
        s ^= s << 25;
        s ^= s >> 27;
        (s.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    };
    for (v, n) in out.vertices.iter_mut().zip(&normals) {
        // Box-Muller.
        let (u1, u2) = (uniform().max(1e-12), uniform());
        let g = (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos();
        *v += n * (noise * g);
    }
    let c = out
        .vertices
        .iter()
        .fold(footscan_geom::P3::origin(), |a, p| a + p.coords)
        / out.vertices.len() as f64;
    let (sn, cs) = yaw.to_radians().sin_cos();
    for v in &mut out.vertices {
        let (x, y) = (v.x - c.x, v.y - c.y);
        v.x = c.x + cs * x - sn * y;
        v.y = c.y + sn * x + cs * y;
    }
    out
}

/// One foot of each kind of the simulated population (flat and high arches, hallux valgus,
/// wide and narrow forefeet, short and long toes, relaxed, toes joined): every rule met on the
/// last cut from its mesh, and the foot inside it where the rules say it must be, or the
/// reason it is not.
#[test]
fn a_population_of_feet_fits_or_says_why() {
    use footscan_sim::foot::population;
    let rules = RuleSet::default_rules();
    let inp = Inputs::default();
    let mut silent = Vec::new();
    let mut missed = 0;
    for pf in population(10, 7) {
        let f = Foot::new(pf.params.clone()).unwrap();
        let m = f.mesh(MeshResolution::default()).tri_mesh();
        let (foot, frame) = foot_in_frame(m, pf.kind).unwrap();
        let c = customize(foot, frame, &rules, &inp)
            .unwrap_or_else(|e| panic!("{} foot: {e}", pf.kind));
        let cl = &c.clearance;
        let fits = cl.regions.iter().all(|r| r.met());
        println!(
            "{:26} L {:5.1}: rules worst {:.3} mm, {}; {}",
            pf.kind,
            pf.params.length_mm,
            c.rules.iter().map(|r| r.error_mm.abs()).fold(0.0, f64::max),
            cl.summary(),
            cl.missed_because.as_deref().unwrap_or("fits")
        );
        for r in &c.rules {
            assert!(
                r.met,
                "{} foot: rule {} off by {:.3} mm",
                pf.kind, r.rule, r.error_mm
            );
        }
        if !fits {
            missed += 1;
            if cl.missed_because.is_none() {
                silent.push(pf.kind);
            }
        }
    }
    assert!(
        silent.is_empty(),
        "must-fit missed without a reason: {silent:?}"
    );
    assert!(missed <= 1, "{missed} of 10 kinds miss must-fit");
}
