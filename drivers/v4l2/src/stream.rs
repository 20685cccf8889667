//! Memory-mapped streaming I/O: a set of driver buffers mapped into this process, queued and
//! dequeued with poll(2) and a timeout, for a capture or an output queue.
//!
//! This replaces `v4l::io::mmap::Stream`: its `next()` blocks without limit on output queues,
//! hides the buffer index and flags, and panics in `Drop` on errors other than ENODEV. The
//! raw requests and structs are still the `v4l` crate's (`v4l::v4l_sys`, `v4l::v4l2::mmap`).
//!
//! Sequence numbers and timestamps: [`SeqTracker`] widens the driver's 32-bit sequence to 64
//! bits and counts gaps as dropped frames; [`buffer_timestamp`] takes the buffer's timestamp
//! when the driver says it is on `CLOCK_MONOTONIC`.

use crate::sys::{self, bindings::*};
use footscan_hal::Timestamp;
use std::io;
use std::os::raw::c_int;
use std::time::Duration;

/// Which queue of the device.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    Capture,
    Output,
}

impl Direction {
    fn buf_type(self) -> u32 {
        match self {
            Direction::Capture => v4l2_buf_type_V4L2_BUF_TYPE_VIDEO_CAPTURE,
            Direction::Output => v4l2_buf_type_V4L2_BUF_TYPE_VIDEO_OUTPUT,
        }
    }
    fn poll_events(self) -> i16 {
        match self {
            Direction::Capture => libc::POLLIN,
            Direction::Output => libc::POLLOUT,
        }
    }
}

/// What a dequeued buffer carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dequeued {
    pub index: usize,
    pub bytesused: usize,
    pub flags: u32,
    pub sequence: u32,
    /// `timeval` as (seconds, microseconds).
    pub timestamp: (i64, i64),
}

impl Dequeued {
    /// The driver marked the data as corrupted (V4L2_BUF_FLAG_ERROR).
    pub fn is_error(&self) -> bool {
        self.flags & V4L2_BUF_FLAG_ERROR != 0
    }
}

/// Why a dequeue gave no buffer.
#[derive(Debug)]
pub enum DequeueError {
    /// Nothing arrived within the timeout.
    Timeout,
    /// Any other failure; ENODEV means the device is gone.
    Io(io::Error),
}

impl From<io::Error> for DequeueError {
    fn from(e: io::Error) -> Self {
        DequeueError::Io(e)
    }
}

struct Mapping {
    ptr: *mut u8,
    len: usize,
}

/// Buffers requested from the driver and mapped; streaming is off until [`MmapQueue::stream_on`].
///
/// Dropping it turns streaming off, unmaps and frees the buffers, ignoring errors (the device
/// may be gone).
pub struct MmapQueue {
    fd: c_int,
    dir: Direction,
    maps: Vec<Mapping>,
    queued: Vec<bool>,
    streaming: bool,
}

// SAFETY: the mappings are owned by this value alone and only touched through &self/&mut self.
unsafe impl Send for MmapQueue {}

impl MmapQueue {
    /// Request `count` buffers (the driver may give more; fewer than `count` is an error) and
    /// map them. `fd` must stay open for the queue's lifetime.
    pub fn new(fd: c_int, dir: Direction, count: u32) -> io::Result<Self> {
        let mut req: v4l2_requestbuffers = sys::zeroed();
        req.count = count;
        req.type_ = dir.buf_type();
        req.memory = v4l2_memory_V4L2_MEMORY_MMAP;
        // SAFETY: REQBUFS takes a v4l2_requestbuffers.
        unsafe { sys::ioctl(fd, sys::VIDIOC_REQBUFS, &mut req)? };
        let mut q = MmapQueue {
            fd,
            dir,
            maps: Vec::new(),
            queued: Vec::new(),
            streaming: false,
        };
        if req.count < count {
            return Err(io::Error::new(
                io::ErrorKind::OutOfMemory,
                format!("the driver gave {} buffers, {count} wanted", req.count),
            ));
        }
        for index in 0..req.count {
            let mut b = q.desc(index);
            // SAFETY: QUERYBUF takes a v4l2_buffer.
            unsafe { sys::ioctl(fd, sys::VIDIOC_QUERYBUF, &mut b)? };
            let len = b.length as usize;
            // SAFETY: map the buffer at the offset the driver gave; checked for MAP_FAILED.
            let ptr = unsafe {
                v4l::v4l2::mmap(
                    std::ptr::null_mut(),
                    len,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_SHARED,
                    fd,
                    b.m.offset as libc::off_t,
                )?
            };
            q.maps.push(Mapping {
                ptr: ptr as *mut u8,
                len,
            });
            q.queued.push(false);
        }
        Ok(q)
    }

    fn desc(&self, index: u32) -> v4l2_buffer {
        let mut b: v4l2_buffer = sys::zeroed();
        b.index = index;
        b.type_ = self.dir.buf_type();
        b.memory = v4l2_memory_V4L2_MEMORY_MMAP;
        b
    }

    pub fn len(&self) -> usize {
        self.maps.len()
    }
    pub fn is_empty(&self) -> bool {
        self.maps.is_empty()
    }
    pub fn direction(&self) -> Direction {
        self.dir
    }
    pub fn is_streaming(&self) -> bool {
        self.streaming
    }
    /// Buffers currently owned by the driver.
    pub fn queued(&self) -> usize {
        self.queued.iter().filter(|&&q| q).count()
    }
    /// Whether buffer `index` is with the driver.
    pub fn is_queued(&self, index: usize) -> bool {
        self.queued[index]
    }

    /// Buffer `index`'s whole mapping. Only meaningful while the buffer is not queued.
    pub fn buffer(&self, index: usize) -> &[u8] {
        let m = &self.maps[index];
        // SAFETY: the mapping is valid and `len` long until drop.
        unsafe { std::slice::from_raw_parts(m.ptr, m.len) }
    }

    /// Buffer `index` for writing (output queues).
    pub fn buffer_mut(&mut self, index: usize) -> &mut [u8] {
        let m = &self.maps[index];
        // SAFETY: as above; &mut self makes the borrow exclusive.
        unsafe { std::slice::from_raw_parts_mut(m.ptr, m.len) }
    }

    /// Give buffer `index` to the driver. `bytesused` matters for output buffers (0 = the
    /// whole buffer), which are queued as progressive (V4L2_FIELD_NONE).
    pub fn queue(&mut self, index: usize, bytesused: usize) -> io::Result<()> {
        let mut b = self.desc(index as u32);
        if self.dir == Direction::Output {
            b.bytesused = bytesused as u32;
            b.field = v4l2_field_V4L2_FIELD_NONE;
        }
        // SAFETY: QBUF takes a v4l2_buffer.
        unsafe { sys::ioctl(self.fd, sys::VIDIOC_QBUF, &mut b)? };
        self.queued[index] = true;
        Ok(())
    }

    /// Queue every buffer not already queued (capture: before stream_on).
    pub fn queue_all(&mut self) -> io::Result<()> {
        for i in 0..self.len() {
            if !self.queued[i] {
                self.queue(i, 0)?;
            }
        }
        Ok(())
    }

    pub fn stream_on(&mut self) -> io::Result<()> {
        let mut t = self.dir.buf_type() as c_int;
        // SAFETY: STREAMON takes an int.
        unsafe { sys::ioctl(self.fd, sys::VIDIOC_STREAMON, &mut t)? };
        self.streaming = true;
        Ok(())
    }

    /// Stop streaming; the driver returns every buffer (all become dequeued).
    pub fn stream_off(&mut self) -> io::Result<()> {
        let mut t = self.dir.buf_type() as c_int;
        self.streaming = false;
        self.queued.iter_mut().for_each(|q| *q = false);
        // SAFETY: STREAMOFF takes an int.
        unsafe { sys::ioctl(self.fd, sys::VIDIOC_STREAMOFF, &mut t) }
    }

    /// Wait up to `timeout` for a buffer the driver is done with and take it back.
    ///
    /// Never blocks longer than `timeout` (the fd may be blocking or not: DQBUF is only issued
    /// after poll says a buffer is ready). A disconnected device makes poll return at once with
    /// POLLERR and DQBUF fail with ENODEV.
    pub fn dequeue(&mut self, timeout: Duration) -> Result<Dequeued, DequeueError> {
        let deadline = std::time::Instant::now() + timeout;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            let rev = sys::poll(self.fd, self.dir.poll_events(), left)?;
            if rev == 0 {
                return Err(DequeueError::Timeout);
            }
            let mut b = self.desc(0);
            // SAFETY: DQBUF takes a v4l2_buffer.
            match unsafe { sys::ioctl(self.fd, sys::VIDIOC_DQBUF, &mut b) } {
                Ok(()) => {
                    let index = b.index as usize;
                    if index >= self.len() {
                        return Err(DequeueError::Io(io::Error::new(
                            io::ErrorKind::InvalidData,
                            format!("driver returned buffer {index} of {}", self.len()),
                        )));
                    }
                    self.queued[index] = false;
                    return Ok(Dequeued {
                        index,
                        bytesused: (b.bytesused as usize).min(self.maps[index].len),
                        flags: b.flags,
                        sequence: b.sequence,
                        #[allow(clippy::unnecessary_cast)]
                        timestamp: (b.timestamp.tv_sec as i64, b.timestamp.tv_usec as i64),
                    });
                }
                // A spurious wake-up on a non-blocking fd: wait again for what is left.
                Err(e) if e.raw_os_error() == Some(libc::EAGAIN) => {
                    if std::time::Instant::now() >= deadline {
                        return Err(DequeueError::Timeout);
                    }
                    // poll returned POLLERR without data (e.g. not streaming): do not spin.
                    if rev & libc::POLLERR != 0 {
                        std::thread::sleep(Duration::from_millis(1));
                    }
                }
                Err(e) => return Err(DequeueError::Io(e)),
            }
        }
    }
}

impl Drop for MmapQueue {
    fn drop(&mut self) {
        if self.streaming {
            let _ = self.stream_off();
        }
        for m in self.maps.drain(..) {
            // SAFETY: each mapping was created by mmap with this length.
            let _ = unsafe { v4l::v4l2::munmap(m.ptr as *mut _, m.len) };
        }
        let mut req: v4l2_requestbuffers = sys::zeroed();
        req.type_ = self.dir.buf_type();
        req.memory = v4l2_memory_V4L2_MEMORY_MMAP;
        // SAFETY: REQBUFS with count 0 frees the buffers; errors (device gone) are ignored.
        let _ = unsafe { sys::ioctl(self.fd, sys::VIDIOC_REQBUFS, &mut req) };
    }
}

/// Where a frame's timestamp came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimestampSource {
    /// The driver's buffer timestamp, on CLOCK_MONOTONIC (V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC).
    Driver,
    /// The driver's timestamp is not on the monotonic clock (TIMESTAMP_COPY: copied from an
    /// output buffer; TIMESTAMP_UNKNOWN) or is zero: the dequeue time was used instead, which
    /// is later than the capture by the driver's latency.
    Dequeue,
}

/// The frame time of a dequeued buffer on the monotonic clock, and where it came from.
pub fn buffer_timestamp(
    flags: u32,
    tv: (i64, i64),
    dequeued_at: Timestamp,
) -> (Timestamp, TimestampSource) {
    let monotonic = flags & V4L2_BUF_FLAG_TIMESTAMP_MASK == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    if monotonic && (tv.0 > 0 || tv.1 > 0) {
        (
            Timestamp::from_timespec(tv.0, tv.1 * 1000),
            TimestampSource::Driver,
        )
    } else {
        (dequeued_at, TimestampSource::Dequeue)
    }
}

/// Widens the driver's 32-bit sequence numbers and counts the frames missing between them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SeqTracker {
    last: Option<u64>,
    /// Frames skipped by the driver (sum of the gaps).
    pub dropped: u64,
    /// Times the sequence went backwards or repeated (a driver restart); not counted as drops.
    pub resets: u64,
}

impl SeqTracker {
    /// The 64-bit sequence number of a buffer carrying `raw`, and the frames dropped just before it.
    pub fn next(&mut self, raw: u32) -> (u64, u64) {
        let Some(last) = self.last else {
            self.last = Some(raw as u64);
            return (raw as u64, 0);
        };
        // The candidate in last's 2^32 epoch, or the next one when raw wrapped.
        let epoch = last & !0xffff_ffff;
        let mut s = epoch | raw as u64;
        if s <= last && last - s > (1 << 31) {
            s += 1 << 32;
        }
        let gap = if s > last {
            s - last - 1
        } else {
            self.resets += 1;
            0
        };
        self.dropped += gap;
        self.last = Some(s);
        (s, gap)
    }

    pub fn last(&self) -> Option<u64> {
        self.last
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seq_counts_gaps() {
        let mut t = SeqTracker::default();
        assert_eq!(t.next(5), (5, 0));
        assert_eq!(t.next(6), (6, 0));
        assert_eq!(t.next(9), (9, 2));
        assert_eq!(t.next(10), (10, 0));
        assert_eq!(t.dropped, 2);
        assert_eq!(t.resets, 0);
    }

    #[test]
    fn seq_widens_across_wrap() {
        let mut t = SeqTracker::default();
        t.next(u32::MAX - 1);
        assert_eq!(t.next(u32::MAX), (u32::MAX as u64, 0));
        assert_eq!(t.next(0), (1 << 32, 0));
        assert_eq!(t.next(2), ((1 << 32) + 2, 1));
        assert_eq!(t.dropped, 1);
    }

    #[test]
    fn seq_backwards_is_a_reset_not_a_drop() {
        let mut t = SeqTracker::default();
        t.next(100);
        assert_eq!(t.next(100), (100, 0));
        assert_eq!(t.next(50), (50, 0));
        assert_eq!(t.resets, 2);
        assert_eq!(t.dropped, 0);
        assert_eq!(t.next(51), (51, 0));
    }

    #[test]
    fn timestamps_monotonic_or_dequeue_time() {
        let now = Timestamp { nanos: 99 };
        let (ts, src) = buffer_timestamp(V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC, (12, 345_678), now);
        assert_eq!(ts.nanos, 12_345_678_000);
        assert_eq!(src, TimestampSource::Driver);
        // Other flags do not disturb the timestamp type.
        let flags = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC | V4L2_BUF_FLAG_DONE | 0x10000;
        assert_eq!(
            buffer_timestamp(flags, (1, 0), now).1,
            TimestampSource::Driver
        );
        assert_eq!(
            buffer_timestamp(V4L2_BUF_FLAG_TIMESTAMP_COPY, (12, 0), now),
            (now, TimestampSource::Dequeue)
        );
        assert_eq!(
            buffer_timestamp(V4L2_BUF_FLAG_TIMESTAMP_UNKNOWN, (12, 0), now),
            (now, TimestampSource::Dequeue)
        );
        assert_eq!(
            buffer_timestamp(V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC, (0, 0), now),
            (now, TimestampSource::Dequeue)
        );
    }
}
