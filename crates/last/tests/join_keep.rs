//! Kept parts true to their meshes (issue 36): each fitted part within 0.1 mm of its mesh, the
//! seams G1 within 0.1 deg against the fitted parts with a fair patch, and the STL the original meshes outside the join region.

use footscan_geom::mesh::{TriMesh, Units};
use footscan_last::join::{self, output, JoinParams};
use std::path::PathBuf;

fn lasts_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let dir = base.join("lasts");
    assert!(
        dir.is_dir(),
        "the real lasts are not at {} (set FOOTSCAN_DATA to the directory holding lasts/)",
        dir.display()
    );
    dir
}

fn pair(name: &str) -> (TriMesh, TriMesh) {
    let dir = lasts_dir();
    let load = |f: &str, len: Option<f64>| {
        TriMesh::load_solid(dir.join(f), Units::Auto, len)
            .unwrap()
            .0
    };
    match name {
        "scan" => (
            load("LastScan_Default.stl", None),
            load("LastScan_Warped.stl", None),
        ),
        _ => (
            load("Last_Heeled_RoundTip.stl", Some(260.0)),
            load("Last_Flat_RoundTip.stl", Some(260.0)),
        ),
    }
}

/// Before the fit the kept parts were the section surfaces, 0.53-0.88 mm from their meshes at
/// most and their seams 8-9 deg off the original lasts on average (issue 36).
#[test]
fn kept_parts_follow_their_meshes_and_the_seams_the_originals() {
    for name in ["scan", "roundtip"] {
        let (b, t) = pair(name);
        // The default continuity (G1 confined to a band next to each seam).
        let p = JoinParams {
            fit_parts: true,
            ..JoinParams::default()
        };
        let j = join::join(&b, &t, &p).unwrap();
        let q = output::quality(&j, 200).unwrap();
        let fits = j.fits.unwrap();
        let (var, _) = footscan_last::blend::fair::surface_fairness(&j.patch, 96, 24);
        println!("{name}: patch curvature variation {var:.3e} 1/mm^2");
        for (part, f) in ["back", "toe"].iter().zip(&fits) {
            println!(
                "{name} {part}: {} facet points, {} fits, {} x {} spans, max {:.3} mm at \
                 ({:.1}, {:.1}, {:.1}) {:.1} mm from the plane, rms {:.4} mm, {:.0} ms",
                f.samples,
                f.rounds,
                f.spans_u,
                f.spans_v,
                f.max_mm,
                f.max_at[0],
                f.max_at[1],
                f.max_at[2],
                f.max_from_plane_mm,
                f.rms_mm,
                f.ms
            );
            // Issue 36 asks 0.1 mm everywhere (0.077-0.089 mm on the four parts; 0.15-0.18 mm
            // on 500 spans around without halving them at the rim).
            assert!(f.max_mm <= 0.1 && f.rms_mm <= 0.02, "{name} {part}: {f:?}");
        }
        // G1 along the whole seam (the default `G1`, as `G1Tangent` but confined to a band):
        // the patch leaves each seam along the fitted part's own v tangent, scaled to the
        // patch's length. 0.001-0.005 deg at most on the two pairs (issue 36 asks 0.1 deg;
        // 0.009-0.053 before the parts were faired at the cut); turning the patch's own
        // tangent into the part's tangent plane at the Greville points (`G1Greville`, the
        // default before) left 2.3 deg (LastScan) and 6.0 deg (RoundTip) at the rim.
        for s in [&q.back_seam, &q.toe_seam] {
            println!("{name} seam: {s:?}");
            assert!(s.gap_max_mm <= 1e-9, "{name}: {s:?}");
            assert!(
                s.normal_max_deg <= 0.1 && s.normal_mean_deg <= 0.01,
                "{name}: {s:?}"
            );
        }
        for (part, o) in [("back", &q.back_original), ("toe", &q.toe_original)] {
            println!(
                "{name} {part} seam against the original: normal {:.2} deg max, {:.2} mean, gap \
                 {:.3} mm",
                o.normal_max_deg, o.normal_mean_deg, o.gap_max_mm
            );
            assert!(
                o.normal_mean_deg <= 2.5 && o.gap_max_mm <= 0.05,
                "{name} {part}: {o:?}"
            );
        }
        println!("{name}: {:?}", j.timings);
    }
}

/// The patch bent to meet the fitted parts stays near the two lasts in the gap (both lasts
/// exist there): the largest distance of a patch point from the nearer of the two meshes.
#[test]
fn the_patch_stays_between_the_lasts() {
    use footscan_geom::mesh::Bvh;
    for name in ["scan", "roundtip"] {
        let (b, t) = pair(name);
        let mut worsts = Vec::new();
        let mut vars = Vec::new();
        for (c, fit) in [
            (join::keep::Continuity::G2, false),
            (join::keep::Continuity::G2, true),
            (join::keep::Continuity::G1, true),
            (join::keep::Continuity::G1Tangent, true),
            (join::keep::Continuity::G1Greville, true),
        ] {
            let p = JoinParams {
                continuity: c,
                fit_parts: fit,
                ..JoinParams::default()
            };
            let j = join::join(&b, &t, &p).unwrap();
            let (bb, tb) = (Bvh::new(&j.back_mesh), Bvh::new(&j.toe_mesh));
            let mut worst: f64 = 0.0;
            for i in 0..200 {
                for k in 0..=20 {
                    let q = j.patch.point(i as f64 / 200.0, k as f64 / 20.0);
                    let d = bb
                        .closest_point(&q)
                        .unwrap()
                        .distance
                        .min(tb.closest_point(&q).unwrap().distance);
                    worst = worst.max(d);
                }
            }
            let (var, _) = footscan_last::blend::fair::surface_fairness(&j.patch, 96, 24);
            let (fine, _) = footscan_last::blend::fair::surface_fairness(&j.patch, 384, 192);
            println!(
                "{name} {c:?} fit {fit}: patch at most {worst:.2} mm from the nearer last, \
                 curvature variation {var:.3e} 1/mm^2 ({fine:.3e} on 384 x 192)"
            );
            worsts.push(worst);
            vars.push((var, fine));
        }
        // The default G1 is fair: its patch varies its curvature no more than twice the
        // section patch's (no fit: 1.4e2 / 3.7e5 on 96 x 24, 1.3e2 / 3.8e5 on 384 x 192; G1
        // 1.8e2 / 3.4e5 and 1.9e2 / 9.2e4) on either grid. The Greville turn, the default
        // before, was 2.1e3 / 8.7e5 (9.7e1 / 2.2e4 against the parts faired at the cut, 9.2e1
        // / 1.8e7 on 384 x 192) and G1Tangent 3.1e7 / 3.2e8 (1.0e2 / 3.2e6 against them).
        let (section, g1) = (vars[0], vars[2]);
        assert!(
            g1.0 <= 2.0 * section.0 && g1.1 <= 2.0 * section.1,
            "{name}: {vars:?}"
        );
        // The section patch (no fit) 1.89 / 10.37 mm; exact G2 to the fitted parts bulged to
        // 8.70 / 63.83 mm; the G1 default (1.90 / 10.37 mm), G1Tangent (1.10 / 10.50 mm) and
        // the Greville turn (1.14 / 10.37 mm) stay within 1 mm of the section patch's figure.
        assert!(
            worsts[2..].iter().all(|&w| w <= worsts[0] + 1.0),
            "{name}: {worsts:?}"
        );
    }
}

/// The fit cache (issue 36: the fits may be cached per last): a second join of the same lasts
/// reads both fits back bit for bit, in a small part of the fit's time; a damaged file is a
/// miss, fitted and stored again; another plane is another key.
#[test]
fn fitted_parts_come_back_from_the_cache() {
    let (b, t) = pair("scan");
    let dir = tempfile::tempdir().unwrap();
    let p = JoinParams {
        fit_parts: true,
        fit_cache: Some(dir.path().to_path_buf()),
        ..JoinParams::default()
    };
    let first = join::join(&b, &t, &p).unwrap();
    let second = join::join(&b, &t, &p).unwrap();
    let (f1, f2) = (first.fits.unwrap(), second.fits.unwrap());
    assert!(!f1[0].cached && !f1[1].cached, "{f1:?}");
    assert!(f2[0].cached && f2[1].cached, "{f2:?}");
    let files: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(files.len(), 2, "{files:?}");
    for (a, c) in [(&first.back, &second.back), (&first.toe, &second.toe)] {
        assert_eq!(a.points, c.points);
        assert_eq!((&a.knots_u, &a.knots_v), (&c.knots_u, &c.knots_v));
    }
    assert_eq!(first.patch.points, second.patch.points);
    for (x, y) in f1.iter().zip(&f2) {
        assert_eq!(
            (x.max_mm, x.rms_mm, x.spans_u, x.ms),
            (y.max_mm, y.rms_mm, y.spans_u, y.ms)
        );
    }
    let (t1, t2) = (&first.timings, &second.timings);
    println!(
        "fit cache: fits {:.0} / {:.0} ms, read back in {:.1} / {:.1} ms",
        t1.fit_back, t1.fit_toe, t2.fit_back, t2.fit_toe
    );
    assert!(
        t2.fit_back < 0.25 * t1.fit_back && t2.fit_toe < 0.25 * t1.fit_toe,
        "{t1:?} {t2:?}"
    );
    // A damaged file is a miss: fitted again, the same surface, and stored whole again.
    for f in &files {
        let bytes = std::fs::read(f).unwrap();
        std::fs::write(f, &bytes[..bytes.len() / 2]).unwrap();
    }
    let third = join::join(&b, &t, &p).unwrap();
    let f3 = third.fits.unwrap();
    assert!(!f3[0].cached && !f3[1].cached);
    assert_eq!(third.back.points, first.back.points);
    assert!(join::join(&b, &t, &p).unwrap().fits.unwrap()[0].cached);
    // Another back plane: other section surfaces and planes, so other keys.
    let moved = JoinParams {
        back_plane: Some(
            footscan_geom::plane::Plane::with_axis(
                first.back_plane.origin - first.back_plane.normal * 3.0,
                first.back_plane.normal,
                first.back_plane.u,
            )
            .unwrap(),
        ),
        ..p.clone()
    };
    let fourth = join::join(&b, &t, &moved).unwrap();
    assert!(!fourth.fits.unwrap()[0].cached);
    assert!(std::fs::read_dir(dir.path()).unwrap().count() >= 3);
}
