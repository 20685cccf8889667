//! The live preview: the latest frame and its detected line, captured by a tap on the detect
//! stage. The tap copies at most 10 frames a second into a preallocated slot with `try_lock`,
//! so the pipeline never waits for a viewer and the steady state allocates nothing; a reader
//! that holds the slot only makes the tap skip a frame.

use footscan::detect::LinePeak;
use footscan::scan::item::FrameMeta;
use footscan::scan::stages::FrameTap;
use footscan_hal::{Frame, Pixels, Timestamp};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Mutex;

/// Minimum spacing of copies (ns): 10 per second.
const PERIOD_NS: u64 = 100_000_000;

#[derive(Default)]
struct Slot {
    /// 0 until the first frame.
    seq: u64,
    /// Copies made since the daemon started (frame seqs restart with every scan).
    generation: u64,
    timestamp: Timestamp,
    x_mm: f64,
    width: u32,
    height: u32,
    /// 8-bit pixels (Gray16 frames keep their high byte).
    pixels: Vec<u8>,
    /// Detected column per row, NaN where no line was accepted.
    cols: Vec<f64>,
}

#[derive(Default)]
pub struct Preview {
    slot: Mutex<Slot>,
    last_copy_ns: AtomicU64,
    /// The slot's generation, readable without the lock.
    generation: AtomicU64,
    /// Rows with an accepted line in the current scan (the running point count).
    points: AtomicU64,
    /// Frames the tap saw in the current scan, and of those copied.
    seen: AtomicU64,
    copied: AtomicU64,
}

/// A downscaled copy of the latest frame.
pub struct PreviewImage {
    pub seq: u64,
    /// The slot copy it was made from (see [`Preview::generation`]).
    pub generation: u64,
    /// Capture time of the frame.
    pub timestamp: Timestamp,
    pub age_ms: f64,
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<u8>,
}

/// The latest detected line.
#[derive(serde::Serialize)]
pub struct PreviewLine {
    pub seq: u64,
    pub width: u32,
    pub height: u32,
    pub age_ms: f64,
    pub cols: Vec<Option<f64>>,
}

impl Preview {
    /// A new scan begins: reset the running counts (the last frame stays visible).
    pub fn reset_counts(&self) {
        self.points.store(0, Ordering::Relaxed);
        self.seen.store(0, Ordering::Relaxed);
        self.copied.store(0, Ordering::Relaxed);
    }

    pub fn points(&self) -> u64 {
        self.points.load(Ordering::Relaxed)
    }

    /// (frames seen, frames copied) by the tap in the current scan.
    pub fn tap_counts(&self) -> (u64, u64) {
        (
            self.seen.load(Ordering::Relaxed),
            self.copied.load(Ordering::Relaxed),
        )
    }

    /// Changes with every frame the tap copies: a reader can tell whether what it made from the
    /// slot is still the latest without taking the lock.
    pub fn generation(&self) -> u64 {
        self.generation.load(Ordering::Acquire)
    }

    /// The slider position of the latest frame.
    pub fn x_mm(&self) -> Option<f64> {
        let s = self.slot.lock().unwrap();
        (s.seq > 0).then_some(s.x_mm)
    }

    /// The latest frame scaled to `width` pixels (box filter), or None before any frame.
    pub fn image(&self, width: u32) -> Option<PreviewImage> {
        let s = self.slot.lock().unwrap();
        if s.seq == 0 || s.width == 0 {
            return None;
        }
        let w = width.min(s.width).max(1);
        let h = ((s.height as u64 * w as u64 + s.width as u64 / 2) / s.width as u64).max(1) as u32;
        let mut out = vec![0u8; (w * h) as usize];
        let (sw, sh) = (s.width as usize, s.height as usize);
        for oy in 0..h as usize {
            let y0 = oy * sh / h as usize;
            let y1 = ((oy + 1) * sh / h as usize).max(y0 + 1);
            for ox in 0..w as usize {
                let x0 = ox * sw / w as usize;
                let x1 = ((ox + 1) * sw / w as usize).max(x0 + 1);
                let mut sum = 0u32;
                for row in s.pixels[y0 * sw..y1 * sw].chunks_exact(sw) {
                    sum += row[x0..x1].iter().map(|&p| p as u32).sum::<u32>();
                }
                out[oy * w as usize + ox] = (sum / ((y1 - y0) * (x1 - x0)) as u32) as u8;
            }
        }
        Some(PreviewImage {
            seq: s.seq,
            generation: s.generation,
            timestamp: s.timestamp,
            age_ms: age_ms(s.timestamp),
            width: w,
            height: h,
            pixels: out,
        })
    }

    pub fn line(&self) -> Option<PreviewLine> {
        let s = self.slot.lock().unwrap();
        if s.seq == 0 {
            return None;
        }
        Some(PreviewLine {
            seq: s.seq,
            width: s.width,
            height: s.height,
            age_ms: age_ms(s.timestamp),
            cols: s
                .cols
                .iter()
                .map(|&c| c.is_finite().then_some((c * 1000.0).round() / 1000.0))
                .collect(),
        })
    }
}

/// Milliseconds since `t` (CLOCK_MONOTONIC), 0 if `t` is in the future.
pub fn age_ms(t: Timestamp) -> f64 {
    let now = Timestamp::now();
    if now.nanos >= t.nanos {
        (now.nanos - t.nanos) as f64 / 1e6
    } else {
        0.0
    }
}

impl FrameTap for Preview {
    fn frame(&self, meta: &FrameMeta, frame: &Frame, lines: &[LinePeak]) {
        let valid = lines.iter().filter(|l| l.is_valid()).count() as u64;
        self.points.fetch_add(valid, Ordering::Relaxed);
        self.seen.fetch_add(1, Ordering::Relaxed);
        let now = Timestamp::now().nanos;
        let last = self.last_copy_ns.load(Ordering::Relaxed);
        if last != 0 && now.saturating_sub(last) < PERIOD_NS {
            return;
        }
        let Ok(mut s) = self.slot.try_lock() else {
            return; // a reader holds the slot: skip this frame, never wait
        };
        s.seq = frame.seq.max(1);
        s.generation += 1;
        s.timestamp = frame.timestamp;
        s.x_mm = meta.x_mm;
        s.width = frame.width;
        s.height = frame.height;
        s.pixels.clear();
        match &frame.pixels {
            Pixels::Gray8(p) => s.pixels.extend_from_slice(p),
            Pixels::Gray16(p) => {
                // 10- and 12-bit data sit in the low bits: scale by the frame's top bit.
                let max = p.iter().copied().max().unwrap_or(0);
                let shift = (16 - max.leading_zeros()).saturating_sub(8);
                s.pixels.extend(p.iter().map(|&v| (v >> shift) as u8));
            }
        }
        s.cols.clear();
        s.cols.extend(
            lines
                .iter()
                .map(|l| if l.is_valid() { l.col } else { f64::NAN }),
        );
        let generation = s.generation;
        drop(s);
        self.generation.store(generation, Ordering::Release);
        self.copied.fetch_add(1, Ordering::Relaxed);
        self.last_copy_ns.store(now, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(seq: u64, w: u32, h: u32, px: Vec<u8>) -> Frame {
        Frame::new(seq, Timestamp::now(), w, h, Pixels::Gray8(px))
    }

    fn meta() -> FrameMeta {
        FrameMeta {
            index: 0,
            seq: 0,
            timestamp: Timestamp::now(),
            x_mm: 12.5,
        }
    }

    fn lines(h: usize) -> Vec<LinePeak> {
        let mut l = vec![LinePeak::NONE; h];
        l[1].col = 3.25;
        l[1].reject = None;
        l
    }

    #[test]
    fn copies_at_most_ten_a_second_and_never_waits() {
        let p = Preview::default();
        assert!(p.image(320).is_none() && p.line().is_none());
        // 4x2: left half 0, right half 200.
        let px = vec![0, 0, 200, 200, 0, 0, 200, 200];
        p.frame(&meta(), &frame(5, 4, 2, px.clone()), &lines(2));
        p.frame(&meta(), &frame(6, 4, 2, px.clone()), &lines(2));
        assert_eq!(p.tap_counts(), (2, 1), "the second frame came too soon");
        assert_eq!(p.x_mm(), Some(12.5));
        let img = p.image(2).unwrap();
        assert_eq!((img.seq, img.width, img.height), (5, 2, 1));
        assert_eq!(img.pixels, [0, 200], "box filter");
        let line = p.line().unwrap();
        assert_eq!(line.cols, [None, Some(3.25)]);
        // A reader holding the slot makes the tap skip, not wait.
        p.last_copy_ns.store(1, Ordering::Relaxed);
        let guard = p.slot.lock().unwrap();
        p.frame(&meta(), &frame(7, 4, 2, px), &lines(2));
        drop(guard);
        assert_eq!(p.tap_counts(), (3, 1));
        assert_eq!(p.image(4).unwrap().seq, 5);
    }

    #[test]
    fn twelve_bit_frames_are_scaled_by_their_top_bit() {
        let p = Preview::default();
        let f = Frame::new(1, Timestamp::now(), 2, 1, Pixels::Gray16(vec![4095, 2048]));
        p.frame(&meta(), &f, &[LinePeak::NONE]);
        assert_eq!(p.image(2).unwrap().pixels, [255, 128]);
    }
}
