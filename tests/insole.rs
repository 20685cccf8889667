//! `footscan insole` end to end (issue 38): on the default simulated scan, every parameter
//! measured back on the written mesh within 0.2 mm / 0.3 deg of what was asked, the top
//! within 0.3 mm of the scanned sole where the foot bears, the STL closed and in one piece,
//! the 3MF read back by lib3mf (target/venv-3mf), the STEP by OpenCASCADE
//! (target/venv-occt), both the STL's solid; a 3/4 insole ending behind the heads; bad
//! parameters refused by name with nothing written. On real feet (../shared/data/feet, read
//! where they are, seen from below through the simulator's mesh scene): the same targets,
//! and a foot scanned without weight laid flat as the last stage lays it.

use footscan::measure::measure_foot;
use footscan_bench::measure::mesh_map;
use footscan_geom::mesh::{Bvh, IntakeOptions, TriMesh};
use footscan_geom::{P3, V3};
use footscan_insole::{write_insole, Params, Plantar, PostSide};
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn data() -> PathBuf {
    std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo().join("../shared/data"))
}

fn footscan(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_footscan"))
        .args(args)
        .current_dir(repo())
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The default simulated scan (250 mm right foot): the package's shared one (tests/common),
/// read only.
fn sim_scan() -> &'static Path {
    common::default_scan()
}

/// Every row of insole.json's checks within its bound, the thinnest place and the contact
/// with the sole within theirs; returns the report.
fn check_report(r: &serde_json::Value, what: &str, min_points: u64) {
    let m = &r["measured"];
    for c in m["checks"].as_array().unwrap() {
        let (name, err) = (c["name"].as_str().unwrap(), c["error"].as_f64());
        let bound = if c["unit"] == "deg" { 0.3 } else { 0.2 };
        println!(
            "{what}: {name} asked {} measured {} error {:?}",
            c["asked"], c["measured"], err
        );
        let err = err.unwrap_or_else(|| panic!("{what}: {name} not measured: {c}"));
        assert!(
            err.abs() <= bound,
            "{what}: {name} off by {err} (bound {bound})"
        );
    }
    let (t, bound) = (
        m["min_thickness_mm"].as_f64().unwrap(),
        m["min_thickness_bound_mm"].as_f64().unwrap(),
    );
    let (n, max, rms) = (
        m["contact_points"].as_u64().unwrap(),
        m["contact_max_mm"].as_f64().unwrap(),
        m["contact_rms_mm"].as_f64().unwrap(),
    );
    println!(
        "{what}: thinnest {t:.3} mm (at least {bound:.3}); top vs sole over {n} points: max \
         {max:.3}, RMS {rms:.3} mm; designed in {} ms",
        r["design_ms"]
    );
    assert!(t >= bound - 1e-6, "{what}: thinnest {t} under {bound}");
    assert!(
        n >= min_points,
        "{what}: only {n} weight-bearing points compared"
    );
    assert!(max <= 0.3, "{what}: top off the sole by {max} mm");
    assert_eq!(r["measured"]["ok"], true, "{what}");
}

/// The mesh's top at (x, y) by a ray from above.
fn top(bvh: &Bvh, x: f64, y: f64) -> f64 {
    bvh.ray_cast(&P3::new(x, y, 500.0), &V3::new(0.0, 0.0, -1.0), 1000.0)
        .map(|h| h.point.z)
        .expect("a point on the insole")
}

fn json_line(prog: &Path, script: &str, file: &Path) -> serde_json::Value {
    assert!(
        prog.exists(),
        "{} is missing: run scripts/setup.sh",
        prog.display()
    );
    let out = Command::new(prog)
        .arg(repo().join(script))
        .arg(file)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{script} {}: {text}{}",
        file.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(text.lines().last().unwrap()).unwrap()
}

#[test]
fn simulated_scan_insole_meets_every_target_and_reads_back() {
    let scan = sim_scan();
    let tmp = tempfile::tempdir().unwrap();
    let params = tmp.path().join("p.toml");
    // Every correction at once, each at a clinically usual value.
    std::fs::write(
        &params,
        "heel_cup_depth_mm = 10\narch_share = 1.1\nrearfoot_post_deg = 4\n\
         forefoot_post_deg = 2\nforefoot_post_side = \"lateral\"\nmet_pad_height_mm = 4\n\
         met_pad_behind_mm = 6\nfirst_ray_cutout_mm = 1\nheel_lift_mm = 3\n\
         extra_length_mm = 5\nstep_cell_mm = 4\n",
    )
    .unwrap();
    let out = tmp.path().join("insole");
    let (ok, stdout, err) = footscan(&[
        "insole",
        "--scan",
        s(scan),
        "--params",
        s(&params),
        "--out",
        s(&out),
    ]);
    println!("{stdout}{err}");
    assert!(ok, "{stdout}{err}");
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("insole.json")).unwrap()).unwrap();
    check_report(&r, "simulated scan", 2000);
    assert_eq!(r["side"], "right");
    assert_eq!(
        r["midfoot_off_glass_mm"], 0.0,
        "the simulated foot bears weight"
    );

    // The STL read back: closed, oriented, outward, one piece, its bottom the plane z = 0.
    let mesh = TriMesh::read(out.join("insole.stl")).unwrap();
    let rep = mesh.check().unwrap_or_else(|e| panic!("insole.stl: {e}"));
    assert_eq!(rep.components, 1);
    assert!(rep.bbox.min.z.abs() < 1e-9, "{:?}", rep.bbox);
    // And it does not pass through itself (the "without self-intersection").
    let crossing = mesh.self_intersections();
    assert!(
        crossing.is_empty(),
        "insole.stl crosses itself: {crossing:?}"
    );
    // Thickness at the heel centre by a ray of our own: what insole.json reports, and more
    // than the shell (3 less the 1 mm cover) and the 3 mm heel lift.
    let bvh = Bvh::new(&mesh);
    let hc = &r["landmarks"]["heel_centre"];
    let (hx, hy) = (hc[0].as_f64().unwrap(), hc[1].as_f64().unwrap());
    let t = top(&bvh, hx, hy);
    let measured = r["measured"]["checks"][0]["measured"].as_f64().unwrap();
    assert_eq!(
        r["measured"]["checks"][0]["name"],
        "thickness_at_heel_centre"
    );
    assert!(
        (t - measured).abs() < 1e-6,
        "heel centre: {t} vs {measured}"
    );
    assert!(
        t > 2.0 + 3.0,
        "heel centre thickness {t}: the lift is missing"
    );
    // The pad raises the top at its apex above the points 25 mm around it.
    let apex = &r["measured"]["pad_apex_mm"];
    let (ax, ay) = (apex[0].as_f64().unwrap(), apex[1].as_f64().unwrap());
    let around = top(&bvh, ax - 25.0, ay).max(top(&bvh, ax, ay + 15.0));
    assert!(top(&bvh, ax, ay) > around + 2.0, "no pad at ({ax}, {ay})");

    // 3MF by lib3mf: the same mesh, in millimetres, closed and oriented.
    let m3 = json_line(
        &repo().join("target/venv-3mf/bin/python"),
        "scripts/threemf_lib3mf.py",
        &out.join("insole.3mf"),
    );
    println!("lib3mf: {m3}");
    let o = &m3["objects"][0];
    assert_eq!(m3["unit"], "millimeter");
    assert_eq!(m3["build_items"], 1);
    assert_eq!(
        o["vertices"].as_u64().unwrap() as usize,
        mesh.vertices.len()
    );
    assert_eq!(
        o["triangles"].as_u64().unwrap() as usize,
        mesh.triangles.len()
    );
    assert_eq!(o["edges_not_in_two"], 0);
    assert_eq!(o["oriented"], true);
    let v3 = o["volume"].as_f64().unwrap();
    assert!(
        (v3 / rep.volume - 1.0).abs() < 1e-4,
        "3MF volume {v3} vs {}",
        rep.volume
    );

    // STEP by OpenCASCADE: one valid closed solid, the STL's volume within 0.5 % (4 mm
    // facets against 1 mm ones).
    let occ = json_line(
        &std::env::var_os("FOOTSCAN_OCCT_PYTHON")
            .map(PathBuf::from)
            .unwrap_or_else(|| repo().join("target/venv-occt/bin/python")),
        "scripts/occt_solid.py",
        &out.join("insole.step"),
    );
    println!("occt: {occ}");
    assert_eq!(occ["valid"], true);
    assert_eq!(occ["solids"], 1);
    assert_eq!(occ["shells_closed"], true);
    assert_eq!(occ["edges_not_in_two_faces"], 0);
    let vs = occ["volume"].as_f64().unwrap();
    assert!(
        (vs / rep.volume - 1.0).abs() < 5e-3,
        "STEP volume {vs} vs {}",
        rep.volume
    );
    for png in ["thickness.png", "top.png", "side.png"] {
        let img = image_size(&out.join(png));
        assert!(img.0 >= 800 && img.1 >= 400, "{png}: {img:?}");
    }

    // A 3/4 insole with the defaults and a pad: it ends behind the heads' line.
    let out34 = tmp.path().join("three-quarter");
    std::fs::write(
        &params,
        "length = \"three_quarter\"\nmet_pad_height_mm = 3\nmet_pad_behind_mm = 22\nstep_cell_mm = 4\n",
    )
    .unwrap();
    let (ok, stdout, err) = footscan(&[
        "insole",
        "--scan",
        s(scan),
        "--params",
        s(&params),
        "--margin-mm",
        "2",
        "--out",
        s(&out34),
    ]);
    assert!(ok, "{stdout}{err}");
    let r34: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out34.join("insole.json")).unwrap()).unwrap();
    check_report(&r34, "3/4, simulated scan", 1000);
    let m34 = TriMesh::read(out34.join("insole.stl")).unwrap();
    m34.check().unwrap();
    // Every vertex behind the line 5 mm behind the first and fifth heads (the defaults).
    let lm = &r34["landmarks"];
    let at = |k: &str| [lm[k][0].as_f64().unwrap() - 5.0, lm[k][1].as_f64().unwrap()];
    let (a, b) = (at("mt1_head"), at("mt5_head"));
    let mut n = [b[1] - a[1], a[0] - b[0]];
    if n[0] < 0.0 {
        n = [-n[0], -n[1]];
    }
    let len = n[0].hypot(n[1]);
    n = [n[0] / len, n[1] / len];
    let ahead = m34
        .vertices
        .iter()
        .map(|p| (p.x - a[0]) * n[0] + (p.y - a[1]) * n[1])
        .fold(f64::MIN, f64::max);
    // The solid keeps its outline crossings a hundredth of a cell off the grid nodes
    // (surface::solid MIN_FRACTION): 0.01 mm on 1 mm cells.
    assert!(
        ahead <= 0.011,
        "a 3/4 vertex {ahead} mm ahead of the end line"
    );
    let end = m34.bbox().max.x;
    assert!(end > 0.5 * r34["foot_length_mm"].as_f64().unwrap());
}

/// The shoe's bottom from `footscan last adjust` (the shared LastScan_Default last adjusted to
/// the simulated scan): the insole's outline is the adjusted last's bottom outline, so the
/// insole lies inside the last's plan and spans its length; a directory without
/// last_adjusted.stl is refused by name, nothing written.
#[test]
fn shoe_bottom_outline_from_last_adjust() {
    let scan = sim_scan();
    let tmp = tempfile::tempdir().unwrap();
    let adj = tmp.path().join("adj");
    let last = repo().join("../shared/data/lasts/LastScan_Default.stl");
    let (ok, out, err) = footscan(&[
        "last",
        "adjust",
        "--scan",
        s(scan),
        "--last",
        s(&last),
        "--out",
        s(&adj),
    ]);
    assert!(ok, "{out}{err}");
    let out_dir = tmp.path().join("insole");
    let (ok, stdout, err) = footscan(&[
        "insole",
        "--scan",
        s(scan),
        "--shoe-bottom",
        s(&adj),
        "--out",
        s(&out_dir),
    ]);
    println!("{stdout}{err}");
    assert!(ok, "{stdout}{err}");
    let r: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("insole.json")).unwrap()).unwrap();
    check_report(&r, "shoe bottom", 2000);
    assert!(r["outline_from"]
        .as_str()
        .unwrap()
        .starts_with("shoe bottom"));
    let mesh = TriMesh::read(out_dir.join("insole.stl")).unwrap();
    assert_eq!(mesh.check().unwrap().components, 1);
    assert!(
        mesh.self_intersections().is_empty(),
        "bent insole.stl crosses itself"
    );
    // The last's downward faces in the foot frame (insole.json's frame).
    let lastm = TriMesh::read(adj.join("last_adjusted.stl")).unwrap();
    let f = &r["frame"];
    let (o, d) = (
        [
            f["origin"][0].as_f64().unwrap(),
            f["origin"][1].as_f64().unwrap(),
        ],
        [
            f["x_axis"][0].as_f64().unwrap(),
            f["x_axis"][1].as_f64().unwrap(),
        ],
    );
    let to = |p: &P3| {
        let (x, y) = (p.x - o[0], p.y - o[1]);
        [d[0] * x + d[1] * y, -d[1] * x + d[0] * y]
    };
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for t in 0..lastm.triangles.len() {
        if lastm.face_normal(t).z < -0.5 {
            for p in lastm.corners(t) {
                let q = to(&p);
                for k in 0..2 {
                    lo[k] = lo[k].min(q[k]);
                    hi[k] = hi[k].max(q[k]);
                }
            }
        }
    }
    let bb = mesh.bbox();
    println!(
        "last bottom x {:.1}..{:.1} y {:.1}..{:.1}; insole {bb:?}",
        lo[0], hi[0], lo[1], hi[1]
    );
    for (k, (a, b)) in [(bb.min.x, bb.max.x), (bb.min.y, bb.max.y)]
        .into_iter()
        .enumerate()
    {
        assert!(
            a >= lo[k] - 0.5 && b <= hi[k] + 0.5,
            "axis {k}: {a}..{b} outside the last's bottom"
        );
        assert!(
            b - a >= 0.97 * (hi[k] - lo[k]),
            "axis {k}: {a}..{b} much smaller than the last's bottom"
        );
    }
    // The outline made fair: no kink from the last's edge behind the heads. The kinks the
    // first smoothing left turned 12.6 deg a millimetre (design.rs unit test); the adjusted
    // bottom's own tightest bend is the foot's, concave on the medial side where the waist
    // meets the ball (x 133-139 mm), 4.2-6.1 deg/mm (radius 9-14 mm) over five scans whose
    // noise differed, so the bound is 8 (a 7 mm radius). In front the adjusted bottom has the
    // toes' lobes (seen in top.png), which turn it several times over in all.
    let (turn, total) = (
        r["outline_max_turn_deg_per_mm"].as_f64().unwrap(),
        r["outline_total_turn_deg"].as_f64().unwrap(),
    );
    let at = &r["outline_max_turn_at"];
    println!("outline turning: at most {turn:.2} deg/mm at {at}, {total:.1} deg in all");
    let _ = std::fs::copy(
        out_dir.join("top.png"),
        repo().join("target/insole-shoe-bottom-top.png"),
    );
    assert!(turn < 8.0, "{turn} deg/mm at {at}");
    assert!(total >= 350.0, "{total} deg");
    // Bent onto the last's bottom curve: the insole's bottom (met from below on the axis)
    // against the last's lowest bottom point per 1 mm station (rays up from below every 1 mm
    // across it), averaged over +-5 stations, both above their lowest over the stations, from
    // 20 % to 85 % of the insole's length.
    let sp = &r["spring"];
    assert!(sp.is_object(), "the insole is bent: {}", r["warnings"]);
    let ibvh = Bvh::new(&mesh);
    let lbvh = Bvh::new(&lastm);
    let lbb = lastm.bbox();
    let from = |q: [f64; 2]| {
        [
            o[0] + d[0] * q[0] - d[1] * q[1],
            o[1] + d[1] * q[0] + d[0] * q[1],
        ]
    };
    let last_low = |x: f64| -> Option<f64> {
        let mut low: Option<f64> = None;
        let mut y = lo[1];
        while y <= hi[1] {
            let w = from([x, y]);
            if let Some(h) = lbvh
                .ray_cast(&P3::new(w[0], w[1], lbb.min.z - 10.0), &V3::z(), 1000.0)
                .filter(|h| h.normal.z < -0.5)
            {
                low = Some(low.map_or(h.point.z, |l: f64| l.min(h.point.z)));
            }
            y += 1.0;
        }
        low
    };
    let (ix0, ix1) = (bb.min.x, bb.max.x);
    let mut rows = Vec::new();
    let mut x = ix0 + 0.2 * (ix1 - ix0);
    while x <= ix0 + 0.85 * (ix1 - ix0) {
        let bottom = ibvh
            .ray_cast(&P3::new(x, 0.0, -100.0), &V3::z(), 1000.0)
            .map(|h| h.point.z);
        let lows: Vec<f64> = (-5..=5).filter_map(|k| last_low(x + k as f64)).collect();
        if let (Some(b), false) = (bottom, lows.is_empty()) {
            rows.push((x, b, lows.iter().sum::<f64>() / lows.len() as f64));
        }
        x += 5.0;
    }
    let b0 = rows.iter().map(|r| r.1).fold(f64::MAX, f64::min);
    let l0 = rows.iter().map(|r| r.2).fold(f64::MAX, f64::min);
    let worst =
        rows.iter()
            .map(|&(x, b, l)| ((b - b0) - (l - l0), x))
            .fold(
                (0.0f64, 0.0),
                |a, e| if e.0.abs() > a.0.abs() { e } else { a },
            );
    let rise = rows.iter().map(|r| r.1 - b0).fold(0.0f64, f64::max);
    println!(
        "bottom curve: heel {:.2} mm, toe {:.2} mm; over {} stations the insole's bottom \
         rises {rise:.2} mm and differs from the last's by at most {:.3} mm (x {:.0})",
        sp["heel_mm"],
        sp["toe_mm"],
        rows.len(),
        worst.0,
        worst.1
    );
    assert!(rows.len() > 20);
    assert!(worst.0.abs() < 0.3, "{worst:?}");
    let missing = tmp.path().join("no-adjust");
    std::fs::create_dir_all(&missing).unwrap();
    let bad = tmp.path().join("bad");
    let (ok, _, err) = footscan(&[
        "insole",
        "--scan",
        s(scan),
        "--shoe-bottom",
        s(&missing),
        "--out",
        s(&bad),
    ]);
    assert!(!ok && err.contains("last_adjusted.stl"), "{err}");
    assert!(!bad.exists());
}

fn image_size(p: &Path) -> (u32, u32) {
    let b = std::fs::read(p).unwrap();
    assert_eq!(&b[1..4], b"PNG", "{}", p.display());
    (
        u32::from_be_bytes(b[16..20].try_into().unwrap()),
        u32::from_be_bytes(b[20..24].try_into().unwrap()),
    )
}

#[test]
fn bad_parameters_are_named_and_nothing_is_written() {
    let scan = sim_scan();
    let tmp = tempfile::tempdir().unwrap();
    let params = tmp.path().join("p.toml");
    let out = tmp.path().join("out");
    for (text, name, range) in [
        (
            "rearfoot_post_deg = 40\n",
            "rearfoot_post_deg",
            "between 0 and 10",
        ),
        (
            "arch_height_mm = 6\nmet_pad_height_mm = 8\n",
            "met_pad_height_mm",
            "between 0 and 6",
        ),
        ("top_cover_mm = 2.5\n", "top_cover_mm", "between 0 and 2"),
        (
            "heel_cup_dept_mm = 3\n",
            "heel_cup_dept_mm",
            "unknown field",
        ),
        (
            "length = \"three_quarter\"\nmet_pad_height_mm = 3\n",
            "met_pad_behind_mm",
            "must lie between",
        ),
        (
            "length = \"three_quarter\"\nfirst_ray_cutout_mm = 1\n",
            "first_ray_cutout_mm",
            "between 0 and 0",
        ),
    ] {
        std::fs::write(&params, text).unwrap();
        let (ok, stdout, err) = footscan(&[
            "insole",
            "--scan",
            s(scan),
            "--params",
            s(&params),
            "--out",
            s(&out),
        ]);
        println!("{text:?}: {err}");
        assert!(!ok, "{text:?} accepted: {stdout}");
        assert!(err.contains(name) && err.contains(range), "{text:?}: {err}");
        assert!(!out.exists(), "{text:?}: something written");
    }
    let (ok, _, err) = footscan(&[
        "insole",
        "--scan",
        s(scan),
        "--margin-mm",
        "-1",
        "--out",
        s(&out),
    ]);
    assert!(!ok && err.contains("margin_mm = -1"), "{err}");
    assert!(!out.exists());
}

/// A scan cut short before the metatarsal heads (a partial scan: the analytic foot's map
/// behind 55 % of its length): a 3/4 insole, which ends at the heads, is refused by name;
/// a full-length one without pad or cut-out is made.
#[test]
fn three_quarter_without_heads_is_refused() {
    use footscan_bench::measure::analytic_map;
    use footscan_sim::foot::{Foot, FootParams};
    let foot = Foot::new(FootParams::default()).unwrap();
    let mut map = analytic_map(&foot, 0.2, true);
    let t = foot.truth();
    let (o, d) = (t.heel_point, t.axis_dir);
    for j in 0..map.ny {
        for i in 0..map.nx {
            let along = (map.x(i) - o[0]) * d[0] + (map.y(j) - o[1]) * d[1];
            if along > 0.55 * t.length_mm {
                map.set(i, j, f64::NAN);
            }
        }
    }
    let m = measure_foot(&map).unwrap();
    assert!(
        m.warnings.iter().any(|w| w.contains("metatarsal head")),
        "{:?}",
        m.warnings
    );
    let p = Plantar {
        map,
        m,
        source: "the cut-short analytic foot".into(),
    };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let params = Params {
        length: footscan_insole::Length::ThreeQuarter,
        ..Params::default()
    };
    let e = write_insole(&p, &params, &out).unwrap_err().to_string();
    println!("{e}");
    assert!(
        e.contains("three_quarter") && e.contains("metatarsal heads"),
        "{e}"
    );
    assert!(!out.exists());
}

/// Real feet seen from below: the dupontgu right foot (an in-store scanner's weight-bearing
/// scan) and the FIND template (a foot without weight on it: its midfoot stands off the
/// glass, laid flat by the curve under its arch as the last stage does).
#[test]
fn real_feet_insoles_meet_every_target() {
    for (file, posted, no_weight) in [
        (
            "feet/dupontgu_my_feet/right_foot.stl",
            PostSide::Medial,
            false,
        ),
        (
            "feet/find_template/template_mm.stl",
            PostSide::Lateral,
            true,
        ),
    ] {
        let path = data().join(file);
        let intake = TriMesh::read_foot(&path, &IntakeOptions::default())
            .unwrap_or_else(|e| panic!("{e} (set FOOTSCAN_DATA to the shared data directory)"));
        let map = mesh_map(&intake.mesh, 0.2).unwrap();
        let m = measure_foot(&map).unwrap();
        let p = Plantar {
            map,
            m,
            source: file.into(),
        };
        // A pad must stand below the insole's arch: the dupontgu foot's own arch is 0.5 mm,
        // so the arch support is asked as a height.
        let params = Params {
            arch_height_mm: Some(10.0),
            heel_cup_depth_mm: 12.0,
            rearfoot_post_deg: 5.0,
            rearfoot_post_side: posted,
            met_pad_height_mm: 3.0,
            heel_lift_mm: 2.0,
            step_cell_mm: 4.0,
            ..Params::default()
        };
        let tmp = tempfile::tempdir().unwrap();
        let w = write_insole(&p, &params, &tmp.path().join("out")).unwrap();
        println!("{file}:\n{}", w.report.text());
        let r = serde_json::to_value(&w.report).unwrap();
        // A foot without weight on it faces the glass over less of its sole (440 points of
        // the FIND template's slope under 0.2, on a 2 mm lattice; 3494 of dupontgu's).
        check_report(&r, file, if no_weight { 300 } else { 2000 });
        let rise = w.report.midfoot_off_glass_mm;
        assert_eq!(
            rise > 0.0,
            no_weight,
            "{file}: midfoot off the glass by {rise} mm"
        );
        let mesh = TriMesh::read(tmp.path().join("out/insole.stl")).unwrap();
        assert_eq!(mesh.check().unwrap().components, 1, "{file}");
        let crossing = mesh.self_intersections();
        assert!(
            crossing.is_empty(),
            "{file}: insole.stl crosses itself: {crossing:?}"
        );
    }
}
