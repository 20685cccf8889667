//! Inputs, outputs and DV timings (HDMI-style sources), which the `v4l` crate does not cover.
//!
//! Capture from an HDMI input (a grabber, or vivid's loopback) needs the input selected and the
//! same DV timings as the source before the format is set.

use crate::sys::{self, bindings::*};
use std::io;
use std::os::raw::c_int;

/// VIDIOC_S_INPUT.
pub fn set_input(fd: c_int, index: u32) -> io::Result<()> {
    let mut i = index as c_int;
    // SAFETY: S_INPUT takes an int.
    unsafe { sys::ioctl(fd, sys::VIDIOC_S_INPUT, &mut i) }
}

/// VIDIOC_S_OUTPUT.
pub fn set_output(fd: c_int, index: u32) -> io::Result<()> {
    let mut i = index as c_int;
    // SAFETY: S_OUTPUT takes an int.
    unsafe { sys::ioctl(fd, sys::VIDIOC_S_OUTPUT, &mut i) }
}

/// One DV timing (BT.656/1120 kind), with the raw record to hand back to S_DV_TIMINGS.
#[derive(Clone, Copy)]
pub struct DvTimings {
    pub raw: v4l2_dv_timings,
}

impl DvTimings {
    fn bt(&self) -> v4l2_bt_timings {
        // SAFETY: the union's bt member is the one V4L2 defines for type 0 (BT.656/1120), the
        // only type there is; reading a packed struct by value is fine.
        unsafe { self.raw.__bindgen_anon_1.bt }
    }
    pub fn width(&self) -> u32 {
        self.bt().width
    }
    pub fn height(&self) -> u32 {
        self.bt().height
    }
    pub fn interlaced(&self) -> bool {
        self.bt().interlaced != 0
    }
    pub fn pixelclock(&self) -> u64 {
        self.bt().pixelclock
    }
    /// Frames per second from the pixel clock and the total frame size.
    pub fn fps(&self) -> f64 {
        let b = self.bt();
        let hs = (b.width + b.hfrontporch + b.hsync + b.hbackporch) as f64;
        let mut vs = (b.height + b.vfrontporch + b.vsync + b.vbackporch) as f64;
        if b.interlaced != 0 {
            vs += (b.il_vfrontporch + b.il_vsync + b.il_vbackporch) as f64;
        }
        if hs * vs == 0.0 {
            0.0
        } else {
            b.pixelclock as f64 / (hs * vs)
        }
    }
}

impl std::fmt::Debug for DvTimings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}x{}{}{:.2} ({} Hz pixel clock)",
            self.width(),
            self.height(),
            if self.interlaced() { "i" } else { "p" },
            self.fps(),
            self.pixelclock()
        )
    }
}

/// Every DV timing the current input or output supports (VIDIOC_ENUM_DV_TIMINGS).
pub fn enum_dv_timings(fd: c_int) -> io::Result<Vec<DvTimings>> {
    let mut out = Vec::new();
    for index in 0.. {
        let mut e: v4l2_enum_dv_timings = sys::zeroed();
        e.index = index;
        // SAFETY: ENUM_DV_TIMINGS takes a v4l2_enum_dv_timings.
        match unsafe { sys::ioctl(fd, sys::VIDIOC_ENUM_DV_TIMINGS, &mut e) } {
            Ok(()) => out.push(DvTimings { raw: e.timings }),
            Err(err) if err.raw_os_error() == Some(libc::EINVAL) => break,
            Err(err) => return Err(err),
        }
    }
    Ok(out)
}

/// The first progressive timing of `width` x `height`, with the rate nearest `fps` if given.
pub fn find_dv_timings(
    fd: c_int,
    width: u32,
    height: u32,
    fps: Option<f64>,
) -> io::Result<Option<DvTimings>> {
    let mut all: Vec<DvTimings> = enum_dv_timings(fd)?
        .into_iter()
        .filter(|t| t.width() == width && t.height() == height && !t.interlaced())
        .collect();
    if let Some(f) = fps {
        all.sort_by(|a, b| (a.fps() - f).abs().total_cmp(&(b.fps() - f).abs()));
    }
    Ok(all.into_iter().next())
}

/// VIDIOC_S_DV_TIMINGS.
pub fn set_dv_timings(fd: c_int, t: &DvTimings) -> io::Result<()> {
    let mut raw = t.raw;
    // SAFETY: S_DV_TIMINGS takes a v4l2_dv_timings.
    unsafe { sys::ioctl(fd, sys::VIDIOC_S_DV_TIMINGS, &mut raw) }
}

/// VIDIOC_G_DV_TIMINGS.
pub fn dv_timings(fd: c_int) -> io::Result<DvTimings> {
    let mut raw: v4l2_dv_timings = sys::zeroed();
    // SAFETY: G_DV_TIMINGS takes a v4l2_dv_timings.
    unsafe { sys::ioctl(fd, sys::VIDIOC_G_DV_TIMINGS, &mut raw)? };
    Ok(DvTimings { raw })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fps_from_cea_timings() {
        // CEA-861 640x480p59.94: 25.175 MHz, 800 x 525 total.
        let mut raw: v4l2_dv_timings = sys::zeroed();
        let mut bt: v4l2_bt_timings = sys::zeroed();
        bt.width = 640;
        bt.height = 480;
        bt.pixelclock = 25_175_000;
        bt.hfrontporch = 16;
        bt.hsync = 96;
        bt.hbackporch = 48;
        bt.vfrontporch = 10;
        bt.vsync = 2;
        bt.vbackporch = 33;
        raw.__bindgen_anon_1.bt = bt;
        let t = DvTimings { raw };
        assert_eq!((t.width(), t.height(), t.interlaced()), (640, 480, false));
        assert!((t.fps() - 59.94).abs() < 0.01, "{}", t.fps());
        assert!(format!("{t:?}").starts_with("640x480p59.94"));
    }

    #[test]
    fn closed_fd_is_an_error() {
        assert!(enum_dv_timings(-1).is_err());
        assert!(set_input(-1, 0).is_err());
    }
}
