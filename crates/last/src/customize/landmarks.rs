//! Landmarks others annotated on a foot mesh, as a table of vertex ids (the FIND foot model
//! ships one: a row per model, a column per landmark, ids counted from 0 into its OBJ's
//! vertex list), set beside the characteristic points cut here (docs/method.md 10.1).
//!
//! The definitions differ, so the comparison says which coordinate is comparable: a plan
//! extreme (MT1, MT5) is where the side is furthest out, which on a straight stretch of side
//! is well defined across the foot and not along it; an annotator puts the point on the
//! joint. The toe tip and the heel's back are extremes along the axis.

use super::measure::{FootFrame, Measures};
use footscan_geom::P3;
use serde::Serialize;
use std::path::Path;

/// One annotated landmark, in the mesh file's coordinates scaled to millimetres.
#[derive(Clone, Debug)]
pub struct Keypoint {
    pub name: String,
    pub at: P3,
}

/// Read the landmarks of row `model` of `csv`, placed at the vertices of `obj` (scaled by
/// `mm_per_unit`: 1000 for an OBJ in metres).
pub fn read_keypoints(
    obj: &Path,
    csv: &Path,
    model: &str,
    mm_per_unit: f64,
) -> Result<Vec<Keypoint>, String> {
    let text = std::fs::read_to_string(csv).map_err(|e| format!("{}: {e}", csv.display()))?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| format!("{}: empty", csv.display()))?
        .split(',')
        .map(str::trim)
        .collect();
    let row: Vec<&str> = lines
        .map(|l| l.split(',').map(str::trim).collect::<Vec<_>>())
        .find(|r| r.first() == Some(&model))
        .ok_or_else(|| format!("{}: no row for model {model:?}", csv.display()))?;
    let vertices: Vec<P3> = std::fs::read_to_string(obj)
        .map_err(|e| format!("{}: {e}", obj.display(), e = footscan_util::Chain(&e)))?
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f64> = l
                .split_whitespace()
                .take(3)
                .filter_map(|v| v.parse().ok())
                .collect();
            (c.len() == 3)
                .then(|| P3::new(c[0], c[1], c[2]) * mm_per_unit)
                .ok_or_else(|| format!("{}: a vertex line is not x y z: {l:?}", obj.display()))
        })
        .collect::<Result<_, _>>()?;
    header
        .iter()
        .zip(&row)
        .skip(1)
        .map(|(name, id)| {
            let i: usize = id.parse().map_err(|_| {
                format!(
                    "{}: {model} {name}: {id:?} is not a vertex id",
                    csv.display()
                )
            })?;
            let at = *vertices.get(i).ok_or_else(|| {
                format!(
                    "{}: {model} {name}: vertex {i} of {} ({} vertices)",
                    csv.display(),
                    obj.display(),
                    vertices.len()
                )
            })?;
            Ok(Keypoint {
                name: name.to_string(),
                at,
            })
        })
        .collect()
}

/// One characteristic point against its annotated counterpart, in the foot's frame (mm).
#[derive(Clone, Debug, Serialize)]
pub struct LandmarkPair {
    /// Ours (docs/method.md 10.1) and the annotation's name.
    pub ours: &'static str,
    pub theirs: &'static str,
    /// Ours minus theirs, along the axis and across it.
    #[serde(rename = "dx_mm")]
    pub dx: f64,
    #[serde(rename = "dy_mm")]
    pub dy: f64,
    /// Which of them the definitions make comparable: "x" (an extreme along the axis) or
    /// "y" (a plan extreme across it).
    pub compared: &'static str,
}

impl LandmarkPair {
    /// The difference in the comparable coordinate.
    pub fn error(&self) -> f64 {
        if self.compared == "x" {
            self.dx
        } else {
            self.dy
        }
    }
}

/// The pairs the annotations of the FIND model allow: toe tip against the big toe's (along
/// the axis), the heel point against the heel's back (along), MT1 and MT5 against the inner
/// and outer extrema (across). Pairs whose landmark is missing are left out.
pub fn pair_with(m: &Measures, frame: &FootFrame, kp: &[Keypoint]) -> Vec<LandmarkPair> {
    let to = frame.world_to_frame();
    let find = |n: &str| kp.iter().find(|k| k.name == n).map(|k| to * k.at);
    [
        ("toe tip A", "big toe", m.a, "x"),
        ("heel point O", "heel", m.o, "x"),
        ("MT1 B", "inner extrema", m.b, "y"),
        ("MT5 C", "outer extrema", m.c, "y"),
    ]
    .into_iter()
    .filter_map(|(ours, theirs, p, compared)| {
        let q = find(theirs)?;
        Some(LandmarkPair {
            ours,
            theirs,
            dx: p.x - q.x,
            dy: p.y - q.y,
            compared,
        })
    })
    .collect()
}
