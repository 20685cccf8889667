//! `last adjust` folds no triangle of the whole last: every shared last (read at test time from
//! FOOTSCAN_DATA/lasts, default the shared data beside the repository) and the simulator's
//! parametric lasts, adjusted to analytic feet of three lengths and both sides, written as
//! last_adjusted.stl and read back, are compared triangle by triangle with the last as read.
//! The count is independent of the deformation's own: the input's triangle normals are
//! carried by the orthogonal map (mirror allowed) that best takes the input's triangle
//! centroids onto the output's, and a triangle whose normal then points against its output
//! normal is folded.
//!
//! The untangling that undoes the faded field's folds may move a vertex only a little: at
//! most `RELAX_MAX_MM` from where the field put it (FOLD_DEBUG=1 prints where each fold is).

use footscan_geom::mesh::{TriMesh, Units};
use footscan_geom::V3;
use footscan_last::adjust::last::{deform_last, prepare_last, prepare_mesh, LastOptions};
use footscan_last::adjust::output::{write_outputs, Report, LAST_STL};
use footscan_last::adjust::surface::fit_bottom;
use footscan_last::adjust::synthetic::AnalyticFoot;
use footscan_last::adjust::{adjust, AdjustOptions, FootPlantar, Side};
use footscan_sim::foot::Side as SimSide;
use footscan_sim::last::{Last, LastParams, Toe};
use nalgebra::Matrix3;
use std::path::{Path, PathBuf};

/// How far the untangling may move a vertex off where the faded field put it (mm; a bottom
/// vertex sliding along the adjusted bottom is no change of shape and is not counted): 1.83
/// at most in the 66 runs here, on the scanned last's 3-4 mm triangles at the toe, where the
/// change is 60 mm; 0.75 on the other lasts.
const RELAX_MAX_MM: f64 = 2.5;

fn lasts_dir() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let dir = base.join("lasts");
    assert!(dir.is_dir(), "no lasts at {}", dir.display());
    dir
}

/// Triangles of `out` whose normal points against the input's, carried by the best
/// orthogonal map between the two meshes' triangle centroids (same triangle order).
fn folds(input: &TriMesh, out: &TriMesh) -> usize {
    assert_eq!(input.triangles.len(), out.triangles.len());
    let cen = |m: &TriMesh, t: usize| {
        let [a, b, c] = m.corners(t);
        (a.coords + b.coords + c.coords) / 3.0
    };
    let n = input.triangles.len();
    let ca = (0..n).map(|t| cen(input, t)).sum::<V3>() / n as f64;
    let cb = (0..n).map(|t| cen(out, t)).sum::<V3>() / n as f64;
    let mut h = Matrix3::zeros();
    for t in 0..n {
        h += (cen(input, t) - ca) * (cen(out, t) - cb).transpose();
    }
    let svd = h.svd(true, true);
    let r = svd.v_t.unwrap().transpose() * svd.u.unwrap().transpose();
    let bad: Vec<usize> = (0..n)
        .filter(|&t| (r * input.face_normal(t)).dot(&out.face_normal(t)) < 0.0)
        .collect();
    if std::env::var_os("FOLD_DEBUG").is_some() {
        let bb = out.bbox();
        for &t in bad.iter().take(12) {
            let c = cen(out, t);
            let [a, b, d] = input.corners(t);
            let e = [(b - a).norm(), (d - b).norm(), (a - d).norm()];
            println!(
                "   fold t{t} at ({:.1}, {:.1}, {:.1}) of x {:.0}..{:.0} z {:.0}; input area {:.3} mm2, edges {:.2} {:.2} {:.2}, n_in {:?} n_out {:?}",
                c.x, c.y, c.z, bb.min.x, bb.max.x, bb.min.z,
                input.face_normal_raw(t).norm() / 2.0, e[0], e[1], e[2],
                (r * input.face_normal(t)).map(|x| (x * 100.0).round() / 100.0).as_slice(),
                out.face_normal(t).map(|x| (x * 100.0).round() / 100.0).as_slice()
            );
            let f = |p: &footscan_geom::P3| format!("({:.2}, {:.2}, {:.2})", p.x, p.y, p.z);
            let [oa, ob, oc] = out.corners(t);
            println!(
                "      in {} {} {} out {} {} {}",
                f(&a),
                f(&b),
                f(&d),
                f(&oa),
                f(&ob),
                f(&oc)
            );
        }
    }
    bad.len()
}

/// Adjusts `prep` to `foot`, writes the outputs, reads last_adjusted.stl back and counts
/// its folds against the last as read.
fn count(
    name: &str,
    foot: &FootPlantar,
    prep: &footscan_last::adjust::last::PreparedLast,
) -> usize {
    let a = adjust(foot, &prep.bottom, &AdjustOptions::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    let surf = fit_bottom(&a, 3.0).unwrap();
    let (mesh, dr) = deform_last(prep, &a, 30.0).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let report = Report::new(&foot.source, name, &a, &surf, Some(dr));
    write_outputs(dir.path(), &a, &surf, Some((prep, &mesh)), &report).unwrap();
    let back = TriMesh::read(dir.path().join(LAST_STL)).unwrap();
    let f = folds(&prep.mesh, &back);
    // Nor does it pass through itself (no triangle pair crosses).
    let crossing = back.self_intersections();
    assert!(crossing.is_empty(), "{name}: crossing pairs {crossing:?}");
    println!(
        "{name}: {f} folded of {} (deform reports {}, {} vertices moved by up to {:.2} mm, \
         slid on the bottom by up to {:.2} mm; bottom vs adjusted RMS {:.3} max {:.3} mm)",
        back.triangles.len(),
        dr.flipped_triangles,
        dr.relaxed_vertices,
        dr.relaxed_max_mm,
        dr.slid_max_mm,
        dr.bottom_rms_mm,
        dr.bottom_max_mm
    );
    assert!(
        dr.relaxed_max_mm <= RELAX_MAX_MM,
        "{name}: the untangling moved a vertex {} mm",
        dr.relaxed_max_mm
    );
    assert!(
        dr.bottom_max_mm <= 1.0,
        "{name}: bottom {} mm off",
        dr.bottom_max_mm
    );
    f
}

fn feet() -> Vec<(String, f64, FootPlantar)> {
    let mut v = Vec::new();
    for len in [230.0, 250.0, 270.0] {
        for side in [Side::Right, Side::Left] {
            v.push((
                format!("{len} mm {side:?} foot"),
                len,
                AnalyticFoot::new(len, side).plantar(0.25),
            ));
        }
    }
    v
}

#[test]
fn no_shared_last_folds() {
    let mut files: Vec<PathBuf> = std::fs::read_dir(lasts_dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            matches!(
                p.extension().and_then(|e| e.to_str()),
                Some("stl" | "obj" | "ply" | "asc")
            )
        })
        .collect();
    files.sort();
    assert!(files.len() >= 4, "{files:?}");
    let mut total = 0;
    for (foot_name, len, foot) in feet() {
        for path in &files {
            let name = path.file_name().unwrap().to_string_lossy();
            // Unscaled files take the foot's length plus the toe allowance.
            let length = (name.contains("RoundTip")).then_some(len + 12.0);
            let opts = LastOptions {
                units: Units::Auto,
                length_mm: length,
                ..LastOptions::default()
            };
            let prep = prepare_last(path, &opts).unwrap();
            total += count(&format!("{name} on the {foot_name}"), &foot, &prep);
        }
    }
    assert_eq!(total, 0, "folded triangles in the adjusted shared lasts");
}

#[test]
fn no_parametric_last_folds() {
    let mut total = 0;
    for (foot_name, len, foot) in feet() {
        for toe in Toe::ALL {
            for (heel, side) in [(0.0, SimSide::Right), (40.0, SimSide::Left)] {
                let last = Last::new(LastParams {
                    toe,
                    heel_mm: heel,
                    length_mm: len + 12.0,
                    side,
                    ..LastParams::default()
                })
                .unwrap();
                let name = format!("{toe:?} toe heel {heel} {side:?} last on the {foot_name}");
                let prep = prepare_mesh(
                    last.local_mesh().clone(),
                    Path::new(&name),
                    &LastOptions::default(),
                )
                .unwrap();
                total += count(&name, &foot, &prep);
            }
        }
    }
    assert_eq!(
        total, 0,
        "folded triangles in the adjusted parametric lasts"
    );
}
