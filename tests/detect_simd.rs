//! The SIMD paths of the detectors against the scalar path (issue 34): on every instruction
//! set this CPU runs, every detector finds the same rows as the scalar code, at columns
//! within 1e-4 px, on the speed benchmark's simulated frames (Gray8 and Gray16, foot and
//! plates, every noise level) and on the real frames of ../shared/data/frames.

use footscan::detect::simd::with_isa;
use footscan::detect::{build_with_prep, files, DetectParams, Isa, LinePeak, NAMES};
use footscan_bench::detect::{noise_config, sweep_frames, NOISE_LEVELS};
use footscan_hal::{Frame, PixelFormat};
use std::path::PathBuf;

/// Every detector's output on `frame` with `params`, on `isa`.
fn detect_on(isa: Isa, name: &str, params: &DetectParams, frame: &Frame) -> Vec<LinePeak> {
    let (mut det, _) = build_with_prep(name, params).expect("detector");
    let mut out = vec![LinePeak::NONE; frame.height as usize];
    with_isa(isa, || det.detect(frame, &mut out)).expect("an available set");
    out
}

/// Same rows accepted, the same reasons for the others, columns within 1e-4 px.
fn assert_same(what: &str, scalar: &[LinePeak], simd: &[LinePeak]) {
    for (r, (a, b)) in scalar.iter().zip(simd).enumerate() {
        assert_eq!(a.reject, b.reject, "{what}: row {r}");
        if a.is_valid() {
            assert!(
                (a.col - b.col).abs() <= 1e-4,
                "{what}: row {r}: scalar {} vs {}",
                a.col,
                b.col
            );
        }
    }
}

fn compare(label: &str, params: &DetectParams, frames: &[Frame]) -> usize {
    let mut rows = 0;
    for name in NAMES {
        for (k, f) in frames.iter().enumerate() {
            let scalar = detect_on(Isa::Scalar, name, params, f);
            rows += scalar.iter().filter(|p| p.is_valid()).count();
            for isa in Isa::available().into_iter().skip(1) {
                let out = detect_on(isa, name, params, f);
                assert_same(&format!("{label} frame {k} {name} {isa:?}"), &scalar, &out);
            }
        }
    }
    rows
}

#[test]
fn simulated_frames_give_the_scalar_result_on_every_set() {
    let mut rows = 0;
    for level in NOISE_LEVELS {
        for format in [PixelFormat::Gray8, PixelFormat::Gray16] {
            let noise = footscan_sim::render::NoiseConfig {
                format,
                ..noise_config(level, 1.6)
            };
            let frames: Vec<Frame> = sweep_frames(&noise, &[6.0], &[120.0], 5)
                .into_iter()
                .map(|(f, _)| f)
                .collect();
            rows += compare(
                &format!("{level} {format:?}"),
                &DetectParams::default(),
                &frames,
            );
        }
    }
    // The comparison covered lines, not empty frames.
    assert!(rows > 10_000, "{rows} rows with a line");
}

#[test]
fn real_frames_give_the_scalar_result_on_every_set() {
    let dir = match std::env::var_os("FOOTSCAN_DATA") {
        Some(d) => PathBuf::from(d).join("frames"),
        None => PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data/frames"),
    };
    let entries = footscan_bench::real::manifest(&dir).expect("frames MANIFEST.csv");
    let mut rows = 0;
    for e in entries
        .iter()
        .filter(|e| e.laser != "none" && !e.channel.is_empty())
    {
        let img = files::load_image(&dir.join(&e.path), 0).expect("frame");
        let img = if e.transpose { img.transposed() } else { img };
        let params = DetectParams {
            channel: Some(footscan::detect::Channel::parse(&e.channel).expect("channel")),
            ..Default::default()
        };
        let (_, mut prep) = build_with_prep("cog", &params).expect("prep");
        let frame = prep.prepare(&img, &e.path).expect("channel image");
        rows += compare(&e.path, &params, std::slice::from_ref(frame));
    }
    assert!(rows > 1_000, "{rows} rows with a line");
}
