//! Stops and reconnects during moves on the real GRBL 1.1h firmware (grbl-sim behind socat,
//! built from ../shared/firmware into target/ as the firmware tests do), counting how many
//! ended in ALARM:3 (a reset while moving: position lost).
//!
//!     cargo run -p footscan-grbl --example grbl_sim_study -- [STOPS] [RECONNECTS]
//!
//! Defaults: 50 and 50. Prints one line per try and a summary; exits non-zero if any try
//! alarmed or failed. After an ALARM:3 grbl-sim does not move again, so it is restarted.

#[path = "../tests/grbl_sim/mod.rs"]
mod grbl_sim;

use footscan_grbl::{GrblConfig, GrblSlider};
use footscan_hal::{Slider, SliderState};
use std::time::{Duration, Instant};

fn connect(sim: &grbl_sim::GrblSim) -> GrblSlider {
    let mut s = GrblSlider::new(
        sim.port_str(),
        GrblConfig {
            reset_timeout: Duration::from_secs(15),
            response_timeout: Duration::from_secs(10),
            motion_slack: 5.0,
            ..GrblConfig::default()
        },
    );
    s.connect().expect("connect to grbl-sim");
    s.command("$120=50").expect("$120");
    s.read_settings().expect("$$");
    s
}

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| {
            a.parse().unwrap_or_else(|_| {
                eprintln!("usage: grbl_sim_study [STOPS] [RECONNECTS] (counts; got {a:?})");
                std::process::exit(2)
            })
        })
        .collect();
    let stops = args.first().copied().unwrap_or(50);
    let reconnects = args.get(1).copied().unwrap_or(50);
    let Some(mut sim) = grbl_sim::GrblSim::start() else {
        std::process::exit(1);
    };
    let mut s = connect(&sim);
    let (mut alarms, mut failures) = ([0usize; 2], [0usize; 2]);
    let mut took = [Vec::new(), Vec::new()];
    let plan: Vec<usize> = (0..stops.max(reconnects))
        .flat_map(|i| [(i < stops).then_some(0), (i < reconnects).then_some(1)])
        .flatten()
        .collect();
    let t_all = Instant::now();
    for (n, &kind) in plan.iter().enumerate() {
        let name = ["stop", "reconnect"][kind];
        let x0 = s.status().map(|st| st.x_mm).unwrap_or(0.0);
        // Back and forth over 0..40 mm so the travel stays small.
        let target = if x0 < 20.0 { x0 + 10.0 } else { x0 - 10.0 };
        if let Err(e) = s.move_to(target, 500.0) {
            println!("{n:3} {name}: move refused: {e}");
            failures[kind] += 1;
            continue;
        }
        let t = Instant::now();
        while !s.status().is_ok_and(|st| st.state == SliderState::Run) && t.elapsed().as_secs() < 5
        {
            std::thread::sleep(Duration::from_millis(10));
        }
        // Stop at a different moment each time: accelerating, cruising.
        std::thread::sleep(Duration::from_millis(30 + (n as u64 * 37) % 400));
        let t = Instant::now();
        let r = if kind == 0 {
            s.stop()
        } else {
            s.reconnect(Duration::from_secs(5)).map(|_| ())
        };
        let dt = t.elapsed();
        took[kind].push(dt);
        let alarm = s.alarm();
        let st = s.status();
        println!(
            "{n:3} {name}: {r:?} in {dt:?}; alarm {alarm:?}; {:?}",
            st.as_ref().map(|st| (st.state, st.x_mm))
        );
        if alarm == Some(3) {
            alarms[kind] += 1;
        }
        if r.is_err() || alarm.is_some() {
            failures[kind] += 1;
            sim.restart();
            s = connect(&sim);
        }
    }
    for (kind, name) in ["stops", "reconnects"].iter().enumerate() {
        let v = &mut took[kind];
        v.sort();
        let med = v.get(v.len() / 2).copied().unwrap_or_default();
        let max = v.last().copied().unwrap_or_default();
        println!(
            "{name}: {} tries, {} ALARM:3, {} failed; took median {med:?}, max {max:?}",
            v.len(),
            alarms[kind],
            failures[kind]
        );
    }
    println!("total {:?}", t_all.elapsed());
    // exit() skips destructors: end the simulator first.
    drop(s);
    drop(sim);
    if failures.iter().sum::<usize>() > 0 {
        std::process::exit(1);
    }
}
