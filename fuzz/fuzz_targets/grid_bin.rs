#![no_main]
//! A scan's grid.bin (the height grid a scan directory holds).
use footscan::scandata::ScanGrid;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    footscan_fuzz::check("grid.bin reader", b.len(), 512 * 1024, || {
        drop(ScanGrid::parse(b, std::path::Path::new("fuzz/grid.bin")))
    });
});
