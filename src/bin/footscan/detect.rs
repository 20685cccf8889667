//! `footscan detect`: a detector over recorded frames (PNG or JPEG files, grey or colour, or
//! directories of them), one CSV line per image row: `frame,row,col,intensity,width,quality`.

use anyhow::{Context, Result};
use clap::Parser;
use footscan::detect::{self, files, Channel, DetectParams, LinePeak, ThresholdParam};
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
    /// Minimum line peak: "auto" (default: relative to each row's background level and noise)
    /// or DN of an 8-bit image (scaled x257 for 16-bit images).
    #[arg(long)]
    threshold: Option<ThresholdParam>,
    /// The channel of colour frames: luma, red, green, blue, red-minus-others (R - (G+B)/2) or
    /// green-minus-others. Required for colour frames.
    #[arg(long, value_parser = |s: &str| Channel::parse(s).map_err(|e| e.to_string()))]
    channel: Option<Channel>,
    /// A frame taken with the laser off, subtracted from every frame (same size and format).
    #[arg(long)]
    background: Option<PathBuf>,
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
        channel: a.channel,
        window: a.window,
        ..Default::default()
    };
    let (mut det, mut prep) =
        detect::build_with_prep(&a.detector, &params).map_err(anyhow::Error::msg)?;
    if let Some(b) = &a.background {
        let off = files::load_image(b, 0).map_err(anyhow::Error::msg)?;
        prep.set_background(&off, &b.display().to_string())
            .map_err(anyhow::Error::msg)?;
    }
    let inputs = files::collect_inputs(&a.input).map_err(anyhow::Error::msg)?;
    let file =
        std::fs::File::create(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut w = std::io::BufWriter::new(file);
    writeln!(w, "{}", files::CSV_HEADER)?;
    let mut peaks: Vec<LinePeak> = Vec::new();
    let (mut rows, mut lines) = (0usize, 0usize);
    for (k, path) in inputs.iter().enumerate() {
        let img = files::load_image(path, k as u64).map_err(anyhow::Error::msg)?;
        let frame = prep
            .prepare(&img, &path.display().to_string())
            .map_err(anyhow::Error::msg)?;
        peaks.clear();
        peaks.resize(frame.height as usize, LinePeak::NONE);
        det.detect(frame, &mut peaks);
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
