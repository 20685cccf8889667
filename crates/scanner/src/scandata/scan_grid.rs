use super::{FrameMeta, FramePoints};
use crate::detect::LinePeak;
use footscan_geom::P3;

/// The scan grid of docs/method.md section 3.2: frame i (slider position X_i) by row j.
#[derive(Debug, Default)]
pub struct ScanGrid {
    pub rows: usize,
    pub frames: Vec<FrameMeta>,
    /// `frames.len() * rows`, frame-major.
    pub lines: Vec<LinePeak>,
    /// `frames.len() * rows`, NaN where no line.
    pub points: Vec<P3>,
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

    pub fn point(&self, frame: usize, row: usize) -> P3 {
        self.points[frame * self.rows + row]
    }

    /// Valid points with (frame, row) and their line.
    pub fn valid(&self) -> impl Iterator<Item = (usize, usize, &P3, &LinePeak)> + '_ {
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

const MAGIC: &[u8; 8] = b"FSGRID01";

/// `grid.bin` in a scan directory: the whole grid, so later commands (model, measure) can work
/// on a saved scan. Little-endian: magic, u32 frames, u32 rows; per frame u64 index, u64 seq,
/// u64 timestamp ns, f64 x_mm; per cell f64 col, f32 intensity, f32 width, f32 quality,
/// u8 reject code (0 = accepted), f64 x, y, z.
impl ScanGrid {
    pub fn save(&self, path: &std::path::Path) -> std::io::Result<()> {
        footscan_util::write_atomic_with(path, |w| {
            w.write_all(MAGIC)?;
            w.write_all(&(self.frames.len() as u32).to_le_bytes())?;
            w.write_all(&(self.rows as u32).to_le_bytes())?;
            for f in &self.frames {
                for v in [f.index, f.seq, f.timestamp.nanos] {
                    w.write_all(&v.to_le_bytes())?;
                }
                w.write_all(&f.x_mm.to_le_bytes())?;
            }
            // Rows gathered in a buffer and written a chunk at a time: eight writes a row
            // through the writer were 7 M calls on a scan's grid, and the sinks run beside
            // the measurement the results wait for (issue 34 item 2).
            const ROW: usize = 8 + 3 * 4 + 1 + 3 * 8;
            let mut buf = Vec::with_capacity(ROW * 4096);
            for (l, p) in self.lines.iter().zip(&self.points) {
                buf.extend_from_slice(&l.col.to_le_bytes());
                for v in [l.intensity, l.width, l.quality] {
                    buf.extend_from_slice(&v.to_le_bytes());
                }
                buf.push(reject_code(l.reject));
                for v in p.iter() {
                    buf.extend_from_slice(&v.to_le_bytes());
                }
                if buf.len() >= ROW * 4096 {
                    w.write_all(&buf)?;
                    buf.clear();
                }
            }
            w.write_all(&buf)
        })
    }

    pub fn load(path: &std::path::Path) -> std::io::Result<Self> {
        Self::parse(&std::fs::read(path)?, path)
    }

    /// A grid.bin's bytes; `path` names it in errors.
    pub fn parse(bytes: &[u8], path: &std::path::Path) -> std::io::Result<Self> {
        // Sizes are checked against the header below, so the unwraps after it cannot fail.
        let bad = |what: &str| {
            std::io::Error::new(
                std::io::ErrorKind::InvalidData,
                format!("{}: not a footscan grid.bin ({what})", path.display()),
            )
        };
        let mut r = Reader { b: bytes, at: 0 };
        if r.take(8).ok_or_else(|| bad("too short"))? != MAGIC {
            return Err(bad("wrong magic"));
        }
        let nf = r.u32().ok_or_else(|| bad("truncated header"))? as usize;
        let rows = r.u32().ok_or_else(|| bad("truncated header"))? as usize;
        // In u128: header counts of up to 2^32 each would overflow (a panic in a debug
        // build, a wrapped size that may match in a release one).
        let expect = 16 + nf as u128 * 32 + nf as u128 * rows as u128 * 45;
        if bytes.len() as u128 != expect {
            return Err(bad(&format!(
                "{nf} frames x {rows} rows need {expect} bytes, the file has {}",
                bytes.len()
            )));
        }
        let mut g = ScanGrid::new(rows);
        // Exact sizes (no doubling), known good from the file size.
        g.frames.reserve_exact(nf);
        g.lines.reserve_exact(nf * rows);
        g.points.reserve_exact(nf * rows);
        for _ in 0..nf {
            g.frames.push(FrameMeta {
                index: r.u64().unwrap(),
                seq: r.u64().unwrap(),
                timestamp: footscan_hal::Timestamp {
                    nanos: r.u64().unwrap(),
                },
                x_mm: r.f64().unwrap(),
            });
        }
        for _ in 0..nf * rows {
            let col = r.f64().unwrap();
            let (intensity, width, quality) =
                (r.f32().unwrap(), r.f32().unwrap(), r.f32().unwrap());
            let reject = reject_from(r.take(1).unwrap()[0]);
            g.lines.push(LinePeak {
                col,
                intensity,
                width,
                quality,
                reject,
            });
            g.points.push(P3::new(
                r.f64().unwrap(),
                r.f64().unwrap(),
                r.f64().unwrap(),
            ));
        }
        Ok(g)
    }
}

use crate::detect::Reject;

fn reject_code(r: Option<Reject>) -> u8 {
    match r {
        None => 0,
        Some(Reject::BelowThreshold) => 1,
        Some(Reject::Saturated) => 2,
        Some(Reject::Ambiguous) => 3,
        Some(Reject::Border) => 4,
        Some(Reject::Isolated) => 5,
    }
}

fn reject_from(c: u8) -> Option<Reject> {
    match c {
        0 => None,
        2 => Some(Reject::Saturated),
        3 => Some(Reject::Ambiguous),
        4 => Some(Reject::Border),
        5 => Some(Reject::Isolated),
        _ => Some(Reject::BelowThreshold),
    }
}

struct Reader<'a> {
    b: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let s = self.b.get(self.at..self.at + n)?;
        self.at += n;
        Some(s)
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
    fn f32(&mut self) -> Option<f32> {
        Some(f32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn f64(&mut self) -> Option<f64> {
        Some(f64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use footscan_hal::Timestamp;

    #[test]
    fn grid_round_trips_and_rejects_garbage() {
        let mut g = ScanGrid::new(2);
        g.push(FramePoints {
            meta: FrameMeta {
                index: 0,
                seq: 7,
                timestamp: Timestamp { nanos: 123 },
                x_mm: 1.5,
            },
            lines: vec![
                LinePeak {
                    col: 12.25,
                    intensity: 180.0,
                    width: 4.0,
                    quality: 0.9,
                    reject: None,
                },
                LinePeak::rejected(Reject::Border, 50.0),
            ],
            points: vec![P3::new(1.0, 2.0, 3.0), P3::from([f64::NAN; 3])],
        });
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("grid.bin");
        g.save(&p).unwrap();
        let h = ScanGrid::load(&p).unwrap();
        assert_eq!(h.frames, g.frames);
        assert_eq!(h.lines[0], g.lines[0]);
        assert_eq!(h.lines[1].reject, Some(Reject::Border));
        assert_eq!(h.points[0], P3::new(1.0, 2.0, 3.0));
        assert!(h.points[1][0].is_nan());
        std::fs::write(&p, b"FSGRID01\x01\x00\x00\x00").unwrap();
        let e = ScanGrid::load(&p).unwrap_err().to_string();
        assert!(e.contains("grid.bin") && e.contains("truncated"), "{e}");
    }
}
