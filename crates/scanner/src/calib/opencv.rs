//! The reference a user would otherwise pick (docs/method.md section 6.6): OpenCV checkerboard
//! calibration (findChessboardCorners, cornerSubPix, calibrateCameraExtended) for F, c_x, c_y
//! and the distortion, the board lying flat on the glass and shot at two slider positions for
//! the camera's pose (glass normal and D) and the slider's direction and scale, and a
//! least-squares laser plane through the line seen on the board at the other poses.
//!
//! Each pose is shot twice under the lamp: laser off (for the corners) and laser on; the line
//! is detected in the difference, with the scan's own detector, and each line pixel's ray is
//! intersected with the board plane of its pose. OpenCV fits fx = fy (one F, as the model has)
//! and k1, k2, p1, p2 (k3 fixed at 0).

use super::{CalibError, Calibration, CameraModel};
use crate::detect::{Detector, LinePeak};
use footscan_hal::{Frame, Pixels, Timestamp};
use footscan_targets::Checkerboard;
use nalgebra::{Matrix3, Vector3};
use opencv::calib3d;
use opencv::core::{Mat, Point2f, Point3f, Size, TermCriteria, Vector, CV_64F};
use opencv::imgproc;
use opencv::prelude::*;
use std::collections::BTreeMap;

/// What a board image is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// A free pose: intrinsics, and the laser line on the board.
    Pose,
    /// The board flat on the glass, first or second slider position.
    Flat(usize),
}

/// One pose: the lamp-only image and, for free poses, the image with the laser on.
#[derive(Clone, Debug)]
pub struct BoardImage {
    pub role: Role,
    /// Slider position (controller mm).
    pub x_mm: f64,
    pub ambient: Pixels,
    pub laser: Option<Pixels>,
}

#[derive(Clone, Debug)]
pub struct BoardShots {
    pub width: u32,
    pub height: u32,
    pub images: Vec<BoardImage>,
}

fn cv(e: opencv::Error) -> CalibError {
    CalibError::OpenCv(e.to_string())
}

fn gray8(p: &Pixels) -> Vec<u8> {
    match p {
        Pixels::Gray8(v) => v.clone(),
        Pixels::Gray16(v) => v.iter().map(|&x| (x >> 8) as u8).collect(),
    }
}

/// Chessboard corners of one image, refined to subpixel; None if OpenCV does not find the
/// board.
pub fn find_corners(
    img: &[u8],
    width: u32,
    height: u32,
    board: &Checkerboard,
) -> Result<Option<Vec<[f64; 2]>>, CalibError> {
    let mat = Mat::new_rows_cols_with_data(height as i32, width as i32, img).map_err(cv)?;
    let pattern = Size::new(board.inner_cols as i32, board.inner_rows as i32);
    let mut corners = Vector::<Point2f>::new();
    let found = calib3d::find_chessboard_corners(
        &mat,
        pattern,
        &mut corners,
        calib3d::CALIB_CB_ADAPTIVE_THRESH
            | calib3d::CALIB_CB_NORMALIZE_IMAGE
            | calib3d::CALIB_CB_FAST_CHECK,
    )
    .map_err(cv)?;
    if !found {
        return Ok(None);
    }
    let criteria = TermCriteria::new(
        opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS,
        100,
        1e-4,
    )
    .map_err(cv)?;
    imgproc::corner_sub_pix(
        &mat,
        &mut corners,
        Size::new(11, 11),
        Size::new(-1, -1),
        criteria,
    )
    .map_err(cv)?;
    Ok(Some(
        corners.iter().map(|p| [p.x as f64, p.y as f64]).collect(),
    ))
}

fn rodrigues(v: [f64; 3]) -> Matrix3<f64> {
    let k = Vector3::from(v);
    let th = k.norm();
    if th < 1e-15 {
        return Matrix3::identity();
    }
    let k = k / th;
    let kx = Matrix3::new(0.0, -k.z, k.y, k.z, 0.0, -k.x, -k.y, k.x, 0.0);
    Matrix3::identity() * th.cos() + (1.0 - th.cos()) * k * k.transpose() + th.sin() * kx
}

/// One view's board pose in camera coordinates: X_c = R X_b + t.
struct View {
    image: usize,
    r: Matrix3<f64>,
    t: Vector3<f64>,
}

/// Calibrate from board shots: OpenCV for the intrinsics, then the world frame, slider and
/// laser plane. Residual keys: `reprojection_rms_px` (OpenCV's RMS), `laser_plane_rms_mm`,
/// `boards_found`, `laser_points`.
pub fn calibrate(
    shots: &BoardShots,
    board: &Checkerboard,
    detector: &mut dyn Detector,
) -> Result<Calibration, CalibError> {
    let (w, h) = (shots.width, shots.height);
    let obj: Vector<Point3f> = board
        .corners()
        .iter()
        .map(|c| Point3f::new(c[0] as f32, c[1] as f32, 0.0))
        .collect();
    let mut objpoints = Vector::<Vector<Point3f>>::new();
    let mut imgpoints = Vector::<Vector<Point2f>>::new();
    let mut used = Vec::new();
    for (k, im) in shots.images.iter().enumerate() {
        if let Some(c) = find_corners(&gray8(&im.ambient), w, h, board)? {
            objpoints.push(obj.clone());
            imgpoints.push(
                c.iter()
                    .map(|p| Point2f::new(p[0] as f32, p[1] as f32))
                    .collect(),
            );
            used.push(k);
        }
    }
    let poses = used
        .iter()
        .filter(|&&k| shots.images[k].role == Role::Pose)
        .count();
    let flats: Vec<usize> = [0, 1]
        .into_iter()
        .filter(|&f| used.iter().any(|&k| shots.images[k].role == Role::Flat(f)))
        .collect();
    if poses < 4 || flats.len() < 2 {
        return Err(CalibError::NoUsableRows {
            target: "the checkerboard shots".into(),
            detail: format!(
                "OpenCV found the board in {poses} of {} free poses and {} of 2 flat shots: need \
                 at least 4 poses and both flat shots (board fully in view, in focus, lit)",
                shots.images.iter().filter(|i| i.role == Role::Pose).count(),
                flats.len()
            ),
        });
    }
    let mut k = Mat::eye(3, 3, CV_64F).map_err(cv)?.to_mat().map_err(cv)?;
    let mut dist = Mat::default();
    let mut rvecs = Vector::<Mat>::new();
    let mut tvecs = Vector::<Mat>::new();
    let mut std_int = Mat::default();
    let mut std_ext = Mat::default();
    let mut per_view = Mat::default();
    let criteria = TermCriteria::new(
        opencv::core::TermCriteria_COUNT + opencv::core::TermCriteria_EPS,
        200,
        1e-12,
    )
    .map_err(cv)?;
    let rms = calib3d::calibrate_camera_extended(
        &objpoints,
        &imgpoints,
        Size::new(w as i32, h as i32),
        &mut k,
        &mut dist,
        &mut rvecs,
        &mut tvecs,
        &mut std_int,
        &mut std_ext,
        &mut per_view,
        calib3d::CALIB_FIX_ASPECT_RATIO | calib3d::CALIB_FIX_K3,
        criteria,
    )
    .map_err(cv)?;
    let at = |m: &Mat, r: i32, c: i32| m.at_2d::<f64>(r, c).copied().map_err(cv);
    let flat_at = |m: &Mat, i: i32| -> Result<f64, CalibError> {
        if m.rows() == 1 {
            at(m, 0, i)
        } else {
            at(m, i, 0)
        }
    };
    let (fx, fy, cx, cy) = (at(&k, 0, 0)?, at(&k, 1, 1)?, at(&k, 0, 2)?, at(&k, 1, 2)?);
    let (k1, k2, p1, p2) = (
        flat_at(&dist, 0)?,
        flat_at(&dist, 1)?,
        flat_at(&dist, 2)?,
        flat_at(&dist, 3)?,
    );
    let mut views = Vec::new();
    for (i, &img) in used.iter().enumerate() {
        let rv = rvecs.get(i).map_err(cv)?;
        let tv = tvecs.get(i).map_err(cv)?;
        views.push(View {
            image: img,
            r: rodrigues([flat_at(&rv, 0)?, flat_at(&rv, 1)?, flat_at(&rv, 2)?]),
            t: Vector3::new(flat_at(&tv, 0)?, flat_at(&tv, 1)?, flat_at(&tv, 2)?),
        });
    }
    // World frame from the flat board: z up (toward the board), D the distance to the glass.
    let flat = |f: usize| {
        views
            .iter()
            .find(|v| shots.images[v.image].role == Role::Flat(f))
            .expect("both flats found")
    };
    let (f0, f1) = (flat(0), flat(1));
    let mut z_w = f0.r.column(2).into_owned();
    if z_w.z < 0.0 {
        z_w = -z_w;
    }
    let d_mm = 0.5 * (z_w.dot(&f0.t).abs() + z_w.dot(&f1.t).abs());
    // Slider: the board is still and the head moves by s dX along world x.
    let s = board.square_mm;
    let centre = Vector3::new(
        (board.inner_cols - 1) as f64 * s / 2.0,
        (board.inner_rows - 1) as f64 * s / 2.0,
        0.0,
    );
    let c0 = f0.r * centre + f0.t;
    let c1 = f1.r * centre + f1.t;
    let dx = shots.images[f1.image].x_mm - shots.images[f0.image].x_mm;
    let moved = -(c1 - c0);
    let moved = moved - z_w * z_w.dot(&moved);
    let slider_scale = moved.norm() / dx.abs();
    let x_w = moved.normalize() * dx.signum();
    let y_w = z_w.cross(&x_w);
    // Camera-to-world rotation: its rows are the world axes in camera coordinates.
    let rot = Matrix3::from_rows(&[x_w.transpose(), y_w.transpose(), z_w.transpose()]);
    let tilt = [
        rot[(2, 1)].atan2(rot[(2, 2)]).to_degrees(),
        (-rot[(2, 0)]).asin().to_degrees(),
        rot[(1, 0)].atan2(rot[(0, 0)]).to_degrees(),
    ];
    // Laser points: line pixels' rays on the board planes of the free poses.
    let intr = CameraModel {
        width: w,
        height: h,
        f_px: fy,
        cx,
        cy,
        d_mm,
        l_mm: 1.0,
        k1,
        k2,
        p1,
        p2,
        camera_tilt_deg: [0.0; 3],
        laser_tilt_deg: [0.0; 2],
        slider_scale: 1.0,
    };
    let mut pts: Vec<Vector3<f64>> = Vec::new();
    let mut lines = vec![LinePeak::NONE; h as usize];
    for v in &views {
        let im = &shots.images[v.image];
        let Some(laser) = &im.laser else { continue };
        let diff: Vec<u8> = gray8(laser)
            .iter()
            .zip(gray8(&im.ambient))
            .map(|(a, b)| a.saturating_sub(b))
            .collect();
        let frame = Frame::new(0, Timestamp::default(), w, h, Pixels::Gray8(diff));
        detector.detect(&frame, &mut lines);
        let n = v.r.column(2).into_owned();
        let d0 = n.dot(&v.t);
        for (row, l) in lines.iter().enumerate() {
            if !l.is_valid() {
                continue;
            }
            let (xn, yn) = intr.undistort((l.col - cx) / fy, (row as f64 - cy) / fy);
            let ray = Vector3::new(xn, yn, 1.0);
            let den = n.dot(&ray);
            if den.abs() > 1e-9 {
                pts.push(ray * (d0 / den));
            }
        }
    }
    if pts.len() < 50 {
        return Err(CalibError::NoUsableRows {
            target: "the laser line on the checkerboard".into(),
            detail: format!(
                "{} line points on the boards: the laser must cross the board in the free poses",
                pts.len()
            ),
        });
    }
    // Plane through the points (camera coordinates), then in the world relative to the head.
    let mean = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
    let mut cov = Matrix3::zeros();
    for p in &pts {
        let d = p - mean;
        cov += d * d.transpose();
    }
    let eig = cov.symmetric_eigen();
    let imin = eig.eigenvalues.imin();
    let n_c = eig.eigenvectors.column(imin).into_owned();
    let plane_rms = (eig.eigenvalues[imin].max(0.0) / pts.len() as f64).sqrt();
    // World (head at X = 0): p_w = rot p_c + (0, 0, -D).
    let n_w = rot * n_c;
    let p_w = rot * mean + Vector3::new(0.0, 0.0, -d_mm);
    // x = L + tan(a) y + tan(b) z  <=>  n_w . (p - p_w) = 0 with n_w scaled to n_x = 1.
    let n_w = n_w / n_w.x;
    let l_mm = n_w.dot(&p_w);
    let (tan_a, tan_b) = (-n_w.y, -n_w.z);
    let model = CameraModel {
        f_px: fy,
        d_mm,
        l_mm,
        camera_tilt_deg: tilt,
        laser_tilt_deg: [tan_a.atan().to_degrees(), tan_b.atan().to_degrees()],
        slider_scale,
        ..intr
    };
    let mut stddev = BTreeMap::new();
    let sd = |i: i32| flat_at(&std_int, i);
    stddev.insert("f_px".to_string(), sd(1)?);
    stddev.insert("cx".to_string(), sd(2)?);
    stddev.insert("cy".to_string(), sd(3)?);
    stddev.insert("k1".to_string(), sd(4)?);
    stddev.insert("k2".to_string(), sd(5)?);
    stddev.insert("p1".to_string(), sd(6)?);
    stddev.insert("p2".to_string(), sd(7)?);
    let mut residuals = BTreeMap::new();
    residuals.insert("reprojection_rms_px".to_string(), rms);
    residuals.insert("laser_plane_rms_mm".to_string(), plane_rms);
    residuals.insert("boards_found".to_string(), used.len() as f64);
    residuals.insert("laser_points".to_string(), pts.len() as f64);
    residuals.insert("fx_over_fy".to_string(), fx / fy);
    Ok(Calibration {
        method: "opencv".into(),
        date: footscan_util::now_rfc3339(),
        model,
        stddev,
        residuals,
        bezier: None,
    })
}
