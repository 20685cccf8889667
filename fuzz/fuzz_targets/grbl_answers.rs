#![no_main]
//! What the GRBL controller says on the serial line: one answer line, a status report, the
//! build info's lines.
use footscan_grbl::{parse_line, parse_status, BuildInfo};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    let line = String::from_utf8_lossy(b).into_owned();
    let lines: Vec<&str> = line.split('\n').collect();
    footscan_fuzz::check("parse_line", b.len(), 16 * 1024, || drop(parse_line(&line)));
    footscan_fuzz::check("parse_status", b.len(), 16 * 1024, || {
        drop(parse_status(&line))
    });
    footscan_fuzz::check("BuildInfo::parse", b.len(), 16 * 1024, || {
        drop(BuildInfo::parse(&lines))
    });
});
