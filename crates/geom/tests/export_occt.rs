//! IGES and STEP exports read back by an independent reader: OpenCASCADE 8 (through OCP, in
//! the venv scripts/setup.sh makes), which must read each file, find the shape valid, find
//! one face per surface and one free edge per curve, keep each B-spline's parameter domain
//! and evaluate the same points as we do at sample parameters, within 1e-6 mm.

use footscan_geom::export::{iges, step, Header};
use footscan_geom::nurbs::{NurbsCurve, NurbsSurface};
use footscan_geom::P3;
use std::path::{Path, PathBuf};
use std::process::Command;

const TOL_MM: f64 = 1e-6;
const FRACTIONS: [f64; 7] = [0.0, 0.07, 0.25, 0.5, 0.618, 0.93, 1.0];

fn python() -> PathBuf {
    if let Some(p) = std::env::var_os("FOOTSCAN_OCCT_PYTHON") {
        return PathBuf::from(p);
    }
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/venv-occt/bin/python");
    assert!(
        p.exists(),
        "{} is missing: run scripts/setup.sh to make the OpenCASCADE venv (or set FOOTSCAN_OCCT_PYTHON)",
        p.display()
    );
    p
}

fn script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/occt_readback.py")
}

fn out_dir(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn p(x: f64, y: f64, z: f64) -> P3 {
    P3::new(x, y, z)
}

fn curve(
    degree: usize,
    knots: Vec<f64>,
    points: Vec<P3>,
    weights: Option<Vec<f64>>,
    periodic: bool,
) -> NurbsCurve {
    let c = if periodic {
        NurbsCurve::new_periodic(degree, knots, points, weights)
    } else {
        NurbsCurve::new(degree, knots, points, weights)
    };
    c.unwrap()
}

/// A periodic curve of `degree` through the loop `pts` as control points, with the
/// non-uniform spacing `gaps` (one per distinct control point) repeated with the period.
fn periodic_curve(degree: usize, pts: &[P3], gaps: &[f64], weights: Option<&[f64]>) -> NurbsCurve {
    let n = pts.len();
    let mut points = pts.to_vec();
    points.extend_from_slice(&pts[..degree]);
    let weights = weights.map(|w| {
        let mut w = w.to_vec();
        w.extend_from_within(..degree);
        w
    });
    let total = n + 2 * degree + 1;
    let mut knots = vec![0.0];
    for i in 1..total {
        let gap = gaps[(i + n - degree) % n];
        knots.push(knots[i - 1] + gap);
    }
    curve(degree, knots, points, weights, true)
}

fn curves() -> Vec<NurbsCurve> {
    let s = 0.5f64.sqrt();
    vec![
        // Degree 1, non-uniform, in 3D.
        curve(
            1,
            vec![0.0, 0.0, 0.3, 0.35, 1.2, 1.2],
            vec![
                p(0.0, 0.0, 0.0),
                p(10.0, 5.0, 1.0),
                p(12.0, 9.0, 4.0),
                p(30.0, -2.0, 7.5),
            ],
            None,
            false,
        ),
        // Degree 2 rational: a full circle of radius 40 (nine points, planar, closed).
        curve(
            2,
            vec![
                0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0,
            ],
            [
                (1.0, 0.0),
                (1.0, 1.0),
                (0.0, 1.0),
                (-1.0, 1.0),
                (-1.0, 0.0),
                (-1.0, -1.0),
                (0.0, -1.0),
                (1.0, -1.0),
                (1.0, 0.0),
            ]
            .iter()
            .map(|(x, y)| p(100.0 + 40.0 * x, 20.0 + 40.0 * y, 5.0))
            .collect(),
            Some(vec![1.0, s, 1.0, s, 1.0, s, 1.0, s, 1.0]),
            false,
        ),
        // Degree 3, open, non-uniform, on a non-[0,1] domain.
        curve(
            3,
            vec![2.0, 2.0, 2.0, 2.0, 2.4, 3.1, 3.15, 5.0, 5.0, 5.0, 5.0],
            vec![
                p(0.0, 0.0, 0.0),
                p(20.0, 30.0, 5.0),
                p(45.0, 28.0, -4.0),
                p(60.0, 0.0, 10.0),
                p(80.0, -25.0, 12.0),
                p(95.0, 3.0, 20.0),
                p(110.0, 10.0, 0.0),
            ],
            None,
            false,
        ),
        // Degree 4, periodic (unclamped), non-uniform, a closed 3D loop.
        periodic_curve(
            4,
            &[
                p(0.0, 0.0, 0.0),
                p(30.0, -10.0, 5.0),
                p(60.0, 0.0, 12.0),
                p(70.0, 30.0, 3.0),
                p(40.0, 55.0, -6.0),
                p(5.0, 40.0, 2.0),
                p(-12.0, 18.0, 8.0),
            ],
            &[1.0, 1.3, 0.8, 1.1, 0.9, 1.25, 0.7],
            None,
        ),
        // Degree 5, open, rational with uneven weights.
        curve(
            5,
            vec![
                0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.2, 0.45, 0.5, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0,
            ],
            (0..9)
                .map(|i| {
                    p(
                        12.0 * i as f64,
                        15.0 * (i as f64 * 0.9).sin(),
                        4.0 * (i as f64 * 0.5).cos(),
                    )
                })
                .collect(),
            Some(vec![1.0, 0.6, 2.2, 1.4, 0.9, 3.0, 1.1, 0.5, 1.0]),
            false,
        ),
        // Degree 3, periodic and rational, planar (z = 7).
        periodic_curve(
            3,
            &[
                p(0.0, 0.0, 7.0),
                p(50.0, 0.0, 7.0),
                p(60.0, 40.0, 7.0),
                p(20.0, 60.0, 7.0),
                p(-10.0, 30.0, 7.0),
            ],
            &[0.2, 0.25, 0.15, 0.3, 0.1],
            Some(&[1.0, 2.0, 0.7, 1.5, 1.2]),
        ),
    ]
}

#[allow(clippy::too_many_arguments)]
fn surface(
    du: usize,
    dv: usize,
    ku: Vec<f64>,
    kv: Vec<f64>,
    nu: usize,
    nv: usize,
    f: impl Fn(usize, usize) -> P3,
    weights: Option<Vec<f64>>,
) -> NurbsSurface {
    let points = (0..nu)
        .flat_map(|i| (0..nv).map(move |j| (i, j)))
        .map(|(i, j)| f(i, j))
        .collect();
    NurbsSurface::new(du, dv, ku, kv, nu, nv, points, weights).unwrap()
}

fn surfaces() -> Vec<NurbsSurface> {
    let s = 0.5f64.sqrt();
    let circle = [
        (1.0, 0.0),
        (1.0, 1.0),
        (0.0, 1.0),
        (-1.0, 1.0),
        (-1.0, 0.0),
        (-1.0, -1.0),
        (0.0, -1.0),
        (1.0, -1.0),
        (1.0, 0.0),
    ];
    let cw = [1.0, s, 1.0, s, 1.0, s, 1.0, s, 1.0];
    let bump = |i: usize, j: usize| ((i * 7 + j * 3) % 5) as f64 - 2.0;
    // A periodic-in-v tube: degree 3 in v around a loop of 6 points, degree 2 along u.
    let ring = 6;
    let tube_kv: Vec<f64> = (0..ring + 3 + 3 + 1).map(|k| k as f64 * 0.5).collect();
    let tube = surface(
        2,
        3,
        vec![0.0, 0.0, 0.0, 0.4, 1.0, 1.0, 1.0],
        tube_kv,
        4,
        ring + 3,
        |i, j| {
            let a = (j % ring) as f64 * std::f64::consts::TAU / ring as f64;
            let r = 20.0 + 3.0 * i as f64;
            p(
                r * a.cos(),
                r * a.sin() * 0.7,
                25.0 * i as f64 + 2.0 * (j % ring) as f64,
            )
        },
        None,
    );
    let tube = tube.with_periodic(false, true).unwrap();
    vec![
        // Degree 1 x 2, non-uniform.
        surface(
            1,
            2,
            vec![0.0, 0.0, 0.3, 1.0, 1.0],
            vec![0.0, 0.0, 0.0, 0.6, 1.0, 1.0, 1.0],
            3,
            4,
            |i, j| p(20.0 * i as f64, 15.0 * j as f64, bump(i, j)),
            None,
        ),
        // Degree 3 x 3, non-uniform, on a non-[0,1] domain.
        surface(
            3,
            3,
            vec![-1.0, -1.0, -1.0, -1.0, -0.2, 0.5, 2.0, 2.0, 2.0, 2.0],
            vec![0.0, 0.0, 0.0, 0.0, 0.1, 0.7, 0.75, 1.0, 1.0, 1.0, 1.0],
            6,
            7,
            |i, j| {
                p(
                    10.0 * i as f64,
                    12.0 * j as f64,
                    3.0 * bump(i, j) + 0.1 * (i * j) as f64,
                )
            },
            None,
        ),
        // Rational 2 x 1: a full cylinder of radius 30, height 80 (closed in u, a seam).
        surface(
            2,
            1,
            vec![
                0.0, 0.0, 0.0, 0.25, 0.25, 0.5, 0.5, 0.75, 0.75, 1.0, 1.0, 1.0,
            ],
            vec![0.0, 0.0, 80.0, 80.0],
            9,
            2,
            |i, j| p(30.0 * circle[i].0, 30.0 * circle[i].1, 80.0 * j as f64),
            Some((0..18).map(|k| cw[k / 2]).collect()),
        ),
        tube,
        // Degree 2 x 3 with its u = 0 boundary collapsed to a point (a cone's apex): the STEP
        // face leaves that side out of its loop.
        surface(
            2,
            3,
            vec![0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0],
            vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
            4,
            4,
            |i, j| {
                let a = j as f64 * 0.5;
                let r = 12.0 * i as f64;
                p(r * a.cos(), r * a.sin(), 60.0 - 15.0 * i as f64)
            },
            None,
        ),
        // Degree 5 x 2, rational with uneven weights, non-uniform.
        surface(
            5,
            2,
            vec![
                0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.35, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0,
            ],
            vec![0.0, 0.0, 0.0, 0.2, 0.9, 1.0, 1.0, 1.0],
            7,
            5,
            |i, j| p(9.0 * i as f64, 11.0 * j as f64, 2.0 * bump(i, j)),
            Some((0..35).map(|k| 0.5 + ((k * 13) % 7) as f64 * 0.3).collect()),
        ),
    ]
}

// ---- Read-back and comparison. ----

fn readback(file: &Path) -> serde_json::Value {
    let mut cmd = Command::new(python());
    cmd.arg(script()).arg(file).arg("--unit");
    for f in FRACTIONS {
        cmd.arg(format!("{f}"));
    }
    for fu in FRACTIONS {
        for fv in FRACTIONS {
            cmd.arg(format!("{fu},{fv}"));
        }
    }
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("running {}: {e}", python().display()));
    let stdout = String::from_utf8_lossy(&out.stdout);
    let json: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap_or_else(|e| {
        panic!(
            "occt_readback.py on {} printed no JSON ({e}); status {}, stderr:\n{}\nstdout:\n{stdout}",
            file.display(),
            out.status,
            String::from_utf8_lossy(&out.stderr)
        )
    });
    assert_eq!(json["read"], true, "OCCT cannot read {}", file.display());
    assert_eq!(
        json["valid"],
        true,
        "OCCT finds {} invalid: {json}",
        file.display()
    );
    json
}

fn xyz(v: &serde_json::Value) -> P3 {
    let a = v.as_array().unwrap();
    P3::new(
        a[0].as_f64().unwrap(),
        a[1].as_f64().unwrap(),
        a[2].as_f64().unwrap(),
    )
}

fn pair(v: &serde_json::Value) -> (f64, f64) {
    (v[0].as_f64().unwrap(), v[1].as_f64().unwrap())
}

/// How many edges OCCT makes of one curve: STEP keeps it whole; OCCT's IGES reader splits
/// a curve at its C0 knots (distinct interior knots of multiplicity >= degree; its
/// read.iges.bspline.continuity = 1 default), keeping the parametrisation of each piece.
fn expected_pieces(c: &NurbsCurve, iges: bool) -> usize {
    if !iges {
        return 1;
    }
    let (lo, hi) = c.domain();
    let mut breaks: Vec<f64> = c
        .knots
        .iter()
        .copied()
        .filter(|k| *k > lo && *k < hi)
        .collect();
    breaks.dedup();
    1 + breaks
        .iter()
        .filter(|b| c.knots.iter().filter(|k| *k == *b).count() >= c.degree)
        .count()
}

/// The largest distance between OCCT's points and ours at the same parameters, after
/// checking that OCCT kept every B-spline's degree and parameter domain (curves split into
/// pieces must tile our domain in order).
fn compare(
    file: &Path,
    json: &serde_json::Value,
    curves: &[NurbsCurve],
    surfaces: &[NurbsSurface],
) -> f64 {
    let name = file.display();
    let iges = json["format"] == "IGES";
    assert_eq!(json["faces"], surfaces.len(), "{name}: faces");
    let pieces: usize = curves.iter().map(|c| expected_pieces(c, iges)).sum();
    assert_eq!(json["free_edges"], pieces, "{name}: free edges");
    if iges {
        assert_eq!(
            json["transferred"],
            curves.len() + surfaces.len(),
            "{name}: IGES entities transferred"
        );
    }
    let mut worst = 0.0f64;
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-12 * (1.0 + a.abs());
    let mut got_curves = json["curves"].as_array().unwrap().iter();
    for (k, c) in curves.iter().enumerate() {
        let (lo, hi) = c.domain();
        let mut at = lo;
        for piece in 0..expected_pieces(c, iges) {
            let got = got_curves.next().unwrap();
            assert_eq!(got["type"], "Geom_BSplineCurve", "{name}: curve {k}: {got}");
            assert_eq!(got["degree"], c.degree, "{name}: curve {k} degree");
            let (olo, ohi) = pair(&got["domain"]);
            assert!(same(at, olo) && ohi <= hi + 1e-12, "{name}: curve {k} piece {piece}: OCCT domain [{olo}, {ohi}], ours [{lo}, {hi}], expected to start at {at}");
            at = ohi;
            for pt in got["points"].as_array().unwrap() {
                let u = pt["u"].as_f64().unwrap();
                let d = (c.point(u) - xyz(&pt["p"])).norm();
                assert!(d <= TOL_MM, "{name}: curve {k} at u = {u}: {d} mm apart");
                worst = worst.max(d);
            }
        }
        assert!(
            same(at, hi),
            "{name}: curve {k}: OCCT's pieces end at {at}, ours at {hi}"
        );
    }
    for (k, (s, got)) in surfaces
        .iter()
        .zip(json["surfaces"].as_array().unwrap())
        .enumerate()
    {
        assert_eq!(
            got["type"], "Geom_BSplineSurface",
            "{name}: surface {k}: {got}"
        );
        assert_eq!(
            (got["degree_u"].clone(), got["degree_v"].clone()),
            (s.degree_u.into(), s.degree_v.into()),
            "{name}: surface {k} degrees"
        );
        let ((u0, u1), (v0, v1)) = (s.domain_u(), s.domain_v());
        let (ou, ov) = (pair(&got["domain_u"]), pair(&got["domain_v"]));
        assert!(
            same(u0, ou.0) && same(u1, ou.1) && same(v0, ov.0) && same(v1, ov.1),
            "{name}: surface {k}: OCCT domain {ou:?} x {ov:?}, ours [{u0}, {u1}] x [{v0}, {v1}]"
        );
        let mut pts = got["points"].as_array().unwrap().iter();
        for fu in FRACTIONS {
            for fv in FRACTIONS {
                let pt = pts.next().unwrap();
                let (u, v) = (pt["u"].as_f64().unwrap(), pt["v"].as_f64().unwrap());
                assert!(same(u, u0 + fu * (u1 - u0)) && same(v, v0 + fv * (v1 - v0)));
                let ours = s.point(u, v);
                let d = (ours - xyz(&pt["p"])).norm();
                assert!(
                    d <= TOL_MM,
                    "{name}: surface {k} at ({fu}, {fv}): {d} mm apart"
                );
                worst = worst.max(d);
            }
        }
    }
    worst
}

#[test]
fn occt_reads_back_iges_and_step() {
    let dir = out_dir("export_occt");
    let (cs, ss) = (curves(), surfaces());
    let header = Header::new("footscan export test");
    let mut report = Vec::new();
    let files: [(&str, &[NurbsCurve], &[NurbsSurface]); 5] = [
        ("all.igs", &cs, &ss),
        ("frame.igs", &cs, &[]),
        ("all.step", &cs, &ss),
        ("surfaces.step", &[], &ss),
        ("curves.step", &cs, &[]),
    ];
    for (name, c, s) in files {
        let path = dir.join(name);
        if name.ends_with(".igs") {
            if s.is_empty() {
                iges::write_frame(&path, c, &header).unwrap();
            } else {
                iges::write(&path, c, s, &header).unwrap();
            }
        } else {
            step::write(&path, c, s, &header).unwrap();
        }
        let json = readback(&path);
        let worst = compare(&path, &json, c, s);
        report.push(format!(
            "{name}: {} faces, {} free edges, valid, max deviation {worst:.3e} mm",
            json["faces"], json["free_edges"]
        ));
    }
    println!(
        "OCCT read-back ({}):\n  {}",
        dir.display(),
        report.join("\n  ")
    );
}

#[test]
fn a_failed_write_names_the_path_and_leaves_nothing() {
    let dir = out_dir("export_fail");
    let path = dir.join("missing_dir").join("x.igs");
    let err = iges::write(&path, &curves(), &[], &Header::new("x")).unwrap_err();
    assert!(err.to_string().contains("missing_dir/x.igs"), "{err}");
    let mut bad = curves();
    bad[2].weights = Some(vec![1.0; 3]);
    let path = dir.join("bad.step");
    let err = step::write(&path, &bad, &[], &Header::new("x")).unwrap_err();
    assert_eq!(err.to_string(), "curve 2: 3 weights for 7 control points");
    assert_eq!(
        std::fs::read_dir(&dir).unwrap().count(),
        0,
        "nothing written"
    );
}
