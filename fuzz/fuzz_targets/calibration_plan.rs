#![no_main]
//! A calibration plan (TOML), parsed and validated.
use footscan::calib::CalibrationPlan;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    let Ok(text) = std::str::from_utf8(b) else {
        return;
    };
    footscan_fuzz::check("calibration plan", b.len(), 512 * 1024, || {
        if let Ok(p) = toml::from_str::<CalibrationPlan>(text) {
            drop(p.validate());
        }
    });
});
