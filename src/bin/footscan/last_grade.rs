//! `footscan last grade`: one last graded into a size run (docs/method.md 9.4); the library
//! (`footscan_last::grade`) does the work, this file reads the inputs, prints the table and
//! writes the run all or nothing.

use anyhow::{anyhow, Result};
use clap::Parser;
use footscan_geom::mesh::{TriMesh, Units};
use footscan_last::grade::{
    grade, parse_sizes, parse_widths, write_graded_atomic, GradeSpec, Mode, System,
};
use footscan_last::size::check_last_size;
use std::path::PathBuf;

#[derive(Parser)]
pub struct GradeArgs {
    /// The last to grade: a closed mesh (STL, OBJ or PLY), z up.
    #[arg(long)]
    last: PathBuf,
    /// Units of the last file: mm, m, or auto (decided from the size).
    #[arg(long, default_value = "auto")]
    units: Units,
    /// Scale the last so its longest side is this many mm (for unitless meshes).
    #[arg(long)]
    length: Option<f64>,
    /// The size the last is (one of --sizes).
    #[arg(long)]
    from: f64,
    /// The run: a range (38-46; Mondopoint 240-280 in 5 mm steps) or a list (38,39.5,41).
    #[arg(long)]
    sizes: String,
    /// Sizing system: paris, uk, us or mondopoint.
    #[arg(long)]
    system: System,
    /// Width fittings to make of every size: letters A-H (UK, US) or fitting offsets
    /// (-1,0,1), each one girth step from the last as given, no length change.
    #[arg(long)]
    widths: Option<String>,
    /// The last's own fitting when --widths are letters (default F for UK, D for US).
    #[arg(long)]
    from_width: Option<String>,
    /// arithmetic (length and girth steps as fixed increments) or geometric (proportional).
    #[arg(long, default_value = "arithmetic")]
    mode: Mode,
    /// Output directory (replaced as a whole once everything is written).
    #[arg(long)]
    out: PathBuf,
}

pub fn run(a: GradeArgs) -> Result<()> {
    let sizes = parse_sizes(&a.sizes, a.system)?;
    let from_width = a.from_width.clone().unwrap_or_else(|| {
        match a.system {
            System::Us => "D",
            _ => "F",
        }
        .to_string()
    });
    let widths = match &a.widths {
        Some(w) => parse_widths(w, &from_width)?,
        None => Vec::new(),
    };
    let (m, _) = TriMesh::load_solid(&a.last, a.units, a.length)
        .map_err(|e| anyhow!("{}: {e}", a.last.display(), e = footscan_util::Chain(&e)))?;
    check_last_size(&a.last, &m)?;
    let spec = GradeSpec {
        system: a.system,
        mode: a.mode,
        from: a.from,
        sizes,
        widths,
    };
    let t0 = std::time::Instant::now();
    let g = grade(m, &a.last.display().to_string(), &spec)?;
    let ms = t0.elapsed().as_secs_f64() * 1e3;
    print!("{}", g.table());
    let files = write_graded_atomic(&g, &a.out)?;
    println!(
        "graded {} lasts in {ms:.0} ms; wrote {} files to {}",
        g.lasts.len(),
        files.len(),
        a.out.display()
    );
    Ok(())
}
