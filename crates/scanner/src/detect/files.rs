//! Recorded frames for `footscan detect`: PNG (or JPEG) files, grey or colour, or directories of
//! them, and the peaks CSV. Colour stays colour: which channel the detector sees is a setting
//! ([`super::Channel`]), never a silent conversion.

use super::{ColorImage, ColorPixels, DetectError, Image, LinePeak};
use footscan_hal::{Frame, Pixels, Timestamp};
use image::DynamicImage;
use std::io::Write;
use std::path::{Path, PathBuf};

fn input(path: &Path, reason: impl std::fmt::Display) -> DetectError {
    DetectError::Input {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// The image files (PNG, JPEG) named by `inputs`, in order: a file as given, a directory as its `*.png`
/// files (case-insensitive extension) in name order. Frame index = position in this list.
pub fn collect_inputs(inputs: &[PathBuf]) -> Result<Vec<PathBuf>, DetectError> {
    let mut files = Vec::new();
    for p in inputs {
        if p.is_dir() {
            let mut v: Vec<PathBuf> = std::fs::read_dir(p)
                .map_err(|e| input(p, e))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|f| {
                    f.is_file()
                        && f.extension().and_then(|x| x.to_str()).is_some_and(|x| {
                            ["png", "jpg", "jpeg"]
                                .iter()
                                .any(|e| x.eq_ignore_ascii_case(e))
                        })
                })
                .collect();
            v.sort();
            if v.is_empty() {
                return Err(input(p, "no .png or .jpg files in this directory"));
            }
            files.extend(v);
        } else if p.is_file() {
            files.push(p.clone());
        } else {
            return Err(input(p, "no such file or directory"));
        }
    }
    if files.is_empty() {
        return Err(DetectError::NoInput);
    }
    Ok(files)
}

/// Read one image file (PNG or JPEG) as it is: 8-bit grey as Gray8, 16-bit grey as Gray16,
/// colour as RGB8 or RGB16 (alpha dropped). `seq` is its frame index.
pub fn load_image(path: &Path, seq: u64) -> Result<Image, DetectError> {
    let img = image::ImageReader::open(path)
        .map_err(|e| input(path, e))?
        .with_guessed_format()
        .map_err(|e| input(path, e))?
        .decode()
        .map_err(|e| input(path, e))?;
    let (w, h) = (img.width(), img.height());
    if w == 0 || h == 0 {
        return Err(input(path, "empty image"));
    }
    let gray = |p| Ok(Image::Gray(Frame::new(seq, Timestamp::default(), w, h, p)));
    let color = |p| Ok(Image::Color(ColorImage::new(w, h, p)));
    match img {
        DynamicImage::ImageLuma8(b) => gray(Pixels::Gray8(b.into_raw())),
        DynamicImage::ImageLuma16(b) => gray(Pixels::Gray16(b.into_raw())),
        DynamicImage::ImageLumaA8(_) => gray(Pixels::Gray8(img.to_luma8().into_raw())),
        DynamicImage::ImageLumaA16(_) => gray(Pixels::Gray16(img.to_luma16().into_raw())),
        DynamicImage::ImageRgb8(b) => color(ColorPixels::Rgb8(b.into_raw())),
        DynamicImage::ImageRgba8(_) => color(ColorPixels::Rgb8(img.to_rgb8().into_raw())),
        other => color(ColorPixels::Rgb16(other.to_rgb16().into_raw())),
    }
}

/// Read one PNG as a grey frame (`seq` = its index). 8-bit gray stays Gray8, 16-bit gray
/// Gray16; colour is converted to luma of its own depth (for callers that want grey whatever
/// the file holds; detection goes through [`load_image`] and a channel).
pub fn load_png(path: &Path, seq: u64) -> Result<Frame, DetectError> {
    let img = image::ImageReader::open(path)
        .map_err(|e| input(path, e))?
        .with_guessed_format()
        .map_err(|e| input(path, e))?
        .decode()
        .map_err(|e| input(path, e))?;
    let (w, h) = (img.width(), img.height());
    let pixels = match img {
        DynamicImage::ImageLuma8(b) => Pixels::Gray8(b.into_raw()),
        DynamicImage::ImageLuma16(b) => Pixels::Gray16(b.into_raw()),
        DynamicImage::ImageLumaA8(_) | DynamicImage::ImageRgb8(_) | DynamicImage::ImageRgba8(_) => {
            Pixels::Gray8(img.to_luma8().into_raw())
        }
        other => Pixels::Gray16(other.to_luma16().into_raw()),
    };
    if w == 0 || h == 0 {
        return Err(input(path, "empty image"));
    }
    Ok(Frame::new(seq, Timestamp::default(), w, h, pixels))
}

/// The CSV header of `footscan detect`.
pub const CSV_HEADER: &str = "frame,row,col,intensity,width,quality";

/// One line per row: `frame,row,col,intensity,width,quality`, col empty where no line was
/// accepted (width and quality then 0).
pub fn write_csv_rows<W: Write>(
    out: &mut W,
    frame: usize,
    peaks: &[LinePeak],
) -> std::io::Result<()> {
    for (r, p) in peaks.iter().enumerate() {
        if p.is_valid() {
            writeln!(
                out,
                "{frame},{r},{:.4},{},{:.3},{:.3}",
                p.col, p.intensity, p.width, p.quality
            )?;
        } else {
            writeln!(out, "{frame},{r},,{},0,0", p.intensity)?;
        }
    }
    Ok(())
}
