//! The schema as versioned migrations, applied in order inside one transaction under an
//! advisory lock (two daemons starting together do not both apply one), each recorded in
//! `fleet_migrations` with the oldest schema version a program must know to keep using the
//! database after it (`compatible_from`). A program that knows versions up to N works on a
//! database at version M > N when every migration above N says `compatible_from <= N`
//! (additive changes), and refuses otherwise with a message naming both versions.

use crate::FleetError;
use postgres::Client;

pub struct Migration {
    pub version: i32,
    pub name: &'static str,
    /// The oldest schema version whose programs still work on the database after this one.
    pub compatible_from: i32,
    pub sql: &'static str,
}

pub const MIGRATIONS: &[Migration] = &[
    Migration {
        version: 1,
        name: "scans, artifacts and content-addressed blobs",
        compatible_from: 1,
        sql: "
CREATE TABLE fleet_blobs (
    sha256 text PRIMARY KEY CHECK (sha256 ~ '^[0-9a-f]{64}$'),
    bytes bigint NOT NULL,
    content bytea NOT NULL,
    -- The database itself refuses a blob whose bytes are not the ones named: a corrupted
    -- upload cannot be stored.
    CONSTRAINT fleet_blobs_content_hash CHECK (encode(sha256(content), 'hex') = sha256),
    CONSTRAINT fleet_blobs_length CHECK (octet_length(content) = bytes)
);
CREATE TABLE fleet_scans (
    scanner text NOT NULL,
    scan_id text NOT NULL,
    clinic text NOT NULL,
    subject text NOT NULL,
    side text NOT NULL,
    notes text NOT NULL,
    status text NOT NULL,
    reason text,
    started timestamptz NOT NULL,
    finished timestamptz,
    frames bigint NOT NULL,
    points bigint NOT NULL,
    calibration text,
    measurements jsonb,
    summary jsonb,
    record jsonb NOT NULL,
    received timestamptz NOT NULL DEFAULT now(),
    PRIMARY KEY (scanner, scan_id)
);
CREATE TABLE fleet_artifacts (
    scanner text NOT NULL,
    scan_id text NOT NULL,
    name text NOT NULL,
    sha256 text NOT NULL REFERENCES fleet_blobs (sha256),
    bytes bigint NOT NULL,
    content_type text NOT NULL,
    PRIMARY KEY (scanner, scan_id, name),
    FOREIGN KEY (scanner, scan_id) REFERENCES fleet_scans (scanner, scan_id)
);
",
    },
    Migration {
        version: 2,
        name: "indexes for the central view's filters; the pushing program's version",
        // Additive: a version-1 program inserts without the new column and is still right.
        compatible_from: 1,
        sql: "
CREATE INDEX fleet_scans_clinic_finished ON fleet_scans (clinic, finished);
CREATE INDEX fleet_scans_subject ON fleet_scans (subject);
CREATE INDEX fleet_scans_finished ON fleet_scans (finished);
ALTER TABLE fleet_scans ADD COLUMN software text;
",
    },
];

/// The newest schema version this program knows.
pub const SCHEMA_VERSION: i32 = 2;

/// The program's version, recorded with each migration it applies.
pub const SOFTWARE: &str = env!("CARGO_PKG_VERSION");

/// Key of the advisory lock taken while migrating ("footscan" in ASCII).
const LOCK_KEY: i64 = 0x666f_6f74_7363_616e;

const HISTORY: &str = "CREATE TABLE IF NOT EXISTS fleet_migrations (
    version integer PRIMARY KEY,
    name text NOT NULL,
    compatible_from integer NOT NULL,
    software text NOT NULL,
    applied timestamptz NOT NULL DEFAULT now()
)";

/// What the database is at, and what this call applied.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SchemaState {
    /// The database's version after the call.
    pub version: i32,
    /// Versions this call applied.
    pub applied: Vec<i32>,
    /// The database is newer than this program but compatible with it.
    pub newer_compatible: bool,
}

/// Bring the database to [`SCHEMA_VERSION`] (or `target`, for tests and staged upgrades),
/// or refuse when it is newer than this program and not compatible with it.
pub fn migrate(client: &mut Client, target: Option<i32>) -> Result<SchemaState, FleetError> {
    let target = target.unwrap_or(SCHEMA_VERSION).min(SCHEMA_VERSION);
    let mut tx = client.transaction()?;
    tx.execute("SELECT pg_advisory_xact_lock($1)", &[&LOCK_KEY])?;
    // Quietly: "already exists, skipping" on every connection is noise in the daemon's log.
    tx.batch_execute("SET LOCAL client_min_messages = warning")?;
    tx.batch_execute(HISTORY)?;
    let rows = tx.query(
        "SELECT version, compatible_from, software FROM fleet_migrations ORDER BY version",
        &[],
    )?;
    let have: Vec<(i32, i32, String)> = rows
        .iter()
        .map(|r| (r.get(0), r.get(1), r.get(2)))
        .collect();
    let db_version = have.iter().map(|h| h.0).max().unwrap_or(0);
    if db_version > SCHEMA_VERSION {
        let needs = have
            .iter()
            .filter(|h| h.0 > SCHEMA_VERSION)
            .map(|h| h.1)
            .max()
            .unwrap_or(0);
        if needs > SCHEMA_VERSION {
            let db_software = have
                .iter()
                .rev()
                .find(|h| h.0 == db_version)
                .map_or("?".to_string(), |h| h.2.clone());
            return Err(FleetError::SchemaTooNew {
                db: db_version,
                needs,
                db_software,
                ours: SCHEMA_VERSION,
                ours_software: SOFTWARE.into(),
            });
        }
        tx.commit()?;
        return Ok(SchemaState {
            version: db_version,
            applied: vec![],
            newer_compatible: true,
        });
    }
    let mut applied = Vec::new();
    for m in MIGRATIONS
        .iter()
        .filter(|m| m.version <= target && !have.iter().any(|h| h.0 == m.version))
    {
        tx.batch_execute(m.sql)?;
        tx.execute(
            "INSERT INTO fleet_migrations (version, name, compatible_from, software) VALUES ($1, $2, $3, $4)",
            &[&m.version, &m.name, &m.compatible_from, &SOFTWARE],
        )?;
        tracing::info!(
            "fleet database: applied schema version {} ({})",
            m.version,
            m.name
        );
        applied.push(m.version);
    }
    tx.commit()?;
    Ok(SchemaState {
        version: db_version.max(applied.last().copied().unwrap_or(0)),
        applied,
        newer_compatible: false,
    })
}

/// One row of `fleet_migrations`: version, name, compatible_from, software, applied (text).
pub type HistoryRow = (i32, String, i32, String, String);

/// The history as recorded.
pub fn history(client: &mut Client) -> Result<Vec<HistoryRow>, FleetError> {
    let rows = client.query(
        "SELECT version, name, compatible_from, software, applied::text FROM fleet_migrations ORDER BY version",
        &[],
    )?;
    Ok(rows
        .iter()
        .map(|r| (r.get(0), r.get(1), r.get(2), r.get(3), r.get(4)))
        .collect())
}
