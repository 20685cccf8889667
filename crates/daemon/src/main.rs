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
    /// Daemon config (see config/footscand.toml).
    #[arg(long, default_value = "config/footscand.toml")]
    config: PathBuf,
    /// Address to listen on (IP:PORT; port 0 picks a free one), overriding [daemon] bind.
    #[arg(long)]
    bind: Option<String>,
}

fn main() {
    let args = Args::parse();
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    if let Err(e) = run(args) {
        eprintln!("footscand: {e:#}");
        std::process::exit(1);
    }
}

fn run(args: Args) -> Result<()> {
    let config = DaemonConfig::load(&args.config, args.bind.as_deref())?;
    let bind = config.bind;
    let daemon = Daemon::open(config)?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    rt.block_on(async move {
        let listener = tokio::net::TcpListener::bind(bind)
            .await
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
        println!("footscand listening on http://{addr}");
        std::io::stdout().flush()?;
        footscan_daemon::api::serve(daemon, listener, shutdown_signal()).await?;
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
