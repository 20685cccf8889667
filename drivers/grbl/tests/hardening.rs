//! The driver's hardened behaviours against the emulator over real ptys, one injected fault at
//! a time: reset and banner, settings and build info, homing failure and timeout, streaming a
//! long program within the RX buffer, status polling, error and alarm meanings, jog cancel,
//! timeouts on every wait, dropped answers, corrupted reports, reconnect.

use footscan_grbl::{alarm_message, error_message, GrblConfig, GrblSlider};
use footscan_hal::{HalError, Slider, SliderState, Timestamp};
use footscan_sim::grbl::{EmulatorConfig, Fault, GrblEmulator, MachineState};
use std::time::{Duration, Instant};

const S10: Duration = Duration::from_secs(10);

fn connected(cfg: EmulatorConfig, drv: GrblConfig) -> (GrblEmulator, GrblSlider) {
    let emu = GrblEmulator::spawn(cfg).expect("spawn emulator");
    let mut s = GrblSlider::new(emu.port_path().to_string_lossy(), drv);
    s.connect().expect("connect");
    (emu, s)
}

fn homed() -> (GrblEmulator, GrblSlider) {
    let (emu, mut s) = connected(EmulatorConfig::default(), GrblConfig::default());
    s.home(S10).expect("home");
    (emu, s)
}

fn wait_state(emu: &GrblEmulator, want: MachineState) {
    let t = Instant::now();
    while emu.state() != want {
        assert!(t.elapsed() < S10, "emulator never reached {want:?}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn soft_reset_waits_for_the_banner_and_times_out_on_silence() {
    let drv = GrblConfig {
        reset_timeout: Duration::from_millis(400),
        response_timeout: Duration::from_millis(400),
        ..Default::default()
    };
    let (emu, mut s) = connected(EmulatorConfig::default(), drv);
    let t = Instant::now();
    s.soft_reset().unwrap();
    println!("soft reset to banner: {:?}", t.elapsed());
    assert_eq!(s.banner(), Some("Grbl 1.1h ['$' for help]"));
    emu.inject(Fault::Silence(true));
    let t = Instant::now();
    match s.soft_reset() {
        Err(HalError::Timeout { what, .. }) => assert!(what.contains("banner"), "{what}"),
        r => panic!("{r:?}"),
    }
    println!("soft reset into silence gave up after {:?}", t.elapsed());
    assert!(t.elapsed() < Duration::from_secs(3));
    emu.inject(Fault::Silence(false));
    s.connect().unwrap();
}

#[test]
fn settings_are_typed_and_build_info_is_read() {
    let (emu, mut s) = connected(EmulatorConfig::default(), GrblConfig::default());
    let b = s.build_info().expect("$I served").clone();
    assert_eq!(b.version, "1.1h.20190830");
    assert_eq!((b.planner_blocks, b.rx_buffer), (Some(15), Some(128)));
    let st = s.read_settings().unwrap();
    assert_eq!(st.raw, emu.settings(), "every $N line read");
    assert_eq!(st.max_rate(0), Some(3000.0));
    assert_eq!(st.acceleration(0), Some(500.0));
    assert_eq!(st.max_travel(0), Some(330.0));
    assert!(st.homing_enabled() && st.soft_limits());
    assert!(st.steps_per_mm(0).is_some());
}

#[test]
fn homing_failure_is_its_alarm() {
    let (emu, mut s) = connected(EmulatorConfig::default(), GrblConfig::default());
    for (code, words) in [(9, "could not find limit switch"), (8, "pull off")] {
        emu.inject(Fault::HomingFail(code));
        match s.home(S10) {
            Err(HalError::Alarm {
                code: c, message, ..
            }) => {
                assert_eq!(c, code as u32);
                assert!(message.contains(words), "{message}");
                assert_eq!(message, alarm_message(c));
            }
            r => panic!("homing fail {code}: {r:?}"),
        }
        wait_state(&emu, MachineState::Alarm);
        assert_eq!(s.status().unwrap().state, SliderState::Alarm);
        assert!(s.move_to(5.0, 1000.0).unwrap_err().is_alarm());
    }
    // The fault is spent: the next cycle homes.
    s.home(S10).unwrap();
    assert_eq!(s.alarm(), None);
    assert_eq!(s.status().unwrap().state, SliderState::Idle);
}

#[test]
fn homing_timeout_aborts_the_cycle() {
    let cfg = EmulatorConfig {
        homing_seconds: 2.0,
        ..Default::default()
    };
    let (emu, mut s) = connected(cfg, GrblConfig::default());
    let t = Instant::now();
    match s.home(Duration::from_millis(300)) {
        Err(HalError::Timeout { what, .. }) => assert!(what.contains("aborted"), "{what}"),
        r => panic!("{r:?}"),
    }
    println!("homing timeout and abort took {:?}", t.elapsed());
    assert!(t.elapsed() < Duration::from_secs(2), "not left to run out");
    assert_eq!(emu.state(), MachineState::Alarm, "the cycle was stopped");
    assert_eq!(s.alarm(), Some(6), "ALARM:6 homing reset");
    s.home(S10).unwrap();
    assert_eq!(s.status().unwrap().state, SliderState::Idle);
}

#[test]
fn a_long_program_streams_within_the_rx_buffer() {
    let cfg = EmulatorConfig {
        accel_mm_s2: 50_000.0,
        max_rate_mm_min: 60_000.0,
        ..Default::default()
    };
    let (emu, mut s) = connected(cfg, GrblConfig::default());
    s.home(S10).unwrap();
    // 600 lines of 3 to 60 bytes: moves, modal-only lines and comments (GRBL counts them too).
    let lines: Vec<String> = (0..600)
        .map(|i| match i % 4 {
            0 => format!("G1 X{:.3} F60000", 5.0 + (i % 50) as f64 * 0.1),
            1 => "G90".to_string(),
            2 => format!(
                "G1X{:.2}F60000 (pass {i} of a long program, spaces count)",
                6.0
            ),
            _ => format!("G21 G1 X{:.4} F60000", 5.5 + (i % 7) as f64 * 0.05),
        })
        .collect();
    let total_bytes: usize = lines.iter().map(|l| l.len() + 1).sum();
    let t = Instant::now();
    assert_eq!(s.stream(&lines).unwrap(), 600);
    let took = t.elapsed();
    let st = s.wait_idle(Duration::from_secs(60)).unwrap();
    let peak = emu.rx_peak_bytes();
    println!(
        "streamed 600 lines ({total_bytes} bytes) in {took:?}; RX buffer peak {peak}/128 bytes, overflow {}",
        emu.rx_overflow_bytes()
    );
    assert_eq!(emu.rx_overflow_bytes(), 0);
    assert!(peak <= 128, "peak {peak}");
    assert!(
        peak > 64,
        "the buffer was used, not one line at a time: peak {peak}"
    );
    assert_eq!(st.x_mm, 5.5 + (599 % 7) as f64 * 0.05);
}

#[test]
fn status_is_polled_at_the_configured_rate_with_monotonic_stamps() {
    let drv = GrblConfig {
        poll_interval: Duration::from_millis(20),
        ..Default::default()
    };
    let (emu, mut s) = connected(EmulatorConfig::default(), drv);
    s.home(S10).unwrap();
    let pos = emu.position_source();
    s.move_to(60.0, 3000.0).unwrap();
    let mut reports = Vec::new();
    let t = Instant::now();
    let n = s
        .poll_status(S10, |st| {
            reports.push((*st, Timestamp::now()));
            st.state == SliderState::Idle && st.x_mm == 60.0
        })
        .unwrap();
    let elapsed = t.elapsed().as_secs_f64();
    assert_eq!(n, reports.len());
    let mut worst: f64 = 0.0;
    for w in reports.windows(2) {
        let ((a, _), (b, b_seen)) = (w[0], w[1]);
        assert!(b.timestamp > a.timestamp, "stamps increase");
        assert!(b.timestamp <= b_seen, "stamped before it was handed out");
        assert!(b.x_mm >= a.x_mm, "monotone move");
    }
    for (st, _) in &reports {
        let err = (st.x_mm - pos.physical_x(st.timestamp)).abs();
        worst = worst.max(err);
    }
    let gaps: Vec<f64> = reports
        .windows(2)
        .map(|w| w[1].0.timestamp.secs_after(w[0].0.timestamp) * 1e3)
        .collect();
    let mean = gaps.iter().sum::<f64>() / gaps.len() as f64;
    println!(
        "{n} reports in {elapsed:.3} s at a 20 ms period: mean gap {mean:.2} ms, min {:.2}, max {:.2}; worst |X - truth at stamp| {worst:.4} mm",
        gaps.iter().cloned().fold(f64::MAX, f64::min),
        gaps.iter().cloned().fold(0.0, f64::max)
    );
    // Never faster than configured: one report per started period at most.
    assert!(n as f64 <= elapsed / 0.020 + 1.0, "{n} in {elapsed} s");
    assert!(n > 10, "{n} reports over a 1.3 s move");
    // A condition never met is a timeout, not a hang.
    let t = Instant::now();
    let e = s
        .poll_status(Duration::from_millis(200), |_| false)
        .unwrap_err();
    assert!(e.is_timeout(), "{e}");
    assert!(t.elapsed() < Duration::from_secs(2));
}

#[test]
fn error_and_alarm_codes_carry_their_meaning() {
    let (emu, mut s) = homed();
    let codes: Vec<u32> = (1..=38).filter(|c| ![18, 19].contains(c)).collect();
    for &code in &codes {
        emu.inject(Fault::RejectNext(code as u8));
        // The fault is picked up with the next line the emulator reads.
        std::thread::sleep(Duration::from_millis(5));
        match s.command("G4 P0") {
            Err(HalError::Rejected {
                code: c, message, ..
            }) => {
                assert_eq!(c, code);
                assert!(message.starts_with(error_message(code)), "{message}");
                assert!(!message.contains("unknown"), "{code}: {message}");
                assert!(message.contains("G4 P0"), "names the line: {message}");
            }
            r => panic!("error:{code}: {r:?}"),
        }
    }
    // Real refusals from the controller's own checks.
    for (line, code) in [
        ("$Q", 2),
        ("$100", 3),
        ("$J=G90X400F1000", 15),
        ("G2 X1 I1", 20),
    ] {
        match s.command(line) {
            Err(HalError::Rejected { code: c, .. }) => assert_eq!(c, code, "{line}"),
            r => panic!("{line}: {r:?}"),
        }
    }
    assert!(error_message(99).contains("unknown"));
    // Alarms 1 to 9, each raised by the controller and named by the driver.
    for code in 1..=9u8 {
        s.connect().unwrap();
        s.home(S10).unwrap();
        emu.inject(Fault::Alarm(code));
        wait_state(&emu, MachineState::Alarm);
        match s.wait_idle(S10) {
            Err(HalError::Alarm {
                code: c, message, ..
            }) => {
                assert_eq!(c, code as u32);
                assert_eq!(message, alarm_message(c));
                assert!(!message.contains("unknown"));
            }
            r => panic!("ALARM:{code}: {r:?}"),
        }
    }
}

#[test]
fn jog_and_jog_cancel() {
    let (emu, mut s) = homed();
    s.jog_to(300.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(s.status().unwrap().state, SliderState::Jog);
    s.jog_cancel().unwrap();
    let st = s.status().unwrap();
    assert_eq!(st.state, SliderState::Idle);
    assert!(st.x_mm > 0.0 && st.x_mm < 300.0, "{st:?}");
    std::thread::sleep(Duration::from_millis(200));
    assert!(
        (emu.machine_x() - st.x_mm).abs() < 5e-4,
        "nothing left queued"
    );
    // Idle: a no-op. Beyond travel: refused with its meaning.
    s.jog_cancel().unwrap();
    match s.jog_to(400.0, 1000.0) {
        Err(HalError::Rejected {
            code: 15, message, ..
        }) => {
            assert!(message.contains("travel exceeded"), "{message}")
        }
        r => panic!("{r:?}"),
    }
    s.jog_to(10.0, 3000.0).unwrap();
    let st = s.wait_idle(S10).unwrap();
    assert_eq!(st.x_mm, 10.0);
}

#[test]
fn every_wait_times_out_on_a_silent_controller() {
    let drv = GrblConfig {
        response_timeout: Duration::from_millis(300),
        reset_timeout: Duration::from_millis(300),
        ..Default::default()
    };
    let (emu, mut s) = connected(EmulatorConfig::default(), drv);
    s.home(S10).unwrap();
    s.move_to(50.0, 3000.0).unwrap();
    emu.inject(Fault::Silence(true));
    std::thread::sleep(Duration::from_millis(50));
    let short = Duration::from_millis(300);
    type Op = Box<dyn Fn(&mut GrblSlider) -> Result<(), HalError>>;
    let ops: Vec<(&str, Op)> = vec![
        ("status", Box::new(|s| s.status().map(|_| ()))),
        ("move_to", Box::new(|s| s.move_to(10.0, 1000.0))),
        (
            "wait_idle",
            Box::new(move |s| s.wait_idle(short).map(|_| ())),
        ),
        ("settings", Box::new(|s| s.read_settings().map(|_| ()))),
        ("command", Box::new(|s| s.command("$I").map(|_| ()))),
        (
            "stream",
            Box::new(|s| s.stream(["G1X1F100", "G1X2"]).map(|_| ())),
        ),
        ("jog_to", Box::new(|s| s.jog_to(20.0, 1000.0))),
        ("jog_cancel", Box::new(|s| s.jog_cancel())),
        ("resume", Box::new(|s| s.resume())),
        ("stop", Box::new(|s| s.stop())),
        ("soft_reset", Box::new(|s| s.soft_reset())),
        ("home", Box::new(move |s| s.home(short))),
        (
            "poll_status",
            Box::new(move |s| s.poll_status(short, |_| true).map(|_| ())),
        ),
    ];
    for (name, op) in ops {
        let t = Instant::now();
        let e = op(&mut s).expect_err(name);
        let took = t.elapsed();
        println!("{name}: {took:?}: {e}");
        assert!(e.is_timeout(), "{name}: {e}");
        assert!(took < Duration::from_secs(3), "{name} took {took:?}");
    }
    emu.inject(Fault::Silence(false));
    s.connect().unwrap();
    assert!(s.status().is_ok());
}

#[test]
fn a_dropped_ok_is_found_and_counting_stays_right() {
    let drv = GrblConfig {
        response_timeout: Duration::from_millis(500),
        ..Default::default()
    };
    let (emu, mut s) = connected(EmulatorConfig::default(), drv);
    s.home(S10).unwrap();
    emu.inject(Fault::DropOk(1));
    std::thread::sleep(Duration::from_millis(5));
    match s.command("G4 P0") {
        Err(HalError::Timeout { what, .. }) => assert!(what.contains("never arrived"), "{what}"),
        r => panic!("{r:?}"),
    }
    assert_eq!(s.stats().lost_answers, 1);
    // Later answers belong to their own lines: $I's feedback comes with its own ok.
    let fb = s.command("$I").unwrap();
    assert!(fb.iter().any(|l| l.starts_with("[VER:")), "{fb:?}");
    s.move_to(10.0, 3000.0).unwrap();
    assert_eq!(s.wait_idle(S10).unwrap().x_mm, 10.0);
    // Mid-stream: every line still runs, the loss is reported, the next command is right.
    emu.inject(Fault::DropOk(1));
    let lines: Vec<String> = (0..30).map(|i| format!("G1X{}F3000", 11 + i)).collect();
    match s.stream(&lines) {
        Err(HalError::Timeout { what, .. }) => assert!(what.contains("never arrived"), "{what}"),
        r => panic!("{r:?}"),
    }
    assert_eq!(s.wait_idle(S10).unwrap().x_mm, 40.0, "every line ran");
    assert_eq!(s.stats().lost_answers, 2);
    s.move_to(0.0, 3000.0).unwrap();
    assert_eq!(s.wait_idle(S10).unwrap().x_mm, 0.0);
    // A lost answer to a long move is reported while the machine still runs it, not after.
    emu.inject(Fault::DropOk(1));
    let t = Instant::now();
    match s.move_to(250.0, 3000.0) {
        Err(HalError::Timeout { what, .. }) => assert!(what.contains("never arrived"), "{what}"),
        r => panic!("{r:?}"),
    }
    println!(
        "lost answer to a 5.5 s move reported after {:?}",
        t.elapsed()
    );
    assert_eq!(emu.state(), MachineState::Run, "reported mid-move");
    assert_eq!(s.wait_idle(S10).unwrap().x_mm, 250.0);
    assert_eq!(s.stats().lost_answers, 3);
    println!("{:?}", s.stats());
}

#[test]
fn a_mangled_ok_is_counted_lost_and_later_answers_stay_right() {
    let drv = GrblConfig {
        response_timeout: Duration::from_millis(500),
        ..Default::default()
    };
    let (emu, mut s) = connected(EmulatorConfig::default(), drv);
    s.home(S10).unwrap();
    emu.inject(Fault::CorruptOk(1));
    match s.move_to(10.0, 3000.0) {
        Err(HalError::Timeout { what, .. }) => assert!(what.contains("never arrived"), "{what}"),
        r => panic!("{r:?}"),
    }
    let st = s.stats();
    assert_eq!((st.garbage_lines, st.lost_answers), (1, 1), "{st:?}");
    assert_eq!(s.wait_idle(S10).unwrap().x_mm, 10.0, "the line ran");
    let fb = s.command("$I").unwrap();
    assert!(fb.iter().any(|l| l.starts_with("[VER:")), "{fb:?}");
    match s.command("G2 X1 I1") {
        Err(HalError::Rejected { code: 20, .. }) => {}
        r => panic!("its own answer: {r:?}"),
    }
}

#[test]
fn corrupted_status_reports_are_asked_again() {
    let (emu, mut s) = homed();
    s.move_to(100.0, 3000.0).unwrap();
    emu.inject(Fault::CorruptStatus(2));
    std::thread::sleep(Duration::from_millis(5));
    let st = s.status().unwrap();
    assert_eq!(st.state, SliderState::Run);
    assert_eq!(s.stats().corrupt_reports, 2);
    // Noise on every answer: BadData naming the line, not a hang, not a wrong position.
    emu.inject(Fault::CorruptStatus(4));
    std::thread::sleep(Duration::from_millis(5));
    match s.status() {
        Err(HalError::BadData { detail, .. }) => assert!(detail.contains("Pos:#"), "{detail}"),
        r => panic!("{r:?}"),
    }
    // A poll during the move rides over sparse noise.
    emu.inject(Fault::CorruptStatus(3));
    let n = s
        .poll_status(S10, |st| st.state == SliderState::Idle)
        .unwrap();
    assert_eq!(s.status().unwrap().x_mm, 100.0);
    println!("{n} reports; {:?}", s.stats());
    assert_eq!(s.stats().corrupt_reports, 9);
}

#[test]
fn reconnect_through_a_stable_path_after_unplug() {
    let dir = std::env::temp_dir().join(format!("footscan-grbl-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("usb-grbl-if00");
    let emu = GrblEmulator::spawn(EmulatorConfig::default()).unwrap();
    GrblEmulator::link(emu.port_path(), &link).unwrap();
    let mut s = GrblSlider::new(link.to_string_lossy(), GrblConfig::default());
    s.connect().unwrap();
    s.home(S10).unwrap();
    s.move_to(20.0, 3000.0).unwrap();
    s.wait_idle(S10).unwrap();

    // 1. The USB adapter drops mid-move and comes back; the controller kept power.
    s.move_to(150.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let new_path = emu.replug().unwrap();
    let e = s.status().unwrap_err();
    assert!(e.is_disconnect(), "{e}");
    let relink = {
        let (new_path, link) = (new_path.clone(), link.clone());
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            GrblEmulator::link(&new_path, &link).unwrap();
        })
    };
    let t = Instant::now();
    s.reconnect(Duration::from_secs(5)).unwrap();
    relink.join().unwrap();
    println!("reconnected after {:?}", t.elapsed());
    assert_eq!(
        s.alarm(),
        None,
        "brought to rest before the reset: no ALARM:3"
    );
    let st = s.wait_idle(S10).unwrap();
    assert!(st.x_mm > 20.0 && st.x_mm < 150.0, "{st:?}");
    assert!((st.x_mm - emu.machine_x()).abs() < 5e-4, "position kept");
    assert_eq!(s.stats().reconnects, 1);
    s.move_to(30.0, 3000.0).unwrap();
    assert_eq!(s.wait_idle(S10).unwrap().x_mm, 30.0);

    // 2. The board power-cycles: the path dangles for a while, then a fresh controller.
    drop(emu);
    std::thread::sleep(Duration::from_millis(50));
    assert!(s.status().unwrap_err().is_disconnect());
    let t = Instant::now();
    let e = s.reconnect(Duration::from_millis(300)).unwrap_err();
    assert!(e.is_disconnect(), "{e}");
    assert!(
        e.to_string().contains("usb-grbl-if00"),
        "names the port: {e}"
    );
    assert!(t.elapsed() < Duration::from_secs(3));
    let emu2 = GrblEmulator::spawn(EmulatorConfig::default()).unwrap();
    GrblEmulator::link(emu2.port_path(), &link).unwrap();
    s.reconnect(Duration::from_secs(5)).unwrap();
    // Unlock policy: never $X on its own; the fresh controller is locked until homed.
    assert_eq!(s.alarm(), Some(0));
    assert!(s.move_to(5.0, 1000.0).unwrap_err().is_alarm());
    s.home(S10).unwrap();
    s.move_to(5.0, 3000.0).unwrap();
    assert_eq!(s.wait_idle(S10).unwrap().x_mm, 5.0);
    assert_eq!(emu2.machine_x(), 5.0);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn reconnect_mid_jog_cancels_the_jog_before_the_reset() {
    let dir = std::env::temp_dir().join(format!("footscan-grbl-jog-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("usb-grbl-if00");
    let emu = GrblEmulator::spawn(EmulatorConfig::default()).unwrap();
    GrblEmulator::link(emu.port_path(), &link).unwrap();
    let mut s = GrblSlider::new(link.to_string_lossy(), GrblConfig::default());
    s.connect().unwrap();
    s.home(S10).unwrap();
    s.jog_to(200.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let new_path = emu.replug().unwrap();
    GrblEmulator::link(&new_path, &link).unwrap();
    assert_eq!(
        emu.state(),
        MachineState::Jog,
        "still jogging after the replug"
    );
    s.reconnect(Duration::from_secs(5)).unwrap();
    assert_eq!(
        s.alarm(),
        None,
        "jog cancelled (0x85), then reset: no ALARM:3"
    );
    let st = s.status().unwrap();
    assert_eq!(st.state, SliderState::Idle);
    assert!(st.x_mm > 0.0 && st.x_mm < 200.0, "{st:?}");
    assert!((st.x_mm - emu.machine_x()).abs() < 5e-4, "position kept");
    let _ = std::fs::remove_dir_all(&dir);
}
