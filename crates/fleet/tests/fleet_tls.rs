//! TLS to the fleet database against a real PostgreSQL with `ssl = on` and the fleet user
//! allowed over TLS only: `disable` is refused by the server, `require` is encrypted (the
//! server's own pg_stat_ssl says so), `verify-full` checks the certificate against the CA and
//! the host name, and a certificate of another authority is refused.

use footscan_fleet::settings::Section;
use footscan_fleet::testing::{PgServer, PASSWORD, USER};
use footscan_fleet::*;
use std::path::{Path, PathBuf};

fn settings(pg: &PgServer, host: &str, tls: &str, ca: Option<PathBuf>) -> Settings {
    let s = Section {
        enabled: Some(true),
        url: format!("postgres://{USER}@{host}:{}/fleet", pg.port),
        tls: Some(tls.into()),
        ca_file: ca,
        password_file: None,
        scanner: "scanner-tls".into(),
        clinic: "north".into(),
        retry_max_s: None,
        connect_timeout_s: Some(5.0),
    };
    Settings::resolve(&s, Path::new("."), Some(PASSWORD.into())).unwrap()
}

fn encrypted(c: &mut Client) -> bool {
    c.query_one(
        "SELECT ssl FROM pg_stat_ssl WHERE pid = pg_backend_pid()",
        &[],
    )
    .unwrap()
    .get(0)
}

#[test]
fn tls_modes_against_a_server_that_requires_tls() {
    let pg = PgServer::start();
    let ca = pg.enable_tls();

    let e = connect(&settings(&pg, "127.0.0.1", "disable", None))
        .err()
        .expect("a plain connection must be refused");
    println!("disable: {e}");
    assert!(
        e.to_string().contains("no encryption") || e.to_string().contains("pg_hba"),
        "{e}"
    );

    let mut c = connect(&settings(&pg, "127.0.0.1", "require", None)).unwrap();
    assert!(encrypted(&mut c), "require: not encrypted");
    migrate(&mut c, None).unwrap();

    for host in ["localhost", "127.0.0.1"] {
        let mut c = connect(&settings(&pg, host, "verify-full", Some(ca.clone()))).unwrap();
        assert!(encrypted(&mut c), "verify-full {host}: not encrypted");
    }

    // Another authority's certificate: the server's is not trusted.
    let other = pg.dir.join("other-ca.pem");
    let out = std::process::Command::new("openssl")
        .args([
            "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj",
        ])
        .args(["/CN=someone else", "-keyout"])
        .arg(pg.dir.join("other-ca.key"))
        .arg("-out")
        .arg(&other)
        .output()
        .unwrap();
    assert!(out.status.success());
    let e = connect(&settings(&pg, "localhost", "verify-full", Some(other)))
        .err()
        .expect("an untrusted certificate must be refused");
    println!("verify-full, other CA: {e}");
    assert!(e.to_string().to_lowercase().contains("certificate"), "{e}");
}
