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
    /// Plantar surface models (seed 002 Table 1): the Bezier network against least squares,
    /// B-spline approximation, NURBS and C2 B-spline interpolation on one scan, printed beside
    /// the paper's figures.
    Surface {
        #[arg(long, default_value = "config/sim.toml")]
        config: PathBuf,
        /// A saved scan directory (its grid.bin); default: run a simulated scan (~15 s).
        #[arg(long)]
        scan: Option<PathBuf>,
        /// One JSON array of objects instead of the table.
        #[arg(long)]
        json: bool,
    },
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
        What::Surface { config, scan, json } => {
            let cfg = footscan::scan::LoadedConfig::load(&config)?;
            let grid = footscan::bench::surface::scan_or_load(&cfg, scan.as_deref())
                .map_err(|e| anyhow::anyhow!(e))?;
            let b = footscan::bench::surface::run(&cfg.config, &grid)
                .map_err(|e| anyhow::anyhow!(e))?;
            if json {
                println!("{}", serde_json::to_string_pretty(&b.rows)?);
            } else {
                println!("{}", footscan::bench::surface::table(&b));
            }
            Ok(())
        }
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
