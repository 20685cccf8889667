//! The OpenCV checkerboard reference against the simulator's ground truth (cargo feature
//! `opencv`, on by default), and the clear error when the feature is off.

use footscan::calib::{CalibError, CalibrationPlan};
use footscan::scan::calibrate::{self as run, Method};
use footscan::scan::LoadedConfig;
use std::path::Path;

fn sim_config() -> LoadedConfig {
    LoadedConfig::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("config/sim.toml")).unwrap()
}

#[cfg(feature = "opencv")]
mod with_opencv {
    use super::*;
    use footscan::calib::opencv;
    use footscan_sim::render::{NoiseConfig, Renderer, RowTruth, Scene};
    use std::sync::Arc;

    #[test]
    fn opencv_reference_recovers_the_scanner() {
        let cfg = sim_config();
        let mut plan = CalibrationPlan::default();
        plan.sim.board_poses.truncate(8);
        let shots = run::render_shots(&cfg.config, &plan, &mut |_, _, _| {}).unwrap();
        // Corners found by OpenCV sit on the exact projections.
        let o = &cfg.config.sim.optics;
        let img = match &shots.images[0].ambient {
            footscan_hal::Pixels::Gray8(v) => v.clone(),
            _ => unreachable!("Gray8 scanner"),
        };
        let found = opencv::find_corners(&img, o.width, o.height, &plan.board)
            .unwrap()
            .expect("board found");
        let r = footscan_sim::targets::BoardRenderer::new(o.clone(), NoiseConfig::noise_free(), 0)
            .unwrap();
        let truth = r
            .render(
                &plan.board,
                &plan.sim.board_poses[0],
                plan.sim.board_x_mm,
                footscan_sim::targets::Lighting {
                    lamp_dn: 100.0,
                    laser: false,
                },
                0,
            )
            .corners;
        let mut worst: f64 = 0.0;
        for c in &found {
            let d = truth
                .iter()
                .flatten()
                .map(|t| ((t[0] - c[0]).powi(2) + (t[1] - c[1]).powi(2)).sqrt())
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(d);
        }
        assert!(worst < 0.15, "corner error up to {worst} px");

        let mut det = run::detector(run::DETECTOR).unwrap();
        let cal = opencv::calibrate(&shots, &plan.board, det.as_mut()).unwrap();
        let t = footscan::scan::sim::true_calibration(&cfg.config).model;
        let m = &cal.model;
        let rel = |a: f64, b: f64| (a - b).abs() / b;
        assert!(rel(m.f_px, t.f_px) < 2e-3, "F {}", m.f_px);
        assert!(
            (m.cx - t.cx).abs() < 1.5 && (m.cy - t.cy).abs() < 1.5,
            "c {} {}",
            m.cx,
            m.cy
        );
        assert!(rel(m.d_mm, t.d_mm) < 2e-3, "D {}", m.d_mm);
        assert!(rel(m.l_mm, t.l_mm) < 2e-3, "L {}", m.l_mm);
        assert!(
            (m.camera_tilt_deg[1] - 0.3).abs() < 0.05,
            "{:?}",
            m.camera_tilt_deg
        );
        assert!((m.slider_scale - 1.0).abs() < 1e-3);
        assert!(cal.residuals["reprojection_rms_px"] < 0.2);
        assert!(cal.residuals["laser_plane_rms_mm"] < 0.05);
        // Heights of a plate between the calibration heights, from exact line positions.
        let tri = cal.triangulator();
        let rr = Renderer::new(
            o.clone(),
            NoiseConfig::noise_free(),
            Scene::Surface(Arc::new(footscan_bench::calibrate::validation_staircase())),
            1,
        )
        .unwrap();
        let (mut sum, mut n) = (0.0, 0);
        for x in [55.0, 75.0, 95.0, 115.0] {
            for (row, rt) in rr.truth(x).rows.iter().enumerate() {
                if let RowTruth::Line { col, point } = rt {
                    let p = tri.point(x, *col, row as f64).unwrap();
                    sum += (p[2] - point[2]).powi(2);
                    n += 1;
                }
            }
        }
        let rms = (sum / n as f64).sqrt();
        assert!(
            n > 1000 && rms < 0.03,
            "held-out height RMS {rms} mm over {n}"
        );
    }

    #[test]
    fn boards_out_of_view_are_reported() {
        let cfg = sim_config();
        let mut plan = CalibrationPlan::default();
        plan.sim.board_poses.truncate(4);
        for p in &mut plan.sim.board_poses {
            p.origin_mm[1] += 200.0; // nobody holds the board in front of the camera
        }
        let shots = run::render_shots(&cfg.config, &plan, &mut |_, _, _| {}).unwrap();
        let mut det = run::detector(run::DETECTOR).unwrap();
        let e = opencv::calibrate(&shots, &plan.board, det.as_mut()).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("0 of 4 free poses"), "{msg}");
    }
}

#[cfg(not(feature = "opencv"))]
#[test]
fn without_the_feature_opencv_says_so() {
    let cfg = sim_config();
    let e = run::calibrate_unattended(
        &cfg.config,
        Method::Opencv,
        &CalibrationPlan::default(),
        &mut |_, _, _| {},
    )
    .unwrap_err();
    assert!(matches!(e, CalibError::OpenCvDisabled), "{e}");
    assert!(e.to_string().contains("cargo feature"));
}

#[test]
fn in_system_methods_refuse_a_plan_with_too_few_heights_before_acquiring() {
    let cfg = sim_config();
    let plan = CalibrationPlan {
        plate_heights_mm: vec![0.0, 20.0],
        ..CalibrationPlan::default()
    };
    let t = std::time::Instant::now();
    let e = run::calibrate_unattended(&cfg.config, Method::Bezier, &plan, &mut |_, _, _| {})
        .unwrap_err();
    assert!(matches!(e, CalibError::TooFewHeights { got: 2, .. }), "{e}");
    assert!(t.elapsed().as_secs_f64() < 1.0, "failed fast");
}
