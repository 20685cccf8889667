//! Opening a connection with the settings' TLS mode: plain, TLS without checking the
//! certificate (`require`), or TLS checked against a CA and the host name (`verify-full`),
//! through the system's OpenSSL (native-tls).

use crate::{FleetError, Settings, Tls};

pub fn connect(s: &Settings) -> Result<postgres::Client, FleetError> {
    let fail = |message: String| FleetError::Connect {
        target: s.target(),
        message,
    };
    let res = match s.tls {
        Tls::Disable => s.pg().connect(postgres::NoTls),
        Tls::Require | Tls::VerifyFull => {
            let mut b = native_tls::TlsConnector::builder();
            if s.tls == Tls::Require {
                b.danger_accept_invalid_certs(true)
                    .danger_accept_invalid_hostnames(true);
            }
            if let Some(ca) = &s.ca_file {
                let pem = std::fs::read(ca)
                    .map_err(|e| fail(format!("ca_file {}: {e}", ca.display())))?;
                let cert = native_tls::Certificate::from_pem(&pem).map_err(|e| {
                    fail(format!(
                        "ca_file {}: not a PEM certificate: {e}",
                        ca.display()
                    ))
                })?;
                b.add_root_certificate(cert);
            }
            let tls = b.build().map_err(|e| fail(format!("TLS setup: {e}")))?;
            s.pg()
                .connect(postgres_native_tls::MakeTlsConnector::new(tls))
        }
    };
    res.map_err(|e| fail(error_text(&e)))
}

/// An error in words, with its causes (the `postgres` error alone often says only "error
/// connecting to server").
pub fn error_text(e: &postgres::Error) -> String {
    let mut out = e.to_string();
    let mut src = std::error::Error::source(e);
    while let Some(s) = src {
        let t = s.to_string();
        if !out.contains(&t) {
            out = format!("{out}: {t}");
        }
        src = s.source();
    }
    out
}
