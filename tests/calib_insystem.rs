//! In-system calibration and the Bezier depth network against the simulator's ground truth,
//! on frames rendered directly (the mathematics; `calib_e2e.rs` goes through the devices).

use footscan::calib::acquire::{InsystemData, PlateObservation, RenderRig};
use footscan::calib::insystem::{fit_insystem, InsystemOptions};
use footscan::calib::{CalibError, Calibration, CalibrationPlan};
use footscan::scan::calibrate::{self as run, Method};
use footscan_bench::calibrate::validation_staircase;
use footscan_sim::foot::{Foot, FootParams};
use footscan_sim::optics::Optics;
use footscan_sim::render::{NoiseConfig, Renderer, RowTruth, Scene};
use footscan_sim::targets::Staircase;
use std::sync::{Arc, OnceLock};

fn acquire(optics: &Optics, plan: &CalibrationPlan) -> InsystemData {
    let st = Staircase::new(plan.staircase.clone(), plan.sim.staircase).unwrap();
    let mut rig = RenderRig::new(optics.clone(), NoiseConfig::default(), 7, st, 1.0).unwrap();
    run::acquire_insystem(&mut rig, plan, &mut |_, _, _| {}).unwrap()
}

/// The default scanner (camera tilted 0.3 deg about y), acquired once for every test here.
fn default_data() -> &'static InsystemData {
    static DATA: OnceLock<InsystemData> = OnceLock::new();
    DATA.get_or_init(|| acquire(&Optics::default(), &CalibrationPlan::default()))
}

/// Height error RMS and max of `cal` on exact line positions of held-out scenes: the
/// validation staircase (steps between the calibration heights) and the foot.
fn held_out_errors(cal: &Calibration, optics: &Optics) -> (f64, f64, usize) {
    let tri = cal.triangulator();
    let foot = Foot::new(FootParams::default()).unwrap();
    let scenes = [
        (
            Scene::Surface(Arc::new(validation_staircase())),
            50.0,
            135.0,
        ),
        (Scene::Foot(foot), 20.0, 300.0),
    ];
    let (mut sum, mut max, mut n) = (0.0, 0.0f64, 0usize);
    for (scene, x0, x1) in scenes {
        let r = Renderer::new(optics.clone(), NoiseConfig::noise_free(), scene, 1).unwrap();
        for k in 0..12 {
            let x = x0 + (x1 - x0) * k as f64 / 11.0;
            for (row, t) in r.truth(x).rows.iter().enumerate() {
                let RowTruth::Line { col, point } = t else {
                    continue;
                };
                let p = tri.point(x, *col, row as f64).expect("triangulates");
                let e = p[2] - point[2];
                sum += e * e;
                max = max.max(e.abs());
                n += 1;
            }
        }
    }
    ((sum / n as f64).sqrt(), max, n)
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

#[test]
fn insystem_meets_the_bar_on_the_default_scanner() {
    let truth = Optics::default();
    let out = run::from_insystem(
        default_data(),
        Method::Insystem,
        &CalibrationPlan::default(),
    )
    .unwrap();
    let m = &out.calibration.model;
    assert!(rel(m.f_px, truth.f_px) < 1e-3, "F {}", m.f_px);
    assert!(rel(m.l_mm, truth.l_mm) < 1e-3, "L {}", m.l_mm);
    // The camera's tilt about y (0.3 deg) cannot be told from a shift of c_x and D with
    // laser-plane data (see calib::insystem): the fit finds the equivalent untilted camera,
    // c_x - F tan(t) and D + L tan(t).
    let t = truth.camera_tilt_deg[1].to_radians().tan();
    let (cx_eq, d_eq) = (truth.cx - truth.f_px * t, truth.d_mm + truth.l_mm * t);
    assert!(
        (m.cx - cx_eq).abs() < 1.0,
        "c_x {} vs equivalent {cx_eq}",
        m.cx
    );
    assert!(
        rel(m.d_mm, d_eq) < 1e-3,
        "D {} vs equivalent {d_eq}",
        m.d_mm
    );
    assert!((m.cy - truth.cy).abs() < 1.2, "c_y {}", m.cy);
    assert!((m.laser_tilt_deg[1] - truth.laser_tilt_deg[1]).abs() < 0.03);
    assert!(
        (m.slider_scale - 1.0).abs() < 2e-4,
        "scale {}",
        m.slider_scale
    );
    // What matters: heights between the calibration heights, on a staircase and a foot.
    let (rms, max, n) = held_out_errors(&out.calibration, &truth);
    assert!(n > 5000, "{n} points");
    assert!(
        rms < 0.01 && max < 0.03,
        "held-out height error RMS {rms} max {max} mm"
    );
    // Uncertainties and residuals are reported.
    let c = &out.calibration;
    for k in [
        "f_px",
        "cx",
        "cy",
        "d_mm",
        "l_mm",
        "k1",
        "k2",
        "slider_scale",
    ] {
        let sd = c.stddev[k];
        assert!(sd.is_finite() && sd > 0.0, "{k}: {sd}");
    }
    assert!(c.stddev["f_px"] < 1.0 && c.stddev["l_mm"] < 0.05);
    for k in [
        "plate_0mm_rms_px",
        "staircase_edges_rms_px",
        "parallel_x_rms_mm",
        "parallel_y_rms_mm",
        "u_h_mm",
        "closed_form_cx_spread_px",
    ] {
        assert!(c.residuals[k].is_finite(), "{k}");
    }
    // Averaged plate lines fit to a few hundredths of a pixel, ends to their quantisation.
    assert!(c.residuals["plate_21mm_rms_px"] < 0.05);
    assert!((c.residuals["staircase_edges_rms_px"] - 0.289).abs() < 0.05);
    assert!(c.residuals["u_h_detection_mm"] > 0.005 && c.residuals["u_h_detection_mm"] < 0.1);
    assert!(c.residuals["u_h_model_mm"] < 0.005);
}

#[test]
fn bezier_network_is_well_conditioned_and_holds_between_heights() {
    let plan = CalibrationPlan::default();
    let out = run::from_insystem(default_data(), Method::Bezier, &plan).unwrap();
    let c = &out.calibration;
    let net = c.bezier.as_ref().expect("network");
    assert_eq!(net.degree_u, plan.plate_heights_mm.len() - 1);
    assert!(net.condition < 1e5, "condition {}", net.condition);
    assert_eq!(c.residuals["bezier_condition"], net.condition);
    let (rms, max, _) = held_out_errors(c, &Optics::default());
    assert!(
        rms < 0.02 && max < 0.08,
        "Bezier held-out RMS {rms} max {max} mm"
    );
    // Round trip through the file: the scan loads the network.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bezier.toml");
    c.save(&path).unwrap();
    let back = Calibration::load(&path).unwrap();
    let (a, b) = (c.triangulator(), back.triangulator());
    let row = 400.0;
    let col = net.reference_col[400] - 30.0;
    assert_eq!(a.point(50.0, col, row), b.point(50.0, col, row));
}

#[test]
fn an_untilted_camera_gives_the_lens_principal_point() {
    let optics = Optics {
        camera_tilt_deg: [0.0; 3],
        ..Optics::default()
    };
    let fit = fit_insystem(
        &acquire(&optics, &CalibrationPlan::default()),
        &InsystemOptions::default(),
    )
    .unwrap();
    let m = &fit.model;
    assert!(rel(m.f_px, optics.f_px) < 1e-3, "F {}", m.f_px);
    assert!(rel(m.d_mm, optics.d_mm) < 1e-3, "D {}", m.d_mm);
    assert!(rel(m.l_mm, optics.l_mm) < 1e-3, "L {}", m.l_mm);
    assert!((m.cx - optics.cx).abs() < 0.4, "c_x {}", m.cx);
    assert!((m.cy - optics.cy).abs() < 1.0, "c_y {}", m.cy);
    // The fitted pose of the staircase is where the simulated operator put it.
    let p = CalibrationPlan::default().sim.staircase;
    assert!((fit.block.x_mm - p.x_mm).abs() < 0.1 && (fit.block.yaw_deg - p.yaw_deg).abs() < 0.01);
}

#[test]
fn bad_input_says_what_is_missing() {
    let data = default_data();
    // Too few heights.
    let mut two = data.clone();
    two.plates.truncate(2);
    let e = fit_insystem(&two, &InsystemOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            CalibError::TooFewHeights {
                got: 2,
                need: 3,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("at least 3"), "{e}");
    let plan = CalibrationPlan {
        plate_heights_mm: vec![0.0, 10.0, 10.0],
        ..CalibrationPlan::default()
    };
    assert!(plan
        .check_insystem()
        .unwrap_err()
        .to_string()
        .contains("2 distinct"));
    // A plate the detector never saw.
    let mut dark = data.clone();
    dark.plates[3] = PlateObservation {
        col: vec![f64::NAN; dark.height as usize],
        ..dark.plates[3].clone()
    };
    let e = fit_insystem(&dark, &InsystemOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("plate at 21 mm") && e.to_string().contains("no usable rows"),
        "{e}"
    );
    // A staircase pass that missed the block.
    let mut missed = data.clone();
    for f in &mut missed.stair {
        f.col.fill(f64::NAN);
    }
    let e = fit_insystem(&missed, &InsystemOptions::default()).unwrap_err();
    assert!(e.to_string().contains("staircase"), "{e}");
    // Lines that are no scanner's: nothing usable comes out.
    let mut garbage = data.clone();
    for (k, p) in garbage.plates.iter_mut().enumerate() {
        for (r, c) in p.col.iter_mut().enumerate() {
            if c.is_finite() {
                *c += 3.0 * (((r * 7919 + k * 104_729) % 1000) as f64 / 500.0 - 1.0);
            }
        }
    }
    let e = fit_insystem(&garbage, &InsystemOptions::default()).unwrap_err();
    assert!(
        matches!(
            e,
            CalibError::Implausible(_) | CalibError::NotConverged { .. }
        ),
        "{e}"
    );
}
