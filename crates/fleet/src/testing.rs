//! A throwaway PostgreSQL server for tests: Debian's binaries (`/usr/lib/postgresql/<ver>/bin`,
//! installed by scripts/setup.sh), `initdb` into a temporary directory, `pg_ctl` on a free
//! loopback port, password authentication (scram-sha-256) so a wrong password is refused as
//! in production. PostgreSQL refuses to run as root, so under root every server command runs
//! as the `postgres` user (`runuser`), the directory handed over to it.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

pub const ADMIN: &str = "fleet_admin";
pub const USER: &str = "footscan";
pub const PASSWORD: &str = "fleet-test-password";
pub const DATABASE: &str = "fleet";

pub struct PgServer {
    pub dir: PathBuf,
    pub port: u16,
    bin: PathBuf,
    run_as: Option<String>,
}

/// The newest installed PostgreSQL's bin directory.
pub fn pg_bin() -> PathBuf {
    let root = Path::new("/usr/lib/postgresql");
    let mut versions: Vec<(u32, PathBuf)> = std::fs::read_dir(root)
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let v: u32 = e.file_name().to_str()?.parse().ok()?;
            let bin = e.path().join("bin");
            bin.join("pg_ctl").is_file().then_some((v, bin))
        })
        .collect();
    versions.sort();
    versions.pop().map(|(_, b)| b).unwrap_or_else(|| {
        panic!(
            "PostgreSQL server binaries not found under /usr/lib/postgresql/<version>/bin: \
             run scripts/setup.sh (it installs Debian's postgresql package)"
        )
    })
}

/// A loopback port nobody listens on right now.
pub fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

impl PgServer {
    /// initdb and start; the database [`DATABASE`] owned by [`USER`] (password [`PASSWORD`]).
    pub fn start() -> PgServer {
        let bin = pg_bin();
        // SAFETY: geteuid has no preconditions.
        let root = unsafe { libc::geteuid() } == 0;
        let base = std::env::temp_dir().join(format!(
            "footscan-pg-{}-{}",
            std::process::id(),
            std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .unwrap()
                .as_nanos()
        ));
        std::fs::create_dir_all(&base).unwrap();
        let run_as = root.then(|| "postgres".to_string());
        if root {
            let ok = Command::new("chown")
                .args(["-R", "postgres:postgres"])
                .arg(&base)
                .status()
                .unwrap()
                .success();
            assert!(ok, "chown {} to postgres failed: is Debian's postgresql package installed (scripts/setup.sh)?", base.display());
        }
        let s = PgServer {
            dir: base,
            port: free_port(),
            bin,
            run_as,
        };
        let pwfile = s.dir.join("admin.pw");
        std::fs::write(&pwfile, format!("{PASSWORD}\n")).unwrap();
        if let Some(u) = &s.run_as {
            let _ = Command::new("chown").arg(u).arg(&pwfile).status();
        }
        s.run(
            "initdb",
            &[
                "-D",
                s.data().to_str().unwrap(),
                "-U",
                ADMIN,
                "--auth=scram-sha-256",
                "--pwfile",
                pwfile.to_str().unwrap(),
                "-E",
                "UTF8",
                "--no-sync",
                "--no-instructions",
            ],
        );
        let conf = format!(
            "\nlisten_addresses = '127.0.0.1'\nunix_socket_directories = '{}'\nfsync = off\nmax_connections = 50\n",
            s.dir.display()
        );
        let mut text = std::fs::read_to_string(s.data().join("postgresql.conf")).unwrap();
        text.push_str(&conf);
        std::fs::write(s.data().join("postgresql.conf"), text).unwrap();
        s.start_server();
        let mut admin = s.client(ADMIN, "postgres");
        admin
            .batch_execute(&format!("CREATE ROLE {USER} LOGIN PASSWORD '{PASSWORD}'"))
            .unwrap();
        admin
            .batch_execute(&format!("CREATE DATABASE {DATABASE} OWNER {USER}"))
            .unwrap();
        s
    }

    /// Turn TLS on: a throwaway certificate authority and a server certificate for
    /// `localhost` and 127.0.0.1 (openssl), `ssl = on`, and [`USER`] allowed over TLS only
    /// (a plain connection of the fleet user is rejected by pg_hba.conf; the admin keeps
    /// plain connections for the test's own setup). Returns the CA's PEM file.
    pub fn enable_tls(&self) -> PathBuf {
        let d = &self.dir;
        let ssl = |args: &[&str]| {
            let out = Command::new("openssl")
                .args(args)
                .current_dir(d)
                .output()
                .expect("openssl (Debian's openssl package)");
            assert!(
                out.status.success(),
                "openssl {args:?}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        };
        ssl(&[
            "req",
            "-x509",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-days",
            "2",
            "-subj",
            "/CN=footscan test CA",
            "-keyout",
            "ca.key",
            "-out",
            "ca.pem",
        ]);
        ssl(&[
            "req",
            "-newkey",
            "rsa:2048",
            "-nodes",
            "-subj",
            "/CN=localhost",
            "-keyout",
            "server.key",
            "-out",
            "server.csr",
        ]);
        std::fs::write(
            d.join("san.ext"),
            "subjectAltName = DNS:localhost, IP:127.0.0.1\n",
        )
        .unwrap();
        ssl(&[
            "x509",
            "-req",
            "-in",
            "server.csr",
            "-CA",
            "ca.pem",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-days",
            "2",
            "-extfile",
            "san.ext",
            "-out",
            "server.pem",
        ]);
        for f in ["server.key", "server.pem"] {
            if let Some(u) = &self.run_as {
                let _ = Command::new("chown").arg(u).arg(d.join(f)).status();
            }
            let _ = Command::new("chmod").arg("600").arg(d.join(f)).status();
        }
        let mut conf = std::fs::read_to_string(self.data().join("postgresql.conf")).unwrap();
        conf.push_str(&format!(
            "\nssl = on\nssl_cert_file = '{}'\nssl_key_file = '{}'\n",
            d.join("server.pem").display(),
            d.join("server.key").display()
        ));
        std::fs::write(self.data().join("postgresql.conf"), conf).unwrap();
        let hba = std::fs::read_to_string(self.data().join("pg_hba.conf")).unwrap();
        let rules = format!(
            "hostssl {DATABASE} {USER} 127.0.0.1/32 scram-sha-256\n\
             hostnossl {DATABASE} {USER} 127.0.0.1/32 reject\n"
        );
        std::fs::write(self.data().join("pg_hba.conf"), rules + &hba).unwrap();
        self.stop("fast");
        self.start_server();
        d.join("ca.pem")
    }

    fn data(&self) -> PathBuf {
        self.dir.join("data")
    }

    fn run(&self, tool: &str, args: &[&str]) {
        let exe = self.bin.join(tool);
        let mut cmd = match &self.run_as {
            Some(u) => {
                let mut c = Command::new("runuser");
                c.args(["-u", u, "--"]).arg(&exe);
                c
            }
            None => Command::new(&exe),
        };
        let out = cmd.args(args).output().unwrap_or_else(|e| {
            panic!(
                "{}: {e} (run scripts/setup.sh to install postgresql)",
                exe.display()
            )
        });
        assert!(
            out.status.success(),
            "{tool} {args:?} failed: {}\n{}\nserver log:\n{}",
            out.status,
            String::from_utf8_lossy(&out.stderr),
            std::fs::read_to_string(self.dir.join("server.log")).unwrap_or_default()
        );
    }

    /// Start the server (again) on the same port.
    pub fn start_server(&self) {
        self.run(
            "pg_ctl",
            &[
                "-D",
                self.data().to_str().unwrap(),
                "-l",
                self.dir.join("server.log").to_str().unwrap(),
                "-o",
                &format!("-p {}", self.port),
                "-w",
                "-t",
                "60",
                "start",
            ],
        );
    }

    /// Stop the server: `fast` (sessions ended, clean) or `immediate` (as if it crashed).
    pub fn stop(&self, mode: &str) {
        self.run(
            "pg_ctl",
            &[
                "-D",
                self.data().to_str().unwrap(),
                "-m",
                mode,
                "-w",
                "-t",
                "60",
                "stop",
            ],
        );
    }

    /// `postgres://footscan@127.0.0.1:PORT/fleet` (the password is separate).
    pub fn url(&self) -> String {
        format!("postgres://{USER}@127.0.0.1:{}/{DATABASE}", self.port)
    }

    /// A connection as `user` to `db` with the test password.
    pub fn client(&self, user: &str, db: &str) -> postgres::Client {
        let mut last = None;
        for _ in 0..50 {
            match postgres::Config::new()
                .host("127.0.0.1")
                .port(self.port)
                .user(user)
                .password(PASSWORD)
                .dbname(db)
                .connect_timeout(Duration::from_secs(5))
                .connect(postgres::NoTls)
            {
                Ok(c) => return c,
                Err(e) => last = Some(e),
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        panic!("cannot connect to the test server: {:?}", last)
    }

    /// The fleet database as its owner.
    pub fn fleet_client(&self) -> postgres::Client {
        self.client(USER, DATABASE)
    }

    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.join("server.log")).unwrap_or_default()
    }
}

impl Drop for PgServer {
    fn drop(&mut self) {
        let pid_file = self.data().join("postmaster.pid");
        if pid_file.is_file() {
            let exe = self.bin.join("pg_ctl");
            let mut cmd = match &self.run_as {
                Some(u) => {
                    let mut c = Command::new("runuser");
                    c.args(["-u", u, "--"]).arg(&exe);
                    c
                }
                None => Command::new(&exe),
            };
            let _ = cmd
                .args([
                    "-D",
                    self.data().to_str().unwrap(),
                    "-m",
                    "immediate",
                    "-w",
                    "stop",
                ])
                .output();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}
