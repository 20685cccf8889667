//! Small helpers shared across modules.

/// The current UTC time as RFC 3339 (seconds precision), for records in files.
pub fn now_rfc3339() -> String {
    humantime::format_rfc3339_seconds(std::time::SystemTime::now()).to_string()
}
