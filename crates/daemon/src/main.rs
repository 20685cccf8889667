//! footscand: the daemon beside the scanner (docs/API.md). Binds 127.0.0.1 unless told
//! otherwise; a non-loopback address needs a token. SIGTERM or Ctrl-C: stop accepting,
//! cancel the running scan (archived as cancelled, "daemon shutting down"), exit 0.

use anyhow::{Context, Result};
use clap::Parser;
use footscan_daemon::daemon::{Daemon, DaemonConfig};
use std::io::Write;
use std::path::PathBuf;

#[derive(Parser)]
#[command(
    version,
    about = "footscan daemon: HTTP API, live preview and scan archive"
)]
struct Args {
    /// Daemon config: a path, or a relative name looked up in the working directory (NAME,
    /// config/NAME), $FOOTSCAN_CONFIG_DIR, $XDG_CONFIG_HOME/footscan (~/.config/footscan),
    /// /etc/footscan, ../share/footscan beside the executable, and the config/ of the checkout
    /// it was built in; first found wins (see config/footscand.toml).
    #[arg(long, default_value = "footscand.toml")]
    config: PathBuf,
    /// Address to listen on (IP:PORT; port 0 picks a free one), overriding [daemon] bind.
    #[arg(long)]
    bind: Option<String>,
    /// Without a command, run the daemon.
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(clap::Subcommand)]
enum Command {
    /// Work on a scan archive without the daemon.
    Archive {
        #[command(subcommand)]
        what: ArchiveCommand,
    },
}

#[derive(clap::Subcommand)]
enum ArchiveCommand {
    /// Where the archive's disk goes: by kind of file, by year, and outside the scans.
    /// Read-only; runs beside a running daemon.
    Du {
        /// The archive directory (default: `archive` of [daemon] in --config).
        archive: Option<PathBuf>,
        /// Print JSON instead of a table.
        #[arg(long)]
        json: bool,
    },
    /// Put every scan into compact form in place (docs/method.md 14h.2): grid.bin and the
    /// large files compressed or rebuilt on request, every file the API serves still served
    /// byte for byte. Scan by scan and resumable: killed at any point and run again, it loses
    /// nothing. Takes the archive lock, so it refuses to run beside the daemon.
    Compact {
        /// The archive directory (default: `archive` of [daemon] in --config).
        archive: Option<PathBuf>,
        /// Say what would be saved, change nothing.
        #[arg(long)]
        dry_run: bool,
    },
}

/// Cap glibc's malloc arenas. Without a cap, every thread that ever allocated (the scan's
/// pipeline threads, the runtime's blocking pool serving previews and downloads) keeps an
/// arena of its own, and the frame-sized buffers freed into them stay resident: resident
/// memory grew by tens of MB per long scan. Two arenas (and a trim after each scan) keep it
/// flat (the soak bench `cargo bench -p footscand --bench soak` measures it).
///
/// Also fix the mmap threshold: glibc raises it to the size of every mapped block freed (up
/// to 32 MB), so after the first scan frees its large buffers, the next scans' frame-sized
/// and map-sized blocks (1-32 MB) come from the arenas, where they fragment and stay
/// resident, raising each scan's peak and what is left after it. A fixed threshold keeps
/// them mapped and returned whole when freed (3 scans at 0.25 mm, debug build: peak 217-227
/// MB and 20-36 MB after with the moving threshold, 205-222 MB and 20 MB with this one).
fn limit_malloc_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only tunes the allocator; called before any other thread exists.
    unsafe {
        if std::env::var_os("MALLOC_ARENA_MAX").is_none() {
            libc::mallopt(libc::M_ARENA_MAX, 2);
        }
        if std::env::var_os("MALLOC_MMAP_THRESHOLD_").is_none() {
            libc::mallopt(libc::M_MMAP_THRESHOLD, 256 * 1024);
        }
    }
}

/// Run the HTTP side (the runtime's workers and its blocking pool: previews, downloads,
/// archive queries) at a lower CPU priority than the scan pipeline's threads: when clients
/// saturate the CPU, web answers slow down instead of the scanner dropping frames (nice +10
/// relative to the daemon). Linux nice values are per thread, and lowering one's own priority
/// needs no privilege. A new thread inherits its creator's value, so jobs are started from a
/// thread made before the runtime (`daemon::jobs::Launcher`), not from these.
fn lower_priority() {
    if let Err(e) = footscan_util::priority::lower_this_thread(10) {
        // Once: every runtime thread would say the same.
        static SAID: std::sync::Once = std::sync::Once::new();
        SAID.call_once(|| {
            tracing::warn!(
                "cannot lower the HTTP threads' priority ({e}): web clients compete with the \
                 scan for the CPU (a seccomp filter without setpriority?)"
            )
        });
    }
}

fn main() {
    limit_malloc_arenas();
    let args = Args::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(footscan::startup::log_colour())
        .init();
    if let Err(e) = run(args) {
        eprintln!("footscand: {e:#}");
        std::process::exit(1);
    }
}

/// The archive directory given, else the config's.
fn archive_root(args: &Args, archive: Option<&PathBuf>) -> Result<PathBuf> {
    let root = match archive {
        Some(a) => a.clone(),
        None => {
            let path = footscan::startup::find_config(&args.config)?;
            DaemonConfig::load(&path, None)?.archive
        }
    };
    if !root.is_dir() {
        anyhow::bail!(
            "archive {}: not a directory; give the archive directory (`archive` of [daemon] in \
             footscand.toml)",
            root.display()
        );
    }
    Ok(root)
}

/// `footscand archive du`: the archive's usage, as a table or JSON.
fn archive_du(args: &Args, archive: Option<&PathBuf>, json: bool) -> Result<()> {
    let root = archive_root(args, archive)?;
    let u = footscan_daemon::archive::usage::usage(&root)?;
    if json {
        println!("{}", serde_json::to_string_pretty(&u)?);
    } else {
        print!("{}", u.table(&root));
    }
    Ok(())
}

/// `footscand archive compact`: every scan into compact form, one line a scan.
fn archive_compact(args: &Args, archive: Option<&PathBuf>, dry_run: bool) -> Result<()> {
    use footscan::compact::CompactOptions;
    let root = archive_root(args, archive)?;
    let opts = CompactOptions {
        dry_run,
        ..Default::default()
    };
    // The kill test's hook (crates/daemon/tests/daemon_compact.rs): abort in that scan.
    let abort_at = std::env::var("FOOTSCAND_TEST_ABORT_AT_SCAN")
        .ok()
        .and_then(|v| v.parse().ok());
    let run = footscan_daemon::archive::compact::compact_archive(
        &root,
        &opts,
        abort_at,
        |id, r| match r {
            Ok(rep) if rep.changed || dry_run => println!(
                "{id}: {:.1} MB -> {:.1} MB in {:.2} s",
                rep.bytes_before as f64 / 1e6,
                rep.bytes_after as f64 / 1e6,
                rep.seconds
            ),
            Ok(_) => {}
            Err(e) => eprintln!("{id}: not compacted: {e}"),
        },
    )
    .map_err(|e| match e {
        footscan_daemon::archive::ArchiveError::Locked { .. } => anyhow::anyhow!(
            "{e}: stop the daemon (systemctl stop footscand) before compacting; new scans are \
             compacted by the daemon itself when [archive] compact is on"
        ),
        e => e.into(),
    })?;
    println!(
        "{} scans, {} {}compacted, {} failed; {:.1} MB -> {:.1} MB in {:.1} s",
        run.scans,
        run.changed,
        if dry_run { "would be " } else { "" },
        run.failed.len(),
        run.bytes_before as f64 / 1e6,
        run.bytes_after as f64 / 1e6,
        run.seconds
    );
    if !run.failed.is_empty() {
        anyhow::bail!(
            "{} scans could not be compacted (listed above)",
            run.failed.len()
        );
    }
    Ok(())
}

fn run(args: Args) -> Result<()> {
    match &args.command {
        Some(Command::Archive {
            what: ArchiveCommand::Du { archive, json },
        }) => return archive_du(&args, archive.as_ref(), *json),
        Some(Command::Archive {
            what: ArchiveCommand::Compact { archive, dry_run },
        }) => return archive_compact(&args, archive.as_ref(), *dry_run),
        None => {}
    }
    let path = footscan::startup::find_config(&args.config)?;
    tracing::info!("config {}", path.display());
    let config = DaemonConfig::load(&path, args.bind.as_deref())?;
    let bind = config.bind;
    let tls = config
        .tls
        .as_ref()
        .map(|t| {
            footscan_daemon::api::tls::load(t, &config.archive, bind, &config.allowed_hosts)
                .context("setting up HTTPS ([daemon] tls)")
        })
        .transpose()?;
    if let Some(t) = &tls {
        tracing::info!(
            "HTTPS with {} certificate {}, SHA-256 fingerprint {}",
            if t.info.self_signed {
                "the self-signed"
            } else {
                "the"
            },
            t.info.certificate.display(),
            t.info.fingerprint_sha256
        );
    }
    let scheme = if tls.is_some() { "https" } else { "http" };
    let daemon = Daemon::open(config)?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .on_thread_start(lower_priority)
        .build()
        .context("starting the async runtime")?;
    rt.block_on(async move {
        let listener = footscan_daemon::api::server::listen(bind)
            .with_context(|| format!("cannot listen on {bind}"))?;
        let addr = listener.local_addr()?;
        tracing::info!(
            "archive {}, scanner config {}, auth {}",
            daemon.config.archive.display(),
            daemon.config.scanner_config.display(),
            if daemon.config.token.is_some() {
                "bearer token"
            } else {
                "none (loopback)"
            }
        );
        // Tests and scripts read the address (with the port chosen for :0) from this line.
        println!("footscand listening on {scheme}://{addr}");
        std::io::stdout().flush()?;
        footscan_daemon::api::serve_tls(daemon, listener, shutdown_signal(), tls).await?;
        Ok(())
    })
}

async fn shutdown_signal() {
    use tokio::signal::unix::{signal, SignalKind};
    let mut term = match signal(SignalKind::terminate()) {
        Ok(s) => s,
        Err(e) => {
            tracing::error!("cannot watch SIGTERM: {e}");
            let _ = tokio::signal::ctrl_c().await;
            return;
        }
    };
    tokio::select! {
        _ = term.recv() => tracing::info!("SIGTERM"),
        _ = tokio::signal::ctrl_c() => tracing::info!("interrupt"),
    }
}
