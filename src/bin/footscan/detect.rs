//! `footscan detect`: a detector over recorded frames (PNG Gray8/Gray16 files or directories of
//! them), one CSV line per image row: `frame,row,col,intensity,width,quality`.

use anyhow::{Context, Result};
use clap::Parser;
use footscan::detect::{self, files, DetectParams, LinePeak};
use std::io::Write;
use std::path::PathBuf;

#[derive(Parser)]
pub struct Args {
    /// PNG files and/or directories of PNG files (each directory in name order); the frame
    /// index is the position in the resulting list.
    #[arg(long, num_args = 1.., required = true)]
    input: Vec<PathBuf>,
    /// bezier, bezier-plus, cog, parabolic, gaussian, blais-rioux or steger.
    #[arg(long, default_value = "bezier-plus")]
    detector: String,
    /// Minimum line peak, DN of an 8-bit image (scaled x257 for 16-bit images).
    #[arg(long)]
    threshold: Option<f32>,
    /// Window n (bezier: n + 1 pixels, default 6; bezier-plus: fixed even n, default auto).
    #[arg(long)]
    window: Option<usize>,
    /// Output CSV.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(a: Args) -> Result<()> {
    let params = DetectParams {
        threshold: a.threshold,
        window: a.window,
        ..Default::default()
    };
    let mut det = detect::build(&a.detector, &params).map_err(anyhow::Error::msg)?;
    let inputs = files::collect_inputs(&a.input).map_err(anyhow::Error::msg)?;
    let file =
        std::fs::File::create(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut w = std::io::BufWriter::new(file);
    writeln!(w, "{}", files::CSV_HEADER)?;
    let mut peaks: Vec<LinePeak> = Vec::new();
    let (mut rows, mut lines) = (0usize, 0usize);
    for (k, path) in inputs.iter().enumerate() {
        let frame = files::load_png(path, k as u64).map_err(anyhow::Error::msg)?;
        peaks.clear();
        peaks.resize(frame.height as usize, LinePeak::NONE);
        det.detect(&frame, &mut peaks);
        files::write_csv_rows(&mut w, k, &peaks)?;
        rows += peaks.len();
        lines += peaks.iter().filter(|p| p.is_valid()).count();
    }
    w.flush()?;
    println!(
        "{} frames, {rows} rows, a line in {lines}: wrote {}",
        inputs.len(),
        a.out.display()
    );
    Ok(())
}
