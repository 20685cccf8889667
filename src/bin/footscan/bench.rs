//! `footscan bench ...`: speed and accuracy measurements, printed as a table or JSON.

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

#[derive(Parser)]
pub struct Args {
    #[command(subcommand)]
    what: What,
}

#[derive(Subcommand)]
enum What {
    /// Simulator renderer: frames/s on one core for the configured scanner.
    Render {
        #[arg(long, default_value = "config/sim.toml")]
        config: PathBuf,
        /// Frames to render.
        #[arg(long, default_value_t = 400)]
        frames: u64,
        #[arg(long)]
        json: bool,
    },
}

pub fn run(args: Args) -> Result<()> {
    match args.what {
        What::Render {
            config,
            frames,
            json,
        } => {
            let cfg = footscan::scan::LoadedConfig::load(&config)?;
            let rows = footscan::bench::render::run(&cfg.config, frames)
                .map_err(|e| anyhow::anyhow!(e))?;
            if json {
                println!("{}", serde_json::to_string_pretty(&rows)?);
            } else {
                println!("{}", footscan::bench::render::table(&rows));
            }
            Ok(())
        }
    }
}
