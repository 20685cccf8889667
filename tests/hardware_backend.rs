//! The hardware backend without hardware: config/footscan.toml, its validation, a missing
//! camera, and the GRBL slider half opened against the emulator on a pty. (No camera exists in
//! CI; the V4L2 driver itself is proven on vivid under qemu: tests/vivid.)

use footscan::scan::config::{Backend, HardwareSlider, ScanSection};
use footscan::scan::{hardware, run_scan, LoadedConfig, ScanError, ScanOptions};
use footscan_hal::{Slider, SliderState};
use footscan_sim::grbl::{EmulatorConfig, GrblEmulator, MachineState};
use std::path::{Path, PathBuf};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn footscan_text() -> String {
    std::fs::read_to_string(root().join("config/footscan.toml")).unwrap()
}

fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

/// A /dev/videoN that does not exist here.
fn absent_video() -> PathBuf {
    (40..100)
        .map(|n| PathBuf::from(format!("/dev/video{n}")))
        .find(|p| !p.exists())
        .expect("a free /dev/videoN")
}

/// config/footscan.toml with the given camera, port and calibration file.
fn hw_config(dir: &Path, device: &Path, port: &str, calibration: Option<&Path>) -> LoadedConfig {
    let text = footscan_text()
        .replace(
            "device = \"/dev/video0\"",
            &format!("device = {:?}", device),
        )
        .replace("port = \"/dev/ttyUSB0\"", &format!("port = {port:?}"));
    let text = match calibration {
        Some(c) => text.replace(
            "calibration = \"calibration.toml\"",
            &format!("calibration = {:?}", c),
        ),
        None => text.replace("calibration = \"calibration.toml\"", ""),
    };
    let path = dir.join("footscan.toml");
    std::fs::write(&path, &text).unwrap();
    LoadedConfig::load(&path).unwrap()
}

/// The simulator's true calibration (1280x1024, like config/footscan.toml's camera).
fn calibration_file(dir: &Path) -> PathBuf {
    let sim = LoadedConfig::load(&root().join("config/sim.toml")).unwrap();
    let p = dir.join("cal.toml");
    footscan::scan::sim::true_calibration(&sim.config)
        .save(&p)
        .unwrap();
    p
}

/// The simulator is the same kind of backend: a scan through the real GRBL driver rides over
/// line noise on the slider's status reports (asked again, not a failed scan).
#[test]
fn a_sim_scan_rides_over_corrupted_status_reports() {
    let path = root().join("config/sim.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("end_mm = 320.0", "end_mm = 60.0")
        .replace(
            "[sim.optics]",
            "[sim.faults]\nslider_corrupt_status_after_s = 1.0\nslider_corrupt_status_count = 3\n\n[sim.optics]",
        );
    // A third of a foot: no foot measurements.
    let m = text.find("stage = \"measure.foot\"").unwrap();
    let (a, b) = (
        text[..m].rfind("[[pipeline.stages]]").unwrap(),
        m + text[m..].find("[[pipeline.stages]]").unwrap(),
    );
    let text = format!("{}{}", &text[..a], &text[b..]);
    let cfg = LoadedConfig::parse(&path, text).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let summary = run_scan(&cfg, &ScanOptions::new(dir.path()), |_| {}).unwrap();
    println!(
        "{} frames, {} dropped, status {}",
        summary.frames, summary.dropped_frames, summary.status
    );
    assert_eq!(summary.status, "complete");
    assert!(summary.frames >= 100, "{} frames", summary.frames);
    assert!(dir.path().join("points.ply").exists());
}

/// config/sim.toml over `end_mm` without the foot measurement (a part of a foot has none).
fn short_sim_config(end_mm: &str, edit: impl Fn(String) -> String) -> LoadedConfig {
    let path = root().join("config/sim.toml");
    let text = edit(
        std::fs::read_to_string(&path)
            .unwrap()
            .replace("end_mm = 320.0", &format!("end_mm = {end_mm}")),
    );
    let m = text.find("stage = \"measure.foot\"").unwrap();
    let (a, b) = (
        text[..m].rfind("[[pipeline.stages]]").unwrap(),
        m + text[m..].find("[[pipeline.stages]]").unwrap(),
    );
    LoadedConfig::parse(&path, format!("{}{}", &text[..a], &text[b..])).unwrap()
}

/// The laser on the emulator's spindle output: the scan switches it on, takes a laser-off
/// frame at rest at each end (no line in any row of either), subtracts the first from every
/// frame, and switches the laser off at the end.
#[test]
fn a_sim_scan_takes_laser_off_frames_at_both_ends() {
    let cfg = short_sim_config("60.0", |t| {
        t.replace("home = true", "home = true\nbackground = \"ends\"")
            .replace("[sim.slider]", "[sim.slider]\nlaser = \"spindle\"")
    });
    let dir = tempfile::tempdir().unwrap();
    let summary = run_scan(&cfg, &ScanOptions::new(dir.path()), |_| {}).unwrap();
    let truth = summary.truth.clone().unwrap();
    println!(
        "{} frames, laser off {:?}, truth {truth:?}",
        summary.frames, summary.laser_off
    );
    assert_eq!(summary.status, "complete");
    let off = summary.laser_off.expect("laser-off frames counted");
    assert_eq!(off.frames, 2, "one at each end");
    assert_eq!(off.rows_found, 0, "false detections in laser-off frames");
    // Every scan frame had the laser on: the line is found where the truth has it.
    assert!(summary.frames >= 50, "{} frames", summary.frames);
    assert!(truth.compared > 10_000, "{truth:?}");
    assert!(truth.missed_rows * 50 < truth.compared, "{truth:?}");
    assert!(truth.rms_mm < 0.2, "{truth:?}");

    // Without a laser the controller switches, laser-off frames cannot be taken.
    let path = root().join("config/sim.toml");
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("home = true", "home = true\nbackground = \"ends\"");
    let e = LoadedConfig::parse(&path, text).unwrap_err().to_string();
    assert!(
        e.contains("scan.background") && e.contains("sim.slider.laser"),
        "{e}"
    );
}

#[test]
fn footscan_toml_parses_with_the_sim_pipeline() {
    let cfg = LoadedConfig::load(&root().join("config/footscan.toml")).unwrap();
    assert_eq!(cfg.config.scanner.backend, Backend::Hardware);
    let hw = cfg.config.hardware.as_ref().unwrap();
    assert_eq!(hw.camera.device, Path::new("/dev/video0"));
    assert_eq!((hw.camera.width, hw.camera.height), (1280, 1024));
    assert_eq!(hw.slider.port, "/dev/ttyUSB0");
    assert_eq!(hw.slider.baud, 115_200);
    assert_eq!(
        cfg.calibration_path().unwrap(),
        root().join("config/calibration.toml")
    );
    let sim = LoadedConfig::load(&root().join("config/sim.toml")).unwrap();
    let stages = |c: &LoadedConfig| -> Vec<String> {
        c.config
            .pipeline
            .stages
            .iter()
            .map(|s| s.stage.clone())
            .collect()
    };
    assert_eq!(
        stages(&cfg),
        stages(&sim),
        "same pipeline as config/sim.toml"
    );
    assert!(sim.config.hardware.is_none());
}

#[test]
fn a_missing_camera_is_a_setup_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let cal = calibration_file(dir.path());
    let video = absent_video();
    let cfg = hw_config(dir.path(), &video, "/dev/ttyFOOTSCAN-none", Some(&cal));
    let out = dir.path().join("scan");
    let e = run_scan(&cfg, &ScanOptions::new(&out), |_| {}).unwrap_err();
    let msg = e.to_string();
    println!("{msg}");
    assert!(matches!(e, ScanError::Setup(_)), "{e:?}");
    assert!(msg.contains(&video.display().to_string()), "{msg}");
    assert!(msg.contains("v4l2-ctl --list-devices"), "{msg}");
    assert!(
        !msg.contains("ttyFOOTSCAN"),
        "the camera is opened first: {msg}"
    );
    let json = std::fs::read_to_string(out.join("scan.json")).unwrap();
    assert!(
        json.contains("\"failed\"") && json.contains("v4l2-ctl"),
        "{json}"
    );
}

#[test]
fn a_scan_with_the_emulator_as_slider_and_no_camera_fails_cleanly() {
    let emu = GrblEmulator::spawn(EmulatorConfig::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let cal = calibration_file(dir.path());
    let video = absent_video();
    let port = emu.port_path().to_string_lossy().into_owned();
    let cfg = hw_config(dir.path(), &video, &port, Some(&cal));
    let out = dir.path().join("scan");
    let e = run_scan(&cfg, &ScanOptions::new(&out), |_| {}).unwrap_err();
    let msg = e.to_string();
    println!("{msg}");
    assert!(
        msg.contains("camera") && msg.contains(&video.display().to_string()),
        "{msg}"
    );
    // A scanner that cannot see never moves: the controller was not even homed.
    assert_eq!(emu.state(), MachineState::Alarm);
    assert_eq!(emu.machine_x(), 0.0);
    let json = std::fs::read_to_string(out.join("scan.json")).unwrap();
    assert!(json.contains("\"failed\""), "{json}");
    assert!(
        !out.join("points.ply").exists(),
        "nothing written as complete"
    );
}

#[test]
fn hardware_scans_need_a_matching_calibration() {
    let dir = tempfile::tempdir().unwrap();
    let video = absent_video();
    let cfg = hw_config(dir.path(), &video, "/dev/ttyFOOTSCAN-none", None);
    let e = run_scan(&cfg, &ScanOptions::new(dir.path().join("a")), |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("calibration") && e.contains("--calibration"),
        "{e}"
    );
    // A calibration named by the config but absent: the file and where it was named.
    let cfg2 = hw_config(
        dir.path(),
        &video,
        "/dev/ttyFOOTSCAN-none",
        Some(&dir.path().join("nope.toml")),
    );
    let e = run_scan(&cfg2, &ScanOptions::new(dir.path().join("c")), |_| {})
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("nope.toml") && e.contains("scanner.calibration"),
        "{e}"
    );
    assert!(
        !e.contains(&video.display().to_string()),
        "checked first: {e}"
    );
    // --calibration wins over the config; a calibration for another camera size is refused.
    let sim = LoadedConfig::load(&root().join("config/sim.toml")).unwrap();
    let mut c = footscan::scan::sim::true_calibration(&sim.config);
    c.model.width = 640;
    c.model.cx = 320.0;
    let small = dir.path().join("small.toml");
    c.save(&small).unwrap();
    let mut opts = ScanOptions::new(dir.path().join("b"));
    opts.calibration = Some(small);
    let e = run_scan(&cfg, &opts, |_| {}).unwrap_err().to_string();
    assert!(e.contains("640x1024") && e.contains("1280x1024"), "{e}");
}

#[test]
fn hardware_sections_are_validated_with_line_and_column() {
    let text = footscan_text();
    let parse = |t: String| {
        LoadedConfig::parse(Path::new("scanner.toml"), t)
            .unwrap_err()
            .to_string()
    };
    // Unknown keys, named with their line and column.
    let t = text.replace("buffers = 4 ", "buffers = 4\n  exposure = 300 ");
    let line = line_of(&t, "exposure = 300");
    let e = parse(t);
    assert!(e.contains("exposure") && e.contains("scanner.toml"), "{e}");
    assert!(e.contains(&format!("line {line}, column 3")), "{e}");
    let t = text.replace("baud = 115200", "baud = 115200\nbaudrate = 9600");
    let line = line_of(&t, "baudrate");
    let e = parse(t);
    assert!(
        e.contains("baudrate") && e.contains(&format!("line {line}, column 1")),
        "{e}"
    );
    // Bad values: the key, its place, and what is valid.
    let t = text.replace("baud = 115200", "baud = 12345");
    let line = line_of(&t, "baud = 12345");
    let e = parse(t);
    assert!(
        e.contains("hardware.slider.baud = 12345") && e.contains("115200"),
        "{e}"
    );
    assert!(e.contains(&format!("line {line}")), "{e}");
    let e = parse(text.replace("pixel_format = \"auto\"", "pixel_format = \"NV12\""));
    assert!(
        e.contains("NV12") && e.contains("RGB3") && e.contains("BA81"),
        "{e}"
    );
    // Colour formats: a channel is needed, and a grey format cannot give a colour channel.
    let e = parse(text.replace("pixel_format = \"auto\"", "pixel_format = \"RGB3\""));
    assert!(
        e.contains("RGB3") && e.contains("channel") && e.contains("red-minus-others"),
        "{e}"
    );
    let e = parse(text.replace(
        "pixel_format = \"auto\"",
        "pixel_format = \"GREY\"\nchannel = \"red\"",
    ));
    assert!(e.contains("GREY") && e.contains("channel red"), "{e}");
    let ok = text.replace(
        "pixel_format = \"auto\"",
        "pixel_format = \"RGGB\"\nchannel = \"red-minus-others\"",
    );
    let c = LoadedConfig::parse(Path::new("scanner.toml"), ok).unwrap();
    let cam = &c.config.hardware.as_ref().unwrap().camera;
    assert_eq!(cam.channel, Some(footscan_hal::Channel::RedMinusOthers));
    let e = parse(text.replace("pixel_format = \"auto\"", "channel = \"purple\""));
    assert!(
        e.contains("purple") && e.contains("green-minus-others"),
        "{e}"
    );
    let e = parse(text.replace("buffers = 4 ", "buffers = 2 "));
    assert!(
        e.contains("hardware.camera.buffers = 2") && e.contains("4 to 32"),
        "{e}"
    );
    let e = parse(text.replace("homing_timeout_s = 60.0", "homing_timeout_s = 0"));
    assert!(e.contains("hardware.slider.homing_timeout_s"), "{e}");
    let e = parse(text.replace("max_feed_mm_min = 3000.0", "max_feed_mm_min = 600.0"));
    assert!(
        e.contains("1500 mm/min") && e.contains("max_feed_mm_min"),
        "{e}"
    );
    // A hardware backend without its sections, and a missing required key.
    let cut = text.find("[hardware.camera]").unwrap();
    let end = text.find("[pipeline]").unwrap();
    let e = parse(format!("{}{}", &text[..cut], &text[end..]));
    assert!(
        e.contains("[hardware.camera]") && e.contains("backend"),
        "{e}"
    );
    let e = parse(text.replace("width = 1280 ", "# width"));
    assert!(e.contains("width"), "{e}");
}

#[test]
fn the_slider_half_opens_against_the_emulator_and_reports_status() {
    let emu = GrblEmulator::spawn(EmulatorConfig::default()).unwrap();
    let port = emu.port_path().to_string_lossy().into_owned();
    let cfg = HardwareSlider {
        port: port.clone(),
        poll_hz: 100.0,
        ..Default::default()
    };
    let scan = ScanSection::default();
    let mut s = hardware::open_slider(&cfg, &scan, 1500.0).unwrap();
    assert_eq!(s.config().poll_interval.as_millis(), 10);
    let st = s.status().unwrap();
    println!("{st:?} {:?}", s.build_info());
    assert_eq!(st.state, SliderState::Idle, "homed (scan.home)");
    assert_eq!(st.x_mm, 0.0);
    assert!(st.timestamp.nanos > 0);
    s.move_to(12.5, 3000.0).unwrap();
    assert_eq!(
        s.wait_idle(std::time::Duration::from_secs(10))
            .unwrap()
            .x_mm,
        12.5
    );
    drop(s);

    // The controller's own limits are checked before anything moves.
    let e = hardware::open_slider(&cfg, &scan, 6000.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("$110") && e.contains(&port), "{e}");
    let far = ScanSection {
        end_mm: 400.0,
        ..Default::default()
    };
    let e = hardware::open_slider(&cfg, &far, 1500.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("$130") && e.contains("400"), "{e}");
    // No homing and a locked controller: refused, never unlocked behind the operator's back.
    let emu2 = GrblEmulator::spawn(EmulatorConfig::default()).unwrap();
    let cfg2 = HardwareSlider {
        port: emu2.port_path().to_string_lossy().into_owned(),
        ..Default::default()
    };
    let no_home = ScanSection {
        home: false,
        ..Default::default()
    };
    let e = hardware::open_slider(&cfg2, &no_home, 1500.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("alarm") && e.contains("$X"), "{e}");
    assert_eq!(emu2.state(), MachineState::Alarm);
    // Homing asked of a controller without a homing cycle.
    let emu3 = GrblEmulator::spawn(EmulatorConfig {
        homing_enabled: false,
        ..Default::default()
    })
    .unwrap();
    let cfg3 = HardwareSlider {
        port: emu3.port_path().to_string_lossy().into_owned(),
        ..Default::default()
    };
    let e = hardware::open_slider(&cfg3, &scan, 1500.0)
        .unwrap_err()
        .to_string();
    assert!(e.contains("$22=0") && e.contains("scan.home"), "{e}");
    let mut s = hardware::open_slider(&cfg3, &no_home, 1500.0).unwrap();
    assert_eq!(s.status().unwrap().state, SliderState::Idle, "never locked");
    // A port that is not there names itself and where to look.
    let gone = HardwareSlider {
        port: "/dev/ttyFOOTSCAN-none".into(),
        ..Default::default()
    };
    let e = hardware::open_slider(&gone, &scan, 1500.0)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("/dev/ttyFOOTSCAN-none") && e.contains("/dev/serial/by-id"),
        "{e}"
    );
}
