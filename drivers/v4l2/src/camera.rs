//! [`V4l2Camera`]: the [`Camera`] trait on a V4L2 capture node.

use crate::controls::{self, CameraControls};
use crate::discover::{self, Capabilities};
use crate::dv;
use crate::format::{Converter, SourceFormat};
use crate::stream::{
    buffer_timestamp, DequeueError, Direction, MmapQueue, SeqTracker, TimestampSource,
};
use footscan_hal::{Camera, CameraInfo, Channel, Frame, FramePool, HalError, HalResult, Timestamp};
use std::io;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use v4l::video::Capture;

/// What to open and how to set it up.
#[derive(Clone, Debug, PartialEq)]
pub struct V4l2Config {
    pub path: PathBuf,
    pub width: u32,
    pub height: u32,
    /// Formats to accept, in order of preference; empty = [`SourceFormat::preference`] of
    /// `channel`.
    pub formats: Vec<SourceFormat>,
    /// The grey channel colour formats are converted to (once per frame, in the driver); None:
    /// grey formats, and the luma of YUYV and MJPG.
    pub channel: Option<Channel>,
    /// Frame rate to ask for (VIDIOC_S_PARM); None keeps the device's.
    pub fps: Option<f64>,
    /// Driver buffers for mmap streaming, at least 4.
    pub buffers: u32,
    /// Manual exposure to set at open, microseconds.
    pub exposure_us: Option<u32>,
    /// Gain to set at open, device units.
    pub gain: Option<f64>,
    /// Input to select first (VIDIOC_S_INPUT), e.g. an HDMI input.
    pub input: Option<u32>,
    /// Set the input's DV timings to the first progressive `width` x `height` timing (nearest
    /// `fps`) before the format: needed by HDMI inputs.
    pub dv_timings: bool,
}

impl Default for V4l2Config {
    fn default() -> Self {
        V4l2Config {
            path: PathBuf::from("/dev/video0"),
            width: 1280,
            height: 1024,
            formats: Vec::new(),
            channel: None,
            fps: None,
            buffers: 4,
            exposure_us: None,
            gain: None,
            input: None,
            dv_timings: false,
        }
    }
}

/// Counters of one camera since it was opened.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct StreamStats {
    /// Frames handed out.
    pub frames: u64,
    /// Frames the driver skipped (gaps in the sequence numbers).
    pub dropped: u64,
    /// Buffers the driver flagged V4L2_BUF_FLAG_ERROR (re-queued, not handed out).
    pub corrupted: u64,
    /// Times the sequence went backwards (a driver restart).
    pub seq_resets: u64,
    /// Frames stamped by the driver on CLOCK_MONOTONIC.
    pub driver_timestamps: u64,
    /// Frames stamped at dequeue time (the driver's stamp was not monotonic).
    pub dequeue_timestamps: u64,
    /// Frames whose timestamp was earlier than the previous frame's.
    pub timestamps_backwards: u64,
}

/// A V4L2 capture device streaming gray frames through mmap buffers.
pub struct V4l2Camera {
    // Declared before `dev`: the buffers are released before the fd closes.
    queue: Option<MmapQueue>,
    dev: v4l::Device,
    name: String,
    caps: Capabilities,
    conv: Converter,
    fps: f64,
    buffers: u32,
    pool: FramePool,
    seq: SeqTracker,
    last_ts: Option<Timestamp>,
    controls: CameraControls,
    exposure_us: u32,
    gain: f64,
    stats: StreamStats,
}

/// Map an errno of request `what` on `device` to the HAL's error kinds.
pub fn io_error(device: &str, what: &str, e: io::Error) -> HalError {
    match e.raw_os_error() {
        // ENODEV: the node is unregistered (unplugged); ENXIO/ENOENT: no such device at open.
        Some(libc::ENODEV) | Some(libc::ENXIO) | Some(libc::ENOENT) => HalError::Disconnected {
            device: device.to_string(),
            reason: format!("{what}: {e}"),
        },
        // vb2 fails DQBUF with EIO once the driver marked the queue broken (uvcvideo does on
        // unplug, before the node goes away).
        Some(libc::EIO) if what == "VIDIOC_DQBUF" => HalError::Disconnected {
            device: device.to_string(),
            reason: format!("{what}: {e}"),
        },
        _ => HalError::Io {
            device: device.to_string(),
            source: io::Error::new(e.kind(), format!("{what}: {e}")),
        },
    }
}

/// The format to stream: the first of `wanted` (or of [`SourceFormat::preference`]) that the
/// device offers and that can give `channel`, with the fourcc the device spells it with. The
/// errors name the fourccs: a named format that cannot give the channel, or none offered (then
/// what the device has and which of it would do).
pub fn choose_format(
    offered: &[v4l::FourCC],
    wanted: &[SourceFormat],
    channel: Option<Channel>,
) -> Result<(SourceFormat, v4l::FourCC), String> {
    for f in wanted {
        f.check_channel(channel)?;
    }
    let prefs = if wanted.is_empty() {
        SourceFormat::preference(channel)
    } else {
        wanted.to_vec()
    };
    for f in &prefs {
        if let Some(&o) = offered
            .iter()
            .find(|&&o| SourceFormat::from_fourcc(o) == Some(*f))
        {
            return Ok((*f, o));
        }
    }
    let has: Vec<String> = offered.iter().map(|f| f.to_string()).collect();
    let usable: Vec<String> = offered
        .iter()
        .filter_map(|&o| SourceFormat::from_fourcc(o))
        .filter(|f| f.check_channel(channel).is_ok())
        .map(|f| f.to_string())
        .collect();
    let channel_s = channel.map_or("no channel (grey)".to_string(), |c| format!("channel {c}"));
    Err(format!(
        "none of the formats {} is offered for {channel_s} (the device has {}; footscan converts {}; of the device's, {})",
        prefs
            .iter()
            .map(|f| f.to_string())
            .collect::<Vec<_>>()
            .join(", "),
        if has.is_empty() { "none".to_string() } else { has.join(", ") },
        SourceFormat::names(),
        if usable.is_empty() {
            "none would do".to_string()
        } else {
            format!("{} would do", usable.join(", "))
        }
    ))
}

impl V4l2Camera {
    /// Open the node, negotiate format, size and rate, and apply exposure and gain.
    pub fn open(cfg: &V4l2Config) -> HalResult<Self> {
        let name = cfg.path.display().to_string();
        let invalid = |detail: String| HalError::InvalidArgument {
            device: name.clone(),
            detail,
        };
        if cfg.buffers < 4 {
            return Err(invalid(format!(
                "{} buffers: at least 4 are needed",
                cfg.buffers
            )));
        }
        let dev = v4l::Device::with_path(&cfg.path).map_err(|e| io_error(&name, "open", e))?;
        let fd = dev.handle().fd();
        let caps = discover::query_caps(fd).map_err(|e| io_error(&name, "VIDIOC_QUERYCAP", e))?;
        if !caps.is_capture() || !caps.can_stream() {
            return Err(invalid(format!(
                "{} ({}) is not a streaming video capture node (caps {:#x})",
                caps.card, caps.driver, caps.device_caps
            )));
        }
        if let Some(i) = cfg.input {
            dv::set_input(fd, i).map_err(|e| io_error(&name, "VIDIOC_S_INPUT", e))?;
        }
        if cfg.dv_timings {
            let t = dv::find_dv_timings(fd, cfg.width, cfg.height, cfg.fps)
                .map_err(|e| io_error(&name, "VIDIOC_ENUM_DV_TIMINGS", e))?
                .ok_or_else(|| {
                    invalid(format!(
                        "the input has no progressive {}x{} DV timing",
                        cfg.width, cfg.height
                    ))
                })?;
            dv::set_dv_timings(fd, &t).map_err(|e| io_error(&name, "VIDIOC_S_DV_TIMINGS", e))?;
        }

        // Format: the first preferred one the device offers that can give the channel.
        let offered: Vec<v4l::FourCC> = dev
            .enum_formats()
            .map_err(|e| io_error(&name, "VIDIOC_ENUM_FMT", e))?
            .into_iter()
            .map(|d| d.fourcc)
            .collect();
        let (source, fourcc) =
            choose_format(&offered, &cfg.formats, cfg.channel).map_err(invalid)?;
        let mut want = v4l::Format::new(cfg.width, cfg.height, fourcc);
        want.field_order = v4l::format::FieldOrder::Progressive;
        let got = dev
            .set_format(&want)
            .map_err(|e| io_error(&name, "VIDIOC_S_FMT", e))?;
        if got.fourcc != fourcc || got.width != cfg.width || got.height != cfg.height {
            return Err(invalid(format!(
                "asked for {}x{} {}, the device gave {}x{} {}",
                cfg.width, cfg.height, fourcc, got.width, got.height, got.fourcc
            )));
        }
        let conv = Converter::new(source, got.width, got.height, got.stride as usize)
            .with_channel(cfg.channel)
            .map_err(|e| invalid(e.to_string()))?;

        // Rate: asked for where the device takes it, otherwise what it reports.
        if let Some(fps) = cfg.fps {
            if !(fps > 0.0 && fps.is_finite()) {
                return Err(invalid(format!("frame rate {fps}")));
            }
            let p = v4l::video::capture::Parameters::new(v4l::Fraction::new(
                1000,
                (fps * 1000.0).round() as u32,
            ));
            // Devices without V4L2_CAP_TIMEPERFRAME (HDMI inputs) refuse or ignore it.
            let _ = dev.set_params(&p);
        }
        let mut actual_fps = dev
            .params()
            .ok()
            .filter(|p| p.interval.numerator > 0)
            .map(|p| p.interval.denominator as f64 / p.interval.numerator as f64)
            .unwrap_or(0.0);
        if actual_fps == 0.0 && cfg.dv_timings {
            actual_fps = dv::dv_timings(fd).map(|t| t.fps()).unwrap_or(0.0);
        }
        if let Some(fps) = cfg.fps {
            let timeperframe = dev
                .params()
                .map(|p| {
                    p.capabilities
                        .contains(v4l::parameters::Capabilities::TIME_PER_FRAME)
                })
                .unwrap_or(false);
            if timeperframe && (actual_fps - fps).abs() > 0.01 * fps {
                return Err(invalid(format!(
                    "asked for {fps} fps, the device runs at {actual_fps:.3} fps"
                )));
            }
        }

        let controls = CameraControls::discover(fd).map_err(|e| io_error(&name, "controls", e))?;
        let mut cam = V4l2Camera {
            queue: None,
            pool: FramePool::new(
                cfg.width,
                cfg.height,
                source.pixel_format(),
                cfg.buffers as usize + 4,
            ),
            dev,
            name,
            caps,
            conv,
            fps: actual_fps,
            buffers: cfg.buffers,
            seq: SeqTracker::default(),
            last_ts: None,
            controls,
            exposure_us: 0,
            gain: 0.0,
            stats: StreamStats::default(),
        };
        cam.read_back_controls();
        if let Some(us) = cfg.exposure_us {
            cam.set_exposure_us(us)?;
        }
        if let Some(g) = cfg.gain {
            cam.set_gain(g)?;
        }
        Ok(cam)
    }

    fn read_back_controls(&mut self) {
        let fd = self.fd();
        if let Some(e) = &self.controls.exposure {
            let id = match e {
                controls::ExposureControl::Absolute(c) | controls::ExposureControl::Plain(c) => {
                    c.id
                }
            };
            if let Ok(v) = controls::get(fd, id) {
                self.exposure_us = e.to_us(v);
            }
        }
        if let Some(g) = &self.controls.gain {
            if let Ok(v) = controls::get(fd, g.id) {
                self.gain = v as f64;
            }
        }
    }

    /// The open file descriptor (for raw ioctls, e.g. device-specific controls).
    pub fn fd(&self) -> std::os::raw::c_int {
        self.dev.handle().fd()
    }
    /// The underlying `v4l` device.
    pub fn device(&self) -> &v4l::Device {
        &self.dev
    }
    pub fn capabilities(&self) -> &Capabilities {
        &self.caps
    }
    /// The negotiated device format and its conversion.
    pub fn converter(&self) -> &Converter {
        &self.conv
    }
    pub fn controls(&self) -> &CameraControls {
        &self.controls
    }
    pub fn stats(&self) -> StreamStats {
        self.stats
    }
    pub fn is_streaming(&self) -> bool {
        self.queue.is_some()
    }

    /// Set any integer, boolean or menu control; returns the value the driver kept.
    pub fn set_control(&mut self, id: u32, value: i32) -> HalResult<i32> {
        controls::set(self.fd(), id, value).map_err(|e| io_error(&self.name, "VIDIOC_S_CTRL", e))
    }
    pub fn control(&self, id: u32) -> HalResult<i32> {
        controls::get(self.fd(), id).map_err(|e| io_error(&self.name, "VIDIOC_G_CTRL", e))
    }

    fn timeout(&self, after: Duration) -> HalError {
        HalError::Timeout {
            device: self.name.clone(),
            what: "a frame (stream stalled)".into(),
            after,
        }
    }
}

impl Camera for V4l2Camera {
    fn info(&self) -> CameraInfo {
        CameraInfo {
            name: self.name.clone(),
            width: self.conv.width,
            height: self.conv.height,
            format: self.conv.format.pixel_format(),
            fps: self.fps,
        }
    }

    /// Allocate and map the buffers, queue them all and turn streaming on. Sequence numbers
    /// start again from the driver's (V4L2 resets them at STREAMON).
    fn start(&mut self) -> HalResult<()> {
        if self.queue.is_some() {
            return Ok(());
        }
        let name = self.name.clone();
        let mut q = MmapQueue::new(self.fd(), Direction::Capture, self.buffers)
            .map_err(|e| io_error(&name, "VIDIOC_REQBUFS", e))?;
        q.queue_all()
            .map_err(|e| io_error(&name, "VIDIOC_QBUF", e))?;
        q.stream_on()
            .map_err(|e| io_error(&name, "VIDIOC_STREAMON", e))?;
        self.queue = Some(q);
        self.seq = SeqTracker::default();
        self.last_ts = None;
        Ok(())
    }

    /// Turn streaming off and release the buffers. A device that is gone is not an error here.
    fn stop(&mut self) -> HalResult<()> {
        if let Some(mut q) = self.queue.take() {
            match q.stream_off() {
                Ok(()) => {}
                Err(e) if e.raw_os_error() == Some(libc::ENODEV) => {}
                Err(e) => return Err(io_error(&self.name, "VIDIOC_STREAMOFF", e)),
            }
        }
        Ok(())
    }

    /// The next frame, waiting at most `timeout`: [`HalError::Timeout`] when the stream stalls,
    /// [`HalError::Disconnected`] when the device is gone, [`HalError::BadData`] when a buffer
    /// cannot be converted (the buffer is re-queued; the stream goes on).
    fn next_frame(&mut self, timeout: Duration) -> HalResult<Frame> {
        let deadline = Instant::now() + timeout;
        loop {
            let name = &self.name;
            let Some(q) = self.queue.as_mut() else {
                return Err(HalError::NotStreaming {
                    device: name.clone(),
                });
            };
            let left = deadline.saturating_duration_since(Instant::now());
            let d = match q.dequeue(left) {
                Ok(d) => d,
                Err(DequeueError::Timeout) => return Err(self.timeout(timeout)),
                Err(DequeueError::Io(e)) => return Err(io_error(name, "VIDIOC_DQBUF", e)),
            };
            let now = Timestamp::now();
            if d.is_error() {
                self.stats.corrupted += 1;
                q.queue(d.index, 0)
                    .map_err(|e| io_error(name, "VIDIOC_QBUF", e))?;
                continue;
            }
            let resets = self.seq.resets;
            let (seq, gap) = self.seq.next(d.sequence);
            let (ts, src) = buffer_timestamp(d.flags, d.timestamp, now);
            let mut frame = self.pool.take(seq, ts);
            let used = if d.bytesused == 0 {
                q.buffer(d.index).len()
            } else {
                d.bytesused
            };
            let converted = self
                .conv
                .convert(&q.buffer(d.index)[..used], &mut frame.pixels);
            q.queue(d.index, 0)
                .map_err(|e| io_error(name, "VIDIOC_QBUF", e))?;
            self.stats.dropped += gap;
            self.stats.seq_resets += self.seq.resets - resets;
            if let Err(e) = converted {
                return Err(HalError::BadData {
                    device: name.clone(),
                    detail: format!("frame {seq}: {e}"),
                });
            }
            match src {
                TimestampSource::Driver => self.stats.driver_timestamps += 1,
                TimestampSource::Dequeue => self.stats.dequeue_timestamps += 1,
            }
            if self.last_ts.is_some_and(|l| ts < l) {
                self.stats.timestamps_backwards += 1;
            }
            self.last_ts = Some(ts);
            self.stats.frames += 1;
            return Ok(frame);
        }
    }

    fn exposure_us(&self) -> u32 {
        self.exposure_us
    }

    fn set_exposure_us(&mut self, us: u32) -> HalResult<()> {
        let Some(e) = self.controls.exposure.clone() else {
            return Err(HalError::InvalidArgument {
                device: self.name.clone(),
                detail: "the device has no exposure control".into(),
            });
        };
        let (id, v) = match &e {
            controls::ExposureControl::Absolute(c) | controls::ExposureControl::Plain(c) => {
                (c.id, e.to_device(us))
            }
        };
        let kept = self.set_control(id, v)?;
        self.exposure_us = e.to_us(kept);
        Ok(())
    }

    fn gain(&self) -> f64 {
        self.gain
    }

    fn set_gain(&mut self, gain: f64) -> HalResult<()> {
        let Some(g) = self.controls.gain.clone() else {
            return Err(HalError::InvalidArgument {
                device: self.name.clone(),
                detail: "the device has no gain control".into(),
            });
        };
        if !gain.is_finite() {
            return Err(HalError::InvalidArgument {
                device: self.name.clone(),
                detail: format!("gain {gain}"),
            });
        }
        let kept = self.set_control(g.id, g.fit(gain.round() as i64))?;
        self.gain = kept as f64;
        Ok(())
    }
}

impl Drop for V4l2Camera {
    fn drop(&mut self) {
        // Buffers first (STREAMOFF, munmap, REQBUFS 0), then the fd closes with `dev`.
        self.queue.take();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errno_mapping() {
        let e = io_error(
            "cam",
            "VIDIOC_DQBUF",
            io::Error::from_raw_os_error(libc::ENODEV),
        );
        assert!(e.is_disconnect(), "{e}");
        let e = io_error(
            "cam",
            "VIDIOC_DQBUF",
            io::Error::from_raw_os_error(libc::EIO),
        );
        assert!(e.is_disconnect());
        let e = io_error(
            "cam",
            "VIDIOC_S_FMT",
            io::Error::from_raw_os_error(libc::EIO),
        );
        assert!(matches!(e, HalError::Io { .. }));
        let e = io_error(
            "cam",
            "VIDIOC_S_FMT",
            io::Error::from_raw_os_error(libc::EBUSY),
        );
        // The operation is the I/O error's own text, printed once as the cause.
        let cause = std::error::Error::source(&e)
            .expect("the I/O error")
            .to_string();
        assert!(cause.contains("VIDIOC_S_FMT"), "{e}: {cause}");
    }

    #[test]
    fn open_missing_device_is_disconnected() {
        let cfg = V4l2Config {
            path: "/dev/video-does-not-exist".into(),
            ..V4l2Config::default()
        };
        let e = V4l2Camera::open(&cfg).err().unwrap();
        assert!(e.is_disconnect(), "{e}");
    }

    #[test]
    fn too_few_buffers_rejected_before_opening() {
        let cfg = V4l2Config {
            buffers: 2,
            ..V4l2Config::default()
        };
        let e = V4l2Camera::open(&cfg).err().unwrap();
        assert!(matches!(e, HalError::InvalidArgument { .. }), "{e}");
    }

    #[test]
    fn a_regular_file_is_not_a_camera() {
        let cfg = V4l2Config {
            path: "/dev/null".into(),
            ..V4l2Config::default()
        };
        let e = V4l2Camera::open(&cfg).err().unwrap();
        // /dev/null answers VIDIOC_QUERYCAP with ENOTTY.
        assert!(matches!(e, HalError::Io { .. }), "{e}");
    }

    #[test]
    fn format_choice_follows_the_channel_and_names_what_would_do() {
        let f = |s: &[u8; 4]| v4l::FourCC::new(s);
        let offered = [f(b"YUYV"), f(b"MJPG"), f(b"BA81"), f(b"NV12")];
        // No channel: grey formats first, so YUYV's luma.
        assert_eq!(
            choose_format(&offered, &[], None).unwrap().0,
            SourceFormat::Yuyv
        );
        // A colour channel: Bayer (a sample per pixel) before YUYV's shared chroma.
        assert_eq!(
            choose_format(&offered, &[], Some(Channel::RedMinusOthers))
                .unwrap()
                .0,
            SourceFormat::BayerBggr
        );
        // Named colour-only format without a channel, grey format with a colour channel.
        let e = choose_format(&offered, &[SourceFormat::BayerBggr], None).unwrap_err();
        assert!(e.contains("BA81") && e.contains("channel"), "{e}");
        let e = choose_format(&offered, &[SourceFormat::Grey], Some(Channel::Green)).unwrap_err();
        assert!(e.contains("GREY") && e.contains("green"), "{e}");
        // Nothing usable offered: the device's formats and which of them would do.
        let e = choose_format(
            &[f(b"NV12"), f(b"YUYV")],
            &[SourceFormat::Rgb24],
            Some(Channel::Red),
        )
        .unwrap_err();
        assert!(
            e.contains("RGB3") && e.contains("NV12, YUYV") && e.contains("YUYV would do"),
            "{e}"
        );
        let e = choose_format(&[f(b"NV12")], &[], Some(Channel::Red)).unwrap_err();
        assert!(e.contains("none would do"), "{e}");
    }

    #[test]
    fn camera_is_send() {
        fn send<T: Send>() {}
        send::<V4l2Camera>();
    }
}
