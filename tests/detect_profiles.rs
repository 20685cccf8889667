//! Every detector on analytic rows: pixel-integrated Gaussian lines at known subpixel centres
//! across a pixel, saturated flat tops, a second (weaker or equal) line, specular spikes, lines
//! at the border, Gray16.

use footscan::detect::{build, DetectParams, LinePeak, Reject, Threshold, ThresholdParam, NAMES};
use footscan_hal::{Frame, Pixels, Timestamp};

/// Ambient + sum of pixel-integrated Gaussians (centre, sigma, peak) of one row, unrounded.
fn row_f(w: usize, lines: &[(f64, f64, f64)]) -> Vec<f64> {
    (0..w)
        .map(|i| {
            let mut v = 8.0;
            for &(c, s, a) in lines {
                let k = 1.0 / (s * std::f64::consts::SQRT_2);
                let e = libm::erf((i as f64 + 0.5 - c) * k) - libm::erf((i as f64 - 0.5 - c) * k);
                v += a * s * (std::f64::consts::PI / 2.0).sqrt() * e;
            }
            v
        })
        .collect()
}

fn frame8(rows: &[Vec<f64>]) -> Frame {
    let w = rows[0].len();
    let px = rows
        .iter()
        .flat_map(|r| r.iter().map(|v| v.round().clamp(0.0, 255.0) as u8))
        .collect();
    Frame::new(
        0,
        Timestamp::default(),
        w as u32,
        rows.len() as u32,
        Pixels::Gray8(px),
    )
}

fn frame16(rows: &[Vec<f64>]) -> Frame {
    let w = rows[0].len();
    let px = rows
        .iter()
        .flat_map(|r| {
            r.iter()
                .map(|v| (v * 257.0).round().clamp(0.0, 65535.0) as u16)
        })
        .collect();
    Frame::new(
        0,
        Timestamp::default(),
        w as u32,
        rows.len() as u32,
        Pixels::Gray16(px),
    )
}

fn detect(name: &str, p: &DetectParams, f: &Frame) -> Vec<LinePeak> {
    let mut d = build(name, p).unwrap();
    let mut out = vec![LinePeak::NONE; f.height as usize];
    d.detect(f, &mut out);
    out
}

/// Max |error| each detector may make on noise-free lines of sigma 1.6 (8-bit rounding
/// included). The 3-point fits and the literal Bezier lock onto pixels; the others do not.
fn bound(name: &str) -> f64 {
    match name {
        "bezier" => 0.08,
        "bezier-plus" => 0.012,
        "cog" => 0.04,
        "parabolic" => 0.06,
        "gaussian" => 0.03,
        "blais-rioux" => 0.04,
        "steger" => 0.05,
        _ => unreachable!(),
    }
}

/// 41 centres across one pixel; rows are independent lines, so bezier-plus's smoothing along
/// rows is switched off here (the lines jump by 1/40 px per row: smoothing would average
/// offsets, which is the next test).
fn offsets() -> Vec<f64> {
    (0..=40).map(|k| 200.0 + k as f64 / 40.0).collect()
}

#[test]
fn every_detector_finds_subpixel_centres_across_a_pixel() {
    for sigma in [1.0, 1.6, 2.5] {
        let cs = offsets();
        let rows: Vec<Vec<f64>> = cs
            .iter()
            .map(|&c| row_f(400, &[(c, sigma, 180.0)]))
            .collect();
        let f = frame8(&rows);
        for name in NAMES {
            let p = if name == "bezier-plus" {
                DetectParams {
                    smooth_rows: Some(0.0),
                    ..Default::default()
                }
            } else {
                DetectParams::default()
            };
            let out = detect(name, &p, &f);
            let mut worst: f64 = 0.0;
            for (o, c) in out.iter().zip(&cs) {
                assert!(o.is_valid(), "{name} sigma {sigma}: no line at {c}: {o:?}");
                worst = worst.max((o.col - c).abs());
                assert!(o.intensity > 100.0 && o.quality > 0.0 && o.width > 1.5);
            }
            let b = bound(name) * if sigma == 1.6 { 1.0 } else { 3.0 };
            assert!(worst < b, "{name} sigma {sigma}: max error {worst} >= {b}");
            if name == "bezier-plus" {
                assert!(worst < 0.012, "bezier-plus sigma {sigma}: {worst}");
            }
        }
    }
}

#[test]
fn bezier_plus_with_smoothing_on_a_slanted_line() {
    // A line moving 0.013 px per row: every offset, and smoothing along rows applies.
    for sigma in [1.0, 1.6, 3.0] {
        let cs: Vec<f64> = (0..300).map(|r| 300.0 + 0.013 * r as f64).collect();
        let rows: Vec<Vec<f64>> = cs
            .iter()
            .map(|&c| row_f(600, &[(c, sigma, 180.0)]))
            .collect();
        let out = detect("bezier-plus", &DetectParams::default(), &frame8(&rows));
        let rms = (out
            .iter()
            .zip(&cs)
            .map(|(o, c)| (o.col - c).powi(2))
            .sum::<f64>()
            / cs.len() as f64)
            .sqrt();
        assert!(rms < 0.010, "sigma {sigma}: rms {rms}");
    }
}

#[test]
fn saturated_flat_tops_are_centred_or_rejected_when_too_long() {
    // Peak 600 DN: clipped at 255 over ~4 px; symmetric, so the centre stays.
    let cs = [150.0, 150.25, 150.5, 150.75];
    let rows: Vec<Vec<f64>> = cs.iter().map(|&c| row_f(300, &[(c, 1.6, 600.0)])).collect();
    let f = frame8(&rows);
    for name in NAMES {
        let p = if name == "bezier-plus" {
            DetectParams {
                smooth_rows: Some(0.0),
                ..Default::default()
            }
        } else {
            DetectParams::default()
        };
        let out = detect(name, &p, &f);
        for (o, c) in out.iter().zip(&cs) {
            assert!(o.is_valid(), "{name}: {o:?}");
            assert_eq!(o.intensity, 255.0);
            assert!(
                o.quality <= 0.5,
                "{name}: saturated rows have reduced quality"
            );
            let tol = match name {
                "parabolic" | "gaussian" | "bezier" => 0.5,
                _ => 0.15,
            };
            assert!((o.col - c).abs() < tol, "{name}: {} vs {c}", o.col);
        }
    }
    // A very wide saturated run (over 12 px) is rejected as saturated.
    let wide = frame8(&[row_f(300, &[(150.0, 4.0, 2000.0)])]);
    for name in NAMES {
        let out = detect(name, &DetectParams::default(), &wide);
        assert_eq!(out[0].reject, Some(Reject::Saturated), "{name}");
        assert!(out[0].col.is_nan());
    }
}

#[test]
fn weaker_second_line_is_ignored_and_equal_one_is_ambiguous() {
    let weak = row_f(400, &[(150.3, 1.6, 180.0), (300.0, 1.6, 60.0)]);
    let equal = row_f(400, &[(150.3, 1.6, 180.0), (300.0, 1.6, 175.0)]);
    // An equal second line with no line in the rows before is ambiguous; below a row that
    // holds the line, the peak that continues it is taken (the reflection beside it is not).
    let f = frame8(&[equal.clone(), weak, equal]);
    for name in NAMES {
        let p = DetectParams {
            smooth_rows: (name == "bezier-plus").then_some(0.0),
            ..Default::default()
        };
        let out = detect(name, &p, &f);
        assert_eq!(
            out[0].reject,
            Some(Reject::Ambiguous),
            "{name}: {:?}",
            out[0]
        );
        for k in [1, 2] {
            assert!(
                out[k].is_valid() && (out[k].col - 150.3).abs() < 0.1,
                "{name} row {k}: {:?}",
                out[k]
            );
            assert!(out[k].quality > 0.0);
        }
    }
    // ambiguity > 1 turns the test off: the stronger line is taken.
    let out = detect(
        "cog",
        &DetectParams {
            ambiguity: Some(2.0),
            ..Default::default()
        },
        &f,
    );
    assert!((out[0].col - 150.3).abs() < 0.1);
}

#[test]
fn specular_spikes_are_skipped() {
    // 3-px saturated spikes beside the line (as the simulator draws them) and alone.
    let mut with_spike = row_f(400, &[(150.4, 1.6, 160.0)]);
    for v in &mut with_spike[170..173] {
        *v = 255.0;
    }
    let mut far = row_f(400, &[(150.4, 1.6, 160.0)]);
    for v in &mut far[10..13] {
        *v = 255.0;
    }
    let mut only_spike = row_f(400, &[]);
    for v in &mut only_spike[100..103] {
        *v = 255.0;
    }
    let f = frame8(&[with_spike, far, only_spike]);
    for name in NAMES {
        let p = DetectParams {
            smooth_rows: (name == "bezier-plus").then_some(0.0),
            ..Default::default()
        };
        let out = detect(name, &p, &f);
        for o in &out[..2] {
            assert!(o.is_valid() && (o.col - 150.4).abs() < 0.1, "{name}: {o:?}");
        }
        assert_eq!(out[2].reject, Some(Reject::BelowThreshold), "{name}");
    }
}

#[test]
fn lines_at_the_border_are_rejected_or_measured_with_a_smaller_window() {
    // Each case on three rows (a line crosses rows: a lone row is rejected as isolated); the
    // middle one of each is checked.
    let cases = [
        row_f(200, &[(0.8, 1.6, 180.0)]),   // cut by the left edge
        row_f(200, &[(199.4, 1.6, 180.0)]), // cut by the right edge
        row_f(200, &[(6.3, 1.6, 180.0)]),   // close, but whole
        row_f(200, &[]),                    // no line
    ];
    let rows: Vec<Vec<f64>> = cases
        .iter()
        .flat_map(|r| std::iter::repeat_n(r.clone(), 3))
        .collect();
    let f = frame8(&rows);
    let middle = |out: Vec<LinePeak>| -> Vec<LinePeak> { (0..4).map(|k| out[3 * k + 1]).collect() };
    for name in NAMES {
        let p = DetectParams {
            smooth_rows: (name == "bezier-plus").then_some(0.0),
            ..Default::default()
        };
        let out = middle(detect(name, &p, &f));
        assert_eq!(out[0].reject, Some(Reject::Border), "{name}: {:?}", out[0]);
        assert_eq!(out[1].reject, Some(Reject::Border), "{name}: {:?}", out[1]);
        assert_eq!(out[3].reject, Some(Reject::BelowThreshold), "{name}");
        match out[2].reject {
            None => assert!((out[2].col - 6.3).abs() < 0.1, "{name}: {:?}", out[2]),
            Some(r) => assert_eq!(r, Reject::Border, "{name}"),
        }
    }
    // The improved detector shrinks its window rather than give up.
    let out = middle(detect(
        "bezier-plus",
        &DetectParams {
            smooth_rows: Some(0.0),
            ..Default::default()
        },
        &f,
    ));
    assert!(out[2].is_valid(), "{:?}", out[2]);
}

#[test]
fn gray16_gives_the_gray8_answer() {
    let cs: Vec<f64> = (0..20).map(|k| 100.0 + k as f64 * 0.05).collect();
    let rows: Vec<Vec<f64>> = cs.iter().map(|&c| row_f(256, &[(c, 1.6, 180.0)])).collect();
    let (f8, f16) = (frame8(&rows), frame16(&rows));
    for name in NAMES {
        let p = DetectParams {
            smooth_rows: (name == "bezier-plus").then_some(0.0),
            ..Default::default()
        };
        let (a, b) = (detect(name, &p, &f8), detect(name, &p, &f16));
        for ((x, y), c) in a.iter().zip(&b).zip(&cs) {
            assert!(y.is_valid(), "{name}: {y:?}");
            // 16 bits keep the sub-DN detail 8 bits round away: at least as close to truth.
            assert!(
                (y.col - c).abs() < bound(name) + 1e-3,
                "{name}: {} vs {c}",
                y.col
            );
            assert!((x.col - y.col).abs() < 2.0 * bound(name), "{name}");
            assert!((y.intensity / 257.0 - x.intensity).abs() < 1.0, "{name}");
        }
    }
    // The threshold is in 8-bit DN for both formats: a 20 DN line is below 30 in both.
    let dim = vec![row_f(256, &[(100.0, 1.6, 12.0)])];
    let fixed = DetectParams {
        threshold: Some(ThresholdParam(Threshold::Dn(30.0))),
        ..Default::default()
    };
    for name in NAMES {
        assert_eq!(
            detect(name, &fixed, &frame16(&dim))[0].reject,
            Some(Reject::BelowThreshold)
        );
    }
}

#[test]
fn unknown_detector_and_parameters_are_refused() {
    assert!(build("nope", &DetectParams::default()).is_err());
    let bad = DetectParams {
        window: Some(8),
        ..Default::default()
    };
    assert!(build("cog", &bad).is_err());
    assert!(build("bezier", &bad).is_ok());
    assert!(build(
        "cog",
        &DetectParams {
            threshold: Some(ThresholdParam(Threshold::Dn(300.0))),
            ..Default::default()
        }
    )
    .is_err());
}

/// Columns of bezier-plus for a vertical line whose column follows `path(row)`, noise-free.
fn bezier_plus_path(path: impl Fn(usize) -> f64, rows: usize, noise_rows: bool) -> Vec<f64> {
    let cs: Vec<f64> = (0..rows).map(&path).collect();
    let mut frame_rows: Vec<Vec<f64>> =
        cs.iter().map(|&c| row_f(200, &[(c, 1.6, 180.0)])).collect();
    if noise_rows {
        // Deterministic +-3 DN ripple so the frame's column noise is not zero.
        for (r, row) in frame_rows.iter_mut().enumerate() {
            for (i, v) in row.iter_mut().enumerate() {
                *v += 3.0 * (((r * 31 + i * 17) % 7) as f64 - 3.0) / 3.0;
            }
        }
    }
    let out = detect(
        "bezier-plus",
        &DetectParams::default(),
        &frame8(&frame_rows),
    );
    out.iter().map(|o| o.col).collect()
}

#[test]
fn smoothing_along_the_line_costs_at_most_half_a_millimetre() {
    // Rows are 0.125 mm apart at the glass: 0.5 mm = 4 rows.
    // A 0.4 px step: the 10-90 % rise of the measured columns spans at most 4 rows.
    let base = 100.3;
    let cols = bezier_plus_path(|r| if r < 60 { base } else { base + 0.4 }, 120, true);
    let rel: Vec<f64> = cols.iter().map(|c| (c - base) / 0.4).collect();
    let first = rel.iter().position(|&v| v > 0.1).unwrap();
    let last = rel.iter().position(|&v| v > 0.9).unwrap();
    eprintln!("10-90 % rise: {} rows", last - first);
    assert!(
        last - first <= 4,
        "10-90 % rise over {} rows: {:?}",
        last - first,
        &rel[50..70]
    );
    // A one-row bump of 0.4 px: the response is at most 4 rows wide at half its height.
    let cols = bezier_plus_path(|r| if r == 60 { base + 0.4 } else { base }, 120, true);
    let resp: Vec<f64> = cols.iter().map(|c| c - base).collect();
    let peak = resp.iter().copied().fold(0.0, f64::max);
    let above = resp.iter().filter(|&&v| v >= 0.5 * peak).count();
    eprintln!("one-row bump: peak {peak:.3} of 0.4 px, {above} rows at half height");
    assert!(above <= 4, "FWHM {above} rows: {:?}", &resp[54..67]);
}
