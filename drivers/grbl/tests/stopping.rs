//! The faults GRBL 1.1h showed in its host simulator (grbl-sim) and the emulator now shares:
//! a status answered before a feed hold applies (stop, reconnect and resume during a move),
//! the reply order of a failed homing cycle, stopping deadlines from the controller's own
//! rate and acceleration, a laser switched during a move, and laser mode (`$32`).

use footscan_grbl::{GrblConfig, GrblSlider, LaserOutput};
use footscan_hal::{HalError, Slider, SliderState};
use footscan_sim::grbl::{EmulatorConfig, Fault, GrblEmulator, LaserWiring, MachineState};
use std::time::{Duration, Instant};

const S10: Duration = Duration::from_secs(10);

fn connected(cfg: EmulatorConfig, drv: GrblConfig) -> (GrblEmulator, GrblSlider) {
    let emu = GrblEmulator::spawn(cfg).expect("spawn emulator");
    let mut s = GrblSlider::new(emu.port_path().to_string_lossy(), drv);
    s.connect().expect("connect");
    (emu, s)
}

fn homed(cfg: EmulatorConfig) -> (GrblEmulator, GrblSlider) {
    let (emu, mut s) = connected(cfg, GrblConfig::default());
    s.home(S10).expect("home");
    (emu, s)
}

#[test]
fn stop_during_a_move_keeps_the_position() {
    let (emu, mut s) = homed(EmulatorConfig::default());
    let mut x = 0.0;
    for i in 0..6 {
        s.move_to(x + 100.0, 3000.0).unwrap();
        std::thread::sleep(Duration::from_millis(150 + 40 * i));
        assert_eq!(s.status().unwrap().state, SliderState::Run, "stop {i}");
        s.stop().unwrap_or_else(|e| panic!("stop {i}: {e}"));
        assert_eq!(s.alarm(), None, "stop {i}: reset while moving (ALARM:3)");
        assert_eq!(emu.state(), MachineState::Idle, "stop {i}");
        let st = s.status().unwrap();
        assert!(
            (st.x_mm - emu.machine_x()).abs() < 5e-4,
            "stop {i}: position kept"
        );
        assert!(st.x_mm != x, "stop {i}: it moved");
        x = st.x_mm;
    }
}

#[test]
fn reconnect_during_a_move_keeps_the_position() {
    let dir = std::env::temp_dir().join(format!("footscan-grbl-stop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link = dir.join("usb-grbl-if00");
    let emu = GrblEmulator::spawn(EmulatorConfig::default()).unwrap();
    GrblEmulator::link(emu.port_path(), &link).unwrap();
    let mut s = GrblSlider::new(link.to_string_lossy(), GrblConfig::default());
    s.connect().unwrap();
    s.home(S10).unwrap();
    for i in 0..3 {
        let x = s.status().unwrap().x_mm;
        s.move_to(x + 100.0, 3000.0).unwrap();
        std::thread::sleep(Duration::from_millis(200));
        assert_eq!(emu.state(), MachineState::Run);
        // The same machine on the same port: reconnect brings it to rest, then resets.
        s.reconnect(Duration::from_secs(5)).unwrap();
        assert_eq!(s.alarm(), None, "reconnect {i}: ALARM:3");
        let st = s.status().unwrap();
        assert_eq!(st.state, SliderState::Idle, "reconnect {i}");
        assert!((st.x_mm - emu.machine_x()).abs() < 5e-4, "position kept");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn resume_right_after_a_feed_hold_resumes() {
    let (emu, mut s) = homed(EmulatorConfig::default());
    s.move_to(300.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    s.feed_hold().unwrap();
    s.resume().unwrap();
    // Later than the emulator's hold latency: a `~` sent before the hold applied is dropped.
    std::thread::sleep(Duration::from_millis(200));
    let st = s.status().unwrap();
    assert_eq!(st.state, SliderState::Run, "resumed, not left held: {st:?}");
    assert_eq!(emu.state(), MachineState::Run);
    s.stop().unwrap();
}

#[test]
fn a_failed_homing_cycle_leaves_the_answer_counting_right() {
    let (emu, mut s) = connected(EmulatorConfig::default(), GrblConfig::default());
    emu.inject(Fault::HomingFail(8));
    match s.home(S10) {
        Err(HalError::Alarm { code: 8, .. }) => {}
        r => panic!("{r:?}"),
    }
    assert_eq!(emu.state(), MachineState::Alarm);
    // The unlock must get its own answer, not the `$H`'s late `ok`.
    s.unlock().unwrap();
    assert_eq!(emu.state(), MachineState::Idle, "really unlocked");
    assert_eq!(s.status().unwrap().state, SliderState::Idle);
    s.command("$22=0").expect("the next command is answered");
    assert_eq!(emu.settings()[&22], 0.0);
    s.command("$22=1").unwrap();
    s.home(S10).unwrap();
}

#[test]
fn jog_cancel_waits_as_long_as_the_deceleration_needs() {
    // 50 mm/s at 20 mm/s²: 2.5 s to stop, longer than the 1 s response timeout.
    let cfg = EmulatorConfig {
        accel_mm_s2: 20.0,
        ..EmulatorConfig::default()
    };
    let drv = GrblConfig {
        response_timeout: Duration::from_secs(1),
        ..GrblConfig::default()
    };
    let (emu, mut s) = connected(cfg, drv);
    s.home(S10).unwrap();
    assert_eq!(
        s.known_settings().and_then(|k| k.acceleration(0)),
        Some(20.0)
    );
    assert!(
        s.stop_deadline() >= Duration::from_secs(5),
        "{:?}",
        s.stop_deadline()
    );
    s.jog_to(300.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(2600));
    let t = Instant::now();
    s.jog_cancel().unwrap();
    assert!(t.elapsed() > Duration::from_secs(2), "{:?}", t.elapsed());
    assert_eq!(emu.state(), MachineState::Idle);
    // A hold from full speed likewise: stop() waits for Hold:0 before its reset.
    s.move_to(0.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(2600));
    s.stop().unwrap();
    assert_eq!(s.alarm(), None);
    // The estimate a caller can use to wait for a move: 200 mm at 50 mm/s with 2.5 s ramps,
    // and a move too short to reach the feed (a triangle).
    let d = s.move_duration(200.0, 3000.0).as_secs_f64();
    assert!((d - 6.5).abs() < 1e-9, "{d}");
    let d = s.move_duration(20.0, 3000.0).as_secs_f64();
    assert!((d - 2.0).abs() < 1e-9, "{d}");
}

#[test]
fn a_stop_that_never_comes_names_the_stop() {
    let drv = GrblConfig {
        response_timeout: Duration::from_millis(300),
        ..GrblConfig::default()
    };
    let (_emu, mut s) = connected(EmulatorConfig::default(), drv);
    s.home(S10).unwrap();
    // The driver read $120=500; the controller now decelerates at 5 mm/s² (1.5 s from where
    // it will be), so the deadline (0.3 s + 2 x 0.1 s) passes mid-stop.
    s.command("$120=5").unwrap();
    s.jog_to(300.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let t = Instant::now();
    let r = s.jog_cancel();
    println!(
        "{:?} {:?} {:?}",
        t.elapsed(),
        s.stop_deadline(),
        s.last_report()
    );
    match r {
        Err(HalError::Timeout { what, .. }) => {
            assert!(
                what.contains("jog cancel") && what.contains("still Jog"),
                "{what}"
            )
        }
        r => panic!("{r:?}"),
    }
}

fn laser_rig(wiring: LaserWiring, out: LaserOutput) -> (GrblEmulator, GrblSlider) {
    let cfg = EmulatorConfig {
        laser: wiring,
        homing_enabled: false,
        ..EmulatorConfig::default()
    };
    let drv = GrblConfig {
        laser: Some(out),
        // Shorter than the move below (3 s), long enough for a status on a loaded machine.
        response_timeout: Duration::from_secs(1),
        ..GrblConfig::default()
    };
    connected(cfg, drv)
}

#[test]
fn laser_on_during_a_move_waits_for_the_move() {
    let (emu, mut s) = laser_rig(LaserWiring::Spindle, LaserOutput::Spindle { power: 800.0 });
    s.move_to(150.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(100));
    s.laser(true).expect("answered when the move ends");
    assert_eq!(
        emu.state(),
        MachineState::Idle,
        "GRBL switched it after the move"
    );
    assert!(emu.laser_on());
    s.laser(false).unwrap();
    assert!(!emu.laser_on());
}

#[test]
fn laser_on_and_off_mean_the_same_in_laser_mode() {
    let (emu, mut s) = laser_rig(LaserWiring::Spindle, LaserOutput::Spindle { power: 800.0 });
    assert_eq!(s.laser_mode(), Some(false));
    s.command("$32=1").unwrap();
    s.soft_reset().unwrap();
    s.read_settings().unwrap();
    assert_eq!(s.laser_mode(), Some(true), "$32 read");
    s.laser(true).unwrap();
    assert!(emu.laser_on(), "lit at rest after a reset in laser mode");
    s.laser(false).unwrap();
    assert!(!emu.laser_on());
    // And a fresh connect reads the mode by itself.
    s.connect().unwrap();
    assert_eq!(s.laser_mode(), Some(true));
    s.laser(true).unwrap();
    assert!(emu.laser_on());
    s.laser(false).unwrap();
    assert!(!emu.laser_on());
}

#[test]
fn resume_right_after_a_feed_hold_at_rest_leaves_no_hold() {
    let (emu, mut s) = homed(EmulatorConfig::default());
    // At rest, `!` makes Hold:0 once it applies; a status taken before that says Idle.
    s.feed_hold().unwrap();
    s.resume().unwrap();
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(emu.state(), MachineState::Idle, "not left held");
    s.move_to(5.0, 3000.0).unwrap();
    assert_eq!(s.wait_idle(S10).unwrap().x_mm, 5.0);
}

#[test]
fn reconnect_to_a_controller_that_stalls_still_stops_it_first() {
    // grbl-sim under load once left a status query unanswered for over 5 s during a
    // reconnect; a single unanswered query must not lead to a reset in motion.
    let (emu, mut s) = homed(EmulatorConfig::default());
    s.move_to(300.0, 3000.0).unwrap();
    std::thread::sleep(Duration::from_millis(200));
    emu.inject(Fault::Silence(true));
    let emu = std::sync::Arc::new(emu);
    let waker = {
        let emu = emu.clone();
        std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(2500));
            emu.inject(Fault::Silence(false));
        })
    };
    // Response timeout 2 s < the 2.5 s stall < the reset timeout 5 s.
    s.reconnect(Duration::from_secs(5)).unwrap();
    waker.join().unwrap();
    assert_eq!(s.alarm(), None, "reset while moving (ALARM:3)");
    let st = s.status().unwrap();
    assert_eq!(st.state, SliderState::Idle);
    assert!(st.x_mm > 10.0 && st.x_mm < 300.0, "{st:?}");
    assert!((st.x_mm - emu.machine_x()).abs() < 5e-4, "position kept");
}
