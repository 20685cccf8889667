use footscan_geom::P3;
use serde::{Deserialize, Serialize};

/// The general scanner model of docs/method.md section 2.3.
///
/// Camera centre at (s·X, 0, −D) for reported slider position X and slider scale s; rotation
/// R = Rz·Ry·Rx (camera to world) from `camera_tilt_deg`; Brown–Conrady distortion on
/// normalised coordinates; laser plane x = s·X + L + tan(a)·y + tan(b)·z.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraModel {
    pub width: u32,
    pub height: u32,
    pub f_px: f64,
    pub cx: f64,
    pub cy: f64,
    pub d_mm: f64,
    pub l_mm: f64,
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    /// Rotations about x, y, z in degrees.
    pub camera_tilt_deg: [f64; 3],
    /// Laser plane yaw `a` (x grows with y) and pitch `b` (x grows with z), degrees.
    pub laser_tilt_deg: [f64; 2],
    /// Physical head position per reported slider millimetre.
    pub slider_scale: f64,
}

/// Precomputed trigonometry for the per-row hot path; optionally a Bezier depth network that
/// gives the height instead of the laser plane.
#[derive(Clone, Debug)]
pub struct Triangulator {
    m: CameraModel,
    r: [[f64; 3]; 3],
    tan_a: f64,
    tan_b: f64,
    depth: Option<std::sync::Arc<super::bezier_depth::BezierDepth>>,
}

/// Why a camera model is refused (it would give silent nonsense heights); each names the key
/// and what is valid.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    #[error("model.{key} = {value}: must be a positive number")]
    NotPositive { key: &'static str, value: f64 },
    #[error("model.l_mm = {0}: the laser offset must be non-zero (no triangulation baseline)")]
    NoBaseline(f64),
    #[error("model.width x height = {width}x{height}: must be at least 2x2")]
    TooSmall { width: u32, height: u32 },
    #[error("model.{key} = {value}: must be finite")]
    NotFinite { key: &'static str, value: f64 },
    #[error("tilt {0} deg: camera_tilt_deg and laser_tilt_deg must be within +/-45 deg")]
    Tilt(f64),
}

impl CameraModel {
    /// The rotation camera -> world.
    pub fn rotation(&self) -> [[f64; 3]; 3] {
        let [rx, ry, rz] = self.camera_tilt_deg.map(f64::to_radians);
        let (sx, cx) = rx.sin_cos();
        let (sy, cy) = ry.sin_cos();
        let (sz, cz) = rz.sin_cos();
        let rxm = [[1.0, 0.0, 0.0], [0.0, cx, -sx], [0.0, sx, cx]];
        let rym = [[cy, 0.0, sy], [0.0, 1.0, 0.0], [-sy, 0.0, cy]];
        let rzm = [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]];
        matmul(&matmul(&rzm, &rym), &rxm)
    }

    pub fn triangulator(&self) -> Triangulator {
        let [a, b] = self.laser_tilt_deg.map(f64::to_radians);
        Triangulator {
            r: self.rotation(),
            tan_a: a.tan(),
            tan_b: b.tan(),
            m: self.clone(),
            depth: None,
        }
    }

    /// Distort normalised coordinates.
    pub fn distort(&self, xn: f64, yn: f64) -> (f64, f64) {
        let r2 = xn * xn + yn * yn;
        let rad = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
        (
            xn * rad + 2.0 * self.p1 * xn * yn + self.p2 * (r2 + 2.0 * xn * xn),
            yn * rad + self.p1 * (r2 + 2.0 * yn * yn) + 2.0 * self.p2 * xn * yn,
        )
    }

    /// Invert [`Self::distort`] by Newton's method (a handful of steps reach 1e-14).
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let (fx, fy) = self.distort(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() < 1e-15 && ey.abs() < 1e-15 {
                break;
            }
            let r2 = x * x + y * y;
            let rad = 1.0 + self.k1 * r2 + self.k2 * r2 * r2;
            let drad = self.k1 + 2.0 * self.k2 * r2; // d rad / d r2
            let j11 = rad + x * drad * 2.0 * x + 2.0 * self.p1 * y + self.p2 * 6.0 * x;
            let j12 = x * drad * 2.0 * y + 2.0 * self.p1 * x + self.p2 * 2.0 * y;
            let j21 = y * drad * 2.0 * x + self.p1 * 2.0 * x + 2.0 * self.p2 * y;
            let j22 = rad + y * drad * 2.0 * y + self.p1 * 6.0 * y + 2.0 * self.p2 * x;
            let det = j11 * j22 - j12 * j21;
            x -= (j22 * ex - j12 * ey) / det;
            y -= (-j21 * ex + j11 * ey) / det;
        }
        (x, y)
    }

    /// Image position (col, row) of world point `p` with the slider reporting `slider_x`.
    /// The pixel position stays a `[col, row]` pair: image coordinates, not millimetres.
    pub fn project(&self, slider_x: f64, p: P3) -> Option<[f64; 2]> {
        let r = self.rotation();
        let c = [self.slider_scale * slider_x, 0.0, -self.d_mm];
        let d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
        // p_cam = R^T d
        let pc = [
            r[0][0] * d[0] + r[1][0] * d[1] + r[2][0] * d[2],
            r[0][1] * d[0] + r[1][1] * d[1] + r[2][1] * d[2],
            r[0][2] * d[0] + r[1][2] * d[1] + r[2][2] * d[2],
        ];
        if pc[2] <= 0.0 {
            return None;
        }
        let (xd, yd) = self.distort(pc[0] / pc[2], pc[1] / pc[2]);
        Some([self.cx + self.f_px * xd, self.cy + self.f_px * yd])
    }

    /// Checks that would otherwise produce silent nonsense heights.
    pub fn validate(&self) -> Result<(), ModelError> {
        let pos = [
            ("f_px", self.f_px),
            ("d_mm", self.d_mm),
            ("slider_scale", self.slider_scale),
        ];
        for (k, v) in pos {
            if !(v.is_finite() && v > 0.0) {
                return Err(ModelError::NotPositive { key: k, value: v });
            }
        }
        if !(self.l_mm.is_finite() && self.l_mm.abs() > 1e-6) {
            return Err(ModelError::NoBaseline(self.l_mm));
        }
        if self.width < 2 || self.height < 2 {
            return Err(ModelError::TooSmall {
                width: self.width,
                height: self.height,
            });
        }
        for (k, v) in [
            ("cx", self.cx),
            ("cy", self.cy),
            ("k1", self.k1),
            ("k2", self.k2),
            ("p1", self.p1),
            ("p2", self.p2),
        ] {
            if !v.is_finite() {
                return Err(ModelError::NotFinite { key: k, value: v });
            }
        }
        for t in self.camera_tilt_deg.iter().chain(&self.laser_tilt_deg) {
            if !(t.is_finite() && t.abs() < 45.0) {
                return Err(ModelError::Tilt(*t));
            }
        }
        Ok(())
    }
}

impl Triangulator {
    pub fn model(&self) -> &CameraModel {
        &self.m
    }

    /// Take heights from `depth` (the point is then where the pixel's ray reaches that height).
    pub fn with_depth(mut self, depth: super::bezier_depth::BezierDepth) -> Self {
        self.depth = Some(std::sync::Arc::new(depth));
        self
    }

    /// 3D point of the laser line seen at (col, row) with the slider reporting `slider_x`:
    /// the pixel's ray intersected with the laser plane. None if the ray is parallel to the
    /// plane or the intersection lies behind the camera.
    pub fn point(&self, slider_x: f64, col: f64, row: f64) -> Option<P3> {
        let m = &self.m;
        let (xn, yn) = m.undistort((col - m.cx) / m.f_px, (row - m.cy) / m.f_px);
        let r = &self.r;
        let d = [
            r[0][0] * xn + r[0][1] * yn + r[0][2],
            r[1][0] * xn + r[1][1] * yn + r[1][2],
            r[2][0] * xn + r[2][1] * yn + r[2][2],
        ];
        let xs = m.slider_scale * slider_x;
        let o = [xs, 0.0, -m.d_mm];
        if let Some(depth) = &self.depth {
            let h = depth.height(row, col)?;
            if d[2] <= 1e-12 {
                return None;
            }
            let t = (h + m.d_mm) / d[2];
            return Some(P3::new(o[0] + t * d[0], o[1] + t * d[1], h));
        }
        // plane: x - tan_a*y - tan_b*z = xs + L
        let denom = d[0] - self.tan_a * d[1] - self.tan_b * d[2];
        if denom.abs() < 1e-12 {
            return None;
        }
        let t = (xs + m.l_mm - o[0] + self.tan_a * o[1] + self.tan_b * o[2]) / denom;
        if t <= 0.0 {
            return None;
        }
        Some(P3::new(o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]))
    }
}

fn matmul(a: &[[f64; 3]; 3], b: &[[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            m[i][j] = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub fn default_model() -> CameraModel {
        CameraModel {
            width: 1280,
            height: 1024,
            f_px: 2000.0,
            cx: 643.7,
            cy: 509.9,
            d_mm: 250.0,
            l_mm: 70.0,
            k1: -0.08,
            k2: 0.01,
            p1: 0.0005,
            p2: -0.0003,
            camera_tilt_deg: [0.2, 0.3, 0.1],
            laser_tilt_deg: [0.1, 0.2],
            slider_scale: 1.0003,
        }
    }

    #[test]
    fn ideal_model_matches_closed_form() {
        let m = CameraModel {
            k1: 0.0,
            k2: 0.0,
            p1: 0.0,
            p2: 0.0,
            camera_tilt_deg: [0.0; 3],
            laser_tilt_deg: [0.0; 2],
            slider_scale: 1.0,
            ..default_model()
        };
        let t = m.triangulator();
        for h in [0.0, 5.0, 20.0] {
            let c = m.cx + m.f_px * m.l_mm / (m.d_mm + h);
            let p = t.point(100.0, c, 700.0).unwrap();
            assert!((p[2] - h).abs() < 1e-9, "h {h} got {}", p[2]);
            assert!((p[0] - 170.0).abs() < 1e-9);
            let y = (700.0 - m.cy) * (m.d_mm + h) / m.f_px;
            assert!((p[1] - y).abs() < 1e-9);
        }
    }

    #[test]
    fn undistort_inverts_distort() {
        let m = default_model();
        for &(x, y) in &[(0.0, 0.0), (0.28, 0.25), (-0.3, 0.2), (0.31, -0.26)] {
            let (xd, yd) = m.distort(x, y);
            let (xu, yu) = m.undistort(xd, yd);
            assert!((xu - x).abs() < 1e-13 && (yu - y).abs() < 1e-13);
        }
    }

    #[test]
    fn triangulation_inverts_projection() {
        let m = default_model();
        let t = m.triangulator();
        let [a, b] = m.laser_tilt_deg.map(f64::to_radians);
        for &(y, z) in &[(0.0, 0.0), (40.0, 3.0), (-55.0, 18.0), (10.0, 30.0)] {
            let sx = 123.4;
            let x = m.slider_scale * sx + m.l_mm + a.tan() * y + b.tan() * z;
            let [c, r] = m.project(sx, P3::new(x, y, z)).unwrap();
            let p = t.point(sx, c, r).unwrap();
            for k in 0..3 {
                assert!(
                    (p[k] - [x, y, z][k]).abs() < 1e-9,
                    "{p:?} vs {:?}",
                    [x, y, z]
                );
            }
        }
    }

    #[test]
    fn validate_names_the_key() {
        let mut m = default_model();
        m.d_mm = -1.0;
        assert!(m.validate().unwrap_err().to_string().contains("d_mm"));
    }
}
