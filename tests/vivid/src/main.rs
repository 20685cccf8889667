//! The driver on a real kernel V4L2 driver: vivid in loopback, inside a VM (tests/vivid/run.sh).
//!
//! For 640x480 and 1280x720 GREY, and 640x480 RGB3 and YUYV (a red line over a grey
//! checkerboard, reduced by the driver to red-minus-others): simulator frames with a laser line
//! over the foot, each with its id written in the first rows, go out through vivid's HDMI
//! output and come back on its HDMI capture through the whole V4L2 capture path, read by
//! `footscan-v4l2`. Checks:
//! sequence numbers increase (gaps are counted as dropped frames), timestamps are monotonic and
//! spaced by the frame period times the sequence step, every captured frame equals the frame
//! regenerated for its id bit for bit (colour frames: the driver's channel of the capture
//! against the same conversion of the frame sent), and the project's detectors find the line in the
//! captured frames to the same accuracy (against the renderer's truth) as in the originals.
//! Then, on the last stream: the output stops being fed (the loop freezes on its last frame,
//! the capture goes on), the capture stalls (vivid drops every buffer: `next_frame` must time
//! out, not hang) and recovers, and the device is unplugged (vivid's Disconnect: `next_frame`
//! must report the disconnect).
//!
//! Prints `VIVID ...` lines and `vivid: N passed, M failed`; exits 0 only if all passed.

mod code;
mod feeder;
mod scene;
mod yuyv;

use footscan::detect::{self, DetectParams, LinePeak};
use footscan_hal::{Camera, Channel, Frame, HalError, Pixels, Timestamp};
use footscan_sim::render::{FrameTruth, RowTruth};
use footscan_v4l2::format::Converter;
use footscan_v4l2::{dv, SourceFormat, V4l2Camera, V4l2Config};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::sync::Arc;
use std::time::{Duration, Instant};

const CAPTURE: &str = "/dev/video0";
const OUTPUT: &str = "/dev/video1";
const HDMI_INPUT: u32 = 3;
const HDMI_OUTPUT: u32 = 1;
// vivid's private controls (drivers/media/test-drivers/vivid/vivid-ctrls.c, base 0x00f0f000).
const VIVID_OSD_TEXT_MODE: u32 = 0x00f0_f001;
const VIVID_LOOP_VIDEO: u32 = 0x00f0_f025;
const VIVID_PERC_DROPPED: u32 = 0x00f0_f040;
const VIVID_DISCONNECT: u32 = 0x00f0_f041;
/// Detectors evaluated on captured and original frames.
const DETECTORS: [&str; 2] = ["cog", "bezier-plus"];

struct Checks {
    passed: u32,
    failed: u32,
}

impl Checks {
    fn check(&mut self, name: &str, ok: bool, detail: impl std::fmt::Display) -> bool {
        if ok {
            self.passed += 1;
            println!("VIVID PASS {name}: {detail}");
        } else {
            self.failed += 1;
            println!("VIVID FAIL {name}: {detail}");
        }
        ok
    }
}

fn uptime() -> f64 {
    std::fs::read_to_string("/proc/uptime")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(f64::NAN)
}

/// Detector accuracy over a set of frames, rows below the id code.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Accuracy {
    frames: u32,
    truth_rows: u64,
    found: u64,
    false_rows: u64,
    sum_sq: f64,
    max_abs: f64,
}

impl Accuracy {
    fn add(&mut self, peaks: &[LinePeak], truth: &FrameTruth) {
        self.frames += 1;
        for (r, (p, t)) in peaks.iter().zip(&truth.rows).enumerate() {
            if r <= code::ID_ROWS {
                continue;
            }
            match t {
                RowTruth::Line { col, .. } => {
                    self.truth_rows += 1;
                    if p.is_valid() {
                        let e = p.col - col;
                        self.found += 1;
                        self.sum_sq += e * e;
                        self.max_abs = self.max_abs.max(e.abs());
                    }
                }
                RowTruth::NoLine => self.false_rows += p.is_valid() as u64,
            }
        }
    }
    fn rms(&self) -> f64 {
        (self.sum_sq / self.found.max(1) as f64).sqrt()
    }
}

impl std::fmt::Display for Accuracy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} frames, {}/{} truth rows found, rms {:.4} px, max {:.4} px, {} false rows",
            self.frames,
            self.found,
            self.truth_rows,
            self.rms(),
            self.max_abs,
            self.false_rows
        )
    }
}

struct Captured {
    frame: Frame,
    id: Option<u32>,
}

fn gray8(f: &Frame) -> &[u8] {
    match &f.pixels {
        Pixels::Gray8(v) => v,
        Pixels::Gray16(_) => &[],
    }
}

/// Frames until `n` arrive or one call fails.
fn capture(cam: &mut V4l2Camera, n: usize, w: usize) -> Result<Vec<Captured>, HalError> {
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let frame = cam.next_frame(Duration::from_secs(3))?;
        let id = code::read_id(gray8(&frame), w);
        out.push(Captured { frame, id });
    }
    Ok(out)
}

/// One loop through vivid: frames in `format` (GREY, RGB24 or YUYV; the colour ones reduced to
/// `channel` by the driver), `n` captured.
fn loop_case(
    checks: &mut Checks,
    (w, h): (u32, u32),
    format: SourceFormat,
    channel: Option<Channel>,
    n: usize,
    last: bool,
) -> Result<(), String> {
    let fourcc: [u8; 4] = format.fourcc().repr;
    let case = format!("{w}x{h} {}", String::from_utf8_lossy(&fourcc));
    let t_case = Instant::now();
    let cfg = V4l2Config {
        path: CAPTURE.into(),
        width: w,
        height: h,
        formats: vec![format],
        channel,
        fps: Some(60.0),
        buffers: 4,
        input: Some(HDMI_INPUT),
        dv_timings: true,
        ..V4l2Config::default()
    };
    let mut cam = V4l2Camera::open(&cfg).map_err(|e| format!("open capture: {e}"))?;
    let timings = dv::dv_timings(cam.fd()).map_err(|e| format!("G_DV_TIMINGS: {e}"))?;
    let info = cam.info();
    println!(
        "VIVID {case}: capture {} ({}), timings {timings:?}, format {} stride {}, {:.3} fps",
        info.name,
        cam.capabilities().card,
        cam.converter().format,
        cam.converter().stride,
        info.fps
    );
    checks.check(
        &format!("{case} negotiate"),
        info.width == w && info.height == h && cam.converter().format == format,
        format!(
            "{} {}x{} at {:.2} fps, channel {channel:?}",
            cam.converter().format.fourcc(),
            info.width,
            info.height,
            info.fps
        ),
    );
    cam.set_control(VIVID_LOOP_VIDEO, 1)
        .map_err(|e| format!("Loop Video: {e}"))?;
    cam.set_control(VIVID_OSD_TEXT_MODE, 2)
        .map_err(|e| format!("OSD Text Mode: {e}"))?;
    if cam.controls().gain.is_some() {
        let r = cam.set_gain(100.0);
        let ok = r.is_ok() && cam.gain() == 100.0 && cam.control(0x0098_0913).ok() == Some(100);
        checks.check(
            &format!("{case} gain"),
            ok,
            format!("set 100, reads {}", cam.gain()),
        );
    }
    let r = cam.set_exposure_us(5000);
    println!(
        "VIVID {case}: exposure control: {:?}",
        r.map(|_| cam.exposure_us()).map_err(|e| e.to_string())
    );

    // The images of the cycle, rendered once; the feeder writes each frame's id in.
    let t = Instant::now();
    let mut frames = scene::Frames::new(w, h);
    let images: Vec<Vec<u8>> = (0..scene::CYCLE)
        .map(|j| frames.render_format(j, &fourcc).0)
        .collect();
    let t_render = t.elapsed();
    let fdr = feeder::Feeder::start(
        Path::new(OUTPUT),
        HDMI_OUTPUT,
        &timings,
        (w, h),
        &fourcc,
        Arc::new(images),
    )?;
    cam.start().map_err(|e| format!("start: {e}"))?;
    let t = Instant::now();
    let caps = capture(&mut cam, n, w as usize).map_err(|e| format!("capture: {e}"))?;
    let t_capture = t.elapsed();
    let stats = cam.stats();
    println!(
        "VIVID {case}: captured {} frames in {:.2} s ({:.1} fps), fed {} so far; stats {stats:?}",
        caps.len(),
        t_capture.as_secs_f64(),
        caps.len() as f64 / t_capture.as_secs_f64(),
        fdr.next_id.load(Ordering::SeqCst)
    );

    if last {
        stall_and_unplug(checks, &case, &mut cam, &fdr, w as usize);
    }
    let fed = fdr.finish();
    if !last {
        checks.check(
            &format!("{case} output"),
            fed.is_ok(),
            format!("{fed:?} frames fed"),
        );
    } else {
        println!("VIVID {case}: feeder after unplug: {fed:?}");
    }
    let stop = cam.stop();
    checks.check(&format!("{case} stop"), stop.is_ok(), format!("{stop:?}"));
    drop(cam);

    // Sequence numbers and timestamps.
    // Debian's kernels tick at HZ=250.
    const JIFFY_S: f64 = 4e-3;
    let period = 1.0 / timings.fps();
    let mut seq_ok = true;
    let mut ts_ok = true;
    let mut gaps = 0u64;
    let mut ratios = Vec::with_capacity(caps.len());
    for p in caps.windows(2) {
        let (a, b) = (&p[0].frame, &p[1].frame);
        if b.seq <= a.seq {
            seq_ok = false;
            continue;
        }
        gaps += b.seq - a.seq - 1;
        if b.timestamp <= a.timestamp {
            ts_ok = false;
            continue;
        }
        ratios.push(b.timestamp.secs_after(a.timestamp) / ((b.seq - a.seq) as f64 * period));
    }
    ratios.sort_by(f64::total_cmp);
    let at = |q: f64| {
        ratios
            .get((q * ratios.len().saturating_sub(1) as f64).round() as usize)
            .copied()
    };
    let (rmin, median, rmax) = (
        at(0.0).unwrap_or(f64::NAN),
        at(0.5).unwrap_or(f64::NAN),
        at(1.0).unwrap_or(f64::NAN),
    );
    checks.check(
        &format!("{case} sequence"),
        seq_ok && gaps == stats.dropped,
        format!(
            "seq {}..{} increasing: {seq_ok}; {gaps} frames missing in the gaps, driver counted {} dropped",
            caps[0].frame.seq,
            caps[caps.len() - 1].frame.seq,
            stats.dropped
        ),
    );
    // vivid stamps a buffer with ktime when its thread fills it, and the thread wakes on
    // jiffies: single steps jitter by a jiffy or more under TCG (4 ms at HZ=250, a quarter of
    // a period), and when the host starves the VM the thread catches up with frames stamped
    // about 1 ms apart (a step of 0.065 periods in CI on a busy host). Those are the VM's
    // scheduling, not the driver's: the check bounds the long-run rate and the median step
    // (within a jiffy of the period: steps are whole jiffies, 16 or 20 ms at 60 Hz) and only
    // reports the extremes.
    let now = Timestamp::now();
    let (first, lastf) = (&caps[0].frame, &caps[caps.len() - 1].frame);
    let mean =
        lastf.timestamp.secs_after(first.timestamp) / ((lastf.seq - first.seq) as f64 * period);
    checks.check(
        &format!("{case} timestamps"),
        ts_ok
            && stats.driver_timestamps == stats.frames
            && (0.98..=1.02).contains(&mean)
            && (median - 1.0).abs() * period <= JIFFY_S + 0.5e-3
            && first.timestamp < now
            && now.secs_after(first.timestamp) < 600.0,
        format!(
            "monotonic: {ts_ok}; {} of {} stamped by the driver on CLOCK_MONOTONIC; spacing / (seq step x {:.3} ms): mean {mean:.4}, median step {median:.3}, steps in [{rmin:.3}, {rmax:.3}]",
            stats.driver_timestamps,
            stats.frames,
            period * 1e3
        ),
    );

    // Frames: each captured frame against the frame regenerated for its id, converted by the
    // driver's own converter (the identity for GREY).
    let mut conv = Converter::new(format, w, h, 0)
        .with_channel(channel)
        .map_err(|e| format!("converter: {e}"))?;
    let t = Instant::now();
    let valid: Vec<&Captured> = caps.iter().filter(|c| c.id.is_some()).collect();
    let leading_invalid = caps.iter().take_while(|c| c.id.is_none()).count();
    let mut fresh = scene::Frames::new(w, h);
    let mut originals: BTreeMap<u32, (Vec<u8>, FrameTruth)> = BTreeMap::new();
    let (mut exact, mut differing) = (0u32, 0u32);
    for c in &valid {
        let id = c.id.unwrap();
        let (orig, _) = originals.entry(id).or_insert_with(|| {
            let (raw, truth) = fresh.render_format(id, &fourcc);
            let mut grey = Pixels::Gray8(vec![0; (w * h) as usize]);
            conv.convert(&raw, &mut grey).expect("a whole frame");
            let Pixels::Gray8(g) = grey else {
                unreachable!("Gray8")
            };
            (g, truth)
        });
        let got = gray8(&c.frame);
        if got == orig.as_slice() {
            exact += 1;
        } else {
            differing += 1;
            let n = got.iter().zip(orig.iter()).filter(|(a, b)| a != b).count();
            println!(
                "VIVID {case}: frame id {id} seq {}: {n} pixels differ",
                c.frame.seq
            );
        }
    }
    let t_compare = t.elapsed();
    checks.check(
        &format!("{case} loop"),
        valid.len() * 2 >= caps.len() && originals.len() >= 10 && leading_invalid + valid.len() == caps.len(),
        format!(
            "{} of {} captured frames carry an id ({} distinct); the {} without one all lead the stream",
            valid.len(),
            caps.len(),
            originals.len(),
            leading_invalid
        ),
    );
    checks.check(
        &format!("{case} bit-exact"),
        differing == 0 && exact > 0,
        format!("{exact} frames compared equal to their regenerated originals, {differing} differ"),
    );

    // Detectors on captured and original frames, against the renderer's truth.
    let t = Instant::now();
    for name in DETECTORS {
        let mut det = match detect::build(name, &DetectParams::default()) {
            Ok(d) => d,
            Err(e) => {
                checks.check(&format!("{case} {name}"), false, e);
                continue;
            }
        };
        let mut peaks = vec![LinePeak::NONE; h as usize];
        let (mut on_cap, mut on_orig) = (Accuracy::default(), Accuracy::default());
        for c in &valid {
            let (orig, truth) = &originals[&c.id.unwrap()];
            det.detect(&c.frame, &mut peaks);
            on_cap.add(&peaks, truth);
            let of = Frame::new(
                c.frame.seq,
                c.frame.timestamp,
                w,
                h,
                Pixels::Gray8(orig.clone()),
            );
            det.detect(&of, &mut peaks);
            on_orig.add(&peaks, truth);
        }
        println!("VIVID {case} {name} captured: {on_cap}");
        println!("VIVID {case} {name} original: {on_orig}");
        checks.check(
            &format!("{case} {name} accuracy"),
            on_cap == on_orig && on_cap.found > 0 && on_cap.rms() < 0.5,
            format!(
                "captured rms {:.4} px over {} rows = original rms {:.4} px over {} rows",
                on_cap.rms(),
                on_cap.found,
                on_orig.rms(),
                on_orig.found
            ),
        );
    }
    let t_detect = t.elapsed();
    println!(
        "VIVID TIME {case}: prerender {:.2} s, capture {:.2} s, compare {:.2} s, detect {:.2} s, case {:.2} s; frames compared {exact}",
        t_render.as_secs_f64(),
        t_capture.as_secs_f64(),
        t_compare.as_secs_f64(),
        t_detect.as_secs_f64(),
        t_case.elapsed().as_secs_f64()
    );
    Ok(())
}

/// Output stopped, capture stalled, device unplugged: errors in bounded time, never a hang.
fn stall_and_unplug(
    checks: &mut Checks,
    case: &str,
    cam: &mut V4l2Camera,
    fdr: &feeder::Feeder,
    w: usize,
) {
    // 1. Stop feeding the output mid-stream: vivid keeps looping the output buffer it holds,
    //    so the capture goes on delivering, frozen on the last frame fed.
    fdr.pause.store(true, Ordering::SeqCst);
    std::thread::sleep(Duration::from_millis(300));
    let last_fed = fdr.next_id.load(Ordering::SeqCst).saturating_sub(1);
    let t = Instant::now();
    let after = capture(cam, 20, w);
    match after {
        Ok(fs) => {
            let ids: Vec<Option<u32>> = fs.iter().map(|c| c.id).collect();
            let tail = &ids[10..];
            let frozen =
                tail.iter().all(|&i| i == tail[0]) && tail[0].is_some_and(|i| i <= last_fed);
            checks.check(
                &format!("{case} output stopped"),
                frozen,
                format!(
                    "capture goes on ({} frames in {:.2} s) frozen on frame id {:?} (last fed {last_fed})",
                    fs.len(),
                    t.elapsed().as_secs_f64(),
                    tail[0]
                ),
            );
        }
        Err(e) => {
            checks.check(&format!("{case} output stopped"), false, e);
        }
    }

    // 2. A stalled capture: vivid drops every buffer. Drain what was already filled, then
    //    next_frame must time out after its timeout, not hang.
    let timeout = Duration::from_millis(500);
    if let Err(e) = cam.set_control(VIVID_PERC_DROPPED, 100) {
        checks.check(&format!("{case} stall"), false, e);
        return;
    }
    let mut result = None;
    for _ in 0..20 {
        let t = Instant::now();
        match cam.next_frame(timeout) {
            Ok(_) => continue,
            Err(e) => {
                result = Some((e, t.elapsed()));
                break;
            }
        }
    }
    match result {
        Some((e, took)) => checks.check(
            &format!("{case} stall"),
            e.is_timeout() && took >= timeout && took < timeout + Duration::from_millis(500),
            format!("next_frame({timeout:?}) returned after {took:?}: {e}"),
        ),
        None => checks.check(&format!("{case} stall"), false, "frames kept coming"),
    };
    let _ = cam.set_control(VIVID_PERC_DROPPED, 0);
    let r = cam.next_frame(Duration::from_secs(3));
    checks.check(
        &format!("{case} stall recovery"),
        r.is_ok(),
        format!("after the stall: {:?}", r.map(|f| f.seq)),
    );

    // 3. Unplug: vivid's Disconnect unregisters the nodes while streaming.
    let t = Instant::now();
    let set = cam.set_control(VIVID_DISCONNECT, 1);
    let mut outcome = None;
    for _ in 0..10 {
        match cam.next_frame(Duration::from_secs(2)) {
            Ok(_) => continue,
            Err(e) => {
                outcome = Some(e);
                break;
            }
        }
    }
    let took = t.elapsed();
    match outcome {
        Some(e) => checks.check(
            &format!("{case} unplug"),
            e.is_disconnect() && took < Duration::from_secs(2),
            format!("Disconnect ({set:?}); next_frame after {took:?}: {e}"),
        ),
        None => checks.check(&format!("{case} unplug"), false, "frames kept coming"),
    };
}

fn main() {
    let boot = uptime();
    let t0 = Instant::now();
    println!("VIVID BOOT guest uptime at test start: {boot:.2} s");
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(120);
    let mut checks = Checks {
        passed: 0,
        failed: 0,
    };

    let cams = footscan_v4l2::discover::list_cameras();
    for c in &cams {
        let fmts: Vec<&str> = c.formats.iter().map(|f| f.fourcc.as_str()).collect();
        println!(
            "VIVID camera {}: {} ({}, {}), formats {}",
            c.path.display(),
            c.caps.card,
            c.caps.driver,
            c.caps.bus,
            fmts.join(" ")
        );
    }
    checks.check(
        "discovery",
        cams.iter().any(|c| {
            c.path == Path::new(CAPTURE)
                && c.caps.driver == "vivid"
                && c.formats
                    .iter()
                    .any(|f| f.source == Some(SourceFormat::Grey))
        }),
        format!("{} capture nodes", cams.len()),
    );

    // Grey at two sizes, then the colour formats reduced to red-minus-others by the driver;
    // the last case also stalls and unplugs the device.
    let rmo = Some(Channel::RedMinusOthers);
    let cases = [
        ((640, 480), SourceFormat::Grey, None, n),
        ((640, 480), SourceFormat::Rgb24, rmo, n / 2),
        ((640, 480), SourceFormat::Yuyv, rmo, n / 2),
        ((1280, 720), SourceFormat::Grey, None, n),
    ];
    for (i, &(size, format, channel, frames)) in cases.iter().enumerate() {
        let last = i + 1 == cases.len();
        if let Err(e) = loop_case(&mut checks, size, format, channel, frames, last) {
            checks.check(&format!("{size:?} {format:?}"), false, e);
        }
    }
    println!(
        "VIVID TIME test {:.2} s (guest uptime {:.2} s)",
        t0.elapsed().as_secs_f64(),
        uptime()
    );
    println!("vivid: {} passed, {} failed", checks.passed, checks.failed);
    std::process::exit(if checks.failed == 0 { 0 } else { 1 });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_are_reproducible_and_carry_their_id() {
        let mut a = scene::Frames::new(640, 480);
        let mut b = scene::Frames::new(640, 480);
        let (fa, ta) = a.render(21);
        let (fb, tb) = b.render(21);
        assert_eq!(fa, fb);
        assert_eq!(ta, tb);
        assert_eq!(code::read_id(&fa, 640), Some(21));
        assert!(
            ta.line_count() > 100,
            "the line misses the foot: {}",
            ta.line_count()
        );
        // Same image, other id: only the code rows differ.
        let (fc, _) = a.render(21 + scene::CYCLE);
        assert_eq!(fa[code::ID_ROWS * 640..], fc[code::ID_ROWS * 640..]);
    }

    #[test]
    fn detector_accuracy_on_the_test_frames() {
        let (w, h) = (1280, 720);
        let mut s = scene::Frames::new(w, h);
        for name in DETECTORS {
            let mut det = detect::build(name, &DetectParams::default()).unwrap();
            let mut acc = Accuracy::default();
            let mut peaks = vec![LinePeak::NONE; h as usize];
            for id in [0, 5, 11] {
                let (px, truth) = s.render(id);
                let f = Frame::new(0, Timestamp::default(), w, h, Pixels::Gray8(px));
                det.detect(&f, &mut peaks);
                acc.add(&peaks, &truth);
            }
            assert!(acc.found * 10 >= acc.truth_rows * 9, "{name}: {acc}");
            assert!(acc.rms() < 0.5, "{name}: {acc}");
        }
    }
}
