//! The untilted equivalent of a camera model: what laser-line data can determine.
//!
//! Every observation of the in-system calibration is a point of the laser plane, so the data
//! fix the mapping from that plane to the image and nothing else (see [`super::insystem`]). A
//! small rotation of the camera about its centre changes the mapping only as a shift of c_x,
//! c_y, D and the laser tilts would, so the in-system fit holds the camera tilts at zero and
//! recovers the equivalent untilted camera. To compare any model with the truth on what the
//! data determine, both are reduced to that equivalent: the untilted model (F, c_x, c_y, D, L,
//! k1, k2, laser yaw and pitch) whose image of the laser plane over the scan volume matches
//! the given model's, fitted by least squares. The largest column/row difference left says how
//! exact the equivalence is.

use super::lm;
use super::CameraModel;
use footscan_geom::P3;

/// Heights (mm) and across-platform positions (mm) of the laser-plane points compared.
const HEIGHTS: (f64, f64, usize) = (0.0, 60.0, 13);
const ACROSS: (f64, f64, usize) = (-60.0, 60.0, 25);

/// Why no untilted equivalent was found.
#[derive(Debug, thiserror::Error)]
pub enum UntiltedError {
    #[error("the laser plane is not in view of the camera")]
    NotInView,
    #[error("fitting the untilted model")]
    Fit(#[from] lm::LmError),
}

/// The untilted model equivalent to `m` and the largest image difference between the two over
/// the scan volume, px. A model without camera tilt is its own equivalent.
pub fn untilted_equivalent(m: &CameraModel) -> Result<(CameraModel, f64), UntiltedError> {
    if m.camera_tilt_deg.iter().all(|t| *t == 0.0) {
        return Ok((m.clone(), 0.0));
    }
    let grid = |(a, b, n): (f64, f64, usize)| -> Vec<f64> {
        (0..n)
            .map(|k| a + (b - a) * k as f64 / (n - 1) as f64)
            .collect()
    };
    let on_plane = |m: &CameraModel, y: f64, h: f64| -> P3 {
        let [a, b] = m.laser_tilt_deg.map(f64::to_radians);
        P3::new(m.l_mm + a.tan() * y + b.tan() * h, y, h)
    };
    // Image of the true laser plane, and the (y, h) of each point.
    let mut target = Vec::new();
    for &h in &grid(HEIGHTS) {
        for &y in &grid(ACROSS) {
            if let Some(px) = m.project(0.0, on_plane(m, y, h)) {
                target.push((y, h, px));
            }
        }
    }
    if target.len() < 20 {
        return Err(UntiltedError::NotInView);
    }
    let model_of = |x: &[f64]| CameraModel {
        f_px: x[0],
        cx: x[1],
        cy: x[2],
        d_mm: x[3],
        l_mm: x[4],
        k1: x[5],
        k2: x[6],
        laser_tilt_deg: [x[7], m.laser_tilt_deg[1]],
        camera_tilt_deg: [0.0; 3],
        ..m.clone()
    };
    // Points are matched by their (y, h) on each model's own laser plane: the plane is what
    // both models see, its coordinates are the gauge-free labels.
    let residuals = |x: &[f64], out: &mut Vec<f64>| {
        out.clear();
        let e = model_of(x);
        for &(y, h, [c, r]) in &target {
            match e.project(0.0, on_plane(&e, y, h)) {
                Some([ec, er]) => {
                    out.push(ec - c);
                    out.push(er - r);
                }
                None => {
                    out.push(1e6);
                    out.push(1e6);
                }
            }
        }
    };
    let x0 = [
        m.f_px,
        m.cx,
        m.cy,
        m.d_mm,
        m.l_mm,
        m.k1,
        m.k2,
        m.laser_tilt_deg[0],
    ];
    let step = [1e-3, 1e-4, 1e-4, 1e-5, 1e-5, 1e-7, 1e-7, 1e-6];
    let sol = lm::solve(&residuals, &x0, &step, 200)?;
    let worst = sol.residuals.iter().fold(0.0f64, |a, r| a.max(r.abs()));
    Ok((model_of(&sol.x), worst))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::model::tests::default_model;

    #[test]
    fn a_tilt_about_y_is_a_shift_of_cx_and_d() {
        let m = CameraModel {
            camera_tilt_deg: [0.0, 0.3, 0.0],
            laser_tilt_deg: [0.0, 0.2],
            p1: 0.0,
            p2: 0.0,
            slider_scale: 1.0,
            ..default_model()
        };
        let (e, worst) = untilted_equivalent(&m).unwrap();
        let t = 0.3f64.to_radians().tan();
        // First order: c_x by -F tan t, D by +L tan t; what is left is second order.
        assert!((e.cx - (m.cx - m.f_px * t)).abs() < 0.1, "cx {}", e.cx);
        assert!(
            (e.d_mm - (m.d_mm + m.l_mm * t)).abs() < 0.01,
            "D {}",
            e.d_mm
        );
        assert!((e.cy - m.cy).abs() < 0.1, "cy {}", e.cy);
        assert!(worst < 0.01, "equivalence leaves {worst} px");
        // The equivalent triangulates the tilted camera's image of the plane to the same points.
        let (tm, te) = (m.triangulator(), e.triangulator());
        for (y, h) in [(-40.0, 0.0), (0.0, 25.0), (35.0, 55.0)] {
            let [a, b] = m.laser_tilt_deg.map(f64::to_radians);
            let p = P3::new(m.l_mm + a.tan() * y + b.tan() * h, y, h);
            let [c, r] = m.project(0.0, p).unwrap();
            let (pt, pe) = (tm.point(0.0, c, r).unwrap(), te.point(0.0, c, r).unwrap());
            assert!((pt[2] - h).abs() < 1e-6, "truth model {pt:?}");
            assert!(
                (pe[2] - h).abs() < 0.002,
                "equivalent: height {} for {h}",
                pe[2]
            );
        }
    }

    #[test]
    fn an_untilted_model_is_its_own_equivalent() {
        let m = default_model();
        let untilted = CameraModel {
            camera_tilt_deg: [0.0; 3],
            ..m
        };
        let (e, worst) = untilted_equivalent(&untilted).unwrap();
        assert_eq!(e, untilted);
        assert_eq!(worst, 0.0);
    }
}
