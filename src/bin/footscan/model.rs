//! `footscan model --scan DIR`: the Bezier-network plantar model of a saved scan, written as
//! closed meshes (STL, and PLY / OBJ on request) with a summary on stdout.

use anyhow::{Context, Result};
use clap::Parser;
use footscan::scan::ScanGrid;
use footscan::surface::{model_scan, MeshFiles};
use std::path::PathBuf;

#[derive(Parser)]
pub struct Args {
    /// Scan directory holding grid.bin (written by the sink.grid stage).
    #[arg(long)]
    scan: PathBuf,
    /// Directory for the mesh files (default: the scan directory).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Mesh formats to write.
    #[arg(long, value_delimiter = ',', default_value = "stl,ply,obj")]
    formats: Vec<Format>,
    /// Cell of the (x, y) grid the mesh is sampled on (mm).
    #[arg(long, default_value_t = 0.5)]
    cell_mm: f64,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Format {
    Stl,
    Ply,
    Obj,
}

pub fn run(a: Args) -> Result<()> {
    let grid_path = a.scan.join("grid.bin");
    let grid = ScanGrid::load(&grid_path)
        .with_context(|| format!("loading the scan grid {}", grid_path.display()))?;
    let out = a.out.unwrap_or_else(|| a.scan.clone());
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let want = |f: Format, name: &str| a.formats.contains(&f).then(|| out.join(name));
    let files = MeshFiles {
        stl: want(Format::Stl, "model.stl"),
        ply: want(Format::Ply, "model.ply"),
        obj: want(Format::Obj, "model.obj"),
        cell_mm: a.cell_mm,
    };
    let (_, summary) = model_scan(&grid, &files)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", summary.text());
    }
    Ok(())
}
