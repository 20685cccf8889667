use crate::Timestamp;
use crossbeam_channel::{Receiver, Sender};
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PixelFormat {
    Gray8,
    Gray16,
}

impl PixelFormat {
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            PixelFormat::Gray8 => 1,
            PixelFormat::Gray16 => 2,
        }
    }
}

/// Pixel storage, row-major, `width` pixels per row with no padding.
#[derive(Clone, Debug, PartialEq)]
pub enum Pixels {
    Gray8(Vec<u8>),
    Gray16(Vec<u16>),
}

impl Pixels {
    pub fn format(&self) -> PixelFormat {
        match self {
            Pixels::Gray8(_) => PixelFormat::Gray8,
            Pixels::Gray16(_) => PixelFormat::Gray16,
        }
    }
    pub fn len(&self) -> usize {
        match self {
            Pixels::Gray8(v) => v.len(),
            Pixels::Gray16(v) => v.len(),
        }
    }
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    fn zeroed(format: PixelFormat, n: usize) -> Self {
        match format {
            PixelFormat::Gray8 => Pixels::Gray8(vec![0; n]),
            PixelFormat::Gray16 => Pixels::Gray16(vec![0; n]),
        }
    }
}

/// One captured image.
///
/// Frames taken from a [`FramePool`] hand their pixel buffer back to the pool when dropped, so
/// a steady stream allocates nothing per frame.
#[derive(Debug)]
pub struct Frame {
    /// Driver sequence number; gaps mean frames were dropped before reaching us.
    pub seq: u64,
    /// Capture time (middle of exposure where the device says so) on the monotonic clock.
    pub timestamp: Timestamp,
    pub width: u32,
    pub height: u32,
    pub pixels: Pixels,
    home: Option<Sender<Pixels>>,
}

impl Frame {
    /// A frame that owns its buffer outright (not pooled).
    pub fn new(seq: u64, timestamp: Timestamp, width: u32, height: u32, pixels: Pixels) -> Self {
        assert_eq!(
            pixels.len(),
            width as usize * height as usize,
            "pixel buffer does not match {width}x{height}"
        );
        Frame {
            seq,
            timestamp,
            width,
            height,
            pixels,
            home: None,
        }
    }

    pub fn format(&self) -> PixelFormat {
        self.pixels.format()
    }

    /// Row `r` as Gray8, or None for a Gray16 frame.
    pub fn row8(&self, r: usize) -> Option<&[u8]> {
        let w = self.width as usize;
        match &self.pixels {
            Pixels::Gray8(v) => Some(&v[r * w..(r + 1) * w]),
            Pixels::Gray16(_) => None,
        }
    }

    /// Row `r` as Gray16, or None for a Gray8 frame.
    pub fn row16(&self, r: usize) -> Option<&[u16]> {
        let w = self.width as usize;
        match &self.pixels {
            Pixels::Gray16(v) => Some(&v[r * w..(r + 1) * w]),
            Pixels::Gray8(_) => None,
        }
    }

    /// Pixel value as f32 (for tests and slow paths; hot loops use `row8`/`row16`).
    pub fn get(&self, r: usize, c: usize) -> f32 {
        let i = r * self.width as usize + c;
        match &self.pixels {
            Pixels::Gray8(v) => v[i] as f32,
            Pixels::Gray16(v) => v[i] as f32,
        }
    }
}

impl Drop for Frame {
    fn drop(&mut self) {
        if let Some(home) = self.home.take() {
            let px = std::mem::replace(&mut self.pixels, Pixels::Gray8(Vec::new()));
            // The pool may be gone already; then the buffer is simply freed.
            let _ = home.try_send(px);
        }
    }
}

/// A bounded set of reusable frame buffers of one size and format.
#[derive(Clone, Debug)]
pub struct FramePool {
    width: u32,
    height: u32,
    format: PixelFormat,
    tx: Sender<Pixels>,
    rx: Receiver<Pixels>,
}

impl FramePool {
    /// `capacity` buffers are kept at most; more are allocated on demand when all are in flight.
    pub fn new(width: u32, height: u32, format: PixelFormat, capacity: usize) -> Self {
        let (tx, rx) = crossbeam_channel::bounded(capacity.max(1));
        FramePool {
            width,
            height,
            format,
            tx,
            rx,
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    pub fn format(&self) -> PixelFormat {
        self.format
    }

    /// A frame with a recycled (or, if none is free, new) buffer. Its contents are stale: the
    /// caller overwrites every pixel.
    pub fn take(&self, seq: u64, timestamp: Timestamp) -> Frame {
        let n = self.width as usize * self.height as usize;
        let pixels = match self.rx.try_recv() {
            Ok(p) if p.len() == n && p.format() == self.format => p,
            _ => Pixels::zeroed(self.format, n),
        };
        Frame {
            seq,
            timestamp,
            width: self.width,
            height: self.height,
            pixels,
            home: Some(self.tx.clone()),
        }
    }

    /// Buffers currently waiting for reuse.
    pub fn idle(&self) -> usize {
        self.rx.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pool_recycles_buffers() {
        let pool = FramePool::new(4, 3, PixelFormat::Gray8, 2);
        let f = pool.take(0, Timestamp::default());
        let ptr = match &f.pixels {
            Pixels::Gray8(v) => v.as_ptr(),
            _ => unreachable!(),
        };
        assert_eq!(pool.idle(), 0);
        drop(f);
        assert_eq!(pool.idle(), 1);
        let g = pool.take(1, Timestamp::default());
        match &g.pixels {
            Pixels::Gray8(v) => assert_eq!(v.as_ptr(), ptr, "buffer was not reused"),
            _ => unreachable!(),
        }
        assert_eq!(g.row8(2).unwrap().len(), 4);
        assert!(g.row16(0).is_none());
    }

    #[test]
    #[should_panic(expected = "does not match")]
    fn new_checks_size() {
        Frame::new(0, Timestamp::default(), 2, 2, Pixels::Gray16(vec![0; 3]));
    }
}
