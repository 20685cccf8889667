//! The GRBL driver against the emulator (and a few scripted fake controllers), over real ptys.

use footscan_grbl::{GrblConfig, GrblSlider};
use footscan_hal::{HalError, Slider, SliderState, Timestamp};
use footscan_sim::grbl::{EmulatorConfig, Fault, GrblEmulator, MachineState};
use std::io::{Read, Write};
use std::time::{Duration, Instant};

const S10: Duration = Duration::from_secs(10);

fn connected(cfg: EmulatorConfig, drv: GrblConfig) -> (GrblEmulator, GrblSlider) {
    let emu = GrblEmulator::spawn(cfg).expect("spawn emulator");
    let mut s = GrblSlider::new(emu.port_path().to_string_lossy(), drv);
    let info = s.connect().expect("connect");
    assert_eq!(info.banner, "Grbl 1.1h ['$' for help]");
    assert_eq!(info.port, emu.port_path().to_string_lossy());
    // $32 as the emulator reports it, read at connect.
    assert_eq!(info.laser_mode, s.laser_mode());
    assert!(info.laser_mode.is_some());
    (emu, s)
}

fn homed() -> (GrblEmulator, GrblSlider) {
    let (emu, mut s) = connected(EmulatorConfig::default(), GrblConfig::default());
    s.home(S10).expect("home");
    (emu, s)
}

#[test]
fn connect_home_move_and_status_track_the_motion() {
    let (emu, mut s) = connected(EmulatorConfig::default(), GrblConfig::default());
    assert_eq!(s.alarm(), Some(0), "powered up locked, homing enabled");
    assert_eq!(s.rx_buffer(), 128, "from $I");
    match s.move_to(10.0, 1000.0) {
        Err(HalError::Alarm { code: 0, .. }) => {}
        r => panic!("move while locked: {r:?}"),
    }
    s.home(S10).unwrap();
    assert_eq!(s.alarm(), None);
    let st = s.status().unwrap();
    assert_eq!((st.state, st.x_mm), (SliderState::Idle, 0.0));

    let settings = s.settings().unwrap();
    assert_eq!(settings.get(&110), Some(&3000.0));
    assert_eq!(settings.get(&120), Some(&500.0));
    assert_eq!(settings.get(&130), Some(&330.0));

    let pos = emu.position_source();
    let t0 = Instant::now();
    s.move_to(100.0, 3000.0).unwrap();
    assert!(
        t0.elapsed() < Duration::from_millis(500),
        "accepted, not completed"
    );
    // Poll during the move: each report's X matches the motion model at its timestamp.
    let mut errs = Vec::new();
    let mut moving = 0;
    loop {
        let before = Timestamp::now();
        let st = s.status().unwrap();
        let rtt = Timestamp::now().secs_after(before);
        let truth = pos.physical_x(st.timestamp);
        let err = (st.x_mm - truth).abs();
        // 0.05 mm at 50 mm/s is 1 ms; allow for half of what this poll's round trip took on a
        // loaded machine (the timestamp is the midpoint of query and answer).
        assert!(
            err <= 0.05 + 50.0 * rtt / 2.0,
            "status {st:?} vs truth {truth} (rtt {rtt} s)"
        );
        if st.state == SliderState::Run {
            moving += 1;
            assert!((0.0..=3000.0).contains(&st.feed_mm_min), "{st:?}");
            errs.push(err);
        }
        if st.state == SliderState::Idle {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    assert!(moving > 20, "{moving} reports while moving");
    errs.sort_by(f64::total_cmp);
    let median = errs[errs.len() / 2];
    assert!(median < 0.05, "median error {median} mm");
    let st = s.wait_idle(S10).unwrap();
    assert_eq!(st.x_mm, 100.0);
    assert_eq!(st.x_mm, emu.machine_x());
    assert!(
        t0.elapsed() >= Duration::from_millis(2000),
        "2.1 s trapezoid"
    );
}

#[test]
fn wait_idle_and_soft_limits() {
    let (emu, mut s) = homed();
    s.move_to(30.0, 3000.0).unwrap();
    let st = s.wait_idle(S10).unwrap();
    assert_eq!(st.state, SliderState::Idle);
    assert_eq!(st.x_mm, 30.0);
    // Too short a wait: timeout, not a hang.
    s.move_to(0.0, 600.0).unwrap();
    let t = Instant::now();
    assert!(s
        .wait_idle(Duration::from_millis(200))
        .unwrap_err()
        .is_timeout());
    assert!(t.elapsed() < Duration::from_secs(2));
    s.wait_idle(S10).unwrap();
    // Beyond travel: GRBL raises ALARM:2 instead of answering.
    match s.move_to(400.0, 1000.0) {
        Err(HalError::Alarm {
            code: 2, message, ..
        }) => assert!(message.contains("soft limit")),
        r => panic!("{r:?}"),
    }
    assert_eq!(emu.state(), MachineState::Alarm);
    // Recover: reconnect (soft reset) and unlock.
    s.connect().unwrap();
    s.unlock().unwrap();
    s.move_to(1.0, 1000.0).unwrap();
    s.wait_idle(S10).unwrap();
    // Bad arguments are refused locally.
    assert!(matches!(
        s.move_to(f64::NAN, 100.0),
        Err(HalError::InvalidArgument { .. })
    ));
    assert!(matches!(
        s.move_to(1.0, 0.0),
        Err(HalError::InvalidArgument { .. })
    ));
    // error:N becomes Rejected with the code's meaning.
    match s.command("G2 X1 I1") {
        Err(HalError::Rejected {
            code: 20, message, ..
        }) => {
            assert!(message.contains("unsupported"), "{message}")
        }
        r => panic!("{r:?}"),
    }
}

#[test]
fn injected_alarm_mid_move() {
    let (emu, mut s) = homed();
    s.move_to(200.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    emu.inject(Fault::Alarm(1));
    let t = Instant::now();
    match s.wait_idle(S10) {
        Err(HalError::Alarm {
            code: 1, message, ..
        }) => assert!(message.contains("hard limit")),
        r => panic!("{r:?}"),
    }
    assert!(t.elapsed() < Duration::from_secs(2));
    let x = emu.machine_x();
    assert!(x > 0.0 && x < 200.0);
    match s.move_to(0.0, 3000.0) {
        Err(HalError::Alarm { code: 1, .. }) => {}
        r => panic!("{r:?}"),
    }
    // An alarm that arrives while a move line waits for its answer fails that move_to.
    s.connect().unwrap();
    s.home(S10).unwrap();
    s.move_to(100.0, 3000.0).unwrap();
    let lines: Vec<String> = (0..14).map(|i| format!("G1X{}F3000", 101 + i)).collect();
    s.stream(&lines).unwrap(); // planner now full
    let emu2 = std::sync::Arc::new(emu);
    let e = emu2.clone();
    let t = std::thread::spawn(move || {
        std::thread::sleep(Duration::from_millis(300));
        e.inject(Fault::Alarm(9));
    });
    match s.move_to(5.0, 3000.0) {
        Err(HalError::Alarm { code: 9, .. }) => {}
        r => panic!("{r:?}"),
    }
    t.join().unwrap();
    // A non-critical alarm resets the controller: it comes back locked.
    assert_eq!(emu2.state(), MachineState::Alarm);
    assert!(s.status().unwrap().state == SliderState::Alarm);
}

#[test]
fn silence_times_out_and_recovers() {
    let drv = GrblConfig {
        response_timeout: Duration::from_millis(500),
        ..Default::default()
    };
    let (emu, mut s) = connected(EmulatorConfig::default(), drv);
    s.home(S10).unwrap();
    emu.inject(Fault::Silence(true));
    std::thread::sleep(Duration::from_millis(50));
    let bound = Duration::from_millis(1500);
    let t = Instant::now();
    assert!(s.status().unwrap_err().is_timeout());
    assert!(t.elapsed() < bound, "{:?}", t.elapsed());
    let t = Instant::now();
    assert!(s.move_to(10.0, 1000.0).unwrap_err().is_timeout());
    assert!(t.elapsed() < bound, "{:?}", t.elapsed());
    let t = Instant::now();
    assert!(s
        .wait_idle(Duration::from_millis(500))
        .unwrap_err()
        .is_timeout());
    assert!(t.elapsed() < bound, "{:?}", t.elapsed());
    let t = Instant::now();
    assert!(s.settings().unwrap_err().is_timeout());
    assert!(t.elapsed() < bound, "{:?}", t.elapsed());
    let t = Instant::now();
    let _ = s.stop();
    assert!(t.elapsed() < bound, "{:?}", t.elapsed());
    // Back from the dead: reconnect resynchronises.
    emu.inject(Fault::Silence(false));
    s.connect().unwrap();
    let st = s.status().unwrap();
    assert!(matches!(st.state, SliderState::Idle | SliderState::Alarm));
}

#[test]
fn disconnect_is_reported() {
    let (emu, mut s) = homed();
    s.move_to(50.0, 3000.0).unwrap();
    emu.inject(Fault::Disconnect);
    std::thread::sleep(Duration::from_millis(50));
    let t = Instant::now();
    let e = s.status().unwrap_err();
    assert!(e.is_disconnect(), "{e}");
    assert!(t.elapsed() < Duration::from_secs(1));
    assert!(!s.is_connected());
    assert!(s.wait_idle(S10).unwrap_err().is_disconnect());
    assert!(s.move_to(0.0, 100.0).unwrap_err().is_disconnect());
    // The position model keeps going: the move completes physically.
    std::thread::sleep(Duration::from_millis(1500));
    assert_eq!(emu.position_source().physical_x(Timestamp::now()), 50.0);
    // Reconnecting to a vanished port fails cleanly.
    let e = s.connect().unwrap_err();
    assert!(e.is_disconnect(), "{e}");
}

#[test]
fn feed_hold_resume_and_stop() {
    let (emu, mut s) = homed();
    s.move_to(200.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(400));
    s.feed_hold().unwrap();
    std::thread::sleep(Duration::from_millis(200));
    let held = s.status().unwrap();
    assert_eq!(held.state, SliderState::Hold);
    assert_eq!(s.last_report().unwrap().substate, Some(0));
    s.resume().unwrap();
    assert_eq!(s.status().unwrap().state, SliderState::Run);
    // Resume issued during the deceleration waits for the hold to complete.
    s.feed_hold().unwrap();
    s.resume().unwrap();
    assert_eq!(s.status().unwrap().state, SliderState::Run);

    // stop() while running: hold, then reset; no position loss, no alarm, planner empty.
    s.stop().unwrap();
    let st = s.status().unwrap();
    assert_eq!(st.state, SliderState::Idle, "{st:?}");
    assert_eq!(emu.state(), MachineState::Idle);
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(s.status().unwrap().x_mm, st.x_mm, "nothing left queued");
    assert!(st.x_mm < 200.0);

    // stop() while jogging: jog cancel.
    s.jog_to(300.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    assert_eq!(s.status().unwrap().state, SliderState::Jog);
    s.stop().unwrap();
    let st = s.wait_idle(S10).unwrap();
    assert!(st.x_mm < 300.0);
    // Idle: stop is a no-op.
    s.stop().unwrap();
    s.move_to(0.0, 3000.0).unwrap();
    s.wait_idle(S10).unwrap();
}

#[test]
fn stream_counts_characters() {
    let (emu, mut s) = homed();
    let lines: Vec<String> = (0..40)
        .map(|i| format!("G1 X{} F3000", 5 + (i % 7)))
        .collect();
    let t = Instant::now();
    assert_eq!(s.stream(&lines).unwrap(), 40);
    // 40 short moves cannot all fit the planner: the stream waited for blocks to finish.
    assert!(t.elapsed() > Duration::from_millis(500));
    assert_eq!(
        emu.rx_overflow_bytes(),
        0,
        "never overflowed the 128-byte RX buffer"
    );
    let st = s.wait_idle(Duration::from_secs(30)).unwrap();
    assert_eq!(st.x_mm, 5.0 + (39 % 7) as f64);
    // The first error stops the stream and names the line.
    match s.stream(["G1 X1 F100", "G2 X1 I1", "G1 X2"]) {
        Err(HalError::Rejected {
            code: 20, message, ..
        }) => {
            assert!(message.starts_with("line 2:"), "{message}")
        }
        r => panic!("{r:?}"),
    }
}

/// A scripted controller on a pty pair: answers each received byte chunk with `reply(bytes)`.
fn fake_controller(
    reply: impl Fn(&[u8]) -> Vec<u8> + Send + 'static,
) -> (
    String,
    std::thread::JoinHandle<()>,
    std::sync::Arc<std::sync::atomic::AtomicBool>,
) {
    let (mut master, slave) = serialport::TTYPort::pair().expect("pty pair");
    let name = serialport::SerialPort::name(&slave).unwrap();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let stop2 = stop.clone();
    let h = std::thread::spawn(move || {
        let _keep = slave;
        serialport::SerialPort::set_timeout(&mut master, Duration::from_millis(20)).unwrap();
        let mut buf = [0u8; 256];
        while !stop2.load(std::sync::atomic::Ordering::Relaxed) {
            if let Ok(n) = master.read(&mut buf) {
                if n > 0 {
                    let out = reply(&buf[..n]);
                    let _ = master.write_all(&out);
                }
            }
        }
    });
    (name, h, stop)
}

#[test]
fn garbage_is_bad_data() {
    let drv = GrblConfig {
        reset_timeout: Duration::from_millis(500),
        response_timeout: Duration::from_millis(500),
        ..Default::default()
    };
    // Noise instead of a banner.
    let (port, h, stop) = fake_controller(|_| b"\xff\xfejunk\r\nHELLO WORLD\r\n".to_vec());
    let mut s = GrblSlider::new(&port, drv.clone());
    match s.connect() {
        Err(HalError::BadData { detail, .. }) => {
            assert!(detail.contains("HELLO WORLD"), "{detail}")
        }
        r => panic!("{r:?}"),
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().unwrap();

    // Wrong firmware generation.
    let (port, h, stop) = fake_controller(|_| b"\r\nGrbl 0.9j ['$' for help]\r\n".to_vec());
    let mut s = GrblSlider::new(&port, drv.clone());
    match s.connect() {
        Err(HalError::BadData { detail, .. }) => assert!(detail.contains("0.9j"), "{detail}"),
        r => panic!("{r:?}"),
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().unwrap();

    // A sane banner, then a mangled status report.
    let (port, h, stop) = fake_controller(|b| {
        if b.contains(&0x18) {
            b"\r\nGrbl 1.1h ['$' for help]\r\n".to_vec()
        } else if b.contains(&b'?') {
            b"<Idle|MPos:1.0,zz,0>\r\n".to_vec()
        } else {
            b"ok\r\n".to_vec()
        }
    });
    let mut s = GrblSlider::new(&port, drv.clone());
    match s.connect() {
        Err(HalError::BadData { detail, .. }) => {
            assert!(detail.contains("MPos:1.0,zz"), "{detail}")
        }
        r => panic!("{r:?}"),
    }
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().unwrap();

    // Nothing at all: timeout.
    let (port, h, stop) = fake_controller(|_| Vec::new());
    let mut s = GrblSlider::new(&port, drv);
    let t = Instant::now();
    assert!(s.connect().unwrap_err().is_timeout());
    assert!(t.elapsed() < Duration::from_millis(1500));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().unwrap();
}

#[test]
fn a_second_banner_during_connect_is_tolerated() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let seen_info = AtomicUsize::new(0);
    let (port, h, stop) = fake_controller(move |b| {
        if b.contains(&0x18) {
            b"\r\nGrbl 1.1h ['$' for help]\r\n".to_vec()
        } else if b.starts_with(b"$I") {
            if seen_info.fetch_add(1, Ordering::SeqCst) == 0 {
                // The board reset once more: the line is lost, a banner comes instead.
                b"\r\nGrbl 1.1h ['$' for help]\r\n".to_vec()
            } else {
                b"[VER:1.1h.20190830:]\r\n[OPT:V,15,256]\r\nok\r\n".to_vec()
            }
        } else if b.contains(&b'?') {
            b"<Idle|MPos:1.500,0.000,0.000|FS:0,0>\r\n".to_vec()
        } else {
            b"ok\r\n".to_vec()
        }
    });
    let mut s = GrblSlider::new(&port, GrblConfig::default());
    let info = s.connect().unwrap();
    assert_eq!(info.banner, "Grbl 1.1h ['$' for help]");
    assert_eq!(s.rx_buffer(), 256, "taken from [OPT:...]");
    assert_eq!(s.status().unwrap().x_mm, 1.5);
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    h.join().unwrap();
}

#[test]
fn laser_on_off_through_spindle_and_coolant_and_refusals_named() {
    use footscan_grbl::LaserOutput;
    use footscan_sim::grbl::LaserWiring;
    for (wiring, out, on_line) in [
        (
            LaserWiring::Spindle,
            LaserOutput::Spindle { power: 1000.0 },
            "M3",
        ),
        (LaserWiring::Flood, LaserOutput::Flood, "M8"),
    ] {
        let cfg = EmulatorConfig {
            laser: wiring,
            homing_enabled: false,
            ..EmulatorConfig::default()
        };
        let drv = GrblConfig {
            laser: Some(out),
            ..GrblConfig::default()
        };
        let (emu, mut s) = connected(cfg, drv);
        assert!(!emu.laser_on(), "{wiring:?}: off at power-up");
        s.laser(true).expect("laser on");
        assert!(emu.laser_on(), "{wiring:?}: on after {on_line}");
        let gc = s.command("$G").unwrap().join(" ");
        assert!(gc.contains(on_line), "{gc}");
        s.laser(false).expect("laser off");
        assert!(!emu.laser_on(), "{wiring:?}: off again");
        // A refused command names the command and the controller's answer.
        emu.inject(Fault::RejectNext(20));
        let e = s.laser(true).unwrap_err().to_string();
        assert!(
            e.contains(on_line) && e.contains("error:20") && e.contains("laser on"),
            "{e}"
        );
        assert!(!emu.laser_on());
    }
    // M7 (mist) is not in GRBL's default build: refused with error:20, named.
    let cfg = EmulatorConfig {
        homing_enabled: false,
        ..EmulatorConfig::default()
    };
    let drv = GrblConfig {
        laser: Some(LaserOutput::Mist),
        ..GrblConfig::default()
    };
    let (_emu, mut s) = connected(cfg, drv);
    let e = s.laser(true).unwrap_err().to_string();
    assert!(
        e.contains("`M7`") && e.contains("error:20") && e.contains("unsupported"),
        "{e}"
    );
    // Without a configured output the driver says so and sends nothing.
    let (_emu, mut s) = homed();
    let e = s.laser(true).unwrap_err().to_string();
    assert!(e.contains("no laser output"), "{e}");
}
