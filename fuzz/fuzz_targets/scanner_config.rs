#![no_main]
//! The scanner's TOML config (footscan.toml).
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    let text = String::from_utf8_lossy(b).into_owned();
    footscan_fuzz::check("scanner config", b.len(), 512 * 1024, || {
        drop(footscan::scan::LoadedConfig::parse(
            std::path::Path::new("fuzz/footscan.toml"),
            text,
        ))
    });
});
