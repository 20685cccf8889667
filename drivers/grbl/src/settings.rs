//! `$$` settings and `$I` build info, typed.

use footscan_hal::SliderSettings;

/// The `$N=value` settings of a GRBL 1.1 controller, with named accessors for the ones a
/// scanner checks (the raw map stays available for the rest).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GrblSettings {
    pub raw: SliderSettings,
}

impl GrblSettings {
    pub fn get(&self, n: u32) -> Option<f64> {
        self.raw.get(&n).copied()
    }
    fn flag(&self, n: u32) -> bool {
        self.get(n).is_some_and(|v| v != 0.0)
    }
    fn axis(&self, base: u32, axis: usize) -> Option<f64> {
        (axis < 3).then(|| self.get(base + axis as u32)).flatten()
    }
    /// `$0` step pulse, microseconds.
    pub fn step_pulse_us(&self) -> Option<f64> {
        self.get(0)
    }
    /// `$10` status report mask (bit 0: MPos instead of WPos, bit 1: `Bf:` buffer field).
    pub fn status_report_mask(&self) -> Option<u32> {
        self.get(10).map(|v| v as u32)
    }
    /// `$13` report inches.
    pub fn report_inches(&self) -> bool {
        self.flag(13)
    }
    /// `$20` soft limits.
    pub fn soft_limits(&self) -> bool {
        self.flag(20)
    }
    /// `$21` hard limits.
    pub fn hard_limits(&self) -> bool {
        self.flag(21)
    }
    /// `$22` homing cycle enabled (the controller powers up alarm-locked until `$H`).
    pub fn homing_enabled(&self) -> bool {
        self.flag(22)
    }
    /// `$23` homing direction invert mask.
    pub fn homing_dir_mask(&self) -> Option<u32> {
        self.get(23).map(|v| v as u32)
    }
    /// `$24` homing locate feed, mm/min.
    pub fn homing_feed(&self) -> Option<f64> {
        self.get(24)
    }
    /// `$25` homing search seek rate, mm/min.
    pub fn homing_seek(&self) -> Option<f64> {
        self.get(25)
    }
    /// `$27` homing pull-off, mm.
    pub fn homing_pulloff_mm(&self) -> Option<f64> {
        self.get(27)
    }
    /// `$32` laser mode: a power (`S`) change applies without stopping the motion, and the
    /// spindle output is lit only in a G1/G2/G3 motion mode.
    pub fn laser_mode(&self) -> bool {
        self.flag(32)
    }
    /// `$100 + axis` steps per mm (axis 0 = X).
    pub fn steps_per_mm(&self, axis: usize) -> Option<f64> {
        self.axis(100, axis)
    }
    /// `$110 + axis` maximum rate, mm/min: GRBL clamps any feed to it.
    pub fn max_rate(&self, axis: usize) -> Option<f64> {
        self.axis(110, axis)
    }
    /// `$120 + axis` acceleration, mm/s².
    pub fn acceleration(&self, axis: usize) -> Option<f64> {
        self.axis(120, axis)
    }
    /// `$130 + axis` maximum travel, mm (soft limits act over it).
    pub fn max_travel(&self, axis: usize) -> Option<f64> {
        self.axis(130, axis)
    }
}

/// `$I`: `[VER:1.1h.20190830:name]` and `[OPT:V,15,128]`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BuildInfo {
    /// e.g. `1.1h.20190830`.
    pub version: String,
    /// The user build string after the second colon (often empty).
    pub name: String,
    /// Option letters, e.g. `V` (variable spindle).
    pub options: String,
    pub planner_blocks: Option<u32>,
    pub rx_buffer: Option<u32>,
}

impl BuildInfo {
    /// From the feedback lines of `$I` (with or without brackets).
    pub fn parse<S: AsRef<str>>(lines: &[S]) -> Option<BuildInfo> {
        let mut info = BuildInfo::default();
        let mut seen = false;
        for l in lines {
            let l = l.as_ref().trim();
            let l = l
                .strip_prefix('[')
                .and_then(|l| l.strip_suffix(']'))
                .unwrap_or(l);
            if let Some(v) = l.strip_prefix("VER:") {
                let (ver, name) = v.split_once(':').unwrap_or((v, ""));
                info.version = ver.to_string();
                info.name = name.to_string();
                seen = true;
            } else if let Some(o) = l.strip_prefix("OPT:") {
                let mut f = o.split(',');
                info.options = f.next().unwrap_or("").to_string();
                info.planner_blocks = f.next().and_then(|v| v.trim().parse().ok());
                info.rx_buffer = f.next().and_then(|v| v.trim().parse().ok());
            }
        }
        seen.then_some(info)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn typed_settings_and_build_info() {
        let mut raw = SliderSettings::new();
        for (k, v) in [(10, 1.0), (20, 1.0), (22, 1.0), (110, 3000.0), (130, 330.0)] {
            raw.insert(k, v);
        }
        let s = GrblSettings { raw };
        assert!(s.soft_limits() && s.homing_enabled() && !s.hard_limits());
        assert_eq!(s.max_rate(0), Some(3000.0));
        assert_eq!(s.max_travel(0), Some(330.0));
        assert_eq!(s.max_rate(1), None);
        assert_eq!(s.max_rate(3), None, "three axes only");
        assert_eq!(s.status_report_mask(), Some(1));
        let b = BuildInfo::parse(&["[VER:1.1h.20190830:slider]", "[OPT:VL,15,128]"]).unwrap();
        assert_eq!(b.version, "1.1h.20190830");
        assert_eq!(b.name, "slider");
        assert_eq!(b.options, "VL");
        assert_eq!((b.planner_blocks, b.rx_buffer), (Some(15), Some(128)));
        assert_eq!(BuildInfo::parse(&["[OPT:V,15,128]"]), None);
    }
}
