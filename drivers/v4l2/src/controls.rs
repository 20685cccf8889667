//! Controls: manual exposure and gain, plus raw access to any integer, boolean or menu control.
//!
//! Exposure: `V4L2_CID_EXPOSURE_ABSOLUTE` (units of 100 us, camera class) when the device has
//! it, with `V4L2_CID_EXPOSURE_AUTO` set to manual; otherwise `V4L2_CID_EXPOSURE` (user class,
//! no unit defined by V4L2: taken as microseconds). Gain: `V4L2_CID_GAIN`, else
//! `V4L2_CID_ANALOGUE_GAIN`, in device units, with `V4L2_CID_AUTOGAIN` turned off.

use crate::sys::{self, bindings::*};
use std::io;
use std::os::raw::c_int;

/// One control as the driver describes it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ControlInfo {
    pub id: u32,
    pub name: String,
    pub minimum: i32,
    pub maximum: i32,
    pub step: i32,
    pub default: i32,
}

impl ControlInfo {
    /// `v` clamped to the range and rounded to the step.
    pub fn fit(&self, v: i64) -> i32 {
        let v = v.clamp(self.minimum as i64, self.maximum as i64);
        let step = self.step.max(1) as i64;
        let k = ((v - self.minimum as i64) as f64 / step as f64).round() as i64;
        (self.minimum as i64 + k * step).min(self.maximum as i64) as i32
    }
}

/// The control `id`, or None if the device has none (or it is disabled).
pub fn query(fd: c_int, id: u32) -> io::Result<Option<ControlInfo>> {
    let mut q: v4l2_queryctrl = sys::zeroed();
    q.id = id;
    // SAFETY: QUERYCTRL takes a v4l2_queryctrl.
    match unsafe { sys::ioctl(fd, sys::VIDIOC_QUERYCTRL, &mut q) } {
        Ok(()) if q.flags & V4L2_CTRL_FLAG_DISABLED == 0 => Ok(Some(ControlInfo {
            id: q.id,
            name: sys::cstr(&q.name),
            minimum: q.minimum,
            maximum: q.maximum,
            step: q.step,
            default: q.default_value,
        })),
        Ok(()) => Ok(None),
        Err(e) if e.raw_os_error() == Some(libc::EINVAL) => Ok(None),
        Err(e) => Err(e),
    }
}

/// Current value of an integer, boolean or menu control.
pub fn get(fd: c_int, id: u32) -> io::Result<i32> {
    let mut c = v4l2_control { id, value: 0 };
    // SAFETY: G_CTRL takes a v4l2_control.
    unsafe { sys::ioctl(fd, sys::VIDIOC_G_CTRL, &mut c)? };
    Ok(c.value)
}

/// Set an integer, boolean or menu control (buttons take any value); returns what the driver kept.
pub fn set(fd: c_int, id: u32, value: i32) -> io::Result<i32> {
    let mut c = v4l2_control { id, value };
    // SAFETY: S_CTRL takes a v4l2_control.
    unsafe { sys::ioctl(fd, sys::VIDIOC_S_CTRL, &mut c)? };
    Ok(c.value)
}

/// How exposure is set on this device.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ExposureControl {
    /// V4L2_CID_EXPOSURE_ABSOLUTE, 100 us units.
    Absolute(ControlInfo),
    /// V4L2_CID_EXPOSURE, taken as microseconds.
    Plain(ControlInfo),
}

impl ExposureControl {
    fn info(&self) -> &ControlInfo {
        match self {
            ExposureControl::Absolute(c) | ExposureControl::Plain(c) => c,
        }
    }
    fn us_per_unit(&self) -> i64 {
        match self {
            ExposureControl::Absolute(_) => 100,
            ExposureControl::Plain(_) => 1,
        }
    }
    /// Device value for `us`, clamped to the control's range.
    pub fn to_device(&self, us: u32) -> i32 {
        let u = self.us_per_unit();
        self.info().fit((us as i64 + u / 2) / u)
    }
    pub fn to_us(&self, v: i32) -> u32 {
        (v as i64 * self.us_per_unit()).clamp(0, u32::MAX as i64) as u32
    }
    /// The settable range in microseconds.
    pub fn range_us(&self) -> (u32, u32) {
        let c = self.info();
        (self.to_us(c.minimum), self.to_us(c.maximum))
    }
}

/// The exposure and gain controls a device has.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CameraControls {
    pub exposure: Option<ExposureControl>,
    pub gain: Option<ControlInfo>,
}

impl CameraControls {
    /// Look the controls up and switch auto exposure and auto gain off where they exist.
    pub fn discover(fd: c_int) -> io::Result<Self> {
        let exposure = if let Some(c) = query(fd, V4L2_CID_EXPOSURE_ABSOLUTE)? {
            if query(fd, V4L2_CID_EXPOSURE_AUTO)?.is_some() {
                set(
                    fd,
                    V4L2_CID_EXPOSURE_AUTO,
                    v4l2_exposure_auto_type_V4L2_EXPOSURE_MANUAL as i32,
                )?;
            }
            Some(ExposureControl::Absolute(c))
        } else {
            query(fd, V4L2_CID_EXPOSURE)?.map(ExposureControl::Plain)
        };
        if query(fd, V4L2_CID_AUTOGAIN)?.is_some() {
            set(fd, V4L2_CID_AUTOGAIN, 0)?;
        }
        let gain = match query(fd, V4L2_CID_GAIN)? {
            Some(g) => Some(g),
            None => query(fd, V4L2_CID_ANALOGUE_GAIN)?,
        };
        Ok(CameraControls { exposure, gain })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn info(min: i32, max: i32, step: i32) -> ControlInfo {
        ControlInfo {
            id: 1,
            name: "x".into(),
            minimum: min,
            maximum: max,
            step,
            default: min,
        }
    }

    #[test]
    fn fit_clamps_and_rounds_to_step() {
        let c = info(3, 2047, 4);
        assert_eq!(c.fit(0), 3);
        assert_eq!(c.fit(5), 7);
        assert_eq!(c.fit(4), 3);
        assert_eq!(c.fit(100_000), 2047);
        assert_eq!(info(0, 255, 0).fit(17), 17);
    }

    #[test]
    fn exposure_units() {
        let abs = ExposureControl::Absolute(info(1, 5000, 1));
        assert_eq!(abs.to_device(2000), 20);
        assert_eq!(abs.to_device(2049), 20);
        assert_eq!(abs.to_device(2050), 21);
        assert_eq!(abs.to_device(10), 1);
        assert_eq!(abs.to_us(20), 2000);
        assert_eq!(abs.range_us(), (100, 500_000));
        let plain = ExposureControl::Plain(info(10, 30000, 1));
        assert_eq!(plain.to_device(2000), 2000);
        assert_eq!(plain.to_device(1), 10);
    }

    #[test]
    fn controls_of_a_closed_fd_are_an_error() {
        assert!(query(-1, V4L2_CID_GAIN).is_err());
        assert!(get(-1, V4L2_CID_GAIN).is_err());
    }
}
