//! `footscan report`: the printable PDF of a measured scan (crates/scanner/src/report.rs): the foot at 1:1
//! with a 100 mm calibration bar, the measurements with their definitions, shoe sizes; or,
//! with `--left` and `--right`, both feet side by side with a left/right comparison.

use anyhow::{bail, Context, Result};
use footscan::report::{render_visit, write_report, ReportInput};
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Scan directory (with measurements.json; scan.json and record.json used when present).
    #[arg(long, conflicts_with_all = ["left", "right"])]
    scan: Option<PathBuf>,
    /// Both feet: the left foot's scan directory (with --right).
    #[arg(long, requires = "right")]
    left: Option<PathBuf>,
    /// Both feet: the right foot's scan directory (with --left).
    #[arg(long, requires = "left")]
    right: Option<PathBuf>,
    /// The PDF to write (default: report.pdf in the scan directory; required for two feet).
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    if let (Some(l), Some(r)) = (&a.left, &a.right) {
        let Some(out) = a.out else {
            bail!("--out: where to write the two feet's report");
        };
        let (li, ri) = (
            ReportInput::from_scan_dir(l)?,
            ReportInput::from_scan_dir(r)?,
        );
        let subject = li.record["subject"]
            .as_str()
            .unwrap_or(&li.title)
            .to_string();
        let bytes = render_visit(&subject, &li, &ri)?;
        footscan::io::write_atomic(&out, &bytes)
            .with_context(|| format!("writing {}", out.display()))?;
        println!(
            "{}: A3 landscape, both feet at 1:1, calibration bar 100 mm",
            out.display()
        );
        return Ok(());
    }
    let Some(scan) = a.scan else {
        bail!("give --scan DIR, or --left DIR --right DIR");
    };
    let out = a.out.unwrap_or_else(|| scan.join("report.pdf"));
    let l = write_report(&scan, &out)?;
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
