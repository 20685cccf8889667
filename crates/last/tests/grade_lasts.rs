//! Grading (docs/method.md 9.4) on the shared real lasts: every graded last cut again by
//! `measure_last` and its steps checked against the sizing system's rule.

use footscan_geom::mesh::{TriMesh, Units};
use footscan_last::grade::{
    grade, parse_sizes, parse_widths, write_graded_atomic, GradeError, GradeSpec, Graded, Mode,
    System, GIRTH_TOL_MM, LENGTH_TOL_MM,
};
use footscan_last::measure_last::measure_last;
use std::path::{Path, PathBuf};

fn data() -> PathBuf {
    std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"))
}

fn default_last() -> TriMesh {
    let p = data().join("lasts/LastScan_Default.stl");
    TriMesh::load_solid(&p, Units::Auto, None)
        .expect("shared last reads")
        .0
}

fn spec(system: System, mode: Mode, from: f64, sizes: &str, widths: &[(&str, f64)]) -> GradeSpec {
    GradeSpec {
        system,
        mode,
        from,
        sizes: parse_sizes(sizes, system).unwrap(),
        widths: widths
            .iter()
            .map(|(l, o)| footscan_last::grade::Width {
                label: l.to_string(),
                offset: *o,
            })
            .collect(),
    }
}

/// Every step within the bounds, and every graded last as written measures the same.
fn check_steps(g: &Graded) {
    print!("{}", g.table());
    for s in &g.steps {
        assert!(
            (s.length_achieved - s.length_rule).abs() <= LENGTH_TOL_MM,
            "{} -> {}: length step {:.3} for {:.3}",
            s.from,
            s.to,
            s.length_achieved,
            s.length_rule
        );
        assert!(
            (s.girth_achieved - s.girth_rule).abs() <= GIRTH_TOL_MM,
            "{} -> {}: joint girth step {:.3} for {:.3}",
            s.from,
            s.to,
            s.girth_achieved,
            s.girth_rule
        );
    }
}

#[test]
fn paris_38_46_from_default_as_40() {
    let g = grade(
        default_last(),
        "LastScan_Default",
        &spec(System::Paris, Mode::Arithmetic, 40.0, "38-46", &[]),
    )
    .unwrap();
    // LastScan_Default's stick length (238.69 mm) is a Paris 36 (240 mm), not a 40 (266.67):
    // inside a size group, so graded as given, and said.
    assert!(
        (g.base.stick_length - 238.69).abs() < 0.05,
        "{}",
        g.base.stick_length
    );
    assert!((g.expected_length - 266.667).abs() < 0.01);
    assert!(
        g.notes.iter().any(|n| n.contains("-4.2 Paris sizes")),
        "{:?}",
        g.notes
    );
    assert_eq!(g.lasts.len(), 9);
    assert_eq!(g.steps.len(), 8);
    check_steps(&g);
    // Heel height and toe spring are kept through the run (bottom profile at the same
    // fractions of the length), within what the standing of this flat last allows.
    for l in &g.lasts {
        let m = &l.measures;
        assert!(
            (m.heel_height - g.base.heel_height).abs() < 1.0,
            "size {}: heel height {:.2} against {:.2}",
            l.size,
            m.heel_height,
            g.base.heel_height
        );
        assert!((m.toe_spring - g.base.toe_spring).abs() < 1.0);
    }
    // Written all at once, and each STL read back measures as tabled.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let files = write_graded_atomic(&g, &out).unwrap();
    assert_eq!(files.len(), 9 * 2 + 3);
    for l in [&g.lasts[0], &g.lasts[8]] {
        let (m, _) =
            TriMesh::load_solid(out.join(format!("{}.stl", l.name)), Units::Mm, None).unwrap();
        let lm = measure_last(m, &l.name).unwrap();
        assert!((lm.stick_length - l.measures.stick_length).abs() < 0.05);
        assert!((lm.joint_girth - l.measures.joint_girth).abs() < 0.1);
        let step = std::fs::read_to_string(out.join(format!("{}.step", l.name))).unwrap();
        assert!(step.starts_with("ISO-10303-21;") && step.contains("FACETED_BREP"));
        assert_eq!(
            step.matches("FACE_SURFACE(").count(),
            l.mesh.triangles.len()
        );
    }
    let csv = std::fs::read_to_string(out.join("steps.csv")).unwrap();
    assert_eq!(csv.lines().count(), 9);
}

#[test]
fn uk_with_width_fittings() {
    let widths = parse_widths("E,F,G", "F").unwrap();
    let sp = GradeSpec {
        widths,
        ..spec(System::Uk, Mode::Arithmetic, 4.0, "3-7", &[])
    };
    let g = grade(default_last(), "LastScan_Default", &sp).unwrap();
    assert_eq!(g.lasts.len(), 15);
    // 4 size steps in each of 3 fittings, 2 fitting steps in each of 5 sizes.
    assert_eq!(g.steps.len(), 12 + 10);
    check_steps(&g);
    let fit: Vec<_> = g.steps.iter().filter(|s| s.length_rule == 0.0).collect();
    assert_eq!(fit.len(), 10);
    for s in fit {
        assert!((s.girth_rule - 6.35).abs() < 1e-9, "{}", s.girth_rule);
    }
    let size: Vec<_> = g.steps.iter().filter(|s| s.length_rule != 0.0).collect();
    for s in size {
        assert!((s.length_rule - 25.4 / 3.0).abs() < 1e-9 && (s.girth_rule - 6.35).abs() < 1e-9);
    }
}

#[test]
fn geometric_is_proportional() {
    let g = grade(
        default_last(),
        "LastScan_Default",
        &spec(System::Paris, Mode::Geometric, 40.0, "38-46", &[]),
    )
    .unwrap();
    check_steps(&g);
    let b = &g.base;
    // Girth step the base's girth times the length step over its length (6.465 mm).
    assert!((g.girth_per_size - b.joint_girth * 20.0 / 3.0 / b.stick_length).abs() < 1e-9);
    for l in &g.lasts {
        let k = l.measures.stick_length / b.stick_length;
        for (name, v0, v) in [
            ("joint girth", b.joint_girth, l.measures.joint_girth),
            ("joint width", b.joint_width, l.measures.joint_width),
            ("instep girth", b.instep_girth, l.measures.instep_girth),
            ("bottom length", b.bottom_length, l.measures.bottom_length),
        ] {
            assert!(
                (v / v0 - k).abs() < 0.01,
                "size {}: {name} ratio {:.4}, length ratio {k:.4}",
                l.size,
                v / v0
            );
        }
    }
}

#[test]
fn bad_inputs_refused_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let run = |sp: Result<GradeSpec, GradeError>| -> String {
        let e = sp
            .and_then(|sp| grade(default_last(), "LastScan_Default", &sp))
            .and_then(|g| write_graded_atomic(&g, &out).map(|_| ()))
            .unwrap_err()
            .to_string();
        assert!(!out.exists(), "{e}");
        e
    };
    let e = run(parse_sizes("50-56", System::Paris).map(|_| -> GradeSpec { unreachable!() }));
    assert!(e.contains("size 53") && e.contains("15-52"), "{e}");
    let e = run(parse_sizes("38.3", System::Paris).map(|_| -> GradeSpec { unreachable!() }));
    assert!(e.contains("not a Paris size"), "{e}");
    let e = run(parse_widths("E,Q", "F").map(|_| -> GradeSpec { unreachable!() }));
    assert!(e.contains("\"Q\""), "{e}");
    let e = run(Ok(spec(
        System::Paris,
        Mode::Arithmetic,
        47.0,
        "38-46",
        &[],
    )));
    assert!(e.contains("--from 47 is not in the run"), "{e}");
    // A 238.7 mm last is no Paris 30 (200 mm): refused, the lengths named.
    let e = run(Ok(spec(
        System::Paris,
        Mode::Arithmetic,
        30.0,
        "28-32",
        &[],
    )));
    assert!(
        e.contains("stick length 238.7 mm") && e.contains("expected 200.0 mm"),
        "{e}"
    );
    // Nor a Mondopoint 300 (310 mm).
    let e = run(Ok(spec(
        System::Mondopoint,
        Mode::Arithmetic,
        300.0,
        "290-310",
        &[],
    )));
    assert!(e.contains("expected 310.0 mm"), "{e}");
}
