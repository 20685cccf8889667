#![no_main]
//! Wavefront OBJ (faces fanned into triangles).
use footscan_geom::mesh::TriMesh;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    // Faces of nine one-digit corners held 4.2 x their text; the reader now refuses more
    // than 8 triangles a vertex, which keeps any OBJ within 4 x (docs/method.md 14.2.2).
    footscan_fuzz::check("OBJ reader", b.len(), 64 * 1024, || {
        drop(TriMesh::parse_obj(b, std::path::Path::new("fuzz.obj")))
    });
});
