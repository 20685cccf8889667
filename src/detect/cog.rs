use super::{Detector, LinePeak, Reject};
use footscan_hal::{Frame, Pixels};

/// Centre of gravity over the contiguous run of pixels above a threshold around the row's
/// maximum, weights `I - threshold` (unbiased for a symmetric profile cut at a level).
#[derive(Clone, Debug)]
pub struct CogDetector {
    /// Minimum peak, DN of an 8-bit frame (scaled by 257 for Gray16).
    pub threshold: f32,
}

impl CogDetector {
    pub fn new(threshold: f32) -> Self {
        CogDetector { threshold }
    }
}

impl Detector for CogDetector {
    fn name(&self) -> &'static str {
        "cog"
    }

    fn detect(&mut self, frame: &Frame, out: &mut [LinePeak]) {
        let w = frame.width as usize;
        assert_eq!(out.len(), frame.height as usize, "one result per row");
        match &frame.pixels {
            Pixels::Gray8(px) => {
                for (row, o) in px.chunks_exact(w).zip(out.iter_mut()) {
                    *o = cog_row(row, self.threshold, 255);
                }
            }
            Pixels::Gray16(px) => {
                for (row, o) in px.chunks_exact(w).zip(out.iter_mut()) {
                    *o = cog_row(row, self.threshold * 257.0, 65535);
                }
            }
        }
    }
}

fn cog_row<T: Copy + Ord + Into<u32>>(row: &[T], threshold: f32, full: u32) -> LinePeak {
    // max() then position(): two simple passes the compiler vectorises.
    let Some(&max) = row.iter().max() else {
        return LinePeak::NONE;
    };
    let peak = max.into();
    if (peak as f32) < threshold {
        return LinePeak::rejected(Reject::BelowThreshold, peak as f32);
    }
    let m = row.iter().position(|&v| v == max).unwrap_or(0);
    let t = threshold;
    let above = |i: usize| row[i].into() as f32 > t;
    let mut lo = m;
    while lo > 0 && above(lo - 1) {
        lo -= 1;
    }
    let mut hi = m;
    while hi + 1 < row.len() && above(hi + 1) {
        hi += 1;
    }
    if lo == 0 || hi + 1 == row.len() {
        return LinePeak::rejected(Reject::Border, peak as f32);
    }
    let (mut s, mut sx) = (0.0f64, 0.0f64);
    let half = (peak as f32) * 0.5;
    let mut width = 0.0f32;
    for (i, v) in row.iter().enumerate().take(hi + 1).skip(lo) {
        let v = (*v).into() as f32;
        let wgt = (v - t) as f64;
        s += wgt;
        sx += wgt * i as f64;
        if v >= half {
            width += 1.0;
        }
    }
    let saturated_run = row[lo..=hi].iter().filter(|v| (**v).into() >= full).count();
    LinePeak {
        col: sx / s,
        intensity: peak as f32,
        width,
        quality: if saturated_run > 0 {
            0.5
        } else {
            ((peak as f32 - t) / (full as f32 - t)).clamp(0.0, 1.0)
        },
        reject: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use footscan_hal::{Pixels, Timestamp};

    fn gaussian_row(w: usize, c0: f64, sigma: f64, peak: f64, bg: f64) -> Vec<u8> {
        (0..w)
            .map(|i| {
                let d = i as f64 - c0;
                (bg + peak * (-d * d / (2.0 * sigma * sigma)).exp())
                    .round()
                    .min(255.0) as u8
            })
            .collect()
    }

    #[test]
    fn finds_subpixel_centre() {
        let w = 64;
        let mut px = Vec::new();
        let centres: Vec<f64> = (0..10).map(|k| 30.0 + k as f64 * 0.1).collect();
        for &c in &centres {
            px.extend(gaussian_row(w, c, 1.6, 180.0, 8.0));
        }
        let f = Frame::new(0, Timestamp::default(), w as u32, 10, Pixels::Gray8(px));
        let mut out = vec![LinePeak::NONE; 10];
        CogDetector::new(30.0).detect(&f, &mut out);
        for (o, c) in out.iter().zip(&centres) {
            assert!(o.is_valid());
            assert!((o.col - c).abs() < 0.05, "{} vs {c}", o.col);
            assert!(o.width >= 3.0 && o.width <= 5.0, "width {}", o.width);
        }
    }

    #[test]
    fn rejects_dark_rows_and_border_lines() {
        let w = 32;
        let mut px = vec![8u8; w];
        px.extend(gaussian_row(w, 0.5, 1.6, 180.0, 8.0));
        let f = Frame::new(0, Timestamp::default(), w as u32, 2, Pixels::Gray8(px));
        let mut out = vec![LinePeak::NONE; 2];
        CogDetector::new(30.0).detect(&f, &mut out);
        assert_eq!(out[0].reject, Some(Reject::BelowThreshold));
        assert_eq!(out[1].reject, Some(Reject::Border));
        assert!(out[1].col.is_nan());
    }

    #[test]
    fn gray16_uses_scaled_threshold() {
        let w = 40;
        let px: Vec<u16> = gaussian_row(w, 20.25, 1.6, 180.0, 8.0)
            .iter()
            .map(|&v| v as u16 * 257)
            .collect();
        let f = Frame::new(0, Timestamp::default(), w as u32, 1, Pixels::Gray16(px));
        let mut out = vec![LinePeak::NONE; 1];
        CogDetector::new(30.0).detect(&f, &mut out);
        assert!((out[0].col - 20.25).abs() < 0.05, "{}", out[0].col);
    }
}
