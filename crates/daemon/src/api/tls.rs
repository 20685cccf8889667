//! HTTPS for footscand on a clinic network: `[daemon] tls = { cert = "...", key = "..." }`
//! (PEM files, e.g. from the clinic's CA) or `tls = "self-signed"` (a certificate made on
//! first start and kept in the archive's directory, under `tls/`).
//!
//! rustls on ring, not OpenSSL: the daemon links no C TLS library, and ring builds with the
//! C compiler alone (aws-lc, rustls' default, needs cmake). A self-signed certificate is
//! only as good as the operator's check of it, so its SHA-256 fingerprint is logged at start
//! and served with the status (`/api/tls`) to compare once with what the browser shows.

use rustls_pki_types::pem::PemObject;
use rustls_pki_types::{CertificateDer, PrivateKeyDer};
use serde::Serialize;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What `[daemon] tls` asks for.
#[derive(Clone, Debug, PartialEq)]
pub enum TlsSetting {
    /// A certificate chain and its private key, PEM files (paths relative to the config).
    Files { cert: PathBuf, key: PathBuf },
    /// Make (once) and keep a self-signed certificate under `<archive>/tls/`.
    SelfSigned,
}

const HOW: &str =
    "valid: tls = \"self-signed\" or tls = { cert = \"cert.pem\", key = \"key.pem\" }";

/// Why `tls` in [daemon] is refused; each names the key and what is valid.
#[derive(Debug, thiserror::Error)]
pub enum TlsSettingError {
    #[error("tls = {0}: {HOW}")]
    Value(String),
    #[error("tls: unknown key {0:?}; {HOW}")]
    UnknownKey(String),
    #[error("tls.{key} = {value}: must be the path of a PEM file; {HOW}")]
    NotAPath { key: &'static str, value: String },
    #[error("tls: {0} is missing; {HOW}")]
    Missing(&'static str),
}

impl TlsSetting {
    /// The setting from the value of `tls` in [daemon]; relative paths are taken from `base`.
    pub fn parse(v: &toml::Value, base: &Path) -> Result<TlsSetting, TlsSettingError> {
        match v {
            toml::Value::String(s) if s == "self-signed" => Ok(TlsSetting::SelfSigned),
            toml::Value::String(s) => Err(TlsSettingError::Value(format!("{s:?}"))),
            toml::Value::Table(t) => {
                if let Some(k) = t.keys().find(|k| *k != "cert" && *k != "key") {
                    return Err(TlsSettingError::UnknownKey(k.clone()));
                }
                let path = |k: &'static str| -> Result<PathBuf, TlsSettingError> {
                    match t.get(k) {
                        Some(toml::Value::String(p)) if !p.is_empty() => {
                            let p = PathBuf::from(p);
                            Ok(if p.is_absolute() { p } else { base.join(p) })
                        }
                        Some(other) => Err(TlsSettingError::NotAPath {
                            key: k,
                            value: other.to_string(),
                        }),
                        None => Err(TlsSettingError::Missing(k)),
                    }
                };
                Ok(TlsSetting::Files {
                    cert: path("cert")?,
                    key: path("key")?,
                })
            }
            other => Err(TlsSettingError::Value(other.to_string())),
        }
    }
}

/// What the operator needs to know about the certificate in use.
#[derive(Clone, Debug, Serialize)]
pub struct TlsInfo {
    /// SHA-256 of the leaf certificate (DER), upper-case hex pairs joined by colons, as
    /// browsers show it.
    pub fingerprint_sha256: String,
    pub certificate: PathBuf,
    pub self_signed: bool,
}

/// Why HTTPS could not be set up; each names the file and what would be valid.
#[derive(Debug, thiserror::Error)]
pub enum TlsError {
    /// The cause is the source, printed once by the chain (`footscan_util::Chain`, anyhow).
    #[error("{}", path.display())]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: {what}", path.display())]
    Pem { path: PathBuf, what: String },
    #[error("the certificate {} and the key {} do not go together: {what}", cert.display(), key.display())]
    Mismatch {
        cert: PathBuf,
        key: PathBuf,
        what: String,
    },
    #[error("making a self-signed certificate: {0}")]
    Generate(String),
}

/// The TLS side of the server: the acceptor and what to tell the operator.
#[derive(Clone)]
pub struct Tls {
    pub acceptor: tokio_rustls::TlsAcceptor,
    pub info: TlsInfo,
}

/// SHA-256 of `der` as AB:CD:...
pub fn fingerprint(der: &[u8]) -> String {
    Sha256::digest(der)
        .iter()
        .map(|b| format!("{b:02X}"))
        .collect::<Vec<_>>()
        .join(":")
}

fn read_chain(path: &Path) -> Result<Vec<CertificateDer<'static>>, TlsError> {
    let bytes = std::fs::read(path).map_err(|source| TlsError::Io {
        path: path.to_owned(),
        source,
    })?;
    let chain: Vec<_> = CertificateDer::pem_slice_iter(&bytes)
        .collect::<Result<_, _>>()
        .map_err(|e| TlsError::Pem {
            path: path.to_owned(),
            what: format!("not a PEM certificate chain ({e})"),
        })?;
    if chain.is_empty() {
        return Err(TlsError::Pem {
            path: path.to_owned(),
            what: "no certificate in it: expected PEM blocks \"-----BEGIN CERTIFICATE-----\""
                .into(),
        });
    }
    Ok(chain)
}

fn read_key(path: &Path) -> Result<PrivateKeyDer<'static>, TlsError> {
    let bytes = std::fs::read(path).map_err(|source| TlsError::Io {
        path: path.to_owned(),
        source,
    })?;
    PrivateKeyDer::from_pem_slice(&bytes).map_err(|e| TlsError::Pem {
        path: path.to_owned(),
        what: format!(
            "no private key in it ({e}): expected a PEM \"PRIVATE KEY\", \"RSA PRIVATE KEY\" or \
             \"EC PRIVATE KEY\" block"
        ),
    })
}

/// The self-signed certificate under `<archive>/tls/`, made on the first call with
/// `names` (DNS names and IP addresses) as its subject alternative names.
pub fn self_signed(archive: &Path, names: &[String]) -> Result<(PathBuf, PathBuf), TlsError> {
    let dir = archive.join("tls");
    let (cert, key) = (dir.join("cert.pem"), dir.join("key.pem"));
    if cert.exists() && key.exists() {
        return Ok((cert, key));
    }
    let io = |path: &Path| {
        let path = path.to_owned();
        move |source| TlsError::Io { path, source }
    };
    {
        use std::os::unix::fs::DirBuilderExt;
        std::fs::DirBuilder::new()
            .recursive(true)
            .mode(0o700)
            .create(&dir)
            .map_err(io(&dir))?;
    }
    let mut params = rcgen::CertificateParams::new(names.to_vec())
        .map_err(|e| TlsError::Generate(format!("subject names {names:?}: {e}")))?;
    params
        .distinguished_name
        .push(rcgen::DnType::CommonName, "footscand (self-signed)");
    // Ten years: a clinic's scanner should not stop working over a forgotten renewal; the
    // pinned fingerprint, not the date, is what the operator checks.
    let now = std::time::SystemTime::now();
    params.not_before = now.into();
    params.not_after = (now + std::time::Duration::from_secs(3650 * 86_400)).into();
    let pair = rcgen::KeyPair::generate().map_err(|e| TlsError::Generate(e.to_string()))?;
    let c = params
        .self_signed(&pair)
        .map_err(|e| TlsError::Generate(e.to_string()))?;
    // The key first, so a certificate on disk always has its key.
    footscan_util::write_atomic(&key, pair.serialize_pem().as_bytes()).map_err(io(&key))?;
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&key, std::fs::Permissions::from_mode(0o600)).map_err(io(&key))?;
    }
    footscan_util::write_atomic(&cert, c.pem().as_bytes()).map_err(io(&cert))?;
    tracing::info!(
        "made a self-signed certificate {} for {}",
        cert.display(),
        names.join(", ")
    );
    Ok((cert, key))
}

/// The names a self-signed certificate is made for: localhost, the loopback addresses, the
/// bound address (unless it is 0.0.0.0 or ::), the machine's host name and `allowed_hosts`.
pub fn subject_names(bind: std::net::SocketAddr, allowed_hosts: &[String]) -> Vec<String> {
    let mut names = vec!["localhost".to_string(), "127.0.0.1".into(), "::1".into()];
    if !bind.ip().is_unspecified() {
        names.push(bind.ip().to_string());
    }
    if let Ok(h) = std::fs::read_to_string("/proc/sys/kernel/hostname") {
        names.push(h.trim().to_string());
    }
    names.extend(allowed_hosts.iter().cloned());
    let mut seen = std::collections::HashSet::new();
    names.retain(|n| !n.is_empty() && seen.insert(n.clone()));
    names
}

/// Set up HTTPS as `setting` asks.
pub fn load(
    setting: &TlsSetting,
    archive: &Path,
    bind: std::net::SocketAddr,
    allowed_hosts: &[String],
) -> Result<Tls, TlsError> {
    let (cert, key, self_signed_) = match setting {
        TlsSetting::Files { cert, key } => (cert.clone(), key.clone(), false),
        TlsSetting::SelfSigned => {
            let (c, k) = self_signed(archive, &subject_names(bind, allowed_hosts))?;
            (c, k, true)
        }
    };
    let chain = read_chain(&cert)?;
    let private = read_key(&key)?;
    let fp = fingerprint(&chain[0]);
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let mut config = rustls::ServerConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| TlsError::Generate(e.to_string()))?
        .with_no_client_auth()
        .with_single_cert(chain, private)
        .map_err(|e| TlsError::Mismatch {
            cert: cert.clone(),
            key: key.clone(),
            what: e.to_string(),
        })?;
    config.alpn_protocols = vec![b"http/1.1".to_vec()];
    Ok(Tls {
        acceptor: tokio_rustls::TlsAcceptor::from(Arc::new(config)),
        info: TlsInfo {
            fingerprint_sha256: fp,
            certificate: cert,
            self_signed: self_signed_,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_parse_and_bad_ones_say_what_is_valid() {
        let base = Path::new("/etc/fs");
        let v: toml::Value = toml::from_str("tls = \"self-signed\"").unwrap();
        assert_eq!(
            TlsSetting::parse(&v["tls"], base).unwrap(),
            TlsSetting::SelfSigned
        );
        let v: toml::Value =
            toml::from_str("tls = { cert = \"c.pem\", key = \"/k.pem\" }").unwrap();
        assert_eq!(
            TlsSetting::parse(&v["tls"], base).unwrap(),
            TlsSetting::Files {
                cert: "/etc/fs/c.pem".into(),
                key: "/k.pem".into()
            }
        );
        for bad in [
            "tls = \"selfsigned\"",
            "tls = true",
            "tls = { cert = \"c.pem\" }",
            "tls = { cert = \"c.pem\", key = \"k.pem\", ca = \"x\" }",
        ] {
            let v: toml::Value = toml::from_str(bad).unwrap();
            let e = TlsSetting::parse(&v["tls"], base).unwrap_err().to_string();
            assert!(
                e.contains("self-signed") && e.contains("cert ="),
                "{bad}: {e}"
            );
        }
    }

    #[test]
    fn subject_names_are_listed_once() {
        let n = subject_names("127.0.0.1:8470".parse().unwrap(), &["localhost".into()]);
        let mut u = n.clone();
        u.sort();
        u.dedup();
        assert_eq!(u.len(), n.len(), "{n:?}");
        assert!(n.contains(&"::1".to_string()), "{n:?}");
    }

    #[test]
    fn a_self_signed_certificate_is_made_once_and_kept() {
        let dir = tempfile::tempdir().unwrap();
        let bind = "127.0.0.1:0".parse().unwrap();
        let a = load(&TlsSetting::SelfSigned, dir.path(), bind, &[]).unwrap();
        let b = load(&TlsSetting::SelfSigned, dir.path(), bind, &[]).unwrap();
        assert_eq!(a.info.fingerprint_sha256, b.info.fingerprint_sha256);
        assert_eq!(a.info.fingerprint_sha256.len(), 32 * 3 - 1);
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(dir.path().join("tls/key.pem"))
            .unwrap()
            .permissions()
            .mode();
        assert_eq!(mode & 0o077, 0, "key readable by others: {mode:o}");
    }

    #[test]
    fn unreadable_or_mismatched_files_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let bind = "127.0.0.1:0".parse().unwrap();
        let (c1, _) = self_signed(&dir.path().join("a"), &["localhost".into()]).unwrap();
        let (_, k2) = self_signed(&dir.path().join("b"), &["localhost".into()]).unwrap();
        let e = load(
            &TlsSetting::Files {
                cert: c1.clone(),
                key: k2.clone(),
            },
            dir.path(),
            bind,
            &[],
        )
        .err()
        .unwrap()
        .to_string();
        assert!(e.contains("do not go together"), "{e}");
        let e = load(
            &TlsSetting::Files {
                cert: k2.clone(),
                key: c1.clone(),
            },
            dir.path(),
            bind,
            &[],
        )
        .err()
        .unwrap()
        .to_string();
        assert!(e.contains("key.pem") && e.contains("no certificate"), "{e}");
        let missing = dir.path().join("none.pem");
        let e = load(
            &TlsSetting::Files {
                cert: missing,
                key: k2,
            },
            dir.path(),
            bind,
            &[],
        )
        .err()
        .unwrap()
        .to_string();
        assert!(e.contains("none.pem"), "{e}");
    }
}
