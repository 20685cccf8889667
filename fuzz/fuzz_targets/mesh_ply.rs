#![no_main]
//! PLY, ASCII and binary; a PLY of vertices only is how point clouds come in.
use footscan_geom::mesh::TriMesh;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    footscan_fuzz::check("PLY reader", b.len(), 64 * 1024, || {
        drop(TriMesh::parse_ply(b, std::path::Path::new("fuzz.ply")))
    });
});
