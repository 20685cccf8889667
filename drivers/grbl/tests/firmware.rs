//! The driver against the real GRBL 1.1h firmware, built from `../shared/firmware` and run in
//! its host simulator (grbl-sim) behind socat (see tests/grbl_sim/mod.rs). Skipped, with the
//! reason printed, only where gcc, make or socat is missing.
//!
//! grbl-sim runs at about 40 % of real time on a busy 2-core machine: motion takes longer than
//! planned, serial round trips do not. Its defaults are `$110=500` mm/min and `$120=10` mm/s²;
//! most tests raise `$120` so moves stay short, one keeps the slow default on purpose.

mod grbl_sim;

use footscan_grbl::{alarm_message, error_message, GrblConfig, GrblSlider, LaserOutput};
use footscan_hal::{HalError, Slider, SliderState};
use grbl_sim::GrblSim;
use std::time::{Duration, Instant};

const S30: Duration = Duration::from_secs(30);
/// One step at grbl-sim's `$100=250` steps/mm: a target rounds to the nearest step.
const STEP: f64 = 1.0 / 250.0 + 1e-9;

fn config() -> GrblConfig {
    GrblConfig {
        // The simulator reads no input during its first simulated second (2-3 s here).
        reset_timeout: Duration::from_secs(15),
        // grbl-sim on a loaded machine stalls for seconds (its README): polling `?` every
        // 20 ms, without the driver, the longest gap between reports was 4.3 s in 40 s at a
        // load average of 8-12 on 2 cores. Some runs hang for good (no report in 30 s): a
        // grbl-sim fault this timeout cannot cure (docs/method.md 14.1).
        response_timeout: Duration::from_secs(10),
        laser: Some(LaserOutput::Spindle { power: 500.0 }),
        motion_slack: 5.0,
        ..GrblConfig::default()
    }
}

/// A fresh simulator and a connected driver, `$120` set to `accel` (None: GRBL's 10 mm/s²).
fn rig(accel: Option<f64>) -> Option<(GrblSim, GrblSlider)> {
    let sim = GrblSim::start()?;
    let mut s = GrblSlider::new(sim.port_str(), config());
    let t = Instant::now();
    s.connect().expect("connect to grbl-sim");
    println!("connected in {:?}", t.elapsed());
    if let Some(a) = accel {
        s.command(&format!("$120={a}")).unwrap();
        s.read_settings().unwrap();
    }
    Some((sim, s))
}

/// The accessory outputs lit, from the next report that carries them (GRBL sends `A:` with
/// `Ov:`, at once after an output changed and every 10-20 reports otherwise).
fn accessories(s: &mut GrblSlider) -> String {
    for _ in 0..40 {
        s.status().unwrap();
        if let Some(a) = s.last_report().and_then(|r| r.accessories.clone()) {
            return a;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    panic!("no report with Ov:/A: in 40");
}

/// Move by `d` mm at the maximum rate and return once it is under way.
fn start_move(s: &mut GrblSlider, d: f64) -> f64 {
    let x0 = s.status().unwrap().x_mm;
    s.move_to(x0 + d, 500.0).unwrap();
    let t = Instant::now();
    while s.status().unwrap().state != SliderState::Run {
        assert!(
            t.elapsed() < Duration::from_secs(5),
            "the move never started"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    x0
}

/// At rest, not alarmed, and the position stays put (nothing left queued, nothing lost).
fn assert_at_rest(s: &mut GrblSlider, what: &str) -> f64 {
    assert_eq!(s.alarm(), None, "{what}: ALARM ({:?})", s.last_report());
    let a = s.status().unwrap();
    assert_eq!(a.state, SliderState::Idle, "{what}: {a:?}");
    std::thread::sleep(Duration::from_millis(200));
    let b = s.status().unwrap();
    assert_eq!(a.x_mm, b.x_mm, "{what}: still moving");
    b.x_mm
}

/// grbl-sim stalls now and then on a busy machine, for seconds or for good (no status report
/// in 30 s: docs/method.md 14.1), and a test then fails on a timeout that is the simulator's,
/// not the driver's. Each test runs on a fresh simulator up to three times; every failed
/// attempt is printed with its reason, and the test fails if all three do (a driver fault
/// fails every time).
fn attempts(name: &str, once: fn()) {
    const TRIES: usize = 3;
    for k in 1..=TRIES {
        match std::panic::catch_unwind(once) {
            Ok(()) => {
                if k > 1 {
                    println!("{name}: passed on attempt {k} of {TRIES} (grbl-sim)");
                }
                return;
            }
            Err(e) => {
                let why = e
                    .downcast_ref::<String>()
                    .cloned()
                    .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
                    .unwrap_or_default();
                eprintln!("{name}: attempt {k} of {TRIES} failed on grbl-sim: {why}");
                if k == TRIES {
                    std::panic::resume_unwind(e);
                }
            }
        }
    }
}

#[test]
fn connect_settings_status_and_error_decoding() {
    attempts(
        "connect_settings_status_and_error_decoding",
        connect_settings_status_and_error_decoding_once,
    );
}

fn connect_settings_status_and_error_decoding_once() {
    let Some((_sim, mut s)) = rig(None) else {
        return;
    };
    assert_eq!(s.banner(), Some("Grbl 1.1h ['$' for help]"));
    assert_eq!(s.rx_buffer(), 128, "from $I");
    assert_eq!(s.build_info().unwrap().version, "1.1h.20190830");
    let set = s.known_settings().expect("$$ read at connect").clone();
    assert_eq!(set.raw.len(), 34, "{:?}", set.raw.keys());
    assert_eq!(
        (set.max_rate(0), set.acceleration(0)),
        (Some(500.0), Some(10.0))
    );
    assert_eq!(s.laser_mode(), Some(false));
    // 500 mm/min at 10 mm/s² stops in 0.83 s: the response timeout + 5 times that.
    let d = s.stop_deadline().as_secs_f64();
    assert!((d - (10.0 + 5.0 * 500.0 / 60.0 / 10.0)).abs() < 1e-9, "{d}");
    let mut rtts = Vec::new();
    for _ in 0..20 {
        let t = Instant::now();
        let st = s.status().unwrap();
        rtts.push(t.elapsed());
        assert_eq!((st.state, st.x_mm), (SliderState::Idle, 0.0));
    }
    rtts.sort();
    println!("status round trip median {:?}", rtts[10]);
    // Errors carry their code and meaning; the driver stays in step afterwards.
    for (line, code) in [("G1X1", 22), ("$99=1", 3), ("G5X1", 20)] {
        match s.command(line) {
            Err(HalError::Rejected {
                code: c, message, ..
            }) => {
                assert_eq!(c, code, "{line}");
                assert!(message.starts_with(error_message(c)), "{message}");
                assert!(message.contains(line), "{message}");
            }
            r => panic!("{line}: {r:?}"),
        }
    }
    s.command("G4P0").unwrap();
    assert_eq!(s.stats().lost_answers, 0);
}

#[test]
fn moves_hold_resume_and_jog_cancel() {
    attempts(
        "moves_hold_resume_and_jog_cancel",
        moves_hold_resume_and_jog_cancel_once,
    );
}

fn moves_hold_resume_and_jog_cancel_once() {
    let Some((_sim, mut s)) = rig(Some(50.0)) else {
        return;
    };
    s.move_to(3.0, 500.0).unwrap();
    let mut xs = Vec::new();
    let st = s
        .poll_status(S30, |st| {
            xs.push(st.x_mm);
            st.state == SliderState::Idle
        })
        .unwrap();
    assert!(xs.windows(2).all(|w| w[1] >= w[0]), "monotonic: {xs:?}");
    assert!(xs.len() >= 3, "{} reports", xs.len());
    assert_eq!(s.status().unwrap().x_mm, 3.0, "{st}");

    // Feed hold, then resume at once: the resume waits for Hold:0 and is not lost.
    start_move(&mut s, 20.0);
    std::thread::sleep(Duration::from_millis(300));
    s.feed_hold().unwrap();
    s.resume().unwrap();
    let after: Vec<String> = (0..10)
        .map(|_| {
            std::thread::sleep(Duration::from_millis(30));
            let st = s.status().unwrap();
            format!("{:?}@{}", st.state, st.x_mm)
        })
        .collect();
    assert_eq!(
        s.status().unwrap().state,
        SliderState::Run,
        "resumed: {after:?}"
    );
    s.feed_hold().unwrap();
    std::thread::sleep(Duration::from_millis(1000));
    assert_eq!(s.status().unwrap().state, SliderState::Hold);
    assert_eq!(s.last_report().unwrap().substate, Some(0));
    s.resume().unwrap();
    assert_eq!(s.status().unwrap().state, SliderState::Run);
    s.stop().unwrap();
    let x = assert_at_rest(&mut s, "stop after the resume");
    assert!(x > 3.0 && x < 23.0, "{x}");

    // Jog, then cancel: the jog stops short and nothing stays queued.
    s.jog_to(x + 20.0, 500.0).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    assert_eq!(s.status().unwrap().state, SliderState::Jog);
    s.jog_cancel().unwrap();
    let y = assert_at_rest(&mut s, "jog cancel");
    assert!(y > x && y < x + 20.0, "{x} -> {y}");
    s.move_to(y + 0.5, 500.0).unwrap();
    let end = s.wait_idle(S30).unwrap().x_mm;
    assert!(
        (end - (y + 0.5)).abs() <= STEP,
        "moves after a cancel: {y} -> {end}"
    );
}

#[test]
fn jog_cancel_and_stop_at_the_slow_default_deceleration() {
    attempts(
        "jog_cancel_and_stop_at_the_slow_default_deceleration",
        jog_cancel_and_stop_at_the_slow_default_deceleration_once,
    );
}

fn jog_cancel_and_stop_at_the_slow_default_deceleration_once() {
    // $120=10: stopping from 500 mm/min takes 0.83 s simulated, about 2 s here; the fixed 2 s
    // response timeout used to run out first.
    let Some((_sim, mut s)) = rig(None) else {
        return;
    };
    s.jog_to(30.0, 500.0).unwrap();
    std::thread::sleep(Duration::from_millis(2500));
    let t = Instant::now();
    s.jog_cancel().unwrap();
    println!("jog cancel at $120=10 took {:?}", t.elapsed());
    let x = assert_at_rest(&mut s, "jog cancel");
    start_move(&mut s, 20.0);
    std::thread::sleep(Duration::from_millis(2500));
    let t = Instant::now();
    s.stop().unwrap();
    println!("stop at $120=10 took {:?}", t.elapsed());
    let y = assert_at_rest(&mut s, "stop");
    assert!(y > x, "{x} -> {y}");
}

/// Stops and reconnects during moves: never a reset in motion. The count per kind is
/// `FOOTSCAN_GRBL_SIM_STOPS` (default 4; the study in examples/grbl_sim_study.rs runs 50).
#[test]
fn stop_and_reconnect_during_moves_never_alarm() {
    attempts(
        "stop_and_reconnect_during_moves_never_alarm",
        stop_and_reconnect_during_moves_never_alarm_once,
    );
}

fn stop_and_reconnect_during_moves_never_alarm_once() {
    let Some((_sim, mut s)) = rig(Some(50.0)) else {
        return;
    };
    let n: usize = std::env::var("FOOTSCAN_GRBL_SIM_STOPS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(4);
    for i in 0..2 * n {
        // 30 mm: 3.6 s at 500 mm/min even at full simulator speed, so a test thread that the
        // loaded machine leaves waiting still stops it under way.
        let x0 = start_move(&mut s, 30.0);
        // Vary the moment: accelerating, cruising.
        std::thread::sleep(Duration::from_millis(50 + 60 * (i as u64 % 5)));
        if i % 2 == 0 {
            s.stop().unwrap_or_else(|e| panic!("stop {i}: {e}"));
        } else {
            s.reconnect(Duration::from_secs(5))
                .unwrap_or_else(|e| panic!("reconnect {i}: {e}"));
        }
        let x = assert_at_rest(
            &mut s,
            &format!("{} {i}", if i % 2 == 0 { "stop" } else { "reconnect" }),
        );
        assert!(x > x0 && x < x0 + 30.0, "{i}: {x0} -> {x}");
    }
    // The controller still moves: grbl-sim would not after an ALARM:3.
    let x = s.status().unwrap().x_mm;
    s.move_to(x + 0.25, 500.0).unwrap();
    let end = s.wait_idle(S30).unwrap().x_mm;
    assert!((end - (x + 0.25)).abs() <= STEP, "{x} + 0.25 -> {end}");
}

#[test]
fn laser_on_and_off_in_both_laser_modes() {
    attempts(
        "laser_on_and_off_in_both_laser_modes",
        laser_on_and_off_in_both_laser_modes_once,
    );
}

fn laser_on_and_off_in_both_laser_modes_once() {
    let Some((_sim, mut s)) = rig(Some(50.0)) else {
        return;
    };
    for mode in [0, 1] {
        s.command(&format!("$32={mode}")).unwrap();
        // After a reset the motion mode is G0: laser mode then kept `M3 S..` dark.
        s.soft_reset().unwrap();
        s.read_settings().unwrap();
        assert_eq!(s.laser_mode(), Some(mode == 1));
        assert_eq!(accessories(&mut s), "", "$32={mode}: off after the reset");
        s.laser(true).unwrap();
        assert_eq!(accessories(&mut s), "S", "$32={mode}: laser on at rest");
        s.laser(false).unwrap();
        assert_eq!(accessories(&mut s), "", "$32={mode}: laser off");
        // On during a move: GRBL switches the spindle on or off only once the queued motion
        // has run, and the driver waits for that rather than timing out. Outside laser mode
        // only: in laser mode grbl-sim sometimes stops the move short (Idle with the block
        // still planned) and never answers the line (docs/method.md 14.1).
        if mode == 1 {
            continue;
        }
        start_move(&mut s, 3.0);
        if let Err(e) = s.laser(true) {
            panic!("laser on during a move: {e}; last {:?}", s.last_report());
        }
        assert_eq!(
            s.status().unwrap().state,
            SliderState::Idle,
            "answered after the move"
        );
        assert_eq!(accessories(&mut s), "S", "$32={mode}: on after a move");
        s.laser(false).unwrap();
        assert_eq!(accessories(&mut s), "", "$32={mode}: off");
    }
}

#[test]
fn homing_alarm_8_then_unlock_and_settings() {
    attempts(
        "homing_alarm_8_then_unlock_and_settings",
        homing_alarm_8_then_unlock_and_settings_once,
    );
}

fn homing_alarm_8_then_unlock_and_settings_once() {
    let Some((_sim, mut s)) = rig(None) else {
        return;
    };
    // grbl-sim's limit pins read active: the cycle fails its pull-off.
    s.command("$22=1").unwrap();
    match s.home(S30) {
        Err(HalError::Alarm { code, message, .. }) => {
            assert_eq!(code, 8);
            assert_eq!(message, alarm_message(8));
        }
        r => panic!("{r:?}"),
    }
    assert_eq!(s.status().unwrap().state, SliderState::Alarm);
    assert!(s.move_to(1.0, 500.0).unwrap_err().is_alarm());
    // The unlock gets its own answer (not `$H`'s late `ok`) and really unlocks.
    s.unlock().unwrap();
    assert_eq!(s.status().unwrap().state, SliderState::Idle);
    s.command("$22=0").expect("answered, not lost to a reset");
    assert!(!s.read_settings().unwrap().homing_enabled());
    assert_eq!(s.stats().lost_answers, 0);
}

#[test]
fn the_port_vanishing_is_a_disconnect() {
    attempts(
        "the_port_vanishing_is_a_disconnect",
        the_port_vanishing_is_a_disconnect_once,
    );
}

fn the_port_vanishing_is_a_disconnect_once() {
    let Some((mut sim, mut s)) = rig(Some(50.0)) else {
        return;
    };
    start_move(&mut s, 10.0);
    sim.kill();
    let e = s.status().unwrap_err();
    assert!(e.is_disconnect(), "{e}");
    let e = s.reconnect(Duration::from_millis(300)).unwrap_err();
    assert!(e.is_disconnect(), "{e}");
    assert!(e.to_string().contains("ttyGRBL"), "names the port: {e}");
    // The controller comes back (a fresh firmware on the same path): reconnect finds it.
    sim.restart();
    s.reconnect(Duration::from_secs(5)).unwrap();
    assert_eq!(s.status().unwrap().state, SliderState::Idle);
}
