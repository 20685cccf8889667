//! Scan ids: time-sortable (`20261121T221503Z-3f2a`) and safe to join onto a path. Every id
//! that reaches the file system went through [`ScanId::parse`], so no request can name a path
//! outside the archive.

use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

/// `YYYYMMDDTHHMMSSZ-xxxx`: UTC start time, then four lowercase hex digits.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ScanId(String);

pub const ID_LEN: usize = 21;

#[derive(Debug, thiserror::Error, PartialEq, Eq)]
#[error("invalid scan id {0:?}: expected YYYYMMDDTHHMMSSZ-xxxx (UTC time, 4 lowercase hex digits), e.g. 20261121T221503Z-3f2a")]
pub struct IdError(pub String);

impl ScanId {
    /// A new id for the current time; `salt` varies the suffix when the caller retries.
    pub fn generate(salt: u64) -> ScanId {
        static COUNTER: AtomicU64 = AtomicU64::new(0);
        let now = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        // splitmix64 over the time, pid, counter and salt: unpredictable enough to avoid
        // collisions within a second, and cheap.
        let mut z = (now.as_nanos() as u64)
            ^ ((std::process::id() as u64) << 32)
            ^ n.wrapping_mul(0x9E37_79B9_7F4A_7C15)
            ^ salt.rotate_left(17);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ScanId(format!("{}-{:04x}", compact_utc(now.as_secs()), z & 0xffff))
    }

    /// The strict parser: exactly the generated shape, a real calendar time, nothing else.
    pub fn parse(s: &str) -> Result<ScanId, IdError> {
        let err = || IdError(s.chars().take(80).collect());
        let b = s.as_bytes();
        if b.len() != ID_LEN || b[8] != b'T' || b[15] != b'Z' || b[16] != b'-' {
            return Err(err());
        }
        let digits = |r: std::ops::Range<usize>| -> Option<u32> {
            b[r].iter().try_fold(0u32, |acc, &c| {
                c.is_ascii_digit().then(|| acc * 10 + (c - b'0') as u32)
            })
        };
        let (Some(mo), Some(d), Some(h), Some(mi), Some(se), Some(y)) = (
            digits(4..6),
            digits(6..8),
            digits(9..11),
            digits(11..13),
            digits(13..15),
            digits(0..4),
        ) else {
            return Err(err());
        };
        if !(1..=12).contains(&mo)
            || !(1..=days_in_month(y, mo)).contains(&d)
            || h > 23
            || mi > 59
            || se > 60
        {
            return Err(err());
        }
        if !b[17..]
            .iter()
            .all(|c| c.is_ascii_digit() || (b'a'..=b'f').contains(c))
        {
            return Err(err());
        }
        Ok(ScanId(s.to_string()))
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for ScanId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

/// Days of month `m` (1-12) of year `y` in the proleptic Gregorian calendar.
fn days_in_month(y: u32, m: u32) -> u32 {
    match m {
        2 if y.is_multiple_of(4) && (!y.is_multiple_of(100) || y.is_multiple_of(400)) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// `YYYYMMDDTHHMMSSZ` of now.
pub(crate) fn compact_utc_now() -> String {
    let now = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .unwrap_or_default();
    compact_utc(now.as_secs())
}

/// `YYYYMMDDTHHMMSSZ` of Unix seconds (civil-from-days, proleptic Gregorian).
fn compact_utc(secs: u64) -> String {
    let days = (secs / 86_400) as i64;
    let rem = secs % 86_400;
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}{m:02}{d:02}T{:02}{:02}{:02}Z",
        rem / 3600,
        rem / 60 % 60,
        rem % 60
    )
}

/// A file name inside a scan directory: the rule the scan's stages write by
/// ([`footscan::io::ARTIFACT_NAME_RULE`]).
pub use footscan::io::is_artifact_name as valid_file_name;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn generated_ids_parse_and_sort_by_time() {
        let a = ScanId::generate(0);
        assert_eq!(ScanId::parse(a.as_str()), Ok(a.clone()));
        assert_eq!(compact_utc(0), "19700101T000000Z");
        assert_eq!(compact_utc(1_795_299_303), "20261121T221503Z");
        assert!(compact_utc(1_000_000_000) < compact_utc(2_000_000_000));
    }

    #[test]
    fn parser_refuses_everything_else() {
        for bad in [
            "",
            "../etc",
            "%2e%2e",
            "20261121T221503Z-3f2",
            "20261121T221503Z-3f2ab",
            "20261121T221503Z-3F2A",
            "20261121T221503Z/3f2a",
            "20261321T221503Z-3f2a",
            "20261121T251503Z-3f2a",
            "20260231T221503Z-3f2a",
            "20260229T221503Z-3f2a",
            "21000229T221503Z-3f2a",
            "20260431T221503Z-3f2a",
            "2026112lT221503Z-3f2a",
            "20261121T221503Z-../a",
            ".tmp-20261121T221503",
        ] {
            assert!(ScanId::parse(bad).is_err(), "{bad:?} accepted");
        }
        assert!(ScanId::parse("20261121T221503Z-3f2a").is_ok());
        assert!(ScanId::parse("20280229T221503Z-3f2a").is_ok(), "a leap day");
        assert!(ScanId::parse("20000229T221503Z-3f2a").is_ok(), "a leap day");
    }
}
