//! The foot inside its last for the dashboard's 3D view (issue 35): the clinic's last job
//! makes the last in the last's own frame from the scan's footprint, so the scan's foot
//! (model.glb, the foot frame) and the last do not share coordinates. The placement is
//! recovered from the footprint itself, which the job carries in both frames point for
//! point (a rigid fit, mirrored when the last's medial side is the other way), so the view
//! follows whatever placement the customization chose without reading its internals. The
//! last is brought into the foot frame laid flat (its bottom curve taken out, as the rules
//! measure it; the scanned foot stands on flat glass), and the foot is coloured by how far
//! each vertex stands out of it. Written as `last/fit.glb` (nodes "foot" and "last").

use footscan::cad::FootFrame;
use footscan::measure::Measurements;
use footscan::scandata::ScanDir;
use footscan_geom::mesh::{GlbPart, TriMesh};
use footscan_geom::{dist_by_hypot, P2, P3, V2};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The view's file in the last's directory.
pub const FIT_FILE: &str = "fit.glb";

/// The foot's colours as foot_in_last.glb has them (footscan_geom::mesh::gltf: skin inside
/// the last, shading to red at PROUD_FULL_MM out; model.glb's skin) and the last's.
const SKIN: [f32; 4] = [0.85, 0.68, 0.58, 1.0];
const PROUD: [f32; 4] = [0.85, 0.05, 0.05, 1.0];
const LAST: [f32; 4] = [0.55, 0.62, 0.75, 0.35];

/// A footprint that moved by more than this (mm) between the frames was not placed rigidly:
/// the view would put the last in the wrong place, so none is made.
const RIGID_TOLERANCE_MM: f64 = 0.05;

/// The last's placement around the scanned foot and what the view shows, as the job's
/// record gives it (`GET /api/scans/{id}/last`, `fit`).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct FitView {
    /// `last/fit.glb`, downloadable as the last's other files.
    pub file: String,
    /// A point (x, y) of the last's frame is, in the foot frame of model.glb (origin the heel
    /// point on the glass, x along the foot's axis, mm): `rotation` applied to (x, y), y
    /// negated first when `mirrored`, then `translation_mm` added; z is the height above the
    /// glass once the last's bottom curve is taken out.
    pub rotation_deg: f64,
    pub translation_mm: V2,
    pub mirrored: bool,
    /// The footprint's largest distance from the placement (mm): the fit's own check.
    pub residual_mm: f64,
    /// The foot's largest protrusion out of the last (mm, 0 inside) and the share of its
    /// vertices standing out by more than 0.5 mm.
    pub foot_out_mm: f64,
    pub foot_out_share: f64,
    /// The protrusion (mm) the view draws fully red; from 0 it shades from skin over to red.
    pub red_at_mm: f64,
}

/// A rigid 2D map (with an optional mirror of y first): q = R(mirror(p)) + t.
#[derive(Clone, Copy, Debug)]
struct Rigid2 {
    cos: f64,
    sin: f64,
    t: V2,
    mirrored: bool,
}

impl Rigid2 {
    fn apply(&self, p: P2) -> P2 {
        let y = if self.mirrored { -p.y } else { p.y };
        P2::new(
            self.cos * p.x - self.sin * y + self.t.x,
            self.sin * p.x + self.cos * y + self.t.y,
        )
    }

    /// The least-squares rotation and translation taking `src` onto `dst` (paired points),
    /// with y mirrored first or not, whichever fits better; and the largest residual (mm).
    fn fit(src: &[P2], dst: &[P2]) -> (Rigid2, f64) {
        let fit_one = |mirrored: bool| {
            let s: Vec<P2> = src
                .iter()
                .map(|p| P2::new(p.x, if mirrored { -p.y } else { p.y }))
                .collect();
            let n = s.len() as f64;
            let mean = |v: &[P2]| {
                let (x, y) = v.iter().fold((0.0, 0.0), |(x, y), p| (x + p.x, y + p.y));
                P2::new(x / n, y / n)
            };
            let (cs, cd) = (mean(&s), mean(dst));
            let (mut a, mut b) = (0.0, 0.0);
            for (p, q) in s.iter().zip(dst) {
                let (p, q) = (p - cs, q - cd);
                a += p.dot(&q);
                b += p.perp(&q);
            }
            let th = b.atan2(a);
            let (sin, cos) = th.sin_cos();
            let t = V2::new(
                cd.x - (cos * cs.x - sin * cs.y),
                cd.y - (sin * cs.x + cos * cs.y),
            );
            let r = Rigid2 {
                cos,
                sin,
                t,
                mirrored,
            };
            let worst = src
                .iter()
                .zip(dst)
                .map(|(p, q)| dist_by_hypot(&r.apply(*p), q))
                .fold(0.0, f64::max);
            (r, worst)
        };
        let (a, b) = (fit_one(false), fit_one(true));
        if a.1 <= b.1 {
            a
        } else {
            b
        }
    }
}

/// The bottom curve's height at `x` (linear between its samples, its end values beyond).
fn curve_at(curve: &[P2], x: f64) -> f64 {
    match curve {
        [] => 0.0,
        [only] => only.y,
        _ => {
            let i = curve.partition_point(|p| p.x < x);
            if i == 0 {
                return curve[0].y;
            }
            if i == curve.len() {
                return curve[curve.len() - 1].y;
            }
            let (a, b) = (curve[i - 1], curve[i]);
            let w = if b.x > a.x {
                (x - a.x) / (b.x - a.x)
            } else {
                0.0
            };
            a.y + w * (b.y - a.y)
        }
    }
}

/// The mesh of node `name` in a .glb footscan wrote (float positions, u32 indices), back
/// in millimetres, z up (the inverse of [`footscan_geom::mesh::gltf_position`]).
pub fn glb_node_mesh(bytes: &[u8], name: &str) -> Result<TriMesh, String> {
    let u32_at = |o: usize| -> Result<usize, String> {
        bytes
            .get(o..o + 4)
            .map(|b| u32::from_le_bytes(b.try_into().unwrap()) as usize)
            .ok_or_else(|| "the file ends inside its header".to_string())
    };
    if bytes.get(0..4) != Some(b"glTF") {
        return Err("not a binary glTF (.glb) file".into());
    }
    let jl = u32_at(12)?;
    let json = bytes
        .get(20..20 + jl)
        .ok_or("the JSON chunk runs past the end")?;
    let doc: serde_json::Value =
        serde_json::from_slice(json).map_err(|e| format!("its JSON chunk: {e}"))?;
    let bin_at = 20 + jl + 8;
    let bin = bytes.get(bin_at..).ok_or("no binary chunk")?;
    let node = doc["nodes"]
        .as_array()
        .and_then(|v| v.iter().find(|n| n["name"] == name))
        .ok_or_else(|| format!("no node named {name:?}"))?;
    let prim = &doc["meshes"][node["mesh"].as_u64().ok_or("the node has no mesh")? as usize]
        ["primitives"][0];
    let view = |acc: usize, comp: u64, per: usize| -> Result<(&[u8], usize), String> {
        let a = &doc["accessors"][acc];
        if a["componentType"].as_u64() != Some(comp) {
            return Err(format!(
                "accessor {acc}: component type {}",
                a["componentType"]
            ));
        }
        let count = a["count"].as_u64().ok_or("an accessor without a count")? as usize;
        let v = &doc["bufferViews"][a["bufferView"].as_u64().ok_or("no buffer view")? as usize];
        let off = v["byteOffset"].as_u64().unwrap_or(0) as usize
            + a["byteOffset"].as_u64().unwrap_or(0) as usize;
        let data = bin
            .get(off..off + count * per * 4)
            .ok_or_else(|| format!("accessor {acc} runs past the binary chunk"))?;
        Ok((data, count))
    };
    let f = |b: &[u8]| f32::from_le_bytes(b.try_into().unwrap()) as f64;
    let pa = prim["attributes"]["POSITION"]
        .as_u64()
        .ok_or("no POSITION")? as usize;
    let (pos, n) = view(pa, 5126, 3)?;
    let vertices: Vec<P3> = (0..n)
        .map(|i| {
            let c = &pos[i * 12..i * 12 + 12];
            let (x, y, z) = (f(&c[0..4]), f(&c[4..8]), f(&c[8..12]));
            P3::new(x * 1000.0, -z * 1000.0, y * 1000.0)
        })
        .collect();
    let ia = prim["indices"].as_u64().ok_or("no indices")? as usize;
    let (idx, k) = view(ia, 5125, 1)?;
    let ids: Vec<u32> = idx
        .chunks_exact(4)
        .map(|b| u32::from_le_bytes(b.try_into().unwrap()))
        .collect();
    if k % 3 != 0 || ids.iter().any(|&i| i as usize >= n) {
        return Err("its indices are not triangles of its vertices".into());
    }
    let triangles = ids.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
    Ok(TriMesh::new(vertices, triangles))
}

/// The footprint loops of the measurements in the foot frame, in the order the clinic path
/// takes them (the outline, then each toe's).
fn footprint_in_foot_frame(m: &Measurements) -> Vec<Vec<P2>> {
    let frame = FootFrame::of(m);
    std::iter::once(&m.outline)
        .chain(&m.toe_outlines)
        .map(|l| l.iter().map(|&p| frame.to_foot(p)).collect())
        .collect()
}

/// Make `last/fit.glb` in the scan's directory `dir` for last `c`; the record's figures.
pub fn write_fit_view(
    dir: &Path,
    last_dir: &Path,
    m: &Measurements,
    c: &footscan_last::customize::Customized,
) -> Result<FitView, String> {
    let model = dir.join(ScanDir::MODEL_GLB);
    // Through the scan directory: a compacted scan rebuilds its model.glb from the grid.
    let bytes = ScanDir::new(dir)
        .read_file(ScanDir::MODEL_GLB)
        .map_err(|e| {
            format!(
                "{}: {e} (the scan's 3D model: a scan whose pipeline ran model.bezier)",
                model.display()
            )
        })?;
    let foot = glb_node_mesh(&bytes, "foot").map_err(|e| format!("{}: {e}", model.display()))?;
    let ours = footprint_in_foot_frame(m);
    let shape = |v: &[Vec<P2>]| v.iter().map(Vec::len).collect::<Vec<_>>();
    if ours.is_empty() || shape(&ours) != shape(&c.footprint) {
        return Err(format!(
            "the last's footprint ({:?} points by loop) is not the scan's ({:?}): no \
             placement to draw the last around the foot",
            shape(&c.footprint),
            shape(&ours)
        ));
    }
    let src: Vec<P2> = c.footprint.iter().flatten().copied().collect();
    let dst: Vec<P2> = ours.iter().flatten().copied().collect();
    let (r, residual) = Rigid2::fit(&src, &dst);
    if residual > RIGID_TOLERANCE_MM {
        return Err(format!(
            "the last's footprint is {residual:.3} mm from a rigid placement of the scan's \
             (at most {RIGID_TOLERANCE_MM} mm): the last cannot be drawn around the foot"
        ));
    }
    let curve = c.bottom_curve.as_deref().unwrap_or(&[]);
    let vertices = c
        .last
        .vertices
        .iter()
        .map(|p| {
            let q = r.apply(p.xy());
            P3::new(q.x, q.y, p.z - curve_at(curve, p.x))
        })
        .collect();
    // A mirror turns the triangles inside out: wind them back so the inside stays inside.
    let triangles = c
        .last
        .triangles
        .iter()
        .map(|t| if r.mirrored { [t[0], t[2], t[1]] } else { *t })
        .collect();
    let last = TriMesh::new(vertices, triangles);
    // model.glb's solid is the scanned sole closed down to a flat base 2 mm under the glass
    // (cad: the solid's bottom); the last's bottom is the glass. Judged where it is, that base
    // stood 2 mm out of every last (half the foot's vertices red): its points are judged at
    // the glass instead, so only the sole and the sides can stand out.
    let bvh = footscan_geom::mesh::Bvh::new(&last);
    let out: Vec<f64> = foot
        .vertices
        .iter()
        .map(|v| {
            let at = P3::new(v.x, v.y, v.z.max(0.0));
            bvh.signed_distance(&at)
                .map_or(0.0, |s| s.distance.max(0.0))
        })
        .collect();
    let worst = out.iter().copied().fold(0.0, f64::max);
    let colours: Vec<[f32; 4]> = out
        .iter()
        .map(|&d| {
            let t = (d / footscan_geom::mesh::PROUD_FULL_MM).clamp(0.0, 1.0) as f32;
            [0, 1, 2, 3].map(|c| SKIN[c] + t * (PROUD[c] - SKIN[c]))
        })
        .collect();
    let p = last_dir.join(FIT_FILE);
    footscan_geom::mesh::write_glb(
        &p,
        &[
            GlbPart {
                name: "foot",
                mesh: &foot,
                colour: [1.0; 4],
                vertex_colours: Some(&colours),
            },
            GlbPart {
                name: "last",
                mesh: &last,
                colour: LAST,
                vertex_colours: None,
            },
        ],
    )
    .map_err(|e| footscan_util::chain(&e))?;
    let n_out = out.iter().filter(|&&d| d > 0.5).count();
    Ok(FitView {
        file: FIT_FILE.into(),
        rotation_deg: r.sin.atan2(r.cos).to_degrees(),
        translation_mm: r.t,
        mirrored: r.mirrored,
        residual_mm: residual,
        foot_out_mm: worst,
        foot_out_share: n_out as f64 / foot.vertices.len().max(1) as f64,
        red_at_mm: footscan_geom::mesh::PROUD_FULL_MM,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fit_finds_a_turn_a_shift_and_a_mirror() {
        let src: Vec<P2> = (0..40)
            .map(|i| {
                let a = i as f64 * 0.3;
                P2::new(120.0 * a.cos() + 130.0, 45.0 * a.sin() + (i % 3) as f64)
            })
            .collect();
        for mirrored in [false, true] {
            let truth = Rigid2 {
                cos: 0.05f64.cos(),
                sin: 0.05f64.sin(),
                t: V2::new(-3.0, 7.5),
                mirrored,
            };
            let dst: Vec<P2> = src.iter().map(|p| truth.apply(*p)).collect();
            let (r, res) = Rigid2::fit(&src, &dst);
            assert!(res < 1e-9, "{res}");
            assert_eq!(r.mirrored, mirrored);
            assert!((r.sin.atan2(r.cos) - 0.05).abs() < 1e-12);
            assert!((r.t.x + 3.0).abs() < 1e-9 && (r.t.y - 7.5).abs() < 1e-9);
        }
    }

    #[test]
    fn the_bottom_curve_is_read_between_and_beyond_its_samples() {
        let c = [P2::new(0.0, 20.0), P2::new(100.0, 0.0), P2::new(200.0, 5.0)];
        assert_eq!(curve_at(&c, -5.0), 20.0);
        assert!((curve_at(&c, 50.0) - 10.0).abs() < 1e-12);
        assert!((curve_at(&c, 150.0) - 2.5).abs() < 1e-12);
        assert_eq!(curve_at(&c, 300.0), 5.0);
        assert_eq!(curve_at(&[], 3.0), 0.0);
    }

    #[test]
    fn a_glb_node_reads_back_in_millimetres() {
        let m = TriMesh::new(
            vec![
                P3::new(0.0, 0.0, 0.0),
                P3::new(10.0, 0.0, 0.0),
                P3::new(0.0, 20.0, 0.0),
                P3::new(0.0, 0.0, 30.0),
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        );
        let b = m.to_glb("foot").unwrap();
        let back = glb_node_mesh(&b, "foot").unwrap();
        assert_eq!(back.triangles, m.triangles);
        for (a, b) in back.vertices.iter().zip(&m.vertices) {
            assert!((a - b).norm() < 1e-4, "{a} {b}");
        }
        assert!(glb_node_mesh(&b, "last").unwrap_err().contains("last"));
        assert!(glb_node_mesh(b"nope", "foot").is_err());
    }
}
