#![no_main]
//! A point cloud (XYZ text) read as a last: the text's reader, and past 1,000 points the
//! closed mesh made through them.
use footscan_geom::mesh::cloud;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    footscan_fuzz::check("XYZ reader", b.len(), 64 * 1024, || {
        drop(cloud::parse_xyz_bytes(b))
    });
    // The mesh, its neighbour lists and search tree are the same size for any cloud (an
    // icosphere of 20,480 triangles: about 10 MB, `cloud_load_grows_by_the_points_alone`).
    footscan_fuzz::check("XYZ last", b.len(), 16 * 1024 * 1024, || {
        drop(cloud::last_from_xyz(b))
    });
});
