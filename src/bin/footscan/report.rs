//! `footscan report`: the printable one-page PDF of a measured scan (src/report.rs): the foot
//! at 1:1 with a 100 mm calibration bar, the measurements with their definitions, shoe sizes.

use anyhow::Result;
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Scan directory (with measurements.json; scan.json and record.json used when present).
    #[arg(long)]
    scan: PathBuf,
    /// The PDF to write (default: report.pdf in the scan directory).
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let out = a.out.unwrap_or_else(|| a.scan.join("report.pdf"));
    let l = footscan::report::write_report(&a.scan, &out)?;
    println!(
        "{}: {:.0} x {:.0} mm page, foot at 1:1 (heel to toe {:.1} mm on paper), calibration bar {:.0} mm",
        out.display(),
        l.page_mm[0],
        l.page_mm[1],
        l.toe[1] - l.heel[1],
        l.ruler[2]
    );
    Ok(())
}
