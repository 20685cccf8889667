//! Device discovery: the `/dev/video*` nodes that capture video, what they are and what they offer.

use crate::format::SourceFormat;
use crate::sys::{self, bindings::*};
use std::io;
use std::os::raw::c_int;
use std::path::{Path, PathBuf};
use v4l::video::Capture;

/// What VIDIOC_QUERYCAP says about a node.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Capabilities {
    pub driver: String,
    pub card: String,
    pub bus: String,
    /// Capabilities of this node (V4L2_CAP_*), `device_caps` when the driver fills it.
    pub device_caps: u32,
}

impl Capabilities {
    pub fn is_capture(&self) -> bool {
        self.device_caps & V4L2_CAP_VIDEO_CAPTURE != 0
    }
    pub fn is_output(&self) -> bool {
        self.device_caps & V4L2_CAP_VIDEO_OUTPUT != 0
    }
    pub fn can_stream(&self) -> bool {
        self.device_caps & V4L2_CAP_STREAMING != 0
    }
}

/// VIDIOC_QUERYCAP on an open node.
pub fn query_caps(fd: c_int) -> io::Result<Capabilities> {
    let mut c: v4l2_capability = sys::zeroed();
    // SAFETY: QUERYCAP takes a v4l2_capability.
    unsafe { sys::ioctl(fd, sys::VIDIOC_QUERYCAP, &mut c)? };
    let device_caps = if c.capabilities & V4L2_CAP_DEVICE_CAPS != 0 {
        c.device_caps
    } else {
        c.capabilities
    };
    Ok(Capabilities {
        driver: sys::cstr(&c.driver),
        card: sys::cstr(&c.card),
        bus: sys::cstr(&c.bus_info),
        device_caps,
    })
}

/// One capture format with its discrete sizes and frame rates.
#[derive(Clone, Debug, PartialEq)]
pub struct FormatInfo {
    /// The fourcc as text (`GREY`, `YUYV`, ...).
    pub fourcc: String,
    pub description: String,
    /// The format the driver can convert, None for the others.
    pub source: Option<SourceFormat>,
    /// Discrete sizes (a stepwise range lists its minimum and maximum only), each with its
    /// discrete frame rates in frames per second.
    pub sizes: Vec<(u32, u32, Vec<f64>)>,
}

/// A capture node.
#[derive(Clone, Debug, PartialEq)]
pub struct DeviceInfo {
    pub path: PathBuf,
    pub caps: Capabilities,
    pub formats: Vec<FormatInfo>,
}

/// The formats, sizes and rates a capture device offers.
pub fn formats(dev: &v4l::Device) -> io::Result<Vec<FormatInfo>> {
    let mut out = Vec::new();
    for d in dev.enum_formats()? {
        let mut sizes = Vec::new();
        for fs in dev.enum_framesizes(d.fourcc).unwrap_or_default() {
            let list: Vec<(u32, u32)> = match fs.size {
                v4l::framesize::FrameSizeEnum::Discrete(s) => vec![(s.width, s.height)],
                v4l::framesize::FrameSizeEnum::Stepwise(s) => {
                    vec![(s.min_width, s.min_height), (s.max_width, s.max_height)]
                }
            };
            for (w, h) in list {
                let mut fps = Vec::new();
                for fi in dev.enum_frameintervals(d.fourcc, w, h).unwrap_or_default() {
                    if let v4l::frameinterval::FrameIntervalEnum::Discrete(f) = fi.interval {
                        if f.numerator > 0 {
                            fps.push(f.denominator as f64 / f.numerator as f64);
                        }
                    }
                }
                sizes.push((w, h, fps));
            }
        }
        out.push(FormatInfo {
            fourcc: String::from_utf8_lossy(&d.fourcc.repr)
                .trim_end()
                .to_string(),
            description: d.description.clone(),
            source: SourceFormat::from_fourcc(d.fourcc),
            sizes,
        });
    }
    Ok(out)
}

/// A fourcc as text: `GREY`, `Y16`, and `Y16-BE` for the big-endian variants (bit 31 set).
pub fn fourcc_name(f: v4l::FourCC) -> String {
    let mut r = f.repr;
    let be = r[3] & 0x80 != 0;
    r[3] &= 0x7f;
    let mut s: String = r
        .iter()
        .map(|&b| {
            if b.is_ascii_graphic() || b == b' ' {
                b as char
            } else {
                '?'
            }
        })
        .collect();
    s.truncate(s.trim_end().len());
    if be {
        s.push_str("-BE");
    }
    s
}

/// Describe one node (any kind; formats are listed for capture nodes only).
pub fn describe(path: &Path) -> io::Result<DeviceInfo> {
    let dev = v4l::Device::with_path(path)?;
    let caps = query_caps(dev.handle().fd())?;
    let formats = if caps.is_capture() {
        formats(&dev)?
    } else {
        Vec::new()
    };
    Ok(DeviceInfo {
        path: path.to_path_buf(),
        caps,
        formats,
    })
}

/// `/dev/video*` nodes in numeric order.
pub fn video_nodes() -> Vec<PathBuf> {
    let mut v: Vec<(u32, PathBuf)> = std::fs::read_dir("/dev")
        .into_iter()
        .flatten()
        .flatten()
        .filter_map(|e| {
            let name = e.file_name().into_string().ok()?;
            let n = name.strip_prefix("video")?.parse().ok()?;
            Some((n, e.path()))
        })
        .collect();
    v.sort();
    v.into_iter().map(|(_, p)| p).collect()
}

/// Every streaming capture node that can be opened (others are skipped silently).
pub fn list_cameras() -> Vec<DeviceInfo> {
    video_nodes()
        .iter()
        .filter_map(|p| describe(p).ok())
        .filter(|d| d.caps.is_capture() && d.caps.can_stream())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn listing_works_without_devices() {
        // CI machines have no cameras: the calls must succeed (possibly empty).
        let nodes = video_nodes();
        let cams = list_cameras();
        assert!(cams.len() <= nodes.len());
        for c in &cams {
            assert!(c.caps.is_capture());
        }
    }

    #[test]
    fn fourcc_names() {
        assert_eq!(fourcc_name(v4l::FourCC::new(b"GREY")), "GREY");
        assert_eq!(fourcc_name(v4l::FourCC::new(b"Y10 ")), "Y10");
        assert_eq!(
            fourcc_name(v4l::FourCC::new(&[b'Y', b'1', b'6', b' ' | 0x80])),
            "Y16-BE"
        );
        assert_eq!(
            fourcc_name(v4l::FourCC::new(&[b'A', 1, b'B', b'C'])),
            "A?BC"
        );
    }

    #[test]
    fn describing_a_missing_node_is_not_found() {
        let e = describe(Path::new("/dev/video-does-not-exist")).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::NotFound);
    }
}
