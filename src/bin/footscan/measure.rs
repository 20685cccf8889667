//! `footscan measure --scan DIR [--out OUT]`: the foot measurements of a saved scan
//! (measurements.json and plantar.png, in DIR or else only in OUT), a table on stdout and, for
//! simulated scans, the error against truth.

use anyhow::{Context, Result};
use clap::Parser;
use footscan::measure::{measure_scan_dir, DEFAULT_CELL_MM};
use footscan::scandata::ScanDir;
use std::path::{Path, PathBuf};

#[derive(Parser)]
pub struct Args {
    /// Scan directory holding grid.bin (written by the sink.grid stage).
    #[arg(long)]
    scan: PathBuf,
    /// Where to write, instead of the scan directory (which is then only read): a folder
    /// (created if needed) for measurements.json and plantar.png, or a file name ending in
    /// .json, with the drawing beside it under the same name ending in .png.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Cell of the height map measured (mm).
    #[arg(long, default_value_t = DEFAULT_CELL_MM)]
    cell_mm: f64,
    /// Heights from the scan grid alone, without building the Bezier model.
    #[arg(long)]
    no_model: bool,
}

/// The measurements JSON and the drawing `--out` names.
fn outputs(out: &Path) -> (PathBuf, PathBuf) {
    if out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
    {
        (out.to_path_buf(), out.with_extension("png"))
    } else {
        let dir = ScanDir::new(out);
        (dir.measurements_path(), dir.plantar_path())
    }
}

pub fn run(a: Args) -> Result<()> {
    let files = a.out.as_deref().map(outputs);
    if let Some((json, _)) = &files {
        if let Some(dir) = json.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("creating --out's folder {}", dir.display()))?;
        }
    }
    let o = measure_scan_dir(
        &a.scan,
        files.as_ref().map(|f| f.0.as_path()),
        files.as_ref().map(|f| f.1.as_path()),
        a.cell_mm,
        !a.no_model,
    )
    .with_context(|| format!("measuring the scan in {}", a.scan.display()))?;
    let m = &o.measurements;
    let side = format!("{:?}", m.side).to_lowercase();
    println!("{side} foot (heights: {})", m.heights_from);
    let rows = [
        ("foot length", m.foot_length_mm, "mm"),
        ("ball width", m.ball_width_mm, "mm"),
        ("mid-foot width", m.midfoot_width_mm, "mm"),
        ("heel width", m.heel_width_mm, "mm"),
        ("arch height", m.arch_height_mm, "mm"),
        ("arch index", m.arch_index, ""),
        ("axis angle", m.axis_angle_deg, "deg"),
    ];
    for (name, v, unit) in rows {
        println!("  {name:16} {v:9.3} {unit}");
    }
    let points = [
        ("heel point", m.heel_point),
        ("toe tip", m.toe_tip),
        ("heel centre", m.heel_centre),
        ("MT2 head", m.mt2_head),
        ("MT1 head", m.mt1_head),
        ("MT5 head", m.mt5_head),
        ("waist inner", m.waist_inner),
        ("waist outer", m.waist_outer),
        ("hallux point", m.hallux_point),
    ];
    for (name, p) in points {
        println!("  {name:16} ({:8.2}, {:8.2}) mm", p[0], p[1]);
    }
    for w in &m.warnings {
        println!("warning: {w}");
    }
    if let Some(c) = &o.comparison {
        println!("\nagainst truth.json:\n{}", c.table());
    }
    println!("wrote {} and {}", o.json.display(), o.png.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn out_names_a_folder_or_the_json() {
        assert_eq!(
            outputs(Path::new("o")),
            (
                PathBuf::from("o/measurements.json"),
                PathBuf::from("o/plantar.png")
            )
        );
        assert_eq!(
            outputs(Path::new("a/m.JSON")),
            (PathBuf::from("a/m.JSON"), PathBuf::from("a/m.png"))
        );
    }
}
