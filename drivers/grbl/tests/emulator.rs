//! Protocol conformance of the GRBL emulator, over a real pty with a bare serial client.

mod common;

use common::{Client, Report};
use footscan_hal::Timestamp;
use footscan_sim::grbl::{trapezoid_time, EmulatorConfig, GrblEmulator, MachineState};
use std::time::Duration;

const S5: Duration = Duration::from_secs(5);

fn setup(cfg: EmulatorConfig) -> (GrblEmulator, Client) {
    let emu = GrblEmulator::spawn(cfg).expect("spawn emulator");
    let client = Client::open(emu.port_path());
    (emu, client)
}

#[test]
fn banner_alarm_lock_and_unlock() {
    let (emu, mut c) = setup(EmulatorConfig::default());
    let r = c.reset();
    assert!(r.contains(&"Grbl 1.1h ['$' for help]".to_string()), "{r:?}");
    assert!(
        r.contains(&"[MSG:'$H'|'$X' to unlock]".to_string()),
        "{r:?}"
    );
    assert_eq!(emu.state(), MachineState::Alarm);
    assert_eq!(c.status().state(), "Alarm");
    assert_eq!(c.cmd("G1 X1 F100"), ["error:9"]);
    assert_eq!(c.cmd("$X"), ["[MSG:Caution: Unlocked]", "ok"]);
    assert_eq!(c.status().state(), "Idle");
    // A reset of an idle machine keeps it unlocked, as GRBL does.
    let r = c.reset();
    assert!(!r.iter().any(|l| l.contains("unlock")), "{r:?}");
    assert_eq!(emu.state(), MachineState::Idle);
    // The banner is exactly GRBL's, CRLF-framed after an empty line.
    c.send(&[0x18]);
    let mut raw = Vec::new();
    let deadline = std::time::Instant::now() + S5;
    while !raw.ends_with(b"help]\r\n") && std::time::Instant::now() < deadline {
        let mut b = [0u8; 64];
        if let Ok(n) = std::io::Read::read(&mut c.port, &mut b) {
            raw.extend_from_slice(&b[..n]);
        }
    }
    assert_eq!(raw, b"\r\nGrbl 1.1h ['$' for help]\r\n");
}

#[test]
fn errors_and_system_commands() {
    let (_emu, mut c) = setup(EmulatorConfig::default());
    c.reset();
    c.ok("$X");
    assert_eq!(c.cmd("G1 X10"), ["error:22"], "G1 without any feed");
    assert_eq!(c.cmd("1X"), ["error:1"]);
    assert_eq!(c.cmd("GX"), ["error:2"]);
    assert_eq!(c.cmd("$999=1"), ["error:3"]);
    assert_eq!(c.cmd("$J X1"), ["error:3"]);
    assert_eq!(c.cmd("G2 X1 I1"), ["error:20"]);
    assert_eq!(c.cmd("G0 G1 X1"), ["error:21"]);
    assert_eq!(c.cmd("$J=G90 X10"), ["error:22"], "jog needs F");
    assert_eq!(c.cmd("$J=G90 X400 F100"), ["error:15"], "jog beyond travel");
    assert_eq!(c.cmd(&format!("G0 X{}", "1".repeat(90))), ["error:11"]);
    assert_eq!(c.cmd(""), ["ok"], "empty line syncs");
    assert_eq!(c.cmd("(comment only)"), ["ok"]);
    c.ok("G21 G90");
    // CRLF ends one line.
    c.send(b"G91\r\n");
    assert_eq!(c.until_response(S5), ["ok"]);
    assert_eq!(
        c.line(Duration::from_millis(150)),
        None,
        "one answer per CRLF line"
    );
    let g = c.cmd("$G");
    assert!(g[0].starts_with("[GC:G0 G54 G17 G21 G91 G94"), "{g:?}");

    let list = c.cmd("$$");
    assert_eq!(list.last().unwrap(), "ok");
    for want in [
        "$0=10",
        "$10=1",
        "$20=1",
        "$22=1",
        "$110=3000.000",
        "$120=500.000",
        "$130=330.000",
    ] {
        assert!(list.iter().any(|l| l == want), "{want} missing in {list:?}");
    }
    assert!(list.len() > 30, "a full settings list: {list:?}");
    assert_eq!(
        c.cmd("$I"),
        ["[VER:1.1h.20190830:]", "[OPT:V,15,128]", "ok"]
    );
    // Settings are writable and take effect.
    c.ok("$110=1200");
    assert!(c.cmd("$$").contains(&"$110=1200.000".to_string()));
    assert_eq!(c.cmd("$110=-5"), ["error:4"]);
}

fn assert_report_format(r: &Report) {
    let l = &r.line;
    assert!(l.starts_with('<') && l.ends_with('>'), "{l}");
    let fields: Vec<&str> = l[1..l.len() - 1].split('|').collect();
    assert!(
        ["Idle", "Run", "Hold:0", "Hold:1", "Jog", "Alarm", "Home"].contains(&fields[0]),
        "{l}"
    );
    let mpos = fields[1].strip_prefix("MPos:").expect("MPos second");
    let xyz: Vec<&str> = mpos.split(',').collect();
    assert_eq!(xyz.len(), 3, "{l}");
    for v in xyz {
        let dot = v.find('.').expect("decimal point");
        assert_eq!(v.len() - dot - 1, 3, "3 decimals in {l}");
    }
    let fs = fields[2].strip_prefix("FS:").expect("FS third");
    let fs: Vec<&str> = fs.split(',').collect();
    assert_eq!(fs.len(), 2, "{l}");
    fs[0].parse::<u32>().expect("integer feed");
    for f in &fields[3..] {
        assert!(f.starts_with("WCO:") || f.starts_with("Ov:"), "{l}");
    }
}

#[test]
fn status_report_format_and_homing_timing() {
    let (emu, mut c) = setup(EmulatorConfig {
        homing_seconds: 1.0,
        ..Default::default()
    });
    c.reset();
    let first = c.status();
    assert_report_format(&first);
    assert!(
        first.line.contains("|WCO:0.000,0.000,0.000"),
        "GRBL sends WCO in the first report after reset: {}",
        first.line
    );
    let mut ov = false;
    for _ in 0..12 {
        let r = c.status();
        assert_report_format(&r);
        ov |= r.line.contains("|Ov:100,100,100");
    }
    assert!(ov, "override values appear periodically");

    // Move away without homing, then home: state Home for homing_seconds, ok at the end.
    c.ok("$X");
    c.ok("G0 X20");
    c.wait_state("Idle", S5);
    assert_eq!(c.status().x(), 20.0);
    let t0 = Timestamp::now();
    c.send(b"$H\n");
    std::thread::sleep(Duration::from_millis(100));
    let mid = c.status();
    assert_eq!(mid.state(), "Home", "{mid:?}");
    assert!(mid.x() > 0.0 && mid.x() < 20.0, "{mid:?}");
    assert_eq!(c.until_response(S5), ["ok"]);
    let took = Timestamp::now().secs_after(t0);
    assert!((0.99..3.0).contains(&took), "homing took {took} s");
    let r = c.status();
    assert_eq!((r.state(), r.x()), ("Idle", 0.0), "{r:?}");
    assert_eq!(emu.machine_x(), 0.0);

    // Homing disabled: $H is refused.
    let (_emu2, mut c2) = setup(EmulatorConfig {
        homing_enabled: false,
        ..Default::default()
    });
    let r = c2.reset();
    assert!(!r.iter().any(|l| l.contains("unlock")), "{r:?}");
    assert_eq!(c2.cmd("$H"), ["error:5"]);
}

/// Polls `?` until Idle, returning every report.
fn poll_until_idle(c: &mut Client) -> Vec<Report> {
    let mut out = Vec::new();
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    loop {
        let r = c.status();
        let idle = r.state() == "Idle";
        out.push(r);
        if idle {
            return out;
        }
        assert!(std::time::Instant::now() < deadline, "never idle");
        std::thread::sleep(Duration::from_millis(4));
    }
}

#[test]
fn g1_motion_timing_and_past_interpolation() {
    let (emu, mut c) = setup(EmulatorConfig::default());
    c.ready();
    let pos = emu.position_source();
    let t_send = Timestamp::now();
    c.send(b"G1 X100 F3000\n");
    assert_eq!(c.until_response(S5), ["ok"]);
    let t_ok = Timestamp::now();
    assert!(
        t_ok.secs_after(t_send) < 0.5,
        "ok comes when queued, not when done"
    );
    let reports = poll_until_idle(&mut c);
    assert!(reports.iter().any(|r| r.state() == "Run"));
    let last_run = reports.iter().rev().find(|r| r.state() == "Run").unwrap();
    let first_idle = reports.last().unwrap();
    assert_eq!(first_idle.x(), 100.0);
    // The move started in [t_send, t_ok] and ended in [last_run.sent, first_idle.received].
    let lo = last_run.sent.secs_after(t_ok);
    let hi = first_idle.received.secs_after(t_send);
    let want = trapezoid_time(100.0, 3000.0, 500.0);
    assert!((want - 2.1).abs() < 1e-9);
    assert!(
        lo - 0.02 <= want && want <= hi + 0.02,
        "duration {want} s outside the observed [{lo}, {hi}]"
    );
    assert!(hi - lo < 0.2, "observation too coarse: [{lo}, {hi}]");

    // Every report lies between the model's positions at its query and arrival times,
    // evaluated now, in the past.
    for r in &reports {
        let (a, b) = (pos.physical_x(r.sent), pos.physical_x(r.received));
        assert!(
            r.x() >= a - 0.0006 && r.x() <= b + 0.0006,
            "{} not in [{a}, {b}]",
            r.line
        );
    }
    // The shape of the past trajectory is the exact trapezoid: find the midpoint crossing.
    let (mut t_lo, mut t_hi) = (t_send.as_secs_f64(), first_idle.received.as_secs_f64());
    for _ in 0..80 {
        let m = 0.5 * (t_lo + t_hi);
        if pos.physical_x(Timestamp::from_secs_f64(m)) < 50.0 {
            t_lo = m;
        } else {
            t_hi = m;
        }
    }
    let at = |dt: f64| pos.physical_x(Timestamp::from_secs_f64(t_lo + dt));
    assert!((at(-0.5) - 25.0).abs() < 1e-3, "{}", at(-0.5));
    assert!((at(0.5) - 75.0).abs() < 1e-3);
    assert!((at(-1.0) - 0.625).abs() < 1e-3, "{}", at(-1.0));
    assert!((at(1.0) - 99.375).abs() < 1e-3);
    assert!((at(-1.2) - 0.0).abs() < 1e-9);
    assert!((at(1.2) - 100.0).abs() < 1e-9);
}

#[test]
fn feed_hold_decelerates_and_resume_continues() {
    // A gentle 50 mm/s² makes the hold deceleration from 50 mm/s last a full second, so the
    // test does not depend on sub-100 ms scheduling.
    let (emu, mut c) = setup(EmulatorConfig {
        accel_mm_s2: 50.0,
        ..Default::default()
    });
    c.ready();
    let pos = emu.position_source();
    c.ok("G1 X150 F3000");
    c.ok("G1 X100");
    // Acceleration ends after 1 s at X 25; then cruise at 50 mm/s.
    std::thread::sleep(Duration::from_millis(1300));
    let t_hold = Timestamp::now();
    c.send(b"!?");
    // As in GRBL, a `?` right behind the `!` is answered before the hold applies.
    let r = c.line(S5).unwrap();
    assert!(r.starts_with("<Run|"), "{r}");
    let t_hold =
        Timestamp::from_secs_f64(t_hold.as_secs_f64() + emu.config().hold_latency_us as f64 * 1e-6);
    std::thread::sleep(Duration::from_millis(50));
    assert_eq!(c.status().state(), "Hold:1");
    // Resume is ignored while decelerating, as in GRBL.
    c.send(b"~");
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(c.status().state(), "Hold:1");
    let stopped = c.wait_state("Hold:0", S5);
    assert!(
        stopped.received.secs_after(t_hold) > 0.99,
        "decel at 50 mm/s² from 50 mm/s lasts 1 s"
    );
    std::thread::sleep(Duration::from_millis(100));
    let held = c.status();
    assert_eq!(held.state(), "Hold:0");
    assert_eq!(held.x(), stopped.x(), "no motion while held");
    // Stopping distance v²/2a = 25 mm from where the hold was received.
    let d = held.x() - pos.physical_x(t_hold);
    assert!((24.999..26.0).contains(&d), "stopping distance {d}");
    // Lines are still accepted during a hold and queue behind it.
    c.ok("G1 X110");
    c.send(b"~");
    let r = c.status();
    assert_eq!(r.state(), "Run", "{r:?}");
    let reports = poll_until_idle(&mut c);
    assert!(
        reports.iter().any(|r| r.x() > 149.0),
        "resumed to 150 first"
    );
    assert!(reports.iter().any(|r| r.x() < 101.0), "then to 100");
    assert_eq!(reports.last().unwrap().x(), 110.0);
    assert_eq!(emu.machine_x(), 110.0);
}

#[test]
fn jog_and_jog_cancel() {
    let (emu, mut c) = setup(EmulatorConfig::default());
    c.ready();
    c.ok("$J=G91 X100 F3000");
    c.ok("$J=G91 X100 F3000");
    let r = c.status();
    assert_eq!(r.state(), "Jog");
    assert_eq!(c.cmd("G1 X5 F100"), ["error:9"], "g-code locked during jog");
    std::thread::sleep(Duration::from_millis(500));
    c.send(&[0x85, b'?']);
    let r = c.line(S5).unwrap();
    assert!(r.starts_with("<Jog|"), "decelerating: {r}");
    let idle = c.wait_state("Idle", S5);
    assert!(idle.x() > 10.0 && idle.x() < 190.0, "{idle:?}");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(c.status().x(), idle.x(), "queued jogs were discarded");
    // Jog cancel outside a jog does nothing; jogging resumes normally afterwards.
    c.send(&[0x85]);
    c.ok("$J=G90 X0 F3000");
    c.wait_state("Idle", S5);
    assert_eq!(emu.machine_x(), 0.0);
}

#[test]
fn soft_limit_alarm_and_reset_in_motion() {
    let (emu, mut c) = setup(EmulatorConfig::default());
    c.ready();
    c.send(b"G1 X400 F1000\n");
    assert_eq!(c.line(S5).as_deref(), Some("ALARM:2"));
    assert_eq!(c.line(S5).as_deref(), Some("[MSG:Reset to continue]"));
    assert_eq!(c.status().state(), "Alarm");
    c.send(b"G0 X1\n$X\n");
    assert_eq!(
        c.line(Duration::from_millis(300)),
        None,
        "nothing but ? and reset until reset"
    );
    let r = c.reset();
    assert_eq!(
        r,
        ["Grbl 1.1h ['$' for help]", "[MSG:'$H'|'$X' to unlock]"],
        "pending lines were flushed by the reset"
    );
    c.ok("$X");

    // Soft limit while moving: decelerate first, then alarm.
    c.ok("G1 X100 F3000");
    std::thread::sleep(Duration::from_millis(300));
    c.send(b"G1 X-5\n");
    assert_eq!(c.line(S5).as_deref(), Some("ALARM:2"));
    let x = emu.machine_x();
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(emu.machine_x(), x, "stopped by the time of the alarm");
    c.reset();
    c.ok("$X");

    // Reset during motion: steppers stop dead, ALARM:3, then the banner and the lock.
    c.ok("G1 X200 F3000");
    std::thread::sleep(Duration::from_millis(300));
    let r = c.reset();
    assert_eq!(
        r,
        [
            "ALARM:3",
            "Grbl 1.1h ['$' for help]",
            "[MSG:'$H'|'$X' to unlock]"
        ]
    );
    let x = emu.machine_x();
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(emu.machine_x(), x);
    assert_eq!(emu.state(), MachineState::Alarm);
    // After a reset the feed rate is undefined again.
    c.ok("$X");
    assert_eq!(c.cmd("G1 X10"), ["error:22"]);
}

#[test]
fn planner_holds_fifteen_blocks_and_counting_never_overflows() {
    let (emu, mut c) = setup(EmulatorConfig::default());
    c.ready();
    // 20 moves, sent with GRBL's character-counting protocol.
    let lines: Vec<String> = (0..20)
        .map(|i| format!("G1 X{} F3000", if i % 2 == 0 { 30 } else { 0 }))
        .collect();
    let mut in_flight: std::collections::VecDeque<usize> = Default::default();
    let mut oks = Vec::new();
    let t0 = Timestamp::now();
    for l in &lines {
        let n = l.len() + 1;
        while in_flight.iter().sum::<usize>() + n > 127 {
            assert_eq!(c.line(S5).as_deref(), Some("ok"));
            oks.push(Timestamp::now().secs_after(t0));
            in_flight.pop_front();
        }
        c.send(format!("{l}\n").as_bytes());
        in_flight.push_back(n);
    }
    while in_flight.pop_front().is_some() {
        assert_eq!(c.line(S5).as_deref(), Some("ok"));
        oks.push(Timestamp::now().secs_after(t0));
    }
    // Each 30 mm move lasts 0.7 s: 15 fit in the planner at once, the 16th waits for one.
    let one = trapezoid_time(30.0, 3000.0, 500.0);
    assert!((one - 0.7).abs() < 1e-9);
    assert!(oks[14] < one * 0.8, "first 15 accepted at once: {oks:?}");
    assert!(
        oks[15] > one * 0.8,
        "16th waits for a block to finish: {oks:?}"
    );
    assert!(oks[19] > one * 4.8, "then one per finished block: {oks:?}");
    assert_eq!(emu.rx_overflow_bytes(), 0);
    // Reset mid-motion discards the rest of the plan.
    let r = c.reset();
    assert_eq!(r[0], "ALARM:3");
    c.ok("$X");
    c.ok("G0 X0");
    c.wait_state("Idle", S5);

    // A client that does not count overflows the 128-byte buffer (counted, still processed).
    let mut burst = String::new();
    for _ in 0..20 {
        burst += "G1 X0.1 F3000\nG1 X0\n";
    }
    c.send(burst.as_bytes());
    for _ in 0..40 {
        assert_eq!(c.line(Duration::from_secs(20)).as_deref(), Some("ok"));
    }
    assert!(emu.rx_overflow_bytes() > 0);
}

#[test]
fn physical_position_has_scale_and_backlash() {
    let (emu, mut c) = setup(EmulatorConfig {
        slider_scale: 1.01,
        backlash_mm: 0.2,
        ..Default::default()
    });
    c.ready();
    let pos = emu.position_source();
    assert_eq!(pos.physical_x(Timestamp::now()), 0.0);
    c.ok("G0 X100");
    c.wait_state("Idle", S5);
    let now = Timestamp::now();
    // The controller reports the motor; the carriage trails by the play, times the scale.
    assert_eq!(c.status().x(), 100.0);
    assert!((pos.physical_x(now) - 1.01 * 99.8).abs() < 1e-9);
    // A reversal smaller than the play does not move the carriage.
    c.ok("G0 X99.9");
    c.wait_state("Idle", S5);
    assert!((pos.physical_x(Timestamp::now()) - 1.01 * 99.8).abs() < 1e-9);
    c.ok("G0 X50");
    c.wait_state("Idle", S5);
    assert!((pos.physical_x(Timestamp::now()) - 1.01 * 50.0).abs() < 1e-9);
    // The past is still there.
    assert!((pos.physical_x(now) - 1.01 * 99.8).abs() < 1e-9);
}

#[test]
fn status_latency_delays_the_report() {
    let (_emu, mut c) = setup(EmulatorConfig {
        status_latency_us: 30_000,
        ..Default::default()
    });
    c.reset();
    for _ in 0..3 {
        let r = c.status();
        assert!(r.received.secs_after(r.sent) >= 0.03, "{r:?}");
    }
}

#[test]
fn dwell_waits_for_the_planner_then_dwells() {
    let (_emu, mut c) = setup(EmulatorConfig::default());
    c.ready();
    c.ok("G1 X10 F3000"); // 0.3 s
    let t0 = Timestamp::now();
    c.ok("G4 P0.2");
    let took = Timestamp::now().secs_after(t0);
    assert!((0.49..2.0).contains(&took), "G4 answered after {took} s");
    assert_eq!(c.status().state(), "Idle");
    assert_eq!(c.cmd("G4"), ["error:28"], "P is required");
}
