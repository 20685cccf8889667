#![no_main]
//! STL, ASCII and binary (geom's reader decides which by the bytes).
use footscan_geom::mesh::TriMesh;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    footscan_fuzz::check("STL reader", b.len(), 64 * 1024, || {
        drop(TriMesh::parse_stl(b, std::path::Path::new("fuzz.stl")))
    });
});
