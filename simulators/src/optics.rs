//! The general optical model of docs/method.md section 2.3: camera pose, pinhole projection with
//! Brown-Conrady distortion, and the laser plane, all relative to the physical slider position.
//!
//! Conventions (the main crate implements the inverse independently; keep them exact):
//! - World: x along the slider travel, y across, z up; the glass top face is z = 0.
//! - Pixel (column c, row r): pixel c covers [c - 0.5, c + 0.5]; integers are pixel centres.
//! - Camera centre C = (X, 0, -D) where X is the PHYSICAL slider position.
//! - Camera rotation R = Rz(rz) * Ry(ry) * Rx(rx) maps camera coordinates to world; the untilted
//!   camera has camera axes = world axes (looks up +z, column grows with world x, row with y).
//! - Projection of P: p = R^T (P - C); xn = p.x/p.z, yn = p.y/p.z; r2 = xn^2 + yn^2;
//!   rad = 1 + k1 r2 + k2 r2^2; xd = xn rad + 2 p1 xn yn + p2 (r2 + 2 xn^2);
//!   yd = yn rad + p1 (r2 + 2 yn^2) + 2 p2 xn yn; c = cx + F xd; r = cy + F yd.
//! - Laser plane: x = X + L + tan(a) y + tan(b) z with a = `laser_tilt_deg[0]` (yaw),
//!   b = `laser_tilt_deg[1]` (pitch), in radians.
//!
//! [`Optics`] is the serde configuration record; [`Projector`] is the same model with the
//! rotation and tangents precomputed, for hot loops.

use serde::{Deserialize, Serialize};

/// Errors of simulator configuration and construction.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// A parameter is outside its valid range.
    #[error("invalid parameter `{key}` = {value}: expected {expected}")]
    InvalidParameter {
        key: String,
        value: String,
        expected: String,
    },
}

/// A target description's error is a parameter error of the scene it is in: same key, value
/// and expectation, same message.
impl From<footscan_targets::TargetError> for SimError {
    fn from(e: footscan_targets::TargetError) -> Self {
        match e {
            footscan_targets::TargetError::InvalidParameter {
                key,
                value,
                expected,
            } => SimError::InvalidParameter {
                key,
                value,
                expected,
            },
        }
    }
}

impl SimError {
    pub(crate) fn invalid(key: &str, value: impl std::fmt::Display, expected: &str) -> Self {
        SimError::InvalidParameter {
            key: key.to_string(),
            value: value.to_string(),
            expected: expected.to_string(),
        }
    }
}

/// Check `lo <= v <= hi` (and finite), naming the key in the error.
pub(crate) fn check_range(key: &str, v: f64, lo: f64, hi: f64) -> Result<(), SimError> {
    if v.is_finite() && v >= lo && v <= hi {
        Ok(())
    } else {
        Err(SimError::invalid(
            key,
            v,
            &format!("a number in [{lo}, {hi}]"),
        ))
    }
}

/// Optical configuration of the simulated scanner (docs/method.md section 2.3, defaults of the
/// default simulated scanner of section 2.4).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Optics {
    /// Image size in pixels.
    pub width: u32,
    pub height: u32,
    /// Focal length in pixels, F = f / eta.
    pub f_px: f64,
    /// Principal point (px).
    pub cx: f64,
    pub cy: f64,
    /// Camera centre distance below the glass top face (mm).
    pub d_mm: f64,
    /// Laser plane offset from the camera centre along x (mm).
    pub l_mm: f64,
    /// Brown-Conrady distortion on normalised coordinates.
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    /// Camera rotation [rx, ry, rz] in degrees, R = Rz * Ry * Rx.
    pub camera_tilt_deg: [f64; 3],
    /// Laser plane tilts [yaw a, pitch b] in degrees: x = X + L + tan(a) y + tan(b) z.
    pub laser_tilt_deg: [f64; 2],
    /// Physical head x = slider_scale * reported x. Applied by the slider emulator; stored here
    /// for the calibration record. The optics themselves always take the physical x.
    pub slider_scale: f64,
}

impl Default for Optics {
    fn default() -> Self {
        Optics {
            width: 1280,
            height: 1024,
            f_px: 2000.0,
            cx: 643.7,
            cy: 509.9,
            d_mm: 250.0,
            l_mm: 70.0,
            k1: -0.08,
            k2: 0.01,
            p1: 0.0,
            p2: 0.0,
            camera_tilt_deg: [0.0, 0.3, 0.0],
            laser_tilt_deg: [0.0, 0.2],
            slider_scale: 1.0,
        }
    }
}

impl Optics {
    /// The ideal model of docs/method.md section 2.1: no distortion, no tilts (same size, F,
    /// c, D, L).
    pub fn ideal(&self) -> Optics {
        Optics {
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            camera_tilt_deg: [0.0; 3],
            laser_tilt_deg: [0.0; 2],
            slider_scale: 1.0,
            ..self.clone()
        }
    }

    /// Check every parameter; the error names the key and its valid range.
    pub fn validate(&self) -> Result<(), SimError> {
        for (key, v) in [("width", self.width), ("height", self.height)] {
            if !(16..=16384).contains(&v) {
                return Err(SimError::invalid(key, v, "an integer in [16, 16384]"));
            }
        }
        check_range("f_px", self.f_px, 1.0, 1e6)?;
        check_range("cx", self.cx, 0.0, self.width as f64)?;
        check_range("cy", self.cy, 0.0, self.height as f64)?;
        check_range("d_mm", self.d_mm, 1.0, 1e5)?;
        check_range("l_mm", self.l_mm, -1e4, 1e4)?;
        if self.l_mm.abs() < 1e-3 {
            return Err(SimError::invalid(
                "l_mm",
                self.l_mm,
                "a nonzero baseline (|l_mm| >= 0.001)",
            ));
        }
        check_range("k1", self.k1, -1.0, 1.0)?;
        check_range("k2", self.k2, -1.0, 1.0)?;
        check_range("p1", self.p1, -0.1, 0.1)?;
        check_range("p2", self.p2, -0.1, 0.1)?;
        for (i, name) in [
            "camera_tilt_deg[0]",
            "camera_tilt_deg[1]",
            "camera_tilt_deg[2]",
        ]
        .iter()
        .enumerate()
        {
            check_range(name, self.camera_tilt_deg[i], -10.0, 10.0)?;
        }
        check_range("laser_tilt_deg[0]", self.laser_tilt_deg[0], -10.0, 10.0)?;
        check_range("laser_tilt_deg[1]", self.laser_tilt_deg[1], -10.0, 10.0)?;
        check_range("slider_scale", self.slider_scale, 0.5, 1.5)?;
        Ok(())
    }

    /// The model with its rotation and tangents precomputed.
    pub fn projector(&self) -> Projector {
        Projector::new(self)
    }

    /// Image of world point `p` with the head at physical `slider_x`: `[col, row]`, or None
    /// when the point is not in front of the camera.
    pub fn project(&self, slider_x: f64, p: [f64; 3]) -> Option<[f64; 2]> {
        self.projector().project(slider_x, p)
    }

    /// x of the laser plane at (y, z) with the head at physical `slider_x`.
    pub fn laser_x(&self, slider_x: f64, y: f64, z: f64) -> f64 {
        self.projector().laser_x(slider_x, y, z)
    }
}

/// [`Optics`] with R, tan(a) and tan(b) precomputed. Same conventions, same numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct Projector {
    /// Camera-to-world rotation, row-major: world = R * cam.
    pub r: [[f64; 3]; 3],
    pub f_px: f64,
    pub cx: f64,
    pub cy: f64,
    pub d_mm: f64,
    pub l_mm: f64,
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub tan_a: f64,
    pub tan_b: f64,
}

/// R = Rz(rz) * Ry(ry) * Rx(rx), angles in degrees: the camera tilt is given in the world's
/// one convention, shared with the calibration boards' poses.
pub use footscan_geom::rotation::rotation_zyx_deg;

impl Projector {
    pub fn new(o: &Optics) -> Self {
        Projector {
            r: rotation_zyx_deg(o.camera_tilt_deg),
            f_px: o.f_px,
            cx: o.cx,
            cy: o.cy,
            d_mm: o.d_mm,
            l_mm: o.l_mm,
            k1: o.k1,
            k2: o.k2,
            p1: o.p1,
            p2: o.p2,
            tan_a: o.laser_tilt_deg[0].to_radians().tan(),
            tan_b: o.laser_tilt_deg[1].to_radians().tan(),
        }
    }

    /// Camera centre in world coordinates.
    pub fn camera_centre(&self, slider_x: f64) -> [f64; 3] {
        [slider_x, 0.0, -self.d_mm]
    }

    /// `p` in camera coordinates: R^T (P - C).
    #[inline]
    pub fn to_camera(&self, slider_x: f64, p: [f64; 3]) -> [f64; 3] {
        let d = [p[0] - slider_x, p[1], p[2] + self.d_mm];
        let r = &self.r;
        [
            r[0][0] * d[0] + r[1][0] * d[1] + r[2][0] * d[2],
            r[0][1] * d[0] + r[1][1] * d[1] + r[2][1] * d[2],
            r[0][2] * d[0] + r[1][2] * d[1] + r[2][2] * d[2],
        ]
    }

    /// Distort normalised coordinates (Brown-Conrady).
    #[inline]
    pub fn distort(&self, xn: f64, yn: f64) -> [f64; 2] {
        let r2 = xn * xn + yn * yn;
        let rad = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
        let xd = xn * rad + 2.0 * self.p1 * xn * yn + self.p2 * (r2 + 2.0 * xn * xn);
        let yd = yn * rad + self.p1 * (r2 + 2.0 * yn * yn) + 2.0 * self.p2 * xn * yn;
        [xd, yd]
    }

    /// Image `[col, row]` of world point `p`, None when not in front of the camera.
    #[inline]
    pub fn project(&self, slider_x: f64, p: [f64; 3]) -> Option<[f64; 2]> {
        let q = self.to_camera(slider_x, p);
        if q[2] <= 1e-9 {
            return None;
        }
        let [xd, yd] = self.distort(q[0] / q[2], q[1] / q[2]);
        Some([self.cx + self.f_px * xd, self.cy + self.f_px * yd])
    }

    /// x of the laser plane at (y, z).
    #[inline]
    pub fn laser_x(&self, slider_x: f64, y: f64, z: f64) -> f64 {
        slider_x + self.l_mm + self.tan_a * y + self.tan_b * z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_give_the_spec_glass_column_and_sensitivity() {
        let o = Optics::default();
        o.validate().unwrap();
        let p = o.projector();
        let x = 100.0;
        let glass = p.project(x, [p.laser_x(x, 0.0, 0.0), 0.0, 0.0]).unwrap();
        assert!(
            (glass[0] - 1200.0).abs() < 15.0,
            "glass column {}",
            glass[0]
        );
        // dh/ds at h = 0 from a 1 mm step.
        let one = p.project(x, [p.laser_x(x, 0.0, 1.0), 0.0, 1.0]).unwrap();
        let dhds = 1.0 / (glass[0] - one[0]);
        assert!((dhds - 0.45).abs() < 0.03, "dh/ds {dhds}");
        // Rows see about |y| < 62 mm at h = 0.
        let edge = p.project(x, [p.laser_x(x, 62.0, 0.0), 62.0, 0.0]).unwrap();
        assert!(edge[1] > 990.0 && edge[1] < 1060.0, "row {}", edge[1]);
    }

    #[test]
    fn ideal_model_matches_the_closed_form() {
        let o = Optics::default().ideal();
        for h in [0.0, 7.5, 30.0] {
            for y in [-40.0, 0.0, 25.0] {
                let x = 37.0;
                let c = o.project(x, [o.laser_x(x, y, h), y, h]).unwrap();
                let col = o.cx + o.f_px * o.l_mm / (o.d_mm + h);
                let row = o.cy + o.f_px * y / (o.d_mm + h);
                assert!((c[0] - col).abs() < 1e-9 && (c[1] - row).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn rotation_is_zyx_and_orthonormal() {
        let r = rotation_zyx_deg([1.0, 2.0, 3.0]);
        for i in 0..3 {
            for j in 0..3 {
                let d: f64 = (0..3).map(|k| r[k][i] * r[k][j]).sum();
                assert!((d - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
            }
        }
        // A pure ry tilt turns the optical axis (camera z) toward +x: R * (0,0,1) = (sin, 0, cos).
        let r = rotation_zyx_deg([0.0, 10.0, 0.0]);
        assert!((r[0][2] - 10f64.to_radians().sin()).abs() < 1e-12);
        assert!(Optics::default().project(0.0, [0.0, 0.0, -300.0]).is_none());
    }

    #[test]
    fn validation_names_the_key() {
        let o = Optics {
            f_px: -1.0,
            ..Optics::default()
        };
        let e = o.validate().unwrap_err().to_string();
        assert!(e.contains("f_px") && e.contains("[1, 1000000]"), "{e}");
        let o = Optics {
            width: 8,
            ..Optics::default()
        };
        assert!(o.validate().unwrap_err().to_string().contains("width"));
        let o: Result<Optics, _> = toml::from_str("f_px = 1900.0\nbogus = 1");
        assert!(o.is_err());
        let o: Optics = toml::from_str("f_px = 1900.0").unwrap();
        assert_eq!(o.f_px, 1900.0);
        assert_eq!(o.d_mm, 250.0);
    }
}
