#![no_main]
//! Wavefront OBJ (faces fanned into triangles).
use footscan_geom::mesh::TriMesh;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    // Faces of nine one-digit corners hold 4.2 x their text (docs/method.md 14.2): the fixed
    // part covers them for inputs up to libFuzzer's default 4 KiB and well beyond.
    footscan_fuzz::check("OBJ reader", b.len(), 64 * 1024, || {
        drop(TriMesh::parse_obj(b, std::path::Path::new("fuzz.obj")))
    });
});
