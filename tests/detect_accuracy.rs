//! Detectors against the simulator's ground truth (default scanner of docs/method.md section
//! 2.4): the accuracy targets of the improved Bezier detector, and robustness to a glass
//! reflection, specular spikes and Gray16 frames.

use footscan::detect::{build, DetectParams, Threshold, ThresholdParam};
use footscan_bench::detect::{accuracy, noise_config, sweep_frames, Accuracy};
use footscan_hal::PixelFormat;
use footscan_sim::render::NoiseConfig;

const PLATES: [f64; 2] = [0.0, 18.0];
const FOOT_X: [f64; 2] = [120.0, 200.0];

fn run(name: &str, noise: &NoiseConfig) -> Accuracy {
    run_with(name, noise, &DetectParams::default())
}

fn run_with(name: &str, noise: &NoiseConfig, p: &DetectParams) -> Accuracy {
    let frames = sweep_frames(noise, &PLATES, &FOOT_X, 5);
    let mut d = build(name, p).unwrap();
    accuracy(d.as_mut(), &frames)
}

#[test]
fn bezier_plus_noise_free_error_is_within_a_hundredth_of_a_pixel() {
    for sigma in [1.0, 1.6, 2.2, 3.0] {
        let a = run("bezier-plus", &noise_config("none", sigma));
        assert!(a.rms_px <= 0.010, "sigma {sigma}: {a:?}");
        assert!(a.bias_px.abs() < 0.002, "sigma {sigma}: {a:?}");
        assert_eq!(a.outlier_rate, 0.0, "sigma {sigma}: {a:?}");
        assert!(a.inliers > 2000);
    }
}

#[test]
fn bezier_plus_halves_the_cog_error_at_default_noise() {
    for sigma in [1.0, 1.6, 3.0] {
        let noise = noise_config("default", sigma);
        let cog = run("cog", &noise);
        let bp = run("bezier-plus", &noise);
        assert!(
            bp.rms_px <= 0.5 * cog.rms_px,
            "sigma {sigma}: bezier-plus {bp:?} vs cog {cog:?}"
        );
        assert!(bp.outlier_rate < 0.002, "{bp:?}");
    }
}

#[test]
fn the_literal_paper_method_is_worse_than_cog_under_speckle() {
    // What the issue observed, kept as a check that `bezier` stays the paper's method.
    let noise = noise_config("default", 1.6);
    let cog = run("cog", &noise);
    let lit = run("bezier", &noise);
    assert!(lit.rms_px > cog.rms_px, "bezier {lit:?} vs cog {cog:?}");
    let lit0 = run("bezier", &noise_config("none", 1.6));
    assert!(
        lit0.rms_px > 0.02,
        "pixel locking of the literal method: {lit0:?}"
    );
}

#[test]
fn glass_reflection_and_specular_spikes_do_not_make_outliers() {
    // The reflection (0.2 of the line, 44 DN with the ambient) is in every row; rows without
    // the sole show only it, so the threshold is set above it, as on a real scanner.
    let noise = NoiseConfig {
        glass_reflection: 0.2,
        specular_spike_rate: 40.0,
        ..noise_config("default", 1.6)
    };
    let p = DetectParams {
        threshold: Some(ThresholdParam(Threshold::Dn(75.0))),
        ..Default::default()
    };
    for name in ["bezier-plus", "cog"] {
        let a = run_with(name, &noise, &p);
        assert!(a.outlier_rate < 0.002, "{name}: {a:?}");
        // A threshold high on the line costs cog (fewer pixels); bezier-plus keeps its window.
        let bound = if name == "cog" { 0.2 } else { 0.08 };
        assert!(a.rms_px < bound, "{name}: {a:?}");
    }
}

#[test]
fn gray16_frames_match_gray8_accuracy() {
    let n8 = noise_config("default", 1.6);
    let n16 = NoiseConfig {
        format: PixelFormat::Gray16,
        ..n8.clone()
    };
    let (a, b) = (run("bezier-plus", &n8), run("bezier-plus", &n16));
    assert!(
        b.rms_px < a.rms_px * 1.1 && b.outlier_rate < 0.002,
        "{a:?} {b:?}"
    );
}
