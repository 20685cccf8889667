//! `footscan insole --scan DIR [--shoe-bottom ADJ_DIR | --margin-mm 3] [--params P.toml]
//! --out DIR`: an orthotic
//! insole from a saved plantar scan (crates/insole): insole.stl, insole.3mf, insole.step,
//! thickness.png, top.png, side.png and insole.json, each parameter measured back on the mesh.

use anyhow::{bail, Context, Result};
use clap::Parser;
use footscan_insole::{write_insole_in, Params, Plantar, ShoeBottom};
use std::path::PathBuf;

#[derive(Parser)]
pub struct Args {
    /// Scan directory holding grid.bin (a plantar scan of the foot).
    #[arg(long)]
    scan: PathBuf,
    /// The clinician's parameters (TOML; docs/method.md "Orthotic insole" lists them, their
    /// meanings, defaults and ranges). Missing keys keep their defaults.
    #[arg(long)]
    params: Option<PathBuf>,
    /// The shoe's inside bottom: the output directory of `footscan last adjust` for this
    /// scan (its last_adjusted.stl); the insole's outline is the last's bottom outline.
    #[arg(long, conflicts_with = "margin_mm")]
    shoe_bottom: Option<PathBuf>,
    /// Outline margin beyond the footprint (mm, 0 to 15); overrides the parameter file's.
    #[arg(long, allow_negative_numbers = true)]
    margin_mm: Option<f64>,
    /// Output directory (replaced whole, or left as it was on an error).
    #[arg(long)]
    out: PathBuf,
    /// Print insole.json instead of the summary.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<()> {
    let mut params = match &a.params {
        Some(p) => Params::load(p)?,
        None => Params::default(),
    };
    if let Some(m) = a.margin_mm {
        params.margin_mm = m;
    }
    // Refuse bad parameters before the scan is read (the foot's own limits come after).
    params
        .validate()
        .with_context(|| "the insole's parameters (nothing written)".to_string())?;
    let shoe = match &a.shoe_bottom {
        Some(d) => Some(ShoeBottom::from_adjust_dir(d).context("nothing written")?),
        None => None,
    };
    let plantar = Plantar::from_scan_dir(&a.scan)?;
    let w = write_insole_in(&plantar, &params, shoe.as_ref(), &a.out).context("nothing written")?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&w.report)?);
    } else {
        print!("{}", w.report.text());
    }
    if !w.report.measured.ok {
        bail!(
            "the insole in {} does not meet what was asked within the bounds (see the OUT rows \
             and warnings above; the files are written for inspection)",
            a.out.display()
        );
    }
    Ok(())
}
