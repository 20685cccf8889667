#![no_main]
//! A last's comfort rule file (TOML).
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    let Ok(text) = std::str::from_utf8(b) else {
        return;
    };
    footscan_fuzz::check("rule file", b.len(), 512 * 1024, || {
        drop(footscan_last::customize::rules::RuleSet::parse(
            text,
            "fuzz/rules.toml",
        ))
    });
});
