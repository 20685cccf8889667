//! The joined last as triangles: a file of its own because output.rs makes it (and writes
//! the pictures) while zebra.rs draws it, and the drawing must not import the writer.

use footscan_geom::{P3, V3};

/// Triangles of the joined last with per-vertex normals and part (0 back, 1 patch, 2 toe).
pub struct Tessellation {
    pub vertices: Vec<P3>,
    pub normals: Vec<V3>,
    pub part: Vec<u8>,
    pub triangles: Vec<[u32; 3]>,
}
