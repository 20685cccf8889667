//! Laser-line detectors against the simulator's ground truth, and their speed beside the
//! memory-bandwidth floor.
//!
//! Frames: the default scanner of docs/method.md section 2.4 (`Optics::default()`), the line
//! at sigma 0.6-3.0 px, five noise levels:
//! - `none`: noise disabled (exact pixel-integrated Gaussian plus ambient, rounded);
//! - `default`: read noise 2 DN, shot noise at 40 e-/DN, 15 % speckle;
//! - `double`: read noise 4 DN, 20 e-/DN (twice the shot-noise variance), 30 % speckle;
//! - `shot4`: the default with strong shot noise, 4 e-/DN (a small-pixel sensor at high gain);
//! - `speckle4`: the default with the speckle correlated along the row over 4 px (grains
//!   wider than a pixel do not average out across the line's few pixels).
//!
//! Slope sweep: straight lines crossing rows at 0, 0.5, 1, 1.5 and 2.5 px per row
//! ([`footscan_sim::render::render_sloped_line`], sigma across the line), 512 x 160, three
//! seeds per cell, bezier-plus beside cog at every noise level.
//!
//! Scenes per (sigma, noise): flat plates at 0, 6, 18 and 45 mm (the line is slanted and curved
//! by the tilts and the distortion, so its rows sweep every subpixel offset) and the default
//! foot at four head positions (walls, arches, line ends).
//!
//! Metrics over the rows whose truth has a line: `rms_px`, `bias_px` (mean signed error) and
//! `max_px` over the inliers; `outlier_rate` = (rows with |error| > 1 px, truth rows with no
//! accepted line, accepted rows without a truth line) / truth rows.
//!
//! Speed: 1280x1024 Gray8 default-noise foot frames, a set of `speed_frames` distinct frames
//! cycled (so with enough frames they stream from memory rather than sit in the core's cache);
//! the floor is [`sum_bytes`] over the same frames in the same run, one core. Time is the
//! thread's CPU time, so other processes sharing the core do not count against either.

use footscan::detect::simd::with_isa;
use footscan::detect::{build, sum_bytes, DetectParams, Detector, Isa, LinePeak, NAMES};
use footscan_hal::{Frame, PixelFormat, Pixels, Timestamp};
use footscan_sim::foot::{Foot, FootParams};
use footscan_sim::optics::Optics;
use footscan_sim::render::{FrameTruth, NoiseConfig, Renderer, RowTruth, Scene};
use serde::Serialize;

/// One line of the table / one object of the JSON array.
#[derive(Clone, Debug, Serialize)]
pub struct DetectRow {
    pub detector: String,
    pub sigma_px: f64,
    pub noise: String,
    pub rms_px: f64,
    pub bias_px: f64,
    pub max_px: f64,
    pub outlier_rate: f64,
    pub fps_per_core: f64,
    pub floor_fps_per_core: f64,
    /// Slope sweep rows: px per row of the straight line (None: the scene sweep).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub slope_px_per_row: Option<f64>,
}

/// Noise levels of the sweep.
pub const NOISE_LEVELS: [&str; 5] = ["none", "default", "double", "shot4", "speckle4"];
/// Line sigmas of the sweep (px).
pub const SIGMAS: [f64; 6] = [0.6, 1.0, 1.6, 2.0, 2.5, 3.0];
/// Slopes of the slope sweep (px per row).
pub const SLOPES: [f64; 5] = [0.0, 0.5, 1.0, 1.5, 2.5];
/// Detectors of the slope sweep: the estimator and the baseline it must beat.
pub const SLOPE_DETECTORS: [&str; 2] = ["bezier-plus", "cog"];

/// The noise configuration called `level` at line sigma `sigma`.
pub fn noise_config(level: &str, sigma: f64) -> NoiseConfig {
    let d = NoiseConfig::default();
    let base = NoiseConfig {
        line_sigma_px: sigma,
        ..d.clone()
    };
    match level {
        "none" => NoiseConfig {
            enabled: false,
            ..base
        },
        "default" => base,
        "double" => NoiseConfig {
            read_noise_dn: 2.0 * d.read_noise_dn,
            electrons_per_dn: 0.5 * d.electrons_per_dn,
            speckle: 2.0 * d.speckle,
            ..base
        },
        "shot4" => NoiseConfig {
            electrons_per_dn: 4.0,
            ..base
        },
        "speckle4" => NoiseConfig {
            speckle_corr_px: 4.0,
            ..base
        },
        other => panic!("unknown noise level {other}"),
    }
}

/// Simulator frames with truth: plates and foot positions (see the module doc).
pub fn sweep_frames(
    noise: &NoiseConfig,
    plates: &[f64],
    foot_x: &[f64],
    seed: u64,
) -> Vec<(Frame, FrameTruth)> {
    let optics = Optics::default();
    let mut out = Vec::new();
    let mut k = 0u64;
    let mut push = |scene: Scene, xs: &[f64], out: &mut Vec<(Frame, FrameTruth)>| {
        let mut r = Renderer::new(optics.clone(), noise.clone(), scene, seed).expect("renderer");
        for &x in xs {
            let (px, truth) = r.render(x, k);
            out.push((
                Frame::new(k, Timestamp::default(), optics.width, optics.height, px),
                truth,
            ));
            k += 1;
        }
    };
    for &h in plates {
        push(Scene::Plate { height_mm: h }, &[100.0], &mut out);
    }
    if !foot_x.is_empty() {
        let foot = Foot::new(FootParams::default()).expect("default foot");
        push(Scene::Foot(foot), foot_x, &mut out);
    }
    out
}

/// Error statistics of one detector on a set of frames.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Accuracy {
    pub rms_px: f64,
    pub bias_px: f64,
    pub max_px: f64,
    pub outlier_rate: f64,
    pub inliers: usize,
    pub truth_rows: usize,
}

/// Compare `det` with the truth on `frames`.
pub fn accuracy(det: &mut dyn Detector, frames: &[(Frame, FrameTruth)]) -> Accuracy {
    let mut out = Vec::new();
    let (mut n, mut s, mut s2, mut mx) = (0usize, 0.0f64, 0.0f64, 0.0f64);
    let (mut truth_rows, mut outliers) = (0usize, 0usize);
    for (f, t) in frames {
        out.resize(f.height as usize, LinePeak::NONE);
        det.detect(f, &mut out);
        for (p, tr) in out.iter().zip(&t.rows) {
            match (tr, p.is_valid()) {
                (RowTruth::Line { col, .. }, true) => {
                    truth_rows += 1;
                    let e = p.col - col;
                    if e.abs() > 1.0 {
                        outliers += 1;
                    } else {
                        n += 1;
                        s += e;
                        s2 += e * e;
                        mx = mx.max(e.abs());
                    }
                }
                (RowTruth::Line { .. }, false) => {
                    truth_rows += 1;
                    outliers += 1;
                }
                (RowTruth::NoLine, true) => outliers += 1,
                (RowTruth::NoLine, false) => {}
            }
        }
    }
    let nf = n.max(1) as f64;
    Accuracy {
        rms_px: (s2 / nf).sqrt(),
        bias_px: s / nf,
        max_px: mx,
        outlier_rate: outliers as f64 / truth_rows.max(1) as f64,
        inliers: n,
        truth_rows,
    }
}

/// CPU time of the calling thread, s: time the thread was not running (another process on the
/// core) does not count, so "per core" figures hold on a shared machine.
pub fn thread_cpu_s() -> f64 {
    // SAFETY: clock_gettime writes one timespec.
    let mut ts: libc::timespec = unsafe { std::mem::zeroed() };
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// Frames per second of `det` over `frames` (cycled for at least `seconds`), on this thread.
pub fn detector_fps(det: &mut dyn Detector, frames: &[Frame], seconds: f64) -> f64 {
    let mut out = vec![LinePeak::NONE; frames[0].height as usize];
    for f in frames {
        det.detect(f, &mut out); // warm-up: scratch sized, pages touched
    }
    let t0 = thread_cpu_s();
    let mut count = 0u64;
    loop {
        for f in frames {
            det.detect(f, &mut out);
            count += 1;
        }
        std::hint::black_box(&out);
        if thread_cpu_s() - t0 >= seconds {
            break;
        }
    }
    count as f64 / (thread_cpu_s() - t0)
}

/// Frames per second of [`sum_bytes`] over `frames`: the memory-bandwidth floor.
pub fn floor_fps(frames: &[Frame], seconds: f64) -> f64 {
    let bytes = |f: &Frame| match &f.pixels {
        Pixels::Gray8(v) => sum_bytes(v),
        Pixels::Gray16(v) => {
            // SAFETY: u16 has no padding; viewing its bytes is sound.
            let b = unsafe { std::slice::from_raw_parts(v.as_ptr() as *const u8, v.len() * 2) };
            sum_bytes(b)
        }
    };
    let mut acc = 0u64;
    for f in frames {
        acc = acc.wrapping_add(bytes(f));
    }
    let t0 = thread_cpu_s();
    let mut count = 0u64;
    loop {
        for f in frames {
            acc = acc.wrapping_add(bytes(std::hint::black_box(f)));
            count += 1;
        }
        if thread_cpu_s() - t0 >= seconds {
            break;
        }
    }
    std::hint::black_box(acc);
    count as f64 / (thread_cpu_s() - t0)
}

/// Options of the benchmark.
#[derive(Clone, Debug)]
pub struct Options {
    /// Distinct frames cycled in the speed test.
    pub speed_frames: usize,
    /// Seconds per speed measurement.
    pub seconds: f64,
    /// Sigmas and noise levels of the sweep.
    pub sigmas: Vec<f64>,
    pub noise: Vec<String>,
    /// Detectors (default: all).
    pub detectors: Vec<String>,
    /// Slopes of the slope sweep (empty: none).
    pub slopes: Vec<f64>,
    /// Instruction sets timed (empty: every one this CPU runs).
    pub isas: Vec<Isa>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            speed_frames: 64,
            seconds: 0.5,
            sigmas: SIGMAS.to_vec(),
            noise: NOISE_LEVELS.iter().map(|s| s.to_string()).collect(),
            detectors: NAMES.iter().map(|s| s.to_string()).collect(),
            slopes: SLOPES.to_vec(),
            isas: Vec::new(),
        }
    }
}

/// One detector's speed on one instruction set, beside the floor measured in the same run.
#[derive(Clone, Debug, Serialize)]
pub struct SpeedRow {
    pub detector: String,
    /// `scalar`, `sse4.1`, `avx2`, `avx512` ([`Isa`]).
    pub isa: String,
    pub fps_per_core: f64,
    pub floor_fps_per_core: f64,
    /// The detector's time per frame over the floor's.
    pub ratio: f64,
}

/// Speed of every detector on every instruction set this CPU runs, and the floor, one core.
/// The floor is timed before and after the detectors and the faster kept (the machine is
/// shared: the faster reading is the nearer to the floor's own cost).
pub fn speed_by_isa(opts: &Options) -> Vec<SpeedRow> {
    let frames = speed_frames(opts);
    super::on_one_core(|| {
        let floor_before = floor_fps(&frames, opts.seconds);
        let mut fps = Vec::new();
        let isas = if opts.isas.is_empty() {
            Isa::available()
        } else {
            opts.isas.clone()
        };
        for isa in isas {
            for name in &opts.detectors {
                let mut det = build(name, &DetectParams::default()).expect("detector");
                let f = with_isa(isa, || detector_fps(det.as_mut(), &frames, opts.seconds))
                    .expect("an available set");
                fps.push((name.clone(), isa, f));
            }
        }
        let floor = floor_before.max(floor_fps(&frames, opts.seconds));
        fps.into_iter()
            .map(|(detector, isa, f)| SpeedRow {
                detector,
                isa: isa.as_str().into(),
                fps_per_core: f,
                floor_fps_per_core: floor,
                ratio: floor / f,
            })
            .collect()
    })
}

/// The speed rows as a table: per detector, frames/s per core and the ratio to the floor for
/// each instruction set.
pub fn speed_table(rows: &[SpeedRow]) -> String {
    let Some(first) = rows.first() else {
        return String::new();
    };
    let mut s = format!(
        "\nspeed, one core, 1280x1024 Gray8 (floor: sum of every byte, {:.0} frames/s)\n{:<12} {:>7} {:>10} {:>9}\n",
        first.floor_fps_per_core, "detector", "isa", "fps/core", "x floor"
    );
    for r in rows {
        s += &format!(
            "{:<12} {:>7} {:>10.0} {:>9.2}\n",
            r.detector, r.isa, r.fps_per_core, r.ratio
        );
    }
    s
}

fn speed_frames(opts: &Options) -> Vec<Frame> {
    let noise = NoiseConfig {
        format: PixelFormat::Gray8,
        ..NoiseConfig::default()
    };
    let n = opts.speed_frames.max(1);
    let xs: Vec<f64> = (0..n).map(|k| 40.0 + 250.0 * k as f64 / n as f64).collect();
    sweep_frames(&noise, &[], &xs, 7)
        .into_iter()
        .map(|(f, _)| f)
        .collect()
}

/// The whole benchmark: accuracy rows (their speed on the detected instruction set) and the
/// speed of every detector on every set.
pub fn run(opts: &Options) -> (Vec<DetectRow>, Vec<SpeedRow>) {
    let speed = speed_by_isa(opts);
    let best = Isa::detected().as_str();
    let fps: Vec<(String, f64)> = speed
        .iter()
        .filter(|r| r.isa == best)
        .map(|r| (r.detector.clone(), r.fps_per_core))
        .collect();
    let floor = speed.first().map_or(f64::NAN, |r| r.floor_fps_per_core);
    let mut rows = Vec::new();
    for &sigma in &opts.sigmas {
        for level in &opts.noise {
            let noise = noise_config(level, sigma);
            let frames = sweep_frames(
                &noise,
                &[0.0, 6.0, 18.0, 45.0],
                &[60.0, 120.0, 180.0, 240.0],
                11,
            );
            for name in &opts.detectors {
                let mut det = build(name, &DetectParams::default()).expect("detector");
                let a = accuracy(det.as_mut(), &frames);
                rows.push(DetectRow {
                    detector: name.clone(),
                    sigma_px: sigma,
                    noise: level.clone(),
                    rms_px: a.rms_px,
                    bias_px: a.bias_px,
                    max_px: a.max_px,
                    outlier_rate: a.outlier_rate,
                    fps_per_core: fps
                        .iter()
                        .find(|(n, _)| n == name)
                        .map(|x| x.1)
                        .unwrap_or(f64::NAN),
                    floor_fps_per_core: floor,
                    slope_px_per_row: None,
                });
            }
        }
    }
    rows.extend(slope_sweep(opts, &fps, floor));
    (rows, speed)
}

/// RMS error over rows 8..h-8 of the sloped frames (a row without a line counts as 1 px, an
/// error is capped at 1 px), and the rows found.
fn sloped_rms(det: &mut dyn Detector, frames: &[(Frame, Vec<f64>)]) -> (f64, f64) {
    let (mut s, mut n, mut found) = (0.0, 0usize, 0usize);
    for (f, truth) in frames {
        let mut out = vec![LinePeak::NONE; truth.len()];
        det.detect(f, &mut out);
        for r in 8..truth.len() - 8 {
            n += 1;
            s += if out[r].is_valid() {
                found += 1;
                (out[r].col - truth[r]).powi(2).min(1.0)
            } else {
                1.0
            };
        }
    }
    ((s / n.max(1) as f64).sqrt(), found as f64 / n.max(1) as f64)
}

/// bezier-plus and cog on straight lines over slope x sigma x noise (see the module doc).
pub fn slope_sweep(opts: &Options, fps: &[(String, f64)], floor: f64) -> Vec<DetectRow> {
    let (w, h) = (512usize, 160usize);
    let mut rows = Vec::new();
    for &slope in &opts.slopes {
        for &sigma in &opts.sigmas {
            for level in &opts.noise {
                let noise = noise_config(level, sigma);
                let frames: Vec<(Frame, Vec<f64>)> = (1..=3u64)
                    .map(|seed| {
                        let (px, t) = footscan_sim::render::render_sloped_line(
                            w,
                            h,
                            slope,
                            &noise,
                            seed * 1000 + (slope * 10.0) as u64,
                        );
                        let f = Frame::new(0, Timestamp::default(), w as u32, h as u32, {
                            Pixels::Gray8(px)
                        });
                        (f, t)
                    })
                    .collect();
                for name in SLOPE_DETECTORS {
                    let mut det = build(name, &DetectParams::default()).expect("detector");
                    let (rms, found) = sloped_rms(det.as_mut(), &frames);
                    rows.push(DetectRow {
                        detector: name.to_string(),
                        sigma_px: sigma,
                        noise: level.clone(),
                        rms_px: rms,
                        bias_px: f64::NAN,
                        max_px: f64::NAN,
                        outlier_rate: 1.0 - found,
                        fps_per_core: fps
                            .iter()
                            .find(|(n, _)| n == name)
                            .map(|x| x.1)
                            .unwrap_or(f64::NAN),
                        floor_fps_per_core: floor,
                        slope_px_per_row: Some(slope),
                    });
                }
            }
        }
    }
    rows
}

/// The slope sweep as one line per slope and sigma: bezier-plus's RMS without noise, then per
/// noise level bezier-plus's and cog's RMS and their ratio.
pub fn slope_table(rows: &[DetectRow]) -> String {
    let sw: Vec<&DetectRow> = rows
        .iter()
        .filter(|r| r.slope_px_per_row.is_some())
        .collect();
    if sw.is_empty() {
        return String::new();
    }
    let mut levels: Vec<&str> = Vec::new();
    for r in &sw {
        if r.noise != "none" && !levels.contains(&r.noise.as_str()) {
            levels.push(&r.noise);
        }
    }
    let get = |slope: f64, sigma: f64, level: &str, det: &str| {
        sw.iter()
            .find(|r| {
                r.slope_px_per_row == Some(slope)
                    && r.sigma_px == sigma
                    && r.noise == level
                    && r.detector == det
            })
            .map_or(f64::NAN, |r| r.rms_px)
    };
    let mut s = String::from(
        "
slope x sigma: straight lines, RMS px (bp = bezier-plus, ratio = bp / cog)
",
    );
    s += &format!("{:>5} {:>5} {:>9}", "slope", "sigma", "bp none");
    for l in &levels {
        s += &format!(" | {:>8} {:>6} {:>5}", format!("bp {l}"), "cog", "ratio");
    }
    s += "
";
    let mut keys: Vec<(f64, f64)> = Vec::new();
    for r in &sw {
        let k = (r.slope_px_per_row.unwrap(), r.sigma_px);
        if !keys.contains(&k) {
            keys.push(k);
        }
    }
    for (slope, sigma) in keys {
        s += &format!(
            "{slope:>5.1} {sigma:>5.1} {:>9.4}",
            get(slope, sigma, "none", "bezier-plus")
        );
        for l in &levels {
            let (bp, cog) = (
                get(slope, sigma, l, "bezier-plus"),
                get(slope, sigma, l, "cog"),
            );
            s += &format!(" | {bp:>8.4} {cog:>6.4} {:>5.2}", bp / cog);
        }
        s += "
";
    }
    s
}

/// The rows as a text table, with the speed summary.
pub fn table(rows: &[DetectRow]) -> String {
    let mut s = format!(
        "{:<12} {:>5} {:>8} {:>8} {:>9} {:>8} {:>8} {:>9} {:>9}\n",
        "detector", "sigma", "noise", "rms_px", "bias_px", "max_px", "outlier", "fps/core", "floor"
    );
    for r in rows.iter().filter(|r| r.slope_px_per_row.is_none()) {
        s += &format!(
            "{:<12} {:>5.1} {:>8} {:>8.4} {:>9.4} {:>8.3} {:>8.4} {:>9.0} {:>9.0}\n",
            r.detector,
            r.sigma_px,
            r.noise,
            r.rms_px,
            r.bias_px,
            r.max_px,
            r.outlier_rate,
            r.fps_per_core,
            r.floor_fps_per_core
        );
    }
    if let Some(bp) = rows.iter().find(|r| r.detector == "bezier-plus") {
        s += &format!(
            "\nbezier-plus {:.0} frames/s per core, floor {:.0}: {:.2}x the floor's time\n",
            bp.fps_per_core,
            bp.floor_fps_per_core,
            bp.floor_fps_per_core / bp.fps_per_core
        );
    }
    s += &slope_table(rows);
    s
}
