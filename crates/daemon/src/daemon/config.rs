//! The daemon's config file (config/footscand.toml). Unknown keys are errors naming the file,
//! line and column, like the scanner config; relative paths are relative to the file.

use serde::Deserialize;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

/// The default address: loopback only, so no token is needed.
pub const DEFAULT_BIND: &str = "127.0.0.1:8470";
/// Environment variable that sets (and overrides) the bearer token.
pub const TOKEN_ENV: &str = "FOOTSCAND_TOKEN";

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct File {
    daemon: DaemonSection,
    /// Optional: push every ended scan to a central PostgreSQL (crates/fleet).
    fleet: Option<footscan_fleet::settings::Section>,
    /// Optional: the clinic (its time zone for visits).
    clinic: Option<ClinicSection>,
    /// Optional: the clinic's customized lasts (the stock collection, the comfort rules).
    lasts: Option<LastsSection>,
    /// Optional: compact scans and retention (docs/method.md 14h.2).
    archive: Option<ArchiveSection>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ArchiveSection {
    compact: Option<bool>,
    keep_raw_days: Option<f64>,
    keep_days: Option<f64>,
    max_gb: Option<f64>,
    retention_interval_h: Option<f64>,
    cache_mb: Option<f64>,
}

/// `[archive]`: how scans are kept (docs/method.md 14h.2).
#[derive(Clone, Debug, PartialEq)]
pub struct ArchivePolicy {
    /// New scans are put into compact form when they end (default on).
    pub compact: bool,
    /// After this many days a scan's raw data goes (grid.bin, points.ply, model.stl,
    /// truth.json; the record, measurements, pictures, model.step and model.glb stay).
    /// None: kept.
    pub keep_raw_days: Option<f64>,
    /// After this many days a whole scan goes. None: kept.
    pub keep_days: Option<f64>,
    /// The archive's scans are kept under this many GB (10^9 bytes on disk), oldest
    /// dropped first. None: no limit.
    pub max_gb: Option<f64>,
    /// Hours between two retention runs (the first at start).
    pub retention_interval_h: f64,
    /// The most the cache of compacted scans' decoded files holds (bytes).
    pub cache_bytes: u64,
}

impl Default for ArchivePolicy {
    fn default() -> Self {
        ArchivePolicy {
            compact: true,
            keep_raw_days: None,
            keep_days: None,
            max_gb: None,
            retention_interval_h: 1.0,
            cache_bytes: DEFAULT_CACHE_MB << 20,
        }
    }
}

/// The default `[archive] cache_mb`: a few dozen decoded scans' models and grids.
pub const DEFAULT_CACHE_MB: u64 = 512;

impl ArchivePolicy {
    /// Whether any retention rule is set.
    pub fn retains(&self) -> bool {
        self.keep_raw_days.is_some() || self.keep_days.is_some() || self.max_gb.is_some()
    }

    fn parse(a: Option<ArchiveSection>) -> Result<ArchivePolicy, String> {
        let Some(a) = a else {
            return Ok(ArchivePolicy::default());
        };
        // 0 (or absent) means "no limit"; else within the range, named with the key.
        let days = |key: &str, v: Option<f64>| match v {
            None => Ok(None),
            Some(0.0) => Ok(None),
            Some(d) if d.is_finite() && (1.0..=36500.0).contains(&d) => Ok(Some(d)),
            Some(d) => Err(format!(
                "[archive] {key} = {d}: must be 0 (keep for ever) or 1 to 36500 days"
            )),
        };
        let keep_raw_days = days("keep_raw_days", a.keep_raw_days)?;
        let keep_days = days("keep_days", a.keep_days)?;
        if let (Some(r), Some(k)) = (keep_raw_days, keep_days) {
            if r > k {
                return Err(format!(
                    "[archive] keep_raw_days = {r} is more than keep_days = {k}: a scan's raw \
                     data cannot outlive the scan"
                ));
            }
        }
        let max_gb = match a.max_gb {
            None => None,
            Some(0.0) => None,
            Some(g) if g.is_finite() && (0.001..=1.0e6).contains(&g) => Some(g),
            Some(g) => {
                return Err(format!(
                    "[archive] max_gb = {g}: must be 0 (no limit) or 0.001 to 1000000 GB"
                ))
            }
        };
        let retention_interval_h = match a.retention_interval_h.unwrap_or(1.0) {
            h if h.is_finite() && (0.001..=168.0).contains(&h) => h,
            h => {
                return Err(format!(
                    "[archive] retention_interval_h = {h}: must be 0.001 to 168 hours"
                ))
            }
        };
        let cache_bytes = match a.cache_mb {
            None => DEFAULT_CACHE_MB << 20,
            Some(m) if m.is_finite() && (16.0..=1.0e6).contains(&m) => (m * 1048576.0) as u64,
            Some(m) => {
                return Err(format!(
                    "[archive] cache_mb = {m}: must be 16 to 1000000 MB (the cache of \
                     compacted scans' files; default {DEFAULT_CACHE_MB})"
                ))
            }
        };
        Ok(ArchivePolicy {
            compact: a.compact.unwrap_or(true),
            keep_raw_days,
            keep_days,
            max_gb,
            retention_interval_h,
            cache_bytes,
        })
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct LastsSection {
    /// The shop's stock lasts (STL, OBJ or PLY files), one of which a last is made from.
    stock_dir: Option<PathBuf>,
    /// The comfort rule file (TOML); default: the rules built into footscan.
    rules: Option<PathBuf>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ClinicSection {
    /// IANA name, e.g. "Europe/Berlin"; default: the machine's zone.
    time_zone: Option<String>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DaemonSection {
    bind: Option<String>,
    token: Option<String>,
    archive: PathBuf,
    scanner_config: PathBuf,
    calibration: Option<PathBuf>,
    allowed_hosts: Option<Vec<String>>,
    header_timeout_s: Option<f64>,
    body_timeout_s: Option<f64>,
    max_connections: Option<usize>,
    max_connections_per_client: Option<usize>,
    /// HTTPS: "self-signed" or { cert, key } (api/tls.rs).
    tls: Option<toml::Value>,
    /// A non-loopback bind with a token and without TLS is refused unless this says the
    /// network is trusted (or a reverse proxy terminates TLS in front).
    allow_plain_http: Option<bool>,
}

/// Defaults of the HTTP limits.
pub const DEFAULT_HEADER_TIMEOUT_S: f64 = 10.0;
pub const DEFAULT_BODY_TIMEOUT_S: f64 = 10.0;
/// High enough that a flood of a few thousand half-sent connections is held (each costs a
/// descriptor and a few KiB) instead of churned through eviction: every evicted connection
/// is reopened at once and waits in the listen queue ahead of real requests. The descriptor
/// limit lowers it (deploy/footscand.service allows 4096).
pub const DEFAULT_MAX_CONNECTIONS: usize = 4096;
pub const DEFAULT_MAX_CONNECTIONS_PER_CLIENT: usize = 3072;

/// The resolved daemon configuration.
#[derive(Clone, Debug)]
pub struct DaemonConfig {
    pub path: PathBuf,
    pub bind: SocketAddr,
    pub token: Option<String>,
    pub archive: PathBuf,
    pub scanner_config: PathBuf,
    pub calibration: Option<PathBuf>,
    /// Host names (besides localhost and the addresses it answers on) the daemon accepts in
    /// the Host header, e.g. its DNS name on the network.
    pub allowed_hosts: Vec<String>,
    /// Time for a request head, and the longest a kept-alive connection may sit idle.
    pub header_timeout: std::time::Duration,
    /// Time for a request body.
    pub body_timeout: std::time::Duration,
    /// Open connections at most (further lowered by the file-descriptor limit).
    pub max_connections: usize,
    /// Open connections from one client address at most.
    pub max_connections_per_client: usize,
    /// The fleet database scans are pushed to (`[fleet]`, when present and enabled).
    pub fleet: Option<footscan_fleet::Settings>,
    /// The clinic's time zone (`[clinic] time_zone`; default: the machine's, else UTC):
    /// visits' local times and dates.
    pub clinic_zone: crate::archive::ClinicZone,
    /// The stock lasts' directory (`[lasts] stock_dir`): none, no last jobs.
    pub stock_lasts: Option<PathBuf>,
    /// The comfort rule file (`[lasts] rules`); None: footscan's built-in rules.
    pub last_rules: Option<PathBuf>,
    /// HTTPS (`[daemon] tls`); None: plain HTTP.
    pub tls: Option<crate::api::tls::TlsSetting>,
    /// `[daemon] allow_plain_http`: plain HTTP with a token on the network is intended.
    pub allow_plain_http: bool,
    /// `[archive]`: compact scans, retention.
    pub archive_policy: ArchivePolicy,
}

#[derive(Debug, thiserror::Error)]
pub enum DaemonConfigError {
    #[error("cannot read daemon config {path}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("daemon config {path}: {message}")]
    Invalid { path: PathBuf, message: String },
    #[error(
        "daemon config {path}: longer than {} MiB, which no config is (is the path right?)",
        MAX_CONFIG_BYTES >> 20
    )]
    TooLong { path: PathBuf },
    #[error("daemon config {path}")]
    Tls {
        path: PathBuf,
        source: crate::api::tls::TlsSettingError,
    },
    #[error("daemon config {path}: [lasts] rules")]
    Rules {
        path: PathBuf,
        source: footscan_last::customize::rules::RulesError,
    },
    #[error(
        "refusing to listen on {bind} without a token: a non-loopback address exposes the \
         scanner to the network; set `token` in [daemon] of {path} or the environment variable \
         {TOKEN_ENV}, or bind 127.0.0.1"
    )]
    NoToken { bind: SocketAddr, path: PathBuf },
    #[error(
        "refusing to listen on {bind} with a token over plain HTTP: the token would cross the \
         network in clear text; set `tls = \"self-signed\"` (or `tls = {{ cert = \"...\", key = \
         \"...\" }}`) in [daemon] of {path}, put a TLS reverse proxy in front and bind \
         127.0.0.1, or set `allow_plain_http = true` if the network is trusted \
         (docs/running-footscand.md)"
    )]
    PlainHttp { bind: SocketAddr, path: PathBuf },
}

/// The longest config file read (the repository's is a few KiB).
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

impl DaemonConfig {
    /// Load `path`; `bind` (from the command line) overrides the file's, and FOOTSCAND_TOKEN
    /// the file's token.
    pub fn load(path: &Path, bind: Option<&str>) -> Result<DaemonConfig, DaemonConfigError> {
        use std::io::Read;
        let read_err = |source| DaemonConfigError::Read {
            path: path.to_owned(),
            source,
        };
        // Read at most one byte past the limit: a path naming a device or a huge file must
        // not make the daemon read it all before refusing it.
        let mut text = String::new();
        std::fs::File::open(path)
            .and_then(|f| f.take(MAX_CONFIG_BYTES + 1).read_to_string(&mut text))
            .map_err(read_err)?;
        if text.len() as u64 > MAX_CONFIG_BYTES {
            return Err(DaemonConfigError::TooLong {
                path: path.to_owned(),
            });
        }
        let env_token = std::env::var(TOKEN_ENV).ok();
        Self::parse(path, &text, bind, env_token)
    }

    pub fn parse(
        path: &Path,
        text: &str,
        bind: Option<&str>,
        env_token: Option<String>,
    ) -> Result<DaemonConfig, DaemonConfigError> {
        let invalid = |message: String| DaemonConfigError::Invalid {
            path: path.to_owned(),
            message,
        };
        let f: File = toml::from_str(text).map_err(|e| {
            invalid(match e.span() {
                Some(s) => format!("{}{}", e.message().trim_end(), line_col(text, s.start)),
                None => e.message().trim_end().to_string(),
            })
        })?;
        let File {
            daemon: d,
            fleet: fleet_section,
            clinic,
            lasts,
            archive,
        } = f;
        let archive_policy = ArchivePolicy::parse(archive).map_err(&invalid)?;
        let clinic_zone = match clinic.and_then(|c| c.time_zone) {
            Some(name) => crate::archive::ClinicZone::named(&name)
                .map_err(|e| invalid(format!("[clinic] time_zone = {name:?}: {e}")))?,
            None => crate::archive::ClinicZone::system(),
        };
        let bind_text = bind
            .map(str::to_string)
            .or(d.bind)
            .unwrap_or_else(|| DEFAULT_BIND.into());
        let bind: SocketAddr = bind_text.parse().map_err(|_| {
            invalid(format!(
                "bind = {bind_text:?}: expected IP:PORT, e.g. {DEFAULT_BIND} or 0.0.0.0:8470"
            ))
        })?;
        let token = env_token.or(d.token);
        if let Some(t) = &token {
            if t.len() < 16 || !t.bytes().all(|c| c.is_ascii_graphic()) {
                return Err(invalid(format!(
                    "token: must be at least 16 printable ASCII characters without spaces (got {} characters)",
                    t.len()
                )));
            }
        }
        if token.is_none() && !bind.ip().is_loopback() {
            return Err(DaemonConfigError::NoToken {
                bind,
                path: path.to_owned(),
            });
        }
        let base = path.parent().unwrap_or(Path::new("."));
        let tls = d
            .tls
            .as_ref()
            .map(|v| crate::api::tls::TlsSetting::parse(v, base))
            .transpose()
            .map_err(|source| DaemonConfigError::Tls {
                path: path.to_owned(),
                source,
            })?;
        let allow_plain_http = d.allow_plain_http.unwrap_or(false);
        if token.is_some() && tls.is_none() && !allow_plain_http && !bind.ip().is_loopback() {
            return Err(DaemonConfigError::PlainHttp {
                bind,
                path: path.to_owned(),
            });
        }
        let secs = |key: &str, v: Option<f64>, default: f64| {
            let v = v.unwrap_or(default);
            if v.is_finite() && (0.1..=3600.0).contains(&v) {
                Ok(std::time::Duration::from_secs_f64(v))
            } else {
                Err(invalid(format!("{key} = {v}: must be 0.1..=3600 seconds")))
            }
        };
        let header_timeout = secs(
            "header_timeout_s",
            d.header_timeout_s,
            DEFAULT_HEADER_TIMEOUT_S,
        )?;
        let body_timeout = secs("body_timeout_s", d.body_timeout_s, DEFAULT_BODY_TIMEOUT_S)?;
        let count = |key: &str, v: Option<usize>, default: usize| match v.unwrap_or(default) {
            n @ 1..=100_000 => Ok(n),
            n => Err(invalid(format!("{key} = {n}: must be 1..=100000"))),
        };
        let max_connections = count(
            "max_connections",
            d.max_connections,
            DEFAULT_MAX_CONNECTIONS,
        )?;
        let max_connections_per_client = count(
            "max_connections_per_client",
            d.max_connections_per_client,
            DEFAULT_MAX_CONNECTIONS_PER_CLIENT,
        )?;
        let allowed_hosts = d.allowed_hosts.unwrap_or_default();
        for h in &allowed_hosts {
            let ok = !h.is_empty()
                && h.len() <= 253
                && h.bytes()
                    .all(|c| c.is_ascii_alphanumeric() || matches!(c, b'.' | b'-'));
            if !ok {
                return Err(invalid(format!(
                    "allowed_hosts: {h:?} is not a host name (letters, digits, dots, hyphens; no port)"
                )));
            }
        }
        let fleet = match &fleet_section {
            Some(sec) => Some(
                footscan_fleet::Settings::resolve(
                    sec,
                    base,
                    std::env::var(footscan_fleet::settings::PASSWORD_ENV).ok(),
                )
                .map_err(|e| invalid(format!("[fleet]: {e}")))?,
            )
            .filter(|s| s.enabled),
            None => None,
        };
        let rel = |p: PathBuf| if p.is_absolute() { p } else { base.join(p) };
        let (stock_lasts, last_rules) = match lasts {
            Some(l) => (l.stock_dir.map(rel), l.rules.map(rel)),
            None => (None, None),
        };
        // A rule file with a typo is named at start, not at the first last job.
        if let Some(r) = &last_rules {
            footscan_last::customize::rules::RuleSet::load(r).map_err(|source| {
                DaemonConfigError::Rules {
                    path: path.to_owned(),
                    source,
                }
            })?;
        }
        Ok(DaemonConfig {
            path: path.to_owned(),
            bind,
            token,
            archive: rel(d.archive),
            scanner_config: rel(d.scanner_config),
            calibration: d.calibration.map(rel),
            allowed_hosts: allowed_hosts
                .into_iter()
                .map(|h| h.to_ascii_lowercase())
                .collect(),
            header_timeout,
            body_timeout,
            max_connections,
            max_connections_per_client,
            fleet,
            clinic_zone,
            stock_lasts,
            last_rules,
            tls,
            allow_plain_http,
            archive_policy,
        })
    }
}

fn line_col(text: &str, offset: usize) -> String {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
    format!(" (line {line}, column {col})")
}

#[cfg(test)]
mod tests {
    use super::*;

    const OK: &str = "[daemon]\narchive = \"scans\"\nscanner_config = \"sim.toml\"\n";

    #[test]
    fn paths_are_relative_to_the_file_and_loopback_needs_no_token() {
        let c = DaemonConfig::parse(Path::new("/etc/fs/d.toml"), OK, None, None).unwrap();
        assert_eq!(c.archive, Path::new("/etc/fs/scans"));
        assert_eq!(c.scanner_config, Path::new("/etc/fs/sim.toml"));
        assert!(c.bind.ip().is_loopback());
    }

    #[test]
    fn errors_name_the_key_and_position() {
        let text = format!("{OK}colour = 1\n");
        let e = DaemonConfig::parse(Path::new("d.toml"), &text, None, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("colour") && e.contains("line 4, column 1"),
            "{e}"
        );
        let e = DaemonConfig::parse(Path::new("d.toml"), OK, Some("0.0.0.0:1"), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("FOOTSCAND_TOKEN") && e.contains("token"), "{e}");
        let t = Some("0123456789abcdef".to_string());
        // With a token on the network: TLS, or plain HTTP said to be intended.
        let e = DaemonConfig::parse(Path::new("d.toml"), OK, Some("0.0.0.0:1"), t.clone())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("clear text") && e.contains("allow_plain_http = true"),
            "{e}"
        );
        for extra in ["allow_plain_http = true\n", "tls = \"self-signed\"\n"] {
            let text = format!("{OK}{extra}");
            let c = DaemonConfig::parse(Path::new("d.toml"), &text, Some("0.0.0.0:1"), t.clone());
            assert!(c.is_ok(), "{extra}: {:?}", c.err());
        }
        let e = DaemonConfig::parse(Path::new("d.toml"), OK, None, Some("short".into()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("at least 16"), "{e}");
    }

    #[test]
    fn archive_policy_keys_and_ranges() {
        let c = DaemonConfig::parse(Path::new("d.toml"), OK, None, None).unwrap();
        assert_eq!(c.archive_policy, ArchivePolicy::default());
        assert!(c.archive_policy.compact && !c.archive_policy.retains());
        let text = format!(
            "{OK}[archive]\nkeep_raw_days = 30\nkeep_days = 3650\nmax_gb = 200\ncache_mb = 64\n"
        );
        let c = DaemonConfig::parse(Path::new("d.toml"), &text, None, None).unwrap();
        assert_eq!(c.archive_policy.keep_raw_days, Some(30.0));
        assert_eq!(c.archive_policy.max_gb, Some(200.0));
        assert_eq!(c.archive_policy.cache_bytes, 64 << 20);
        for (bad, words) in [
            (
                "keep_days = -1",
                "keep_days = -1: must be 0 (keep for ever) or 1 to 36500",
            ),
            ("max_gb = 1e9", "max_gb = 1000000000: must be 0 (no limit)"),
            (
                "keep_raw_days = 40\nkeep_days = 30",
                "keep_raw_days = 40 is more than keep_days",
            ),
            (
                "retention_interval_h = 0",
                "retention_interval_h = 0: must be",
            ),
            ("cache_mb = 1", "cache_mb = 1: must be 16 to 1000000 MB"),
            ("keep = 3", "unknown field `keep`"),
        ] {
            let text = format!("{OK}[archive]\n{bad}\n");
            let e = DaemonConfig::parse(Path::new("d.toml"), &text, None, None)
                .unwrap_err()
                .to_string();
            assert!(e.contains("d.toml") && e.contains(words), "{bad}: {e}");
        }
    }

    #[test]
    fn the_clinic_time_zone_is_an_iana_name() {
        let text = format!("{OK}[clinic]\ntime_zone = \"Europe/Berlin\"\n");
        let c = DaemonConfig::parse(Path::new("d.toml"), &text, None, None).unwrap();
        assert_eq!(c.clinic_zone.name, "Europe/Berlin");
        assert_eq!(
            c.clinic_zone.local("2026-11-24T23:30:00Z").as_deref(),
            Some("2026-11-25T00:30:00+01:00")
        );
        for bad in [
            "Europe/Berln",
            "CET-1CEST,M3.5.0,M10.5.0/3",
            "/etc/localtime",
            "",
        ] {
            let text = format!("{OK}[clinic]\ntime_zone = {bad:?}\n");
            let e = DaemonConfig::parse(Path::new("d.toml"), &text, None, None)
                .unwrap_err()
                .to_string();
            assert!(
                e.contains("d.toml")
                    && e.contains(&format!("[clinic] time_zone = {bad:?}"))
                    && e.contains("Europe/Berlin"),
                "{e}"
            );
        }
    }
}
