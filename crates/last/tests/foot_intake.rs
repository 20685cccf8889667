//! Real feet read as they come (docs/method.md 10.1, "Reading a foot as it comes"): each foot
//! of ../shared/data/feet as published, and copies of it written turned (heel to toe along y
//! or z, y up), in centimetres or metres, with the triangles facing inward and with the top
//! cap taken off, must come out as the same foot: the same length within 0.5 mm, the same
//! side, the heel point at the same place of the original. Non-feet are refused, naming the
//! file and why. The data directory is read at test time (FOOTSCAN_DATA, default: the shared
//! data directory beside the repository); a missing directory fails the test.

use footscan_geom::mesh::{Axes, Format, IntakeOptions, TriMesh, Units};
use footscan_geom::{P3, V3};
use footscan_last::customize::load_foot_with;
use footscan_last::customize::measure::{plan_ends, Side};
use nalgebra::Matrix3;
use std::path::{Path, PathBuf};

fn feet_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let dir = base.join("feet");
    assert!(
        dir.is_dir(),
        "the real feet are not at {} (set FOOTSCAN_DATA to the directory holding feet/)",
        dir.display()
    );
    dir
}

/// The real feet: file, its unit in mm, side (from each SOURCE.txt), and how deep the top is
/// taken off to open it (mm): 0 takes the triangles wholly in the top 3 mm (a flat cap);
/// the FIND template's top is not one flat face but a low dome with folds, so everything
/// with a corner in its top 5 mm goes (its triangles are 1-2 mm: the cut stays flat).
const FEET: [(&str, f64, Side, f64); 5] = [
    ("find_template/template_mm.stl", 1.0, Side::Left, 5.0),
    (
        "find_lowres/find_demo_template.obj",
        1000.0,
        Side::Left,
        0.0,
    ),
    (
        "makehuman/makehuman_default_right_foot_cut150mm.stl",
        1.0,
        Side::Right,
        0.0,
    ),
    ("dupontgu_my_feet/left_foot.stl", 1000.0, Side::Left, 0.0),
    ("dupontgu_my_feet/right_foot.stl", 1000.0, Side::Right, 0.0),
];

/// What a copy is: a proper rotation of the file's coordinates (mm), the unit it is written
/// in (mm per file unit), triangles turned inward, the top cap removed.
struct Copy {
    name: &'static str,
    rot: Matrix3<f64>,
    mm_per_unit: f64,
    inward: bool,
    open: bool,
    /// Every fifth triangle turned (locally inconsistent orientation).
    patchy: bool,
}

fn copies() -> Vec<Copy> {
    let id = Matrix3::identity();
    // Heel to toe along +y: x -> y, y -> -x.
    let along_y = Matrix3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0);
    // Heel to toe along +z, up +y: (x, y, z) -> (y, z, x).
    let along_z_y_up = Matrix3::new(0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0);
    // y up, heel to toe along x: (x, y, z) -> (x, z, -y).
    let y_up = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0);
    // Heel to toe along -y, upside down.
    let upside_down = Matrix3::new(0.0, 1.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 1.0)
        * Matrix3::new(1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, -1.0);
    let c = |name, rot, mm_per_unit, inward, open| Copy {
        name,
        rot,
        mm_per_unit,
        inward,
        open,
        patchy: false,
    };
    // Turned 30 degrees about up (in plan) and every fifth triangle turned.
    let (s, co) = 30f64.to_radians().sin_cos();
    let yawed = Matrix3::new(co, -s, 0.0, s, co, 0.0, 0.0, 0.0, 1.0);
    vec![
        c("mm", id, 1.0, false, false),
        c("along y", along_y, 1.0, false, false),
        c("along z, y up", along_z_y_up, 1.0, false, false),
        c("y up", y_up, 1.0, false, false),
        c("upside down", upside_down, 1.0, false, false),
        c("cm", id, 10.0, false, false),
        c("m", id, 1000.0, false, false),
        c("inward", id, 1.0, true, false),
        c("open", id, 1.0, false, true),
        c("y up, cm, inward, open", y_up, 10.0, true, true),
        Copy {
            patchy: true,
            ..c("yawed 30, patchy", yawed, 1.0, false, false)
        },
    ]
}

/// The top taken off (mm, z up): `depth` 0 takes every triangle wholly in the top 3 mm (a
/// flat cap), else every triangle with a corner in the top `depth` mm.
fn remove_top_cap(m: &mut TriMesh, depth: f64) -> usize {
    let top = m.bbox().max.z;
    let n0 = m.triangles.len();
    let keep: Vec<[u32; 3]> = (0..n0)
        .filter(|&t| {
            let c = m.corners(t);
            if depth == 0.0 {
                c.iter().any(|p| p.z < top - 3.0)
            } else {
                c.iter().all(|p| p.z <= top - depth)
            }
        })
        .map(|t| m.triangles[t])
        .collect();
    m.triangles = keep;
    n0 - m.triangles.len()
}

/// The heel point, length and side of a foot as `load_foot_with` reads it.
fn read(path: &Path, opts: &IntakeOptions) -> (P3, f64, Side, Vec<String>) {
    let (foot, frame, intake) = load_foot_with(path, opts).unwrap_or_else(|e| panic!("{e}"));
    let (o, a) = plan_ends(&foot);
    (P3::from(frame.origin), a.x - o.x, frame.side, intake.notes)
}

#[test]
fn real_feet_come_out_the_same_however_written() {
    let dir = feet_dir();
    let tmp = tempfile::tempdir().unwrap();
    let mut worst = 0.0f64;
    for (file, unit_mm, side, depth) in FEET {
        let path = dir.join(file);
        let (o0, l0, s0, notes) = read(&path, &IntakeOptions::default());
        println!("{file}: length {l0:.2} mm, {s0:?}, heel point {o0:.2?} (file frame, mm)");
        for n in &notes {
            println!("    {n}");
        }
        assert_eq!(s0, side, "{file}: side");
        let mut mm = TriMesh::read(&path).unwrap();
        mm.scale(unit_mm);
        for c in copies() {
            let mut m = mm.clone();
            if c.open {
                let n = remove_top_cap(&mut m, depth);
                assert!(n > 0, "{file}: no top cap to remove");
            }
            for p in &mut m.vertices {
                *p = P3::from(c.rot * p.coords / c.mm_per_unit);
            }
            if c.inward {
                m.flip();
            }
            if c.patchy {
                for t in m.triangles.iter_mut().step_by(5) {
                    t.swap(1, 2);
                }
            }
            let out = tmp.path().join(format!(
                "{}_{}.stl",
                file.replace('/', "_"),
                c.name.replace([' ', ','], "_")
            ));
            m.write(&out, Format::StlBinary).unwrap();
            let (o, l, s, _) = read(&out, &IntakeOptions::default());
            // The heel point back in the original's millimetres.
            let back = P3::from(c.rot.transpose() * o.coords);
            let dl = l - l0;
            let dh = (back - o0).norm();
            println!(
                "  {:24} length {l:.2} mm ({dl:+.3}), {s:?}, heel point {dh:.3} mm from the original's",
                c.name
            );
            assert!(dl.abs() <= 0.5, "{file} {}: length {l} vs {l0}", c.name);
            assert_eq!(s, s0, "{file} {}: side", c.name);
            assert!(dh <= 2.0, "{file} {}: heel point {dh} mm away", c.name);
            worst = worst.max(dl.abs());
        }
    }
    println!("largest length difference {worst:.3} mm");
}

#[test]
fn given_units_length_and_axes_are_obeyed() {
    let path = feet_dir().join("dupontgu_my_feet/left_foot.stl");
    let (_, l0, _, _) = read(&path, &IntakeOptions::default());
    // Given the axes it is: heel to toe along -y (the heel is at high y), z up.
    let given = IntakeOptions {
        axes: "-y,z".parse().unwrap(),
        units: Units::M,
        length_mm: None,
    };
    let (_, l, _, notes) = read(&path, &given);
    assert!((l - l0).abs() < 0.5, "{l} vs {l0}");
    assert!(notes.iter().any(|n| n.contains("given")), "{notes:?}");
    // The axes the wrong way round put the heel at the toe: the foot frame still finds the
    // heel under the leg, but the intake says what it was told.
    let wrong = IntakeOptions {
        axes: Axes::Given {
            forward: V3::y(),
            up: V3::z(),
        },
        ..given
    };
    let (_, _, _, notes) = read(&path, &wrong);
    assert!(notes.iter().any(|n| n.contains("+y")), "{notes:?}");
    // A given length scales heel to toe to it.
    let i = TriMesh::read_foot(
        &path,
        &IntakeOptions {
            length_mm: Some(250.0),
            ..Default::default()
        },
    )
    .unwrap();
    assert!((i.length_mm - 250.0).abs() < 1e-6, "{}", i.length_mm);
    // Millimetres said of a foot in metres: refused by its size, naming it.
    let e = TriMesh::read_foot(
        &path,
        &IntakeOptions {
            units: Units::Mm,
            ..Default::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("left_foot.stl") && e.contains("not a foot") && e.contains("100 to 360 mm"),
        "{e}"
    );
}

#[test]
fn non_feet_are_refused_saying_why() {
    let tmp = tempfile::tempdir().unwrap();
    let write = |name: &str, m: &TriMesh| {
        let p = tmp.path().join(name);
        m.write(&p, Format::StlBinary).unwrap();
        p
    };
    let cube = write(
        "cube.stl",
        &TriMesh::cuboid(P3::origin(), P3::new(200.0, 200.0, 200.0)),
    );
    let sphere = write("sphere.stl", &TriMesh::icosphere(P3::origin(), 120.0, 3));
    let rod = write(
        "rod.stl",
        &TriMesh::cuboid(P3::origin(), P3::new(300.0, 20.0, 20.0)),
    );
    let tiny = write(
        "tiny.stl",
        &TriMesh::cuboid(P3::origin(), P3::new(4.5, 1.8, 1.5)),
    );
    for (p, why) in [
        (&cube, "times as long as broad"),
        (&sphere, "times as long as broad"),
        (&rod, "times as long as broad"),
        (&tiny, "--length MM"),
    ] {
        let e = TriMesh::read_foot(p, &IntakeOptions::default())
            .unwrap_err()
            .to_string();
        println!("{e}");
        assert!(
            e.contains(&p.display().to_string()) && e.contains(why),
            "{e}"
        );
    }
    // A hole that is not the top cut: a foot with a triangle out of its sole.
    let mut m =
        TriMesh::read(feet_dir().join("makehuman/makehuman_default_right_foot_cut150mm.stl"))
            .unwrap();
    let t = (0..m.triangles.len())
        .filter(|&t| m.face_normal(t).z < -0.9)
        .min_by(|&a, &b| {
            let z = |t: usize| m.corners(t).iter().map(|p| p.z).sum::<f64>();
            z(a).total_cmp(&z(b))
        })
        .unwrap();
    m.triangles.remove(t);
    let holed = write("holed.stl", &m);
    let e = TriMesh::read_foot(&holed, &IntakeOptions::default())
        .unwrap_err()
        .to_string();
    println!("{e}");
    assert!(e.contains("holed.stl") && e.contains("too small"), "{e}");
    // A hole as large as a cut, in the sole: not at the top.
    let mut m =
        TriMesh::read(feet_dir().join("makehuman/makehuman_default_right_foot_cut150mm.stl"))
            .unwrap();
    let n0 = m.triangles.len();
    let low: Vec<P3> = m.vertices.iter().filter(|p| p.z < 1.0).copied().collect();
    let mid = low.iter().fold(V3::zeros(), |s, p| s + p.coords) / low.len() as f64;
    let verts = m.vertices.clone();
    m.triangles.retain(|t| {
        let c = t.map(|i| verts[i as usize]);
        let g = (c[0].coords + c[1].coords + c[2].coords) / 3.0;
        !(g.z < 5.0 && (g.x - mid.x).hypot(g.y - mid.y) < 25.0)
    });
    assert!(m.triangles.len() < n0);
    let holed = write("sole_cut.stl", &m);
    let e = TriMesh::read_foot(&holed, &IntakeOptions::default())
        .unwrap_err()
        .to_string();
    println!("{e}");
    assert!(
        e.contains("sole_cut.stl") && e.contains("it is not at the top"),
        "{e}"
    );
}
