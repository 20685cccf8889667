//! The output side of the loop: a thread that keeps vivid's output queue full of frames.
//!
//! `v4l::io::mmap::Stream` hangs on vivid's output queue, so this uses the driver crate's
//! [`MmapQueue`] (raw ioctls and mmap of the `v4l` crate). vivid's output thread only takes a
//! buffer when another one is queued behind it, and the capture side copies the oldest queued
//! output buffer: with every buffer queued and each re-queued as soon as it comes back, the
//! loop never runs empty.

use crate::code;
use footscan_v4l2::dv::{self, DvTimings};
use footscan_v4l2::stream::{DequeueError, Direction, MmapQueue};
use footscan_v4l2::v4l;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use v4l::video::Output;

/// Writes a frame id into the first rows of a packed image of the given width.
type IdWriter = fn(&mut [u8], usize, u32);

pub struct Feeder {
    /// Set: stop queueing (the output stream stays on with what it holds).
    pub pause: Arc<AtomicBool>,
    /// Set: leave the loop, stream off.
    pub quit: Arc<AtomicBool>,
    /// Id of the next frame to be queued.
    pub next_id: Arc<AtomicU32>,
    handle: Option<JoinHandle<Result<u64, String>>>,
}

impl Feeder {
    /// Open the output node, select its HDMI output, set `timings` and `fourcc` (GREY, RGB3 or
    /// YUYV) at `w` x `h`, and start streaming `images[id % images.len()]` (packed rows) with
    /// the id written in.
    pub fn start(
        path: &Path,
        output: u32,
        timings: &DvTimings,
        (w, h): (u32, u32),
        fourcc: &[u8; 4],
        images: Arc<Vec<Vec<u8>>>,
    ) -> Result<Feeder, String> {
        let (bpp, write_id): (usize, IdWriter) = match fourcc {
            b"GREY" => (1, code::write_id),
            b"RGB3" => (3, code::write_id_rgb),
            b"YUYV" => (2, code::write_id_yuyv),
            other => return Err(format!("no feeder for {}", String::from_utf8_lossy(other))),
        };
        let dev = v4l::Device::with_path(path).map_err(|e| format!("open {path:?}: {e}"))?;
        let fd = dev.handle().fd();
        dv::set_output(fd, output).map_err(|e| format!("S_OUTPUT {output}: {e}"))?;
        dv::set_dv_timings(fd, timings).map_err(|e| format!("output S_DV_TIMINGS: {e}"))?;
        let mut f = v4l::Format::new(w, h, v4l::FourCC::new(fourcc));
        f.field_order = v4l::format::FieldOrder::Progressive;
        let got = Output::set_format(&dev, &f).map_err(|e| format!("output S_FMT: {e}"))?;
        if got.width != w || got.height != h || got.fourcc != f.fourcc {
            return Err(format!("output format became {got}"));
        }
        let stride = got.stride as usize;
        let size = got.size as usize;
        let mut q =
            MmapQueue::new(fd, Direction::Output, 4).map_err(|e| format!("output REQBUFS: {e}"))?;
        let pause = Arc::new(AtomicBool::new(false));
        let quit = Arc::new(AtomicBool::new(false));
        let next_id = Arc::new(AtomicU32::new(0));
        let (p, qt, nid) = (pause.clone(), quit.clone(), next_id.clone());
        let (w, h) = (w as usize, h as usize);
        let row = w * bpp;
        let fill = move |buf: &mut [u8], id: u32| {
            let img = &images[id as usize % images.len()];
            for r in 0..h {
                buf[r * stride..r * stride + row].copy_from_slice(&img[r * row..(r + 1) * row]);
            }
            // The id goes into the buffer's rows directly (stride-aware).
            let mut head = vec![0u8; code::ID_ROWS * row];
            write_id(&mut head, w, id);
            for r in 0..code::ID_ROWS {
                buf[r * stride..r * stride + row].copy_from_slice(&head[r * row..(r + 1) * row]);
            }
        };
        for i in 0..q.len() {
            let id = nid.fetch_add(1, Ordering::SeqCst);
            fill(q.buffer_mut(i), id);
            q.queue(i, size).map_err(|e| format!("output QBUF: {e}"))?;
        }
        q.stream_on().map_err(|e| format!("output STREAMON: {e}"))?;
        let handle = std::thread::spawn(move || {
            let _dev = dev; // keeps the fd open as long as the queue
            let mut fed = q.len() as u64;
            while !qt.load(Ordering::SeqCst) {
                if p.load(Ordering::SeqCst) {
                    std::thread::sleep(Duration::from_millis(5));
                    continue;
                }
                match q.dequeue(Duration::from_millis(200)) {
                    Ok(d) => {
                        let id = nid.fetch_add(1, Ordering::SeqCst);
                        fill(q.buffer_mut(d.index), id);
                        q.queue(d.index, size)
                            .map_err(|e| format!("output QBUF: {e}"))?;
                        fed += 1;
                    }
                    Err(DequeueError::Timeout) => {}
                    Err(DequeueError::Io(e)) => return Err(format!("output DQBUF: {e}")),
                }
            }
            drop(q);
            Ok(fed)
        });
        Ok(Feeder {
            pause,
            quit,
            next_id,
            handle: Some(handle),
        })
    }

    /// Stop the thread; the frames it queued in all, or its error.
    pub fn finish(mut self) -> Result<u64, String> {
        self.quit.store(true, Ordering::SeqCst);
        self.handle
            .take()
            .map(|h| h.join().map_err(|_| "feeder panicked".to_string())?)
            .unwrap_or(Ok(0))
    }
}

impl Drop for Feeder {
    fn drop(&mut self) {
        self.quit.store(true, Ordering::SeqCst);
        if let Some(h) = self.handle.take() {
            let _ = h.join();
        }
    }
}
