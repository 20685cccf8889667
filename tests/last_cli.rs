//! `footscan last join` on the RoundTip pair (unitless meshes scaled by --length): the files
//! it promises, seams.json's figures within the seam targets, and a bad plane refused with a
//! message naming it. The bottom adjustment on a real simulated scan: `footscan scan` with the
//! `last.adjust` stage after measure.foot (the last's files land in the scan directory beside
//! the scan's), then `footscan last adjust` on the saved scan against each of the four real
//! lasts scaled to the foot's size class, with the bounds on the result, and bad
//! inputs refused by name with nothing written. The lasts are read at test time
//! (FOOTSCAN_DATA, default: the shared data directory beside the repository).

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn footscan() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_footscan"));
    c.current_dir(env!("CARGO_MANIFEST_DIR"));
    c
}

fn lasts_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    let dir = base.join("lasts");
    assert!(
        dir.is_dir(),
        "the real lasts are not at {} (set FOOTSCAN_DATA to the directory holding lasts/)",
        dir.display()
    );
    dir
}

/// Each of `files` is in `out`, not empty, and named in the command's output.
fn assert_wrote(out: &Path, stdout: &str, files: &[&str]) {
    for f in files {
        let p = out.join(f);
        assert!(
            p.metadata().map(|m| m.len() > 0).unwrap_or(false),
            "{} missing or empty",
            p.display()
        );
        assert!(stdout.contains(f), "{f} not reported");
    }
}

#[test]
fn last_join_writes_the_joined_last_and_its_seam_figures() {
    let lasts = lasts_dir();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("joined");
    let o = footscan()
        .args(["last", "join", "--back"])
        .arg(lasts.join("Last_Heeled_RoundTip.stl"))
        .arg("--toe")
        .arg(lasts.join("Last_Flat_RoundTip.stl"))
        .args([
            "--length", "260", "--angle", "10", "--points", "300", "--aux", "2,2",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    println!("{stdout}{}", String::from_utf8_lossy(&o.stderr));
    assert!(o.status.success());
    assert_wrote(
        &out,
        &stdout,
        &[
            "joined.igs",
            "joined.step",
            "joined.stl",
            "seams.json",
            "network.json",
            "zebra.png",
            "views.png",
        ],
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("seams.json")).unwrap()).unwrap();
    assert_eq!(json["points_per_section"], 300);
    assert!(
        json["stl"].as_str().unwrap().starts_with("closed"),
        "{json}"
    );
    for seam in ["back_seam", "toe_seam"] {
        let s = &json["quality"][seam];
        assert!(s["gap_max_mm"].as_f64().unwrap() <= 0.01, "{s}");
        assert!(s["normal_max_deg"].as_f64().unwrap() <= 0.1, "{s}");
        assert!(s["curvature_rel_max"].as_f64().unwrap() <= 0.05, "{s}");
    }
    // At 10 deg the bundle gives up to 36 guides, less those too near the sole guides.
    assert!(json["guides"].as_u64().unwrap() >= 24, "{json}");
}

#[test]
fn last_join_refuses_a_plane_that_misses_the_last() {
    let lasts = lasts_dir();
    let dir = tempfile::tempdir().unwrap();
    let o = footscan()
        .args(["last", "join", "--back"])
        .arg(lasts.join("Last_Heeled_RoundTip.stl"))
        .arg("--toe")
        .arg(lasts.join("Last_Flat_RoundTip.stl"))
        .args(["--length", "260", "--toe-plane", "400"])
        .arg("--out")
        .arg(dir.path().join("x"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("toe last") && err.contains("400.0"), "{err}");
    assert!(
        !dir.path().join("x").exists(),
        "wrote output for a failed join"
    );
    let o = footscan()
        .args([
            "last",
            "join",
            "--back",
            "a.stl",
            "--toe",
            "b.stl",
            "--back-plane",
            "x%",
        ])
        .arg("--out")
        .arg(dir.path().join("y"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(err.contains("a.stl"), "{err}");
}

/// `footscan last adjust --scan SCAN --last LAST EXTRA... --out OUT`.
fn last_adjust(scan: &Path, last: &Path, extra: &[&str], out: &Path) -> std::process::Output {
    footscan()
        .args(["last", "adjust", "--scan"])
        .arg(scan)
        .arg("--last")
        .arg(last)
        .args(extra)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

fn report(dir: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(dir.join("adjust.json")).unwrap()).unwrap()
}

/// The targets on an adjusted bottom: outline RMS 0.3 mm, landmarks 0.5 mm, sole
/// height RMS 0.3 mm; and the deformed last better than the rigid fit.
fn check(r: &Value, what: &str) {
    let after = &r["after"];
    let f = |k: &str| after[k].as_f64().unwrap();
    println!(
        "{what}: eps {:.4} zeta {:.4}; after: height RMS {:.3} max {:.3} mm, >0.5 mm {:.2} %, outline RMS {:.3} mm, landmarks {:.3} mm; before: height RMS {:.2}, outline RMS {:.2}",
        r["eps"].as_f64().unwrap(),
        r["zeta"].as_f64().unwrap(),
        f("height_rms_mm"),
        f("height_max_mm"),
        100.0 * f("share_beyond_0_5"),
        f("outline_rms_mm"),
        f("landmark_max_mm"),
        r["before"]["height_rms_mm"].as_f64().unwrap(),
        r["before"]["outline_rms_mm"].as_f64().unwrap(),
    );
    assert!(f("outline_rms_mm") <= 0.3, "{what}: outline RMS");
    assert!(f("landmark_max_mm") <= 0.5, "{what}: landmarks");
    assert!(f("height_rms_mm") <= 0.3, "{what}: height RMS");
    assert!(f("uncovered_share") == 0.0, "{what}: footprint uncovered");
    assert!(r["before"]["height_rms_mm"].as_f64().unwrap() > f("height_rms_mm"));
}

#[test]
fn scan_with_last_adjust_then_the_cli_on_every_real_last() {
    let lasts = lasts_dir();
    let tmp = tempfile::tempdir().unwrap();
    let base =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml"))
            .unwrap();
    let warped = lasts.join("LastScan_Warped.stl");
    let cfg = tmp.path().join("scan-last.toml");
    std::fs::write(
        &cfg,
        format!(
            "{base}\n[[pipeline.stages]]\nstage = \"last.adjust\"\nlast = {:?}\nlength_mm = 262.0\n",
            warped.display().to_string()
        ),
    )
    .unwrap();
    let scan = tmp.path().join("scan");
    // A file --out held before: the scan must not claim it wrote it.
    std::fs::create_dir(&scan).unwrap();
    std::fs::write(scan.join("old-notes.txt"), "from an earlier visit").unwrap();
    let o = footscan()
        .args(["scan", "--config"])
        .arg(&cfg)
        .arg("--out")
        .arg(&scan)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let said = String::from_utf8_lossy(&o.stdout);
    let wrote = said.lines().find(|l| l.starts_with("wrote ")).unwrap_or("");
    assert!(
        wrote.contains("adjust.json") && wrote.contains("grid.bin"),
        "{said}"
    );
    assert!(!wrote.contains("old-notes.txt"), "{wrote}");
    for f in [
        "bottom.igs",
        "bottom.step",
        "last_adjusted.stl",
        "last_adjusted.glb",
        "deviation.png",
        "adjust.json",
        "measurements.json",
        "grid.bin",
    ] {
        assert!(
            scan.join(f).is_file(),
            "{f} missing from the scan directory"
        );
    }
    let in_scan = report(&scan);
    check(&in_scan, "stage last.adjust, LastScan_Warped");
    // Nothing temporary left behind in the scan directory.
    for e in std::fs::read_dir(&scan).unwrap() {
        let n = e.unwrap().file_name().to_string_lossy().to_string();
        assert!(!n.starts_with('.'), "{n} left in the scan directory");
    }

    // The CLI on the saved scan: every real last, scaled to the foot's size class (foot
    // length + 12 mm toe allowance; the foot is 250 mm).
    for name in [
        "LastScan_Default.stl",
        "LastScan_Warped.stl",
        "Last_Flat_RoundTip.stl",
        "Last_Heeled_RoundTip.stl",
    ] {
        let out = tmp.path().join(name.trim_end_matches(".stl"));
        let o = last_adjust(&scan, &lasts.join(name), &["--length", "262"], &out);
        let text = String::from_utf8_lossy(&o.stdout);
        println!("{text}");
        assert!(
            o.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(text.contains("outline RMS"), "{text}");
        let r = report(&out);
        check(&r, name);
        if name == "LastScan_Warped.stl" {
            // The stage and the CLI do the same computation on the same inputs.
            // (The stage's grid is in memory, the CLI's read back from grid.bin, which stores
            // f32 coordinates: equal to 1e-4 mm.)
            let k = |v: &Value| v["after"]["height_rms_mm"].as_f64().unwrap();
            assert!(
                (k(&r) - k(&in_scan)).abs() < 1e-4,
                "{} vs {}",
                k(&r),
                k(&in_scan)
            );
        }
        // The deformed last keeps the adjusted bottom and folds nothing (7 of 6,784 folds on
        // LastScan_Default before the untangling, docs/method.md 9.2.1).
        let d = &r["deform"];
        let g = |k: &str| d[k].as_f64().unwrap();
        assert!(g("bottom_max_mm") <= 1.0, "{name}: {d}");
        assert_eq!(g("flipped_triangles"), 0.0, "{name}: {d}");
        // The deformed last is a closed solid in millimetres that OpenCASCADE-free readers
        // accept: binary STL with 84 + 50 n bytes.
        let stl = std::fs::read(out.join("last_adjusted.stl")).unwrap();
        let n = u32::from_le_bytes(stl[80..84].try_into().unwrap()) as usize;
        assert_eq!(stl.len(), 84 + 50 * n);
    }

    // A scanned last bottom as the last: the simulator's parametric last (round toe, 260 mm,
    // heel 25 mm) scanned like a foot, then adjusted to the foot scan. Only the bottom: no
    // whole last is written.
    let last_scan = tmp.path().join("last-scan");
    let o = footscan()
        .args(["scan", "--config"])
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim-last.toml"))
        .arg("--out")
        .arg(&last_scan)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = tmp.path().join("from-last-scan");
    let o = last_adjust(&scan, &last_scan, &[], &out);
    let text = String::from_utf8_lossy(&o.stdout);
    println!("{text}");
    assert!(
        o.status.success(),
        "last scan: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(text.contains("no whole last to deform"), "{text}");
    check(&report(&out), "scanned parametric last bottom");
    for f in ["bottom.igs", "bottom.step", "deviation.png", "adjust.json"] {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    assert!(!out.join("last_adjusted.stl").exists());

    // Bad input: a scan without measurements, a last in metres said to be millimetres, a
    // last far too short for the foot. Each names its input; nothing is written.
    let bare = tmp.path().join("bare");
    std::fs::create_dir(&bare).unwrap();
    std::fs::copy(scan.join("grid.bin"), bare.join("grid.bin")).unwrap();
    // A directory given as the last is a last scan: without its grid.bin, refused.
    let empty = tmp.path().join("empty-last-scan");
    std::fs::create_dir(&empty).unwrap();
    let cases: [(&Path, PathBuf, &[&str], &str); 4] = [
        (&scan, empty.clone(), &[], "grid.bin"),
        (&bare, warped.clone(), &[], "measurements.json"),
        (
            &scan,
            warped.clone(),
            &["--units", "mm"],
            "LastScan_Warped.stl",
        ),
        (
            &scan,
            warped.clone(),
            &["--length", "120"],
            "shorter than the foot",
        ),
    ];
    for (k, (s, last, extra, says)) in cases.iter().enumerate() {
        let out = tmp.path().join(format!("bad{k}"));
        let o = last_adjust(s, last, extra, &out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "case {k} succeeded");
        assert!(err.contains(says), "case {k}: {err}");
        assert!(!out.exists(), "case {k}: {} written", out.display());
    }
}

/// `footscan last join` on the RoundTip pair scaled to 260 mm, with `extra` arguments.
fn last_join(extra: &[&str], out: &Path) -> std::process::Output {
    let lasts = lasts_dir();
    let o = footscan()
        .args(["last", "join", "--length", "260", "--back"])
        .arg(lasts.join("Last_Heeled_RoundTip.stl"))
        .arg("--toe")
        .arg(lasts.join("Last_Flat_RoundTip.stl"))
        .args(extra)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap();
    println!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    o
}

#[test]
fn last_join_by_the_blend_with_a_table_writes_what_the_gordon_join_writes() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("b.txt");
    std::fs::write(&table, "# t b\n0 0\n0.25 0.2\n0.5 1\n0.75 0.2\n1 0\n").unwrap();
    let out = dir.path().join("blend");
    let blend = format!("table:{}", table.display());
    let o = last_join(&["--method", "blend", "--blend", &blend], &out);
    assert!(o.status.success());
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert_wrote(
        &out,
        &stdout,
        &[
            "joined.igs",
            "joined.step",
            "joined.stl",
            "seams.json",
            "zebra.png",
            "views.png",
        ],
    );
    let json: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("seams.json")).unwrap()).unwrap();
    assert_eq!(json["method"], "blend");
    assert_eq!(json["points_per_slice"], 240);
    assert!(
        json["stl"].as_str().unwrap().starts_with("closed"),
        "{json}"
    );
    // The same seam figures as the Gordon join's seams.json; the slices close the gap.
    for seam in ["back_seam", "toe_seam"] {
        let s = &json["quality"][seam];
        assert!(s["gap_max_mm"].as_f64().unwrap() <= 0.01, "{s}");
        assert!(s["normal_max_deg"].as_f64().unwrap().is_finite(), "{s}");
        assert!(s["curvature_rel_max"].as_f64().unwrap().is_finite(), "{s}");
    }
    // The fill used the table: b at every fill slice is the table's (linear between rows)
    // where it was read, from 0 at the boundary step to 1/2 at the middle step of each front.
    let at = |t: f64| {
        let rows = [(0.0, 0.0), (0.25, 0.2), (0.5, 1.0), (0.75, 0.2), (1.0, 0.0)];
        let i = rows.iter().position(|r| r.0 >= t).unwrap().max(1);
        let (a, b) = (rows[i - 1], rows[i]);
        a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
    };
    let w = json["weights"].as_array().unwrap();
    assert!(w.len() >= 9, "{w:?}");
    for r in w {
        let (tb, b) = (r[1].as_f64().unwrap(), r[2].as_f64().unwrap());
        assert!((b - at(tb)).abs() < 1e-9, "b({tb}) = {b}, table {}", at(tb));
    }
    // The first step of each front is the extension itself (the table's b(0) = b(1) = 0).
    assert_eq!(
        (w[1][2].as_f64(), w[w.len() - 2][2].as_f64()),
        (Some(0.0), Some(0.0))
    );
}

#[test]
fn last_join_refuses_a_bad_blend_naming_the_word_or_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("b.txt");
    std::fs::write(&table, "0 0\n0.5 1\n0.4 0\n").unwrap();
    let bad_table = format!("table:{}", table.display());
    let missing = format!("table:{}", dir.path().join("none.txt").display());
    let cases: [(&[&str], String); 4] = [
        (&["--blend", "cubic"], "table:FILE".into()),
        (
            &["--blend", &bad_table],
            format!("{}, line 3", table.display()),
        ),
        (&["--blend", &missing], "none.txt".into()),
        (
            &["--blend", "poly", "--toe-plane", "150,0,0,1,0.2,0"],
            "not parallel".into(),
        ),
    ];
    for (k, (args, says)) in cases.iter().enumerate() {
        let out = dir.path().join(format!("out{k}"));
        let mut a = vec!["--method", "blend"];
        a.extend_from_slice(args);
        let o = last_join(&a, &out);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "case {k} succeeded");
        assert!(err.contains(says.as_str()), "case {k}: {err}");
        assert!(!out.exists(), "case {k}: {} written", out.display());
    }
}

/// A solid along x from 0 to `len` whose cross-section (y, z) is the band between the
/// polylines `outer` and `inner` (same length, outer[k] facing inner[k]), as STL at `path`.
fn band_prism_stl(outer: &[(f64, f64)], inner: &[(f64, f64)], len: f64, path: &Path) {
    use footscan_geom::mesh::{Format, TriMesh};
    use footscan_geom::P3;
    let m = outer.len();
    let ring: Vec<(f64, f64)> = outer.iter().chain(inner.iter().rev()).copied().collect();
    let n = ring.len() as u32;
    let mut v: Vec<P3> = ring.iter().map(|&(y, z)| P3::new(0.0, y, z)).collect();
    v.extend(ring.iter().map(|&(y, z)| P3::new(len, y, z)));
    let (a, b) = (|j: u32| j % n, |j: u32| n + j % n);
    let mut t = Vec::new();
    for j in 0..n {
        t.push([a(j), a(j + 1), b(j + 1)]);
        t.push([a(j), b(j + 1), b(j)]);
    }
    for k in 0..m as u32 - 1 {
        let (o0, o1, i1, i0) = (k, k + 1, n - 2 - k, n - 1 - k);
        t.extend([[a(o1), a(o0), a(i0)], [a(o1), a(i0), a(i1)]]);
        t.extend([[b(o0), b(o1), b(i0)], [b(i0), b(o1), b(i1)]]);
    }
    let mut mesh = TriMesh::new(v, t);
    if mesh.volume() < 0.0 {
        mesh.triangles.iter_mut().for_each(|tr| tr.swap(1, 2));
    }
    mesh.write(path, Format::StlBinary).unwrap();
}

#[test]
fn last_join_names_the_section_plane_or_last_it_cannot_use() {
    let dir = tempfile::tempdir().unwrap();
    let p = |f: &str| dir.path().join(f);
    // An arch (half ring open below): its centroid lies under the arch, outside the loop.
    let arc = |r: f64, dx: f64| -> Vec<(f64, f64)> {
        (0..=24)
            .map(|k| {
                let a = std::f64::consts::PI * k as f64 / 24.0;
                (r * a.cos() + dx, r * a.sin())
            })
            .collect()
    };
    band_prism_stl(&arc(40.0, 0.0), &arc(30.0, 0.0), 260.0, &p("arch.stl"));
    // Two small arches side by side in one file: every section is two loops.
    band_prism_stl(&arc(10.0, -30.0), &arc(5.0, -30.0), 260.0, &p("a.stl"));
    let mut two = footscan_geom::mesh::TriMesh::read(p("a.stl")).unwrap();
    let other = {
        band_prism_stl(&arc(10.0, 30.0), &arc(5.0, 30.0), 260.0, &p("b.stl"));
        footscan_geom::mesh::TriMesh::read(p("b.stl")).unwrap()
    };
    let n = two.vertices.len() as u32;
    two.vertices.extend(other.vertices.iter().copied());
    two.triangles
        .extend(other.triangles.iter().map(|t| t.map(|i| i + n)));
    two.write(p("two.stl"), footscan_geom::mesh::Format::StlBinary)
        .unwrap();
    let mut far = footscan_geom::mesh::TriMesh::read(p("arch.stl")).unwrap();
    far.translate(&footscan_geom::V3::new(1000.0, 0.0, 0.0));
    far.write(p("far.stl"), footscan_geom::mesh::Format::StlBinary)
        .unwrap();
    let cases: [(&str, &str, &[&str], &[&str]); 4] = [
        (
            "arch.stl",
            "arch.stl",
            &[],
            &[
                "of the back last at",
                "cannot be aligned",
                "misses the loop",
            ],
        ),
        (
            "two.stl",
            "arch.stl",
            &[],
            &["back last", "(161.2, 0.0, 0.0)", "2 loops"],
        ),
        (
            "arch.stl",
            "two.stl",
            &["--method", "blend"],
            &["toe last", "(182.0, 0.0, 0.0)", "2 loops"],
        ),
        (
            "arch.stl",
            "far.stl",
            &[],
            &["do not overlap", "1000.0..1260.0"],
        ),
    ];
    for (k, (back, toe, extra, says)) in cases.iter().enumerate() {
        let out = p(&format!("out{k}"));
        let o = footscan()
            .args(["last", "join", "--as-is", "--units", "mm", "--back"])
            .arg(p(back))
            .arg("--toe")
            .arg(p(toe))
            .args(*extra)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        println!("case {k}: {err}");
        assert!(!o.status.success(), "case {k} succeeded");
        for s in *says {
            assert!(err.contains(s), "case {k}: {s:?} not in {err}");
        }
        assert!(!out.exists(), "case {k}: {} written", out.display());
    }
}
