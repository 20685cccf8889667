//! glTF binary exports read back by independent readers: the Khronos glTF validator (npm
//! gltf-validator, scripts/gltf_validate.mjs) must report no errors, and Python trimesh
//! (scripts/gltf_trimesh.py) must read, per named node, the triangle count of our STL and its
//! bounds (read by trimesh from the STL too) in metres with glTF's +Y up. Both tools are
//! installed under target/ by scripts/setup.sh; the real meshes come from the shared data
//! directory (FOOTSCAN_DATA).

use footscan_geom::mesh::{
    write_glb, write_glb_scene, GlbLine, GlbMark, GlbPart, GlbScene, TriMesh,
};
use footscan_geom::P3;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Bounds agree to 1 micrometre: f32 metres near 0.3 m are exact to 3e-8 m.
const TOL_M: f64 = 1e-6;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn data() -> PathBuf {
    let base = std::env::var_os("FOOTSCAN_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| repo().join("../shared/data"));
    assert!(
        base.join("lasts").is_dir(),
        "the real meshes are not at {} (set FOOTSCAN_DATA to the directory holding lasts/ and feet/)",
        base.display()
    );
    base
}

fn tool(rel: &str, env: &str) -> PathBuf {
    if let Some(p) = std::env::var_os(env) {
        return PathBuf::from(p);
    }
    let p = repo().join(rel);
    assert!(
        p.exists(),
        "{} is missing: run scripts/setup.sh to install it (or set {env})",
        p.display()
    );
    p
}

fn lines(out: std::process::Output, what: &str) -> Vec<Value> {
    assert!(
        out.status.success(),
        "{what} failed: {}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

fn validate(files: &[PathBuf]) -> Vec<Value> {
    tool(
        "target/npm-gltf/node_modules/gltf-validator",
        "FOOTSCAN_GLTF_NPM",
    );
    let out = Command::new("node")
        .arg(repo().join("scripts/gltf_validate.mjs"))
        .args(files)
        .output()
        .expect("node (Node.js) runs the glTF validator; install it with scripts/setup.sh");
    lines(out, "the glTF validator")
}

fn trimesh(files: &[PathBuf]) -> Vec<Value> {
    let py = tool("target/venv-gltf/bin/python", "FOOTSCAN_GLTF_PYTHON");
    let out = Command::new(py)
        .arg(repo().join("scripts/gltf_trimesh.py"))
        .args(files)
        .output()
        .unwrap();
    lines(out, "trimesh")
}

/// A fresh directory per test (the tests run in parallel).
fn out_dir(test: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("gltf_readback")
        .join(test);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Bounds of a trimesh part: [[min x, y, z], [max x, y, z]].
fn bounds(v: &Value) -> [[f64; 3]; 2] {
    let b = |i: usize, d: usize| v["bounds"][i][d].as_f64().unwrap();
    [[b(0, 0), b(0, 1), b(0, 2)], [b(1, 0), b(1, 1), b(1, 2)]]
}

/// STL bounds (mm, +Z up) as glTF bounds (m, +Y up): (x, y, z) -> (x, z, -y) / 1000.
fn stl_bounds_in_gltf(b: [[f64; 3]; 2]) -> [[f64; 3]; 2] {
    let m = 1e-3;
    [
        [b[0][0] * m, b[0][2] * m, -b[1][1] * m],
        [b[1][0] * m, b[1][2] * m, -b[0][1] * m],
    ]
}

fn assert_bounds(name: &str, got: [[f64; 3]; 2], want: [[f64; 3]; 2]) {
    for i in 0..2 {
        for d in 0..3 {
            assert!(
                (got[i][d] - want[i][d]).abs() < TOL_M,
                "{name}: bound [{i}][{d}] is {} m in the glb, {} m from the STL",
                got[i][d],
                want[i][d]
            );
        }
    }
}

#[test]
fn lasts_feet_and_a_scene_pass_the_validator_and_read_back_in_trimesh() {
    let data = data();
    let stls: Vec<(&str, PathBuf)> = vec![
        ("last", data.join("lasts/LastScan_Default.stl")),
        ("last", data.join("lasts/Last_Heeled_RoundTip.stl")),
        ("foot", data.join("feet/dupontgu_my_feet/right_foot.stl")),
        (
            "foot",
            data.join("feet/makehuman/makehuman_default_right_foot_cut150mm.stl"),
        ),
    ];
    let dir = out_dir("readers");
    let mut glbs = Vec::new();
    let mut meshes = Vec::new();
    for (i, (name, stl)) in stls.iter().enumerate() {
        let m = TriMesh::read(stl).unwrap();
        let p = dir.join(format!("{i}-{name}.glb"));
        write_glb(
            &p,
            &[GlbPart {
                name,
                mesh: &m,
                colour: [0.8, 0.7, 0.6, 1.0],
                vertex_colours: None,
            }],
        )
        .unwrap();
        glbs.push(p);
        meshes.push(m);
    }
    // A scene: the makehuman foot inside the default last (both in their own frames: the
    // readers do not care whether it fits), the last translucent and coloured per vertex.
    let (foot, last) = (&meshes[3], &meshes[0]);
    let colours: Vec<[f32; 4]> = last
        .vertices
        .iter()
        .map(|p| {
            let t = (p.z / 100.0).clamp(0.0, 1.0) as f32;
            [t, 0.5, 1.0 - t, 0.4]
        })
        .collect();
    let scene = dir.join("scene.glb");
    let (heel, toe) = (P3::new(10.0, 20.0, 0.0), P3::new(250.0, -30.0, 5.0));
    write_glb_scene(
        &scene,
        &GlbScene {
            parts: &[
                GlbPart {
                    name: "foot",
                    mesh: foot,
                    colour: [0.9, 0.75, 0.65, 1.0],
                    vertex_colours: None,
                },
                GlbPart {
                    name: "last",
                    mesh: last,
                    colour: [1.0, 1.0, 1.0, 0.4],
                    vertex_colours: Some(&colours),
                },
            ],
            marks: &[GlbMark {
                name: "heel",
                at: heel,
            }],
            lines: &[GlbLine {
                name: "length",
                points: &[heel, toe],
                colour: [1.0, 0.0, 0.0, 1.0],
            }],
        },
    )
    .unwrap();
    glbs.push(scene.clone());

    for r in validate(&glbs) {
        assert_eq!(
            r["errors"], 0,
            "{}: the validator found errors: {:#}",
            r["file"], r["messages"]
        );
        eprintln!(
            "{}: validator: 0 errors, {} warnings, {} infos",
            r["file"], r["warnings"], r["infos"]
        );
    }

    let stl_paths: Vec<PathBuf> = stls.iter().map(|(_, p)| p.clone()).collect();
    let from_stl = trimesh(&stl_paths);
    let from_glb = trimesh(&glbs);
    for (i, (name, stl)) in stls.iter().enumerate() {
        let s = from_stl[i]["parts"].as_object().unwrap();
        assert_eq!(s.len(), 1, "{}", stl.display());
        let s = s.values().next().unwrap();
        let g = &from_glb[i]["parts"][*name];
        assert!(
            g.is_object(),
            "{}: no node {name:?}: {}",
            glbs[i].display(),
            from_glb[i]
        );
        assert_eq!(g["triangles"], s["triangles"], "{}", stl.display());
        assert_eq!(
            g["triangles"].as_u64().unwrap() as usize,
            meshes[i].triangles.len()
        );
        assert_bounds(
            &glbs[i].display().to_string(),
            bounds(g),
            stl_bounds_in_gltf(bounds(s)),
        );
    }
    let parts = &from_glb[4]["parts"];
    for (name, i) in [("foot", 3), ("last", 0)] {
        let s = &from_stl[i]["parts"]
            .as_object()
            .unwrap()
            .values()
            .next()
            .unwrap();
        assert_eq!(parts[name]["triangles"], s["triangles"], "scene {name}");
        assert_bounds(
            &format!("scene {name}"),
            bounds(&parts[name]),
            stl_bounds_in_gltf(bounds(s)),
        );
    }
    // The mark sits where it was put, in metres with +Y up; the line spans heel to toe.
    let mark = &from_glb[4]["marks"]["heel"];
    for (d, want) in [0.010, 0.0, -0.020].iter().enumerate() {
        assert!(
            (mark[d].as_f64().unwrap() - want).abs() < TOL_M,
            "heel mark {mark}"
        );
    }
    assert_bounds(
        "scene length line",
        bounds(&parts["length"]),
        stl_bounds_in_gltf([[10.0, -30.0, 0.0], [250.0, 20.0, 5.0]]),
    );
    // The normals are in the file: the viewer shades with them (the validator has checked
    // they are unit vectors).
    let bytes = std::fs::read(&glbs[0]).unwrap();
    let jl = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: Value = serde_json::from_slice(&bytes[20..20 + jl]).unwrap();
    let prim = &doc["meshes"][0]["primitives"][0];
    assert!(prim["attributes"]["NORMAL"].is_u64(), "{prim}");
}

#[test]
fn a_failed_write_names_the_file_and_leaves_nothing() {
    let dir = out_dir("failed_write").join("missing");
    let m = TriMesh::new(
        vec![
            footscan_geom::P3::new(0.0, 0.0, 0.0),
            footscan_geom::P3::new(1.0, 0.0, 0.0),
            footscan_geom::P3::new(0.0, 1.0, 0.0),
        ],
        vec![[0, 1, 2]],
    );
    let p = dir.join("x.glb");
    let e = write_glb(
        &p,
        &[GlbPart {
            name: "t",
            mesh: &m,
            colour: [1.0; 4],
            vertex_colours: None,
        }],
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("x.glb"), "{e}");
    assert!(!p.exists());
}
