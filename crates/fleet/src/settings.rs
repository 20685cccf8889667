//! The `[fleet]` section (in footscand's config, read by `footscan fleet` too): where the
//! database is, how to reach it, and who this scanner is. The password never appears in a
//! `Debug`, a `Display`, a log line or the daemon's status: [`Settings::target`] is what is
//! shown.

use crate::FleetError;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::time::Duration;

/// Environment variable holding the database password (wins over `password_file` and a
/// password in the URL).
pub const PASSWORD_ENV: &str = "FOOTSCAN_FLEET_PASSWORD";

/// How the connection is protected, with libpq's meanings of the names.
#[derive(Clone, Copy, Debug, Default, Deserialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum Tls {
    /// Plain TCP (a trusted network, or a tunnel).
    #[default]
    Disable,
    /// TLS required, the server's certificate not checked (encryption without
    /// authentication of the server, as libpq's sslmode=require).
    Require,
    /// TLS required, the certificate checked against `ca_file` (or the system's roots) and
    /// the host name (as libpq's sslmode=verify-full).
    VerifyFull,
}

impl Tls {
    pub fn as_str(self) -> &'static str {
        match self {
            Tls::Disable => "disable",
            Tls::Require => "require",
            Tls::VerifyFull => "verify-full",
        }
    }
}

/// A `tls` value that is not one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("tls = {0:?}: expected \"disable\", \"require\" or \"verify-full\"")]
pub struct UnknownTls(pub String);

impl FromStr for Tls {
    type Err = UnknownTls;
    fn from_str(s: &str) -> Result<Tls, UnknownTls> {
        match s {
            "disable" => Ok(Tls::Disable),
            "require" => Ok(Tls::Require),
            "verify-full" => Ok(Tls::VerifyFull),
            _ => Err(UnknownTls(s.to_string())),
        }
    }
}

/// The `[fleet]` section as written.
#[derive(Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Section {
    /// Default true: a present section is on; `enabled = false` keeps it but pushes nothing.
    pub enabled: Option<bool>,
    /// `postgres://user@host:port/dbname` (or libpq's `key=value` form).
    pub url: String,
    pub tls: Option<String>,
    /// PEM file of the certificate authority for `tls = "verify-full"`.
    pub ca_file: Option<PathBuf>,
    /// File holding the password (first line); [`PASSWORD_ENV`] wins over it.
    pub password_file: Option<PathBuf>,
    /// This scanner's name in the fleet (unique per scanner): 1-64 of `[A-Za-z0-9._-]`.
    pub scanner: String,
    /// The clinic it stands in: 1-64 of `[A-Za-z0-9._-]`.
    pub clinic: String,
    /// Longest wait between two attempts while the database is unreachable (seconds).
    pub retry_max_s: Option<f64>,
    /// Time allowed to open a connection (seconds).
    pub connect_timeout_s: Option<f64>,
}

impl std::fmt::Debug for Section {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Section")
            .field("url", &redact_url(&self.url))
            .field("scanner", &self.scanner)
            .field("clinic", &self.clinic)
            .finish_non_exhaustive()
    }
}

/// The resolved settings: a parsed connection config with its password, and who we are.
#[derive(Clone)]
pub struct Settings {
    pub enabled: bool,
    pg: postgres::Config,
    pub tls: Tls,
    pub ca_file: Option<PathBuf>,
    pub scanner: String,
    pub clinic: String,
    pub retry_max: Duration,
}

impl std::fmt::Debug for Settings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Settings {{ target: {:?}, scanner: {:?}, clinic: {:?}, enabled: {} }}",
            self.target(),
            self.scanner,
            self.clinic,
            self.enabled
        )
    }
}

pub const DEFAULT_RETRY_MAX_S: f64 = 30.0;
pub const DEFAULT_CONNECT_TIMEOUT_S: f64 = 10.0;

/// A name of the fleet (scanner, clinic): safe in a file name and a URL.
pub fn valid_name(s: &str) -> bool {
    (1..=64).contains(&s.len())
        && s.bytes()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, b'.' | b'_' | b'-'))
}

impl Settings {
    /// Resolve a section read from a file in `base` (relative paths are relative to it);
    /// `env_password` is the value of [`PASSWORD_ENV`] if set.
    pub fn resolve(
        s: &Section,
        base: &Path,
        env_password: Option<String>,
    ) -> Result<Settings, FleetError> {
        let bad = |m: String| FleetError::Settings(m);
        let rel = |p: &PathBuf| {
            if p.is_absolute() {
                p.clone()
            } else {
                base.join(p)
            }
        };
        let tls = match &s.tls {
            Some(t) => t.parse::<Tls>().map_err(|e| bad(e.to_string()))?,
            None => Tls::Disable,
        };
        for (key, v) in [("scanner", &s.scanner), ("clinic", &s.clinic)] {
            if !valid_name(v) {
                return Err(bad(format!(
                    "{key} = {v:?}: must be 1-64 of A-Z a-z 0-9 . _ -"
                )));
            }
        }
        let secs = |key: &str, v: Option<f64>, d: f64| {
            let v = v.unwrap_or(d);
            if v.is_finite() && (0.1..=3600.0).contains(&v) {
                Ok(Duration::from_secs_f64(v))
            } else {
                Err(bad(format!("{key} = {v}: must be 0.1..=3600 seconds")))
            }
        };
        let retry_max = secs("retry_max_s", s.retry_max_s, DEFAULT_RETRY_MAX_S)?;
        let connect_timeout = secs(
            "connect_timeout_s",
            s.connect_timeout_s,
            DEFAULT_CONNECT_TIMEOUT_S,
        )?;
        let mut pg = postgres::Config::from_str(&s.url).map_err(|e| {
            bad(format!(
                "url = {:?}: {e}; expected postgres://USER@HOST:PORT/DATABASE",
                redact_url(&s.url)
            ))
        })?;
        if pg.get_user().is_none_or(str::is_empty) {
            return Err(bad(format!(
                "url = {:?}: names no user; expected postgres://USER@HOST:PORT/DATABASE",
                redact_url(&s.url)
            )));
        }
        let file_password = match &s.password_file {
            Some(p) => {
                let p = rel(p);
                let text = std::fs::read_to_string(&p)
                    .map_err(|e| bad(format!("password_file = {}: {e}", p.display())))?;
                Some(text.lines().next().unwrap_or("").to_string())
            }
            None => None,
        };
        if let Some(pw) = env_password.or(file_password) {
            pg.password(pw);
        }
        pg.connect_timeout(connect_timeout);
        pg.application_name("footscan");
        pg.ssl_mode(match tls {
            Tls::Disable => postgres::config::SslMode::Disable,
            Tls::Require | Tls::VerifyFull => postgres::config::SslMode::Require,
        });
        let ca_file = s.ca_file.as_ref().map(rel);
        if ca_file.is_some() && tls != Tls::VerifyFull {
            return Err(bad(format!(
                "ca_file is set but tls = {:?}: the certificate authority is used by tls = \"verify-full\" only",
                tls.as_str()
            )));
        }
        Ok(Settings {
            enabled: s.enabled.unwrap_or(true),
            pg,
            tls,
            ca_file,
            scanner: s.scanner.clone(),
            clinic: s.clinic.clone(),
            retry_max,
        })
    }

    /// Settings from a URL alone (the CLI's `--url`), for reading: scanner and clinic unset.
    pub fn from_url(
        url: &str,
        tls: Tls,
        env_password: Option<String>,
    ) -> Result<Settings, FleetError> {
        let s = Section {
            enabled: Some(true),
            url: url.to_string(),
            tls: Some(tls.as_str().to_string()),
            ca_file: None,
            password_file: None,
            scanner: "cli".into(),
            clinic: "cli".into(),
            retry_max_s: None,
            connect_timeout_s: None,
        };
        Settings::resolve(&s, Path::new("."), env_password)
    }

    /// The `[fleet]` section of a TOML file (other sections are not read).
    pub fn from_file(path: &Path, env_password: Option<String>) -> Result<Settings, FleetError> {
        let text = std::fs::read_to_string(path).map_err(|source| FleetError::Io {
            path: path.to_owned(),
            source,
        })?;
        let v: toml_value::Table = toml_value::parse(&text)
            .map_err(|e| FleetError::Settings(format!("{}: {e}", path.display())))?;
        let section = v.get("fleet").ok_or_else(|| {
            FleetError::Settings(format!("{}: no [fleet] section", path.display()))
        })?;
        let s: Section = section
            .clone()
            .try_into()
            .map_err(|e| FleetError::Settings(format!("[fleet] of {}: {e}", path.display())))?;
        Settings::resolve(&s, path.parent().unwrap_or(Path::new(".")), env_password)
    }

    pub fn pg(&self) -> &postgres::Config {
        &self.pg
    }

    /// Whether a password is set (from any source); the password itself is never shown.
    pub fn has_password(&self) -> bool {
        self.pg.get_password().is_some()
    }

    /// Where the database is, for messages and the status: `postgres://user@host:port/db
    /// (tls require)`, never the password.
    pub fn target(&self) -> String {
        let host = self
            .pg
            .get_hosts()
            .iter()
            .map(|h| match h {
                postgres::config::Host::Tcp(n) => n.clone(),
                postgres::config::Host::Unix(p) => p.display().to_string(),
            })
            .collect::<Vec<_>>()
            .join(",");
        let port = self
            .pg
            .get_ports()
            .first()
            .map_or(String::new(), |p| format!(":{p}"));
        format!(
            "postgres://{}@{host}{port}/{} (tls {})",
            self.pg.get_user().unwrap_or("?"),
            self.pg.get_dbname().or(self.pg.get_user()).unwrap_or("?"),
            self.tls.as_str()
        )
    }

    /// A copy pointing at another TCP port (tests: a closed port is a cut network).
    pub fn with_port(&self, port: u16) -> Settings {
        let mut s = self.clone();
        let hosts: Vec<_> = s.pg.get_hosts().to_vec();
        let mut pg = postgres::Config::new();
        for h in hosts {
            if let postgres::config::Host::Tcp(n) = h {
                pg.host(&n);
            }
        }
        pg.port(port);
        if let Some(u) = s.pg.get_user() {
            pg.user(u);
        }
        if let Some(d) = s.pg.get_dbname() {
            pg.dbname(d);
        }
        if let Some(p) = s.pg.get_password() {
            pg.password(p);
        }
        if let Some(t) = s.pg.get_connect_timeout() {
            pg.connect_timeout(*t);
        }
        pg.ssl_mode(s.pg.get_ssl_mode());
        s.pg = pg;
        s
    }
}

/// `url` with any password replaced by `***` (for messages about a URL that did not parse).
pub fn redact_url(url: &str) -> String {
    // postgres://user:secret@host... -> postgres://user:***@host...
    if let Some((scheme, rest)) = url.split_once("://") {
        if let Some((auth, host)) = rest.rsplit_once('@') {
            if let Some((user, _)) = auth.split_once(':') {
                return format!("{scheme}://{user}:***@{host}");
            }
        }
        return url.to_string();
    }
    // key=value form: password=... -> password=***
    url.split_whitespace()
        .map(|kv| {
            if kv.starts_with("password=") {
                "password=***".to_string()
            } else {
                kv.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// Just enough TOML to take one table out of a file that has others.
mod toml_value {
    pub use toml::Table;
    pub fn parse(text: &str) -> Result<Table, toml::de::Error> {
        text.parse::<Table>()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn section(url: &str) -> Section {
        Section {
            enabled: None,
            url: url.into(),
            tls: None,
            ca_file: None,
            password_file: None,
            scanner: "scanner-1".into(),
            clinic: "north".into(),
            retry_max_s: None,
            connect_timeout_s: None,
        }
    }

    #[test]
    fn the_password_is_never_shown() {
        let s = Settings::resolve(
            &section("postgres://fs:hunter2secret@db.example:5433/fleet"),
            Path::new("."),
            None,
        )
        .unwrap();
        assert!(s.has_password());
        for text in [
            format!("{s:?}"),
            s.target(),
            format!("{:?}", section("postgres://fs:hunter2secret@h/d")),
        ] {
            assert!(!text.contains("hunter2secret"), "{text}");
        }
        assert_eq!(
            s.target(),
            "postgres://fs@db.example:5433/fleet (tls disable)"
        );
        let s = Settings::resolve(
            &section("postgres://fs@h/d"),
            Path::new("."),
            Some("envpw".into()),
        )
        .unwrap();
        assert_eq!(s.pg().get_password(), Some(&b"envpw"[..]));
        assert!(!format!("{s:?}").contains("envpw"));
    }

    #[test]
    fn bad_settings_name_the_key_and_what_is_valid() {
        let mut sec = section("postgres://fs@h/d");
        sec.tls = Some("maybe".into());
        let e = Settings::resolve(&sec, Path::new("."), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tls") && e.contains("verify-full"), "{e}");
        let mut sec = section("postgres://fs@h/d");
        sec.scanner = "a b".into();
        let e = Settings::resolve(&sec, Path::new("."), None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("scanner") && e.contains("A-Z"), "{e}");
        let e = Settings::resolve(&section("postgres://:pw@h/d"), Path::new("."), None)
            .unwrap_err()
            .to_string();
        assert!(!e.contains("pw@"), "{e}");
        let mut sec = section("postgres://fs@h/d");
        sec.password_file = Some("/nonexistent/pw".into());
        let e = Settings::resolve(&sec, Path::new("."), None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("password_file") && e.contains("/nonexistent/pw"),
            "{e}"
        );
        assert_eq!(
            redact_url("host=h password=x user=u"),
            "host=h password=*** user=u"
        );
    }
}
