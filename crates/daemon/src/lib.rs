//! footscand, the daemon beside the scanner: the HTTP API and dashboard ([`api`], axum on
//! tokio; contract in docs/API.md), the one running job and its events ([`daemon`]), and the
//! scan archive ([`archive`]: one directory per scan, a SQLite index).
//!
//! Dependencies: the `footscan` library (scans, calibration, measurement) and the web and
//! storage crates (tokio, axum, rusqlite). Nothing depends on this crate, so algorithm tests
//! never compile the web server.

pub mod api;
pub mod archive;
pub mod daemon;
