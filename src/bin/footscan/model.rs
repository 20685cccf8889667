//! `footscan model --scan DIR`: the foot model for CAD of a saved scan (`footscan::cad`): the
//! Bezier network, the foot measured for its frame and outline, the closed solid written as
//! STL, PLY, OBJ, a faceted STEP solid and glTF binary (.glb, with the landmarks and the
//! length and ball-width lines), with a summary on stdout.

use anyhow::{Context, Result};
use clap::Parser;
use footscan::cad::{check_cell, model_scan, ModelFiles, DEFAULT_STEP_CELL_MM};
use footscan::scandata::ScanDir;
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
    #[arg(long, value_delimiter = ',', default_value = "stl,ply,obj,step")]
    formats: Vec<Format>,
    /// Cell of the grid the mesh is sampled on, in the foot frame (mm): from 0.1 to a
    /// quarter of the foot's ball width.
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    cell_mm: f64,
    /// Cell of the .glb solid (mm), same range; default: --cell-mm (every triangle of the STL).
    #[arg(long, allow_negative_numbers = true)]
    glb_cell_mm: Option<f64>,
    /// Cell of the STEP (and IGES) solid (mm), same range.
    #[arg(long, default_value_t = DEFAULT_STEP_CELL_MM, allow_negative_numbers = true)]
    step_cell_mm: f64,
    /// Print the summary as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum Format {
    Stl,
    Ply,
    Obj,
    Step,
    Iges,
    Glb,
}

pub fn run(a: Args) -> Result<()> {
    // Refuse a hopeless cell before reading the grid; the foot's width is checked after.
    check_cell("--cell-mm", a.cell_mm, None)?;
    if a.formats.contains(&Format::Step) || a.formats.contains(&Format::Iges) {
        check_cell("--step-cell-mm", a.step_cell_mm, None)?;
    }
    let glb_cell_mm = a.glb_cell_mm.unwrap_or(a.cell_mm);
    if a.formats.contains(&Format::Glb) {
        check_cell("--glb-cell-mm", glb_cell_mm, None)?;
    }
    let scan = ScanDir::new(&a.scan);
    let grid_path = scan.grid_path();
    let grid = scan
        .load_grid()
        .with_context(|| format!("loading the scan grid {}", grid_path.display()))?;
    let out = a.out.unwrap_or_else(|| a.scan.clone());
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    let want = |f: Format, name: &str| a.formats.contains(&f).then(|| out.join(name));
    let files = ModelFiles {
        stl: want(Format::Stl, ScanDir::MODEL_STL),
        ply: want(Format::Ply, ScanDir::MODEL_PLY),
        obj: want(Format::Obj, ScanDir::MODEL_OBJ),
        step: want(Format::Step, ScanDir::MODEL_STEP),
        iges: want(Format::Iges, ScanDir::MODEL_IGES),
        glb: want(Format::Glb, ScanDir::MODEL_GLB),
        cell_mm: a.cell_mm,
        step_cell_mm: a.step_cell_mm,
        glb_cell_mm,
    };
    let (_, summary) = model_scan(
        &grid,
        &files,
        ["--cell-mm", "--step-cell-mm", "--glb-cell-mm"],
    )
    .with_context(|| format!("modelling the scan in {}", a.scan.display()))?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", summary.text());
    }
    Ok(())
}
