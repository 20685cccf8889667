//! What a per-frame detector plugin returns, the same for a wasm module and a process: one
//! 24-byte record per row, checked before the scan sees it.

/// Bytes of one output row: f64 col, f32 intensity, f32 width, f32 quality, u32 reject.
pub const ROW_BYTES: usize = 24;
/// The reject codes of an output row, index = code (0 = a line was found).
pub const REJECT_CODES: [&str; 6] = [
    "accepted",
    "below_threshold",
    "saturated",
    "ambiguous",
    "border",
    "isolated",
];

/// One output row as the module wrote it, checked.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowOut {
    /// Subpixel column; NaN when the row was rejected.
    pub col: f64,
    pub intensity: f32,
    pub width: f32,
    pub quality: f32,
    /// Index into [`REJECT_CODES`]; 0 = a line was found.
    pub reject: u32,
}

/// Pixels of a frame handed to a detector (row-major, no padding).
#[derive(Clone, Copy, Debug)]
pub enum Pixels<'a> {
    Gray8(&'a [u8]),
    Gray16(&'a [u16]),
}

impl Pixels<'_> {
    pub fn bytes_per_px(&self) -> usize {
        match self {
            Self::Gray8(_) => 1,
            Self::Gray16(_) => 2,
        }
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    pub fn len(&self) -> usize {
        match self {
            Self::Gray8(p) => p.len(),
            Self::Gray16(p) => p.len(),
        }
    }
}

impl Pixels<'_> {
    /// The pixels as the ABI lays them out: row-major, 16-bit values little-endian.
    pub fn write_le(&self, dst: &mut [u8]) {
        match self {
            Self::Gray8(p) => dst[..p.len()].copy_from_slice(p),
            Self::Gray16(p) => {
                for (d, v) in dst[..2 * p.len()].chunks_exact_mut(2).zip(p.iter()) {
                    d.copy_from_slice(&v.to_le_bytes());
                }
            }
        }
    }
}

/// Check and decode `out.len()` records of a frame `width` pixels wide; the error says what
/// was wrong and in which row.
pub fn parse(bytes: &[u8], width: u32, out: &mut [RowOut]) -> Result<(), String> {
    let f32_at = |b: &[u8], i: usize| f32::from_le_bytes(b[i..i + 4].try_into().unwrap());
    for (r, (b, o)) in bytes
        .chunks_exact(ROW_BYTES)
        .zip(out.iter_mut())
        .enumerate()
    {
        let col = f64::from_le_bytes(b[0..8].try_into().unwrap());
        let (intensity, w, q) = (f32_at(b, 8), f32_at(b, 12), f32_at(b, 16));
        let reject = u32::from_le_bytes(b[20..24].try_into().unwrap());
        if reject as usize >= REJECT_CODES.len() {
            return Err(format!(
                "wrote reject code {reject} for row {r}; valid codes are 0..={} ({})",
                REJECT_CODES.len() - 1,
                REJECT_CODES.join(", ")
            ));
        }
        if !intensity.is_finite() {
            return Err(format!(
                "wrote intensity {intensity} for row {r}; it must be finite"
            ));
        }
        if reject == 0 {
            if !(col.is_finite() && col >= 0.0 && col <= f64::from(width) - 1.0) {
                return Err(format!(
                    "returned column {col} for row {r}, an accepted row; it must lie in 0..={} \
                     (reject the row instead)",
                    width - 1
                ));
            }
            if !(w.is_finite() && q.is_finite()) {
                return Err(format!(
                    "wrote width {w} and quality {q} for row {r}; both must be finite"
                ));
            }
            *o = RowOut {
                col,
                intensity,
                width: w,
                quality: q,
                reject,
            };
        } else {
            *o = RowOut {
                col: f64::NAN,
                intensity,
                width: 0.0,
                quality: 0.0,
                reject,
            };
        }
    }
    Ok(())
}
