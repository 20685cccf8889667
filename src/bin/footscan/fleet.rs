//! `footscan fleet migrate|list|show|fetch`: the central view of the fleet database that the
//! footscand daemons push their scans to (crates/fleet). The connection comes from the
//! `[fleet]` section of a footscand config (`--config`) or from `--url`; the password from
//! FOOTSCAN_FLEET_PASSWORD, the section's password_file, or the URL.

use anyhow::{bail, Result};
use clap::{Parser, Subcommand};
use footscan_fleet::settings::PASSWORD_ENV;
use footscan_fleet::{Filter, Settings, Tls};
use std::path::PathBuf;

#[derive(Parser)]
pub struct Args {
    /// A footscand config whose [fleet] section says where the database is.
    #[arg(long, global = true, conflicts_with = "url")]
    config: Option<PathBuf>,
    /// The database: postgres://USER@HOST:PORT/DATABASE (password from FOOTSCAN_FLEET_PASSWORD).
    #[arg(long, global = true)]
    url: Option<String>,
    /// With --url: disable, require (encrypted, certificate not checked) or verify-full.
    #[arg(long, global = true, default_value = "disable")]
    tls: Tls,
    #[command(subcommand)]
    what: What,
}

#[derive(Subcommand)]
enum What {
    /// Bring the database's schema to this program's version (the daemons also do it when
    /// they connect) and print the migration history.
    Migrate,
    /// Scans in the database, oldest first, narrowed by the filters.
    List {
        #[arg(long)]
        clinic: Option<String>,
        #[arg(long)]
        scanner: Option<String>,
        #[arg(long)]
        subject: Option<String>,
        /// complete, complete with warnings, side mismatch, rescan, failed or cancelled.
        #[arg(long)]
        status: Option<String>,
        /// Started on or after this date (YYYY-MM-DD) or time (RFC 3339).
        #[arg(long)]
        since: Option<String>,
        /// Started before this date or time.
        #[arg(long)]
        until: Option<String>,
        #[arg(long)]
        limit: Option<i64>,
        /// One JSON array instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// One scan: its record, measurements and files with their sha256.
    Show {
        scan_id: String,
        /// The scanner, when several scanners have a scan of this id.
        #[arg(long)]
        scanner: Option<String>,
        #[arg(long)]
        json: bool,
    },
    /// Write a scan's files into a new directory (each checked against its sha256), which
    /// `footscan last adjust --scan DIR` and `footscan measure` read like a local scan.
    Fetch {
        scan_id: String,
        #[arg(long)]
        scanner: Option<String>,
        /// Directory to create (it must not exist).
        #[arg(long)]
        out: PathBuf,
    },
}

fn settings(a: &Args) -> Result<Settings> {
    let pw = std::env::var(PASSWORD_ENV).ok();
    Ok(match (&a.config, &a.url) {
        (Some(c), _) => Settings::from_file(c, pw)?,
        (None, Some(u)) => Settings::from_url(u, a.tls, pw)?,
        (None, None) => bail!(
            "no database: give --config FOOTSCAND_TOML (its [fleet] section) or --url postgres://USER@HOST:PORT/DATABASE"
        ),
    })
}

pub fn run(a: Args) -> Result<()> {
    let s = settings(&a)?;
    let mut c = footscan_fleet::connect(&s)?;
    match a.what {
        What::Migrate => {
            let st = footscan_fleet::migrate(&mut c, None)?;
            match (st.applied.is_empty(), st.newer_compatible) {
                (_, true) => println!(
                    "{}: schema version {} (newer than this footscan's {}, compatible with it)",
                    s.target(),
                    st.version,
                    footscan_fleet::SCHEMA_VERSION
                ),
                (true, _) => println!("{}: schema version {}, up to date", s.target(), st.version),
                (false, _) => println!(
                    "{}: applied {:?}, now at schema version {}",
                    s.target(),
                    st.applied,
                    st.version
                ),
            }
            for (v, name, from, sw, at) in footscan_fleet::migrate::history(&mut c)? {
                println!("  {v:3}  {at}  footscan {sw:8}  compatible from {from}: {name}");
            }
        }
        What::List {
            clinic,
            scanner,
            subject,
            status,
            since,
            until,
            limit,
            json,
        } => {
            let rows = footscan_fleet::list(
                &mut c,
                &Filter {
                    clinic,
                    scanner,
                    subject,
                    status,
                    since,
                    until,
                    limit,
                },
            )?;
            if json {
                println!("{}", serde_json::to_string_pretty(&rows)?);
            } else {
                println!(
                    "{:<21} {:<16} {:<16} {:<16} {:<5} {:<22} {:>5} {:>12}",
                    "scan", "scanner", "clinic", "subject", "side", "status", "files", "bytes"
                );
                for r in &rows {
                    println!(
                        "{:<21} {:<16} {:<16} {:<16} {:<5} {:<22} {:>5} {:>12}",
                        r.scan_id,
                        r.scanner,
                        r.clinic,
                        r.subject,
                        r.side,
                        r.status,
                        r.files,
                        r.bytes
                    );
                }
                println!("{} scans", rows.len());
            }
        }
        What::Show {
            scan_id,
            scanner,
            json,
        } => {
            let d = footscan_fleet::show(&mut c, scanner.as_deref(), &scan_id)?;
            if json {
                println!("{}", serde_json::to_string_pretty(&d)?);
            } else {
                let r = &d.row;
                println!(
                    "scan {} of scanner {} (clinic {})",
                    r.scan_id, r.scanner, r.clinic
                );
                println!("  subject {}, {} foot, {}", r.subject, r.side, r.status);
                if let Some(why) = &r.reason {
                    println!("  reason: {why}");
                }
                println!(
                    "  started {}, finished {}, received {}",
                    r.started,
                    r.finished.as_deref().unwrap_or("-"),
                    r.received
                );
                println!("  {} frames, {} points", r.frames, r.points);
                if let Some(m) = &d.measurements {
                    for k in [
                        "foot_length_mm",
                        "ball_width_mm",
                        "heel_width_mm",
                        "arch_height_mm",
                    ] {
                        if let Some(v) = m.get(k).and_then(|v| v.as_f64()) {
                            println!("  {k} {v:.1}");
                        }
                    }
                }
                for f in &d.files_list {
                    println!("  {:<24} {:>12}  sha256 {}", f.name, f.bytes, f.sha256);
                }
            }
        }
        What::Fetch {
            scan_id,
            scanner,
            out,
        } => {
            for p in footscan_fleet::fetch(&mut c, scanner.as_deref(), &scan_id, &out)? {
                println!("wrote {}", p.display());
            }
        }
    }
    Ok(())
}
