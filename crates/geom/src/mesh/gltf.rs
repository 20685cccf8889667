//! glTF 2.0 binary (.glb): triangle meshes for the web (three.js, the dashboard's viewer) and
//! for Blender, one named node per part.
//!
//! glTF fixes its units and axes: metres, +Y up, +Z to the front. footscan works in
//! millimetres with +Z up (the glass is z = 0), so every position is mapped
//! (x, y, z) mm -> (x, z, -y) / 1000 m, a proper rotation (-90 degrees about x) plus the
//! scale, baked into the vertices rather than left in a node transform: a reader that ignores
//! the scene graph (some mesh tools do) still gets the right size and the foot standing up.
//!
//! Written with serde_json rather than the `gltf-json` crate: a scene of a few meshes needs
//! one JSON object and one binary chunk, and the Khronos validator checks the result in the
//! tests (crates/geom/tests/gltf_readback.rs).

use super::TriMesh;
use crate::V3;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// One part of a scene: a mesh in millimetres, drawn as `name` in one colour or with a colour
/// per vertex.
#[derive(Debug, Clone, Copy)]
pub struct GlbPart<'a> {
    /// The node's (and mesh's) name, e.g. "foot" or "last".
    pub name: &'a str,
    pub mesh: &'a TriMesh,
    /// Linear RGBA, each in [0, 1]; alpha below 1 draws the part translucent (glTF "BLEND").
    pub colour: [f32; 4],
    /// A linear RGBA colour per vertex (COLOR_0), multiplied with `colour` by glTF's rule;
    /// e.g. the clearance between the foot and a last.
    pub vertex_colours: Option<&'a [[f32; 4]]>,
}

/// A named point (a landmark), written as an empty node at that place so a viewer (or
/// Blender) finds it by name.
#[derive(Debug, Clone, Copy)]
pub struct GlbMark<'a> {
    pub name: &'a str,
    /// Millimetres, in the parts' frame.
    pub at: crate::P3,
}

/// A named polyline (a measured length), drawn as glTF lines.
#[derive(Debug, Clone, Copy)]
pub struct GlbLine<'a> {
    pub name: &'a str,
    /// Millimetres, in the parts' frame; two points at least.
    pub points: &'a [crate::P3],
    /// Linear RGBA, each in [0, 1].
    pub colour: [f32; 4],
}

/// A whole scene: meshes, then marks, then lines, one node each in that order.
#[derive(Debug, Clone, Copy, Default)]
pub struct GlbScene<'a> {
    pub parts: &'a [GlbPart<'a>],
    pub marks: &'a [GlbMark<'a>],
    pub lines: &'a [GlbLine<'a>],
}

/// Why a scene could not be written; each names the part or file.
#[derive(Debug, thiserror::Error)]
pub enum GlbError {
    #[error("a glTF scene needs at least one part")]
    NoParts,
    #[error("part {name:?}: {what}")]
    Part { name: String, what: String },
    /// The cause is the source, printed once by the chain (`footscan_util::Chain`, anyhow).
    #[error("{}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
}

/// glTF's position of a footscan point in millimetres.
pub fn gltf_position(p: &crate::P3) -> [f32; 3] {
    [
        (p.x / 1000.0) as f32,
        (p.z / 1000.0) as f32,
        (-p.y / 1000.0) as f32,
    ]
}

fn gltf_direction(v: &V3) -> [f32; 3] {
    [v.x as f32, v.z as f32, -v.y as f32]
}

fn check(part: &GlbPart) -> Result<(), GlbError> {
    let err = |what: String| GlbError::Part {
        name: part.name.to_string(),
        what,
    };
    let m = part.mesh;
    if m.triangles.is_empty() {
        return Err(err("the mesh has no triangles".into()));
    }
    if let Some((i, p)) = m
        .vertices
        .iter()
        .enumerate()
        .find(|(_, p)| !p.iter().all(|c| c.is_finite()))
    {
        return Err(err(format!("vertex {i} is not finite: {p:?}")));
    }
    let n = m.vertices.len();
    if let Some((t, tri)) = m
        .triangles
        .iter()
        .enumerate()
        .find(|(_, t)| t.iter().any(|&k| k as usize >= n))
    {
        return Err(err(format!(
            "triangle {t} refers to vertex {tri:?}, but there are {n} vertices"
        )));
    }
    let in_unit = |c: &[f32]| c.iter().all(|v| (0.0..=1.0).contains(v));
    if !in_unit(&part.colour) {
        return Err(err(format!(
            "colour {:?} is outside [0, 1] (linear RGBA)",
            part.colour
        )));
    }
    if let Some(vc) = part.vertex_colours {
        if vc.len() != n {
            return Err(err(format!(
                "{} vertex colours for {n} vertices (one per vertex)",
                vc.len()
            )));
        }
        if let Some((i, c)) = vc.iter().enumerate().find(|(_, c)| !in_unit(&c[..])) {
            return Err(err(format!(
                "vertex colour {i} {c:?} is outside [0, 1] (linear RGBA)"
            )));
        }
    }
    Ok(())
}

fn f32s(v: &mut dyn Iterator<Item = f32>) -> Vec<u8> {
    v.flat_map(|x| x.to_le_bytes()).collect()
}

/// Appends `bytes` as a buffer view (4-byte aligned) and returns its index.
fn push_view(bin: &mut Vec<u8>, views: &mut Vec<Value>, bytes: &[u8], target: u32) -> usize {
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    views.push(json!({
        "buffer": 0,
        "byteOffset": bin.len(),
        "byteLength": bytes.len(),
        "target": target,
    }));
    bin.extend_from_slice(bytes);
    views.len() - 1
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

/// The .glb bytes of a scene of `parts`, one node each, in the order given.
pub fn glb(parts: &[GlbPart]) -> Result<Vec<u8>, GlbError> {
    glb_scene(&GlbScene {
        parts,
        ..GlbScene::default()
    })
}

/// Appends `data` as a float vertex attribute (a buffer view and its accessor, "VEC3" or
/// "VEC4" by N; positions carry their bounds, as glTF requires) and returns the accessor's
/// index.
fn push_floats<const N: usize>(
    bin: &mut Vec<u8>,
    views: &mut Vec<Value>,
    accessors: &mut Vec<Value>,
    data: &[[f32; N]],
    position: bool,
) -> usize {
    let view = push_view(
        bin,
        views,
        &f32s(&mut data.iter().flatten().copied()),
        ARRAY_BUFFER,
    );
    let mut a = json!({
        "bufferView": view, "componentType": FLOAT, "count": data.len(),
        "type": format!("VEC{N}"),
    });
    if position {
        let (mut lo, mut hi) = ([f32::MAX; N], [f32::MIN; N]);
        for p in data {
            for d in 0..N {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        a["min"] = json!(lo.as_slice());
        a["max"] = json!(hi.as_slice());
    }
    accessors.push(a);
    accessors.len() - 1
}

/// The .glb bytes of `scene`.
pub fn glb_scene(scene: &GlbScene) -> Result<Vec<u8>, GlbError> {
    let parts = scene.parts;
    if parts.is_empty() {
        return Err(GlbError::NoParts);
    }
    let (mut bin, mut views, mut accessors) = (Vec::new(), Vec::new(), Vec::new());
    let (mut meshes, mut materials, mut nodes) = (Vec::new(), Vec::new(), Vec::new());
    for part in parts {
        check(part)?;
        let m = part.mesh;
        let pos: Vec<[f32; 3]> = m.vertices.iter().map(gltf_position).collect();
        // The validator wants unit normals; a vertex no triangle uses has none, so it gets up.
        let normals: Vec<[f32; 3]> = m
            .vertex_normals()
            .iter()
            .map(|n| {
                if n.norm() > 0.5 {
                    gltf_direction(n)
                } else {
                    [0.0, 1.0, 0.0]
                }
            })
            .collect();
        let pa = push_floats(&mut bin, &mut views, &mut accessors, &pos, true);
        let na = push_floats(&mut bin, &mut views, &mut accessors, &normals, false);
        let mut attributes = json!({ "POSITION": pa, "NORMAL": na });
        if let Some(vc) = part.vertex_colours {
            let ca = push_floats(&mut bin, &mut views, &mut accessors, vc, false);
            attributes["COLOR_0"] = json!(ca);
        }
        let idx: Vec<u8> = m
            .triangles
            .iter()
            .flatten()
            .flat_map(|k| k.to_le_bytes())
            .collect();
        let iv = push_view(&mut bin, &mut views, &idx, ELEMENT_ARRAY_BUFFER);
        accessors.push(json!({
            "bufferView": iv, "componentType": UNSIGNED_INT,
            "count": m.triangles.len() * 3, "type": "SCALAR",
        }));
        let indices = accessors.len() - 1;
        let translucent = part.colour[3] < 1.0
            || part
                .vertex_colours
                .is_some_and(|vc| vc.iter().any(|c| c[3] < 1.0));
        let mut material = json!({
            "name": part.name,
            "pbrMetallicRoughness": {
                "baseColorFactor": part.colour,
                "metallicFactor": 0.0,
                "roughnessFactor": 0.8,
            },
        });
        if translucent {
            // Seen through, the far side of a translucent part must be drawn too.
            material["alphaMode"] = json!("BLEND");
            material["doubleSided"] = json!(true);
        }
        materials.push(material);
        meshes.push(json!({
            "name": part.name,
            "primitives": [{
                "attributes": attributes,
                "indices": indices,
                "material": materials.len() - 1,
                "mode": 4,
            }],
        }));
        nodes.push(json!({ "name": part.name, "mesh": meshes.len() - 1 }));
    }
    for mark in scene.marks {
        if !mark.at.iter().all(|c| c.is_finite()) {
            return Err(GlbError::Part {
                name: mark.name.to_string(),
                what: format!("the mark is not at a finite point: {:?}", mark.at),
            });
        }
        nodes.push(json!({ "name": mark.name, "translation": gltf_position(&mark.at) }));
    }
    for line in scene.lines {
        let err = |what: String| GlbError::Part {
            name: line.name.to_string(),
            what,
        };
        if line.points.len() < 2 {
            return Err(err(format!(
                "a line needs two points at least, it has {}",
                line.points.len()
            )));
        }
        if !line
            .points
            .iter()
            .flat_map(|p| p.iter())
            .all(|c| c.is_finite())
        {
            return Err(err("a point of the line is not finite".into()));
        }
        if !line.colour.iter().all(|v| (0.0..=1.0).contains(v)) {
            return Err(err(format!(
                "colour {:?} is outside [0, 1] (linear RGBA)",
                line.colour
            )));
        }
        // Segments as glTF LINES (each segment's two ends), which more readers take than
        // LINE_STRIP (trimesh 4 drops strips).
        let pos: Vec<[f32; 3]> = line
            .points
            .windows(2)
            .flat_map(|w| [gltf_position(&w[0]), gltf_position(&w[1])])
            .collect();
        let pa = push_floats(&mut bin, &mut views, &mut accessors, &pos, true);
        materials.push(json!({
            "name": line.name,
            "pbrMetallicRoughness": { "baseColorFactor": line.colour, "metallicFactor": 0.0 },
        }));
        meshes.push(json!({
            "name": line.name,
            "primitives": [{
                "attributes": { "POSITION": pa },
                "material": materials.len() - 1,
                "mode": 1,
            }],
        }));
        nodes.push(json!({ "name": line.name, "mesh": meshes.len() - 1 }));
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let doc = json!({
        "asset": { "version": "2.0", "generator": "footscan" },
        "scene": 0,
        "scenes": [{ "name": "footscan", "nodes": (0..nodes.len()).collect::<Vec<_>>() }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{ "byteLength": bin.len() }],
    });
    let mut json_bytes = serde_json::to_vec(&doc).expect("a JSON value always serializes");
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    Ok(out)
}

/// Writes [`glb`] of `parts` to `path` (a temporary file renamed into place, so a failed
/// write leaves no partial file).
pub fn write_glb(path: impl AsRef<Path>, parts: &[GlbPart]) -> Result<(), GlbError> {
    write_glb_scene(
        path,
        &GlbScene {
            parts,
            ..GlbScene::default()
        },
    )
}

/// Writes [`glb_scene`] of `scene` to `path`, atomically as [`write_glb`].
pub fn write_glb_scene(path: impl AsRef<Path>, scene: &GlbScene) -> Result<(), GlbError> {
    let path = path.as_ref();
    let bytes = glb_scene(scene)?;
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".tmp");
    let tmp = path.with_file_name(name);
    let io = |source| GlbError::Io {
        path: path.to_path_buf(),
        source,
    };
    std::fs::write(&tmp, bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)
}

/// Skin colour of the foot, and the red it turns where it stands out of the last.
const SKIN: [f32; 4] = [0.85, 0.68, 0.58, 1.0];
const PROUD: [f32; 4] = [0.85, 0.05, 0.05, 1.0];
/// How far out of the last (mm) the foot is fully red; from 0 to this it shades over.
pub const PROUD_FULL_MM: f64 = 2.0;

/// The foot inside the last, for a last maker to look at before the milling: the foot
/// (node `inner`: "foot", or "stock last" where a stock last stands for the foot) coloured by where it stands out of the last (skin inside, shading to red at
/// [`PROUD_FULL_MM`] out), the last (node "last") translucent around it. Both in the same
/// frame, millimetres. Returns the bytes and the foot's largest protrusion (mm, 0 if none).
pub fn foot_in_last_glb(
    foot: &TriMesh,
    inner: &str,
    last: &TriMesh,
) -> Result<(Vec<u8>, f64), GlbError> {
    let bvh = super::Bvh::new(last);
    let mut worst = 0.0f64;
    let colours: Vec<[f32; 4]> = foot
        .vertices
        .iter()
        .map(|p| {
            let out = bvh.signed_distance(p).map_or(0.0, |s| s.distance.max(0.0));
            worst = worst.max(out);
            let t = (out / PROUD_FULL_MM).clamp(0.0, 1.0) as f32;
            [0, 1, 2, 3].map(|c| SKIN[c] + t * (PROUD[c] - SKIN[c]))
        })
        .collect();
    let bytes = glb(&[
        GlbPart {
            name: inner,
            mesh: foot,
            colour: [1.0; 4],
            vertex_colours: Some(&colours),
        },
        GlbPart {
            name: "last",
            mesh: last,
            colour: [0.55, 0.62, 0.75, 0.35],
            vertex_colours: None,
        },
    ])?;
    Ok((bytes, worst))
}

/// [`foot_in_last_glb`] written atomically to `path`; the foot's largest protrusion (mm).
pub fn write_foot_in_last_glb(
    path: impl AsRef<Path>,
    foot: &TriMesh,
    inner: &str,
    last: &TriMesh,
) -> Result<f64, GlbError> {
    let path = path.as_ref();
    let (bytes, worst) = foot_in_last_glb(foot, inner, last)?;
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(".tmp");
    let tmp = path.with_file_name(name);
    let io = |source| GlbError::Io {
        path: path.to_path_buf(),
        source,
    };
    std::fs::write(&tmp, bytes).map_err(io)?;
    std::fs::rename(&tmp, path).map_err(io)?;
    Ok(worst)
}

impl TriMesh {
    /// This mesh alone as a .glb scene: one node `name`, in a neutral grey.
    pub fn to_glb(&self, name: &str) -> Result<Vec<u8>, GlbError> {
        glb(&[GlbPart {
            name,
            mesh: self,
            colour: [0.8, 0.8, 0.8, 1.0],
            vertex_colours: None,
        }])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::P3;

    fn tetra() -> TriMesh {
        TriMesh::new(
            vec![
                P3::new(0.0, 0.0, 0.0),
                P3::new(10.0, 0.0, 0.0),
                P3::new(0.0, 10.0, 0.0),
                P3::new(0.0, 0.0, 10.0),
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
    }

    #[test]
    fn header_and_chunks_are_consistent() {
        let b = tetra().to_glb("t").unwrap();
        assert_eq!(&b[0..4], b"glTF");
        assert_eq!(
            u32::from_le_bytes(b[8..12].try_into().unwrap()) as usize,
            b.len()
        );
        let jl = u32::from_le_bytes(b[12..16].try_into().unwrap()) as usize;
        assert_eq!(jl % 4, 0);
        let doc: Value = serde_json::from_slice(&b[20..20 + jl]).unwrap();
        assert_eq!(doc["nodes"][0]["name"], "t");
        // 10 mm along y is 0.01 m along -z in glTF.
        let bl = u32::from_le_bytes(b[20 + jl..24 + jl].try_into().unwrap()) as usize;
        assert_eq!(b.len(), 28 + jl + bl);
        assert_eq!(
            doc["accessors"][0]["min"][2].as_f64().unwrap() as f32,
            -0.01
        );
        assert_eq!(doc["accessors"][0]["max"][1].as_f64().unwrap() as f32, 0.01);
    }

    #[test]
    fn bad_parts_are_named() {
        let mut m = tetra();
        m.triangles.push([0, 1, 9]);
        let e = m.to_glb("last").unwrap_err().to_string();
        assert!(e.contains("\"last\"") && e.contains("vertex"), "{e}");
        let e = glb(&[]).unwrap_err().to_string();
        assert!(e.contains("at least one part"), "{e}");
        let t = tetra();
        let e = glb(&[GlbPart {
            name: "foot",
            mesh: &t,
            colour: [1.0, 0.0, 0.0, 1.0],
            vertex_colours: Some(&[[0.0; 4]; 3]),
        }])
        .unwrap_err()
        .to_string();
        assert!(e.contains("3 vertex colours for 4 vertices"), "{e}");
    }
}
