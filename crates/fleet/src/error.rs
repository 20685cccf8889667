//! The fleet's errors. None of them carries the password: connection errors are the server's
//! or the socket's words, and the target is always shown by [`crate::Settings::target`].

use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum FleetError {
    #[error("fleet settings: {0}")]
    Settings(String),
    #[error("fleet database {target}: cannot connect: {message}")]
    Connect { target: String, message: String },
    #[error("fleet database")]
    Db(#[from] postgres::Error),
    /// The database's schema is newer than this program and not usable by it.
    #[error(
        "fleet database is at schema version {db} (written by footscan {db_software}), which \
         needs a program that knows schema version {needs} or later; this footscan {ours_software} \
         knows schema versions up to {ours}: upgrade footscan on this scanner"
    )]
    SchemaTooNew {
        db: i32,
        needs: i32,
        db_software: String,
        ours: i32,
        ours_software: String,
    },
    /// The same scanner name and scan id are in the database with other files: two scanners
    /// share a name, or a scan directory was changed after it was pushed.
    #[error(
        "scan {scan_id} of scanner {scanner:?} is already in the fleet database with other \
         content ({detail}); two scanners configured with the same name?"
    )]
    Conflict {
        scanner: String,
        scan_id: String,
        detail: String,
    },
    /// What was stored is not what was sent.
    #[error("scan {scan_id}: file {name} in the fleet database does not match: {detail}")]
    Mismatch {
        scan_id: String,
        name: String,
        detail: String,
    },
    #[error("{path}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{0}")]
    NotFound(String),
}

impl FleetError {
    /// Whether retrying later may succeed (the network or the server), as opposed to a
    /// refusal that needs a person (a schema too new, a conflict, a wrong password).
    pub fn is_transient(&self) -> bool {
        match self {
            FleetError::Connect { message, .. } => !message.contains("password authentication"),
            FleetError::Db(e) => match e.code() {
                // Server-side errors with a SQLSTATE: transient only for the classes that
                // mean the server went away or is starting/stopping.
                Some(c) => {
                    let c = c.code();
                    c.starts_with("08")
                        || c.starts_with("57")
                        || c.starts_with("53")
                        || c == "40001"
                        || c == "40P01"
                }
                None => true,
            },
            FleetError::Io { .. } => true,
            _ => false,
        }
    }
}
