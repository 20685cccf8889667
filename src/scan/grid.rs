use super::item::{FrameMeta, FramePoints};
use crate::detect::LinePeak;

/// The scan grid of SPEC section 3: frame i (slider position X_i) by row j.
#[derive(Debug, Default)]
pub struct ScanGrid {
    pub rows: usize,
    pub frames: Vec<FrameMeta>,
    /// `frames.len() * rows`, frame-major.
    pub lines: Vec<LinePeak>,
    /// `frames.len() * rows`, NaN where no line.
    pub points: Vec<[f64; 3]>,
}

impl ScanGrid {
    pub fn new(rows: usize) -> Self {
        ScanGrid {
            rows,
            ..Default::default()
        }
    }

    pub fn push(&mut self, fp: FramePoints) {
        assert_eq!(
            fp.points.len(),
            self.rows,
            "frame with a different row count"
        );
        self.frames.push(fp.meta);
        self.lines.extend_from_slice(&fp.lines);
        self.points.extend_from_slice(&fp.points);
    }

    pub fn point(&self, frame: usize, row: usize) -> [f64; 3] {
        self.points[frame * self.rows + row]
    }

    /// Valid points with (frame, row) and their line.
    pub fn valid(&self) -> impl Iterator<Item = (usize, usize, &[f64; 3], &LinePeak)> + '_ {
        self.points
            .iter()
            .zip(&self.lines)
            .enumerate()
            .filter(|(_, (p, _))| p[0].is_finite())
            .map(|(k, (p, l))| (k / self.rows, k % self.rows, p, l))
    }

    pub fn valid_count(&self) -> usize {
        self.points.iter().filter(|p| p[0].is_finite()).count()
    }
}
