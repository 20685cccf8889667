//! Errors of mesh loading, validation and units, each naming the input.

use crate::{P3, V3};
use std::path::PathBuf;

/// Why a mesh is not a valid closed solid. Edges are named by vertex ids and positions.
#[derive(Debug, Clone, PartialEq)]
pub enum Defect {
    /// No triangles.
    Empty,
    /// An index beyond the vertex list.
    IndexOutOfRange {
        triangle: usize,
        index: u32,
        vertices: usize,
    },
    /// A triangle with a repeated corner or (nearly) zero area.
    Degenerate {
        triangle: usize,
        corners: [u32; 3],
        positions: [P3; 3],
    },
    /// An edge used by one triangle only: the mesh has a hole.
    OpenEdge { a: u32, b: u32, pa: P3, pb: P3 },
    /// An edge shared by more than two triangles.
    NonManifoldEdge {
        a: u32,
        b: u32,
        pa: P3,
        pb: P3,
        triangles: usize,
    },
    /// Two triangles run along an edge in the same direction: one of them is flipped.
    Misoriented { a: u32, b: u32, pa: P3, pb: P3 },
    /// The enclosed volume is negative (or zero): the triangles face inward.
    InsideOut { volume: f64 },
}

fn p(q: &P3) -> String {
    format!("({:.6}, {:.6}, {:.6})", q.x, q.y, q.z)
}

impl std::fmt::Display for Defect {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Defect::Empty => write!(f, "the mesh has no triangles"),
            Defect::IndexOutOfRange { triangle, index, vertices } => write!(
                f,
                "triangle {triangle} refers to vertex {index}, but there are {vertices} vertices"
            ),
            Defect::Degenerate { triangle, corners, positions } => write!(
                f,
                "triangle {triangle} (vertices {} {} {} at {} {} {}) is degenerate (repeated corner or zero area)",
                corners[0], corners[1], corners[2], p(&positions[0]), p(&positions[1]), p(&positions[2])
            ),
            Defect::OpenEdge { a, b, pa, pb } => write!(
                f,
                "the mesh is not closed: edge {a}-{b} from {} to {} belongs to one triangle only (every edge of a closed surface has two)",
                p(pa), p(pb)
            ),
            Defect::NonManifoldEdge { a, b, pa, pb, triangles } => write!(
                f,
                "the mesh is not 2-manifold: edge {a}-{b} from {} to {} belongs to {triangles} triangles (a manifold surface has exactly two)",
                p(pa), p(pb)
            ),
            Defect::Misoriented { a, b, pa, pb } => write!(
                f,
                "inconsistent orientation: both triangles at edge {a}-{b} from {} to {} run along it in the same direction (one is flipped)",
                p(pa), p(pb)
            ),
            Defect::InsideOut { volume } => write!(
                f,
                "the enclosed volume is {volume:.6} (not positive): the triangles face inward; reverse them"
            ),
        }
    }
}

/// An error reading, writing, validating or scaling a mesh; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    #[error("{}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {what}", path.display())]
    Parse { path: PathBuf, what: String },
    #[error("{}: unknown mesh format (extension {ext:?}); valid: .stl, .ply, .obj", path.display())]
    UnknownFormat { path: PathBuf, ext: String },
    #[error("{}: {defect}", path.display())]
    Invalid { path: PathBuf, defect: Defect },
    #[error(
        "{}: the mesh is {:.4} x {:.4} x {:.4} mm, smaller than 1 mm: it is in metres, not millimetres; \
         {hint}",
        path.display(), size.x, size.y, size.z
    )]
    MetresAsMm {
        path: PathBuf,
        size: V3,
        hint: String,
    },
    #[error(
        "{}: the mesh is {:.3} x {:.3} x {:.3} units, too small for millimetres ({min_mm} mm at least) \
         and too large for metres: it is in unscaled model units; {hint}",
        path.display(), size.x, size.y, size.z, min_mm = super::MIN_PLAUSIBLE_MM
    )]
    Unscaled {
        path: PathBuf,
        size: V3,
        hint: String,
    },
    /// The mesh is not a foot (size, shape), and why.
    #[error("{}: not a foot: {why}", path.display())]
    NotAFoot { path: PathBuf, why: String },
    /// A hole that is not a flat cut at the top, and where.
    #[error("{}: {why}", path.display())]
    Hole { path: PathBuf, why: String },
    #[error("{}: invalid target length {length_mm} mm (must be positive and finite)", path.display())]
    BadLength { path: PathBuf, length_mm: f64 },
}

impl MeshError {
    /// The file the error is about.
    pub fn path(&self) -> &std::path::Path {
        match self {
            MeshError::Io { path, .. }
            | MeshError::Parse { path, .. }
            | MeshError::UnknownFormat { path, .. }
            | MeshError::Invalid { path, .. }
            | MeshError::MetresAsMm { path, .. }
            | MeshError::Unscaled { path, .. }
            | MeshError::BadLength { path, .. }
            | MeshError::NotAFoot { path, .. }
            | MeshError::Hole { path, .. } => path,
        }
    }

    /// The same error with the advice on units and length put in the words of the command
    /// or configuration that read the mesh (`units`: how to give the unit, `length`: how to
    /// give the length), so it names options that exist there.
    pub fn retold(self, units: &str, length: &str) -> MeshError {
        match self {
            MeshError::MetresAsMm { path, size, .. } => MeshError::MetresAsMm {
                path,
                size,
                hint: units.to_string(),
            },
            MeshError::Unscaled { path, size, .. } => MeshError::Unscaled {
                path,
                size,
                hint: length.to_string(),
            },
            e => e,
        }
    }
}
