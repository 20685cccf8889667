//! footscan fleet: scans from many scanners in one PostgreSQL.
//!
//! Each footscand keeps its own archive and pushes every ended scan here: the record (one row
//! of `fleet_scans`, keyed by scanner name and scan id) and its files, stored once by content
//! (`fleet_blobs`, keyed by sha256, which the database itself checks) and listed per scan
//! (`fleet_artifacts`). A push is one transaction whose inserts all do nothing when the row is
//! there already, so a retry after any failure (lost connection, killed daemon, lost commit
//! acknowledgement) never duplicates a scan or a file. The schema is a list of versioned
//! migrations recorded in `fleet_migrations` ([`migrate`]). The central view (list, show,
//! fetch into a scan directory) is [`query`].
//!
//! Blocking client (`postgres`): the daemon pushes from a thread of its own and the CLI is
//! synchronous, so neither needs an async runtime of its own here.

pub mod connect;
pub mod error;
pub mod migrate;
pub mod push;
pub mod query;
pub mod settings;
#[cfg(feature = "test-server")]
pub mod testing;

pub use connect::connect;
pub use error::FleetError;
pub use migrate::{migrate, SchemaState, SCHEMA_VERSION};
/// The client type, re-exported so users need not name `postgres` themselves.
pub use postgres::Client;
pub use push::{push, LocalFile, PushOutcome, ScanUpload};
pub use query::{fetch, list, show, Filter, ScanRow};
pub use settings::{Settings, Tls};

/// sha256 of `bytes` as 64 lowercase hex digits (the key of `fleet_blobs`).
pub fn sha256_hex(bytes: &[u8]) -> String {
    use sha2::Digest;
    let d = sha2::Sha256::digest(bytes);
    let mut s = String::with_capacity(64);
    for b in d {
        s.push_str(&format!("{b:02x}"));
    }
    s
}
