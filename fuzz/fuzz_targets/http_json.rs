#![no_main]
//! HTTP JSON bodies as the API's handlers parse them (axum's Json is serde_json on the body).
use footscan_daemon::daemon::lastjob::{LastRequest, RankRequest};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|b: &[u8]| {
    footscan_fuzz::check("JSON value", b.len(), 16 * 1024, || {
        drop(serde_json::from_slice::<serde_json::Value>(b))
    });
    footscan_fuzz::check("last request", b.len(), 16 * 1024, || {
        drop(serde_json::from_slice::<LastRequest>(b))
    });
    footscan_fuzz::check("rank request", b.len(), 16 * 1024, || {
        drop(serde_json::from_slice::<RankRequest>(b))
    });
});
