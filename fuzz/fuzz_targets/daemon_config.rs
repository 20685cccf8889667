#![no_main]
//! The daemon's TOML config (footscand.toml).
use footscan_daemon::daemon::DaemonConfig;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    let Ok(text) = std::str::from_utf8(b) else {
        return;
    };
    footscan_fuzz::check("daemon config", b.len(), 512 * 1024, || {
        drop(DaemonConfig::parse(
            std::path::Path::new("fuzz/footscand.toml"),
            text,
            None,
            None,
        ))
    });
});
