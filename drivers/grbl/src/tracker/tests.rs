//! The tracker driven by byte strings, through the same [`LineBuffer`] the link uses, so
//! partial reads, noise and interleaving are exercised without a port.

use super::*;
use crate::codes::error_message;
use crate::link::LineBuffer;

const GC: &[u8] = b"[GC:G0 G54 G17 G21 G90 G94 M5 M9 T0 F0 S0]\r\n";

struct Wire {
    t: Tracker,
    rx: LineBuffer,
    clock: u64,
}

impl Wire {
    fn new() -> Wire {
        Wire {
            t: Tracker::new(128),
            rx: LineBuffer::default(),
            clock: 0,
        }
    }

    fn send(&mut self, line: &str) -> u64 {
        self.t.send(line, LineKind::Command).unwrap().0
    }

    fn sync(&mut self) -> u64 {
        self.t.send("$G", LineKind::Sync).unwrap().0
    }

    /// One read: bytes in, every complete line routed (stamped with this read's time).
    fn feed(&mut self, bytes: &[u8]) -> Vec<Routed> {
        self.clock += 1;
        self.rx.push(bytes);
        let mut out = Vec::new();
        while let Some(l) = self.rx.next_line().unwrap() {
            out.push(self.t.on_line(&l, Timestamp { nanos: self.clock }));
        }
        out
    }

    fn outcome(&mut self, id: u64) -> Option<Outcome> {
        self.t.skip_older(id);
        match self.t.poll(id) {
            Poll::Answered(a) => {
                assert_eq!(a.id, id);
                Some(a.outcome)
            }
            Poll::Pending => None,
            Poll::Missing => panic!("line #{id} missing"),
        }
    }
}

#[test]
fn ok_answers_pair_with_lines_in_order() {
    let mut w = Wire::new();
    let ids: Vec<u64> = ["G21", "G90", "G1X10F3000"]
        .iter()
        .map(|l| w.send(l))
        .collect();
    assert_eq!(
        w.feed(b"ok\r\nok\r\n"),
        [
            Routed::Answer(ids[0], Outcome::Ok),
            Routed::Answer(ids[1], Outcome::Ok)
        ]
    );
    assert_eq!(w.outcome(ids[0]), Some(Outcome::Ok));
    assert_eq!(w.outcome(ids[1]), Some(Outcome::Ok));
    assert_eq!(w.outcome(ids[2]), None, "still in flight");
    w.feed(b"ok\r\n");
    assert_eq!(w.outcome(ids[2]), Some(Outcome::Ok));
    assert_eq!(w.t.poll(ids[2]), Poll::Missing, "taken once");
    assert_eq!(w.feed(b"ok\r\n"), [Routed::Unsolicited]);
    assert!(!w.t.unsynced());
}

#[test]
fn error_code_is_the_outcome_of_its_own_line() {
    let mut w = Wire::new();
    let a = w.send("G2 X1 I1");
    let b = w.send("G4 P0");
    w.feed(b"error:20\r\nok\r\n");
    assert_eq!(w.outcome(a), Some(Outcome::Error(20)));
    assert_eq!(w.outcome(b), Some(Outcome::Ok));
    assert!(error_message(20).starts_with("unsupported command"));
}

#[test]
fn answers_nobody_waits_for_are_skipped() {
    let mut w = Wire::new();
    let a = w.send("G2 X1 I1");
    let b = w.send("G4 P0");
    w.feed(b"error:20\r\nok\r\n");
    let skipped = w.t.skip_older(b);
    assert_eq!(skipped.len(), 1);
    assert_eq!(
        (skipped[0].id, skipped[0].outcome, skipped[0].line.as_str()),
        (a, Outcome::Error(20), "G2 X1 I1")
    );
    assert_eq!(w.outcome(b), Some(Outcome::Ok));
}

#[test]
fn alarm_mid_stream_loses_every_line_in_flight() {
    let mut w = Wire::new();
    let ids: Vec<u64> = (0..4)
        .map(|i| w.send(&format!("G1X{}F3000", i * 100)))
        .collect();
    let r = w.feed(b"ok\r\nok\r\nALARM:2\r\n[MSG:Reset to continue]\r\n");
    assert_eq!(r[2], Routed::Alarm(2));
    assert_eq!(w.outcome(ids[1]), Some(Outcome::Ok));
    assert_eq!(w.outcome(ids[2]), Some(Outcome::LostToAlarm(2)));
    assert_eq!(w.outcome(ids[3]), Some(Outcome::LostToAlarm(2)));
    assert_eq!(w.t.in_flight_bytes(), 0);
    assert_eq!(w.t.alarm(), Some(2));
    // A report in Alarm keeps the code; the unlock message clears it.
    w.feed(b"<Alarm|MPos:0.000,0.000,0.000|FS:0,0>\r\n");
    assert_eq!(w.t.alarm(), Some(2));
    w.feed(b"[MSG:Caution: Unlocked]\r\n");
    assert_eq!(w.t.alarm(), None);
    // The lock message after a reset is an alarm without a code.
    w.feed(b"\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n");
    assert_eq!(w.t.alarm(), Some(0));
    w.feed(b"<Idle|MPos:0.000,0.000,0.000|FS:0,0>\r\n");
    assert_eq!(w.t.alarm(), None, "an Idle report ends it");
}

#[test]
fn a_reset_loses_the_lines_in_flight() {
    let mut w = Wire::new();
    w.feed(b"<Idle|MPos:0.000,0.000,0.000|FS:0,0|WCO:5.000,0.000,0.000>\r\n");
    assert_eq!(w.t.wco(), Some(&[5.0, 0.0, 0.0][..]));
    let a = w.send("G4 P1");
    assert_eq!(
        w.feed(b"\r\nGrbl 1.1h ['$' for help]\r\n"),
        [Routed::Banner]
    );
    assert_eq!(w.outcome(a), Some(Outcome::LostToReset));
    assert_eq!(w.t.banners(), 1);
    assert_eq!(w.t.banner(), Some("Grbl 1.1h ['$' for help]"));
    assert_eq!(w.t.wco(), None, "the offset is re-reported after a reset");
}

#[test]
fn a_dropped_ok_is_found_by_the_resync_and_later_answers_stay_right() {
    let mut w = Wire::new();
    let a = w.send("G1X10F3000");
    let b = w.send("G1X20F3000");
    // The controller answered both, but the second `ok` never arrived.
    w.feed(b"ok\r\n");
    assert_eq!(w.outcome(a), Some(Outcome::Ok));
    assert_eq!(w.outcome(b), None);
    // The waiter times out and queues a sync `$G` behind it.
    let g = w.sync();
    assert_eq!(w.t.stats.resyncs, 1);
    let c = w.send("G1X30F3000");
    let r = w.feed(&[GC, b"ok\r\nok\r\n"].concat());
    assert_eq!(r[0], Routed::Resynced { lost: 1 });
    assert_eq!(w.outcome(b), Some(Outcome::Lost));
    assert_eq!(w.outcome(g), Some(Outcome::Ok), "the $G has its own ok");
    assert_eq!(
        w.outcome(c),
        Some(Outcome::Ok),
        "not shifted by the lost one"
    );
    assert_eq!(w.t.stats.lost_answers, 1);
    assert!(w.t.take_feedback().iter().any(|l| l.starts_with("[GC:")));
}

#[test]
fn a_late_ok_before_the_resync_is_not_lost() {
    let mut w = Wire::new();
    let a = w.send("G1X10F3000");
    let g = w.sync();
    w.feed(&[b"ok\r\n", GC, b"ok\r\n"].concat());
    assert_eq!(w.outcome(a), Some(Outcome::Ok));
    assert_eq!(w.outcome(g), Some(Outcome::Ok));
    assert_eq!(w.t.stats.lost_answers, 0);
}

#[test]
fn a_gc_without_a_sync_in_flight_marks_nothing() {
    let mut w = Wire::new();
    let a = w.send("G4 P0");
    let g = w.send("$G");
    assert_eq!(
        w.feed(GC),
        [Routed::Feedback],
        "a plain $G asked by the user"
    );
    assert_eq!(w.outcome(a), None);
    w.feed(b"ok\r\nok\r\n");
    assert_eq!(w.outcome(a), Some(Outcome::Ok));
    assert_eq!(w.outcome(g), Some(Outcome::Ok));
}

#[test]
fn a_corrupted_ok_is_garbage_and_the_resync_finds_it_lost() {
    let mut w = Wire::new();
    let a = w.send("G1X10F3000");
    let r = w.feed(b"0k\r\n");
    assert_eq!(r, [Routed::Garbage("0k".into())]);
    assert_eq!(w.t.stats.garbage_lines, 1);
    assert!(w.t.unsynced(), "it may have been the answer");
    assert_eq!(w.outcome(a), None);
    let g = w.sync();
    w.feed(&[GC, b"ok\r\n"].concat());
    assert_eq!(w.outcome(a), Some(Outcome::Lost));
    assert_eq!(w.outcome(g), Some(Outcome::Ok));
    assert!(!w.t.unsynced());
    assert_eq!(w.t.garbage().collect::<Vec<_>>(), ["0k"]);
}

#[test]
fn status_reports_interleave_with_answers() {
    let mut w = Wire::new();
    let a = w.send("G1X100F3000");
    let b = w.send("G1X200F3000");
    let r = w.feed(
        b"<Run|MPos:12.500,0.000,0.000|FS:3000,0>\r\nok\r\n<Run|MPos:13.000,0.000,0.000|FS:3000,0>\r\nok\r\n",
    );
    assert_eq!(r[0], Routed::Report);
    assert_eq!(r[1], Routed::Answer(a, Outcome::Ok));
    assert_eq!(r[3], Routed::Answer(b, Outcome::Ok));
    assert_eq!(w.t.reports(), 2);
    let (rep, at) = w.t.last_report().unwrap();
    assert_eq!(rep.state, SliderState::Run);
    assert_eq!(rep.machine_x(None), Some(13.0));
    assert_eq!(at.nanos, 1, "stamped with the read it arrived in");
    // A mangled report is counted as such and leaves the pairing alone.
    let c = w.send("G4 P0");
    w.feed(b"<Run|MPos:1#.000,0.000,0.000|FS:3000,0>\r\nok\r\n");
    assert_eq!(w.t.stats.corrupt_reports, 1);
    assert_eq!(w.t.reports(), 2, "not counted as a report");
    assert!(!w.t.unsynced());
    assert_eq!(w.outcome(c), Some(Outcome::Ok));
}

#[test]
fn rx_budget_counts_the_bytes_in_flight() {
    let mut w = Wire::new();
    assert_eq!(w.t.stream_budget(), 127);
    let line = "G1X100.0000F3000.000"; // 20 bytes + '\n'
    let mut ids = Vec::new();
    while w.t.has_room(line) {
        ids.push(w.send(line));
    }
    assert_eq!(ids.len(), 6, "6 x 21 = 126 of 127 bytes");
    assert_eq!(w.t.in_flight_bytes(), 126);
    assert!(!w.t.has_room("G4"), "126 + 3 > 127");
    w.feed(b"ok\r\n");
    assert_eq!(w.t.in_flight_bytes(), 105);
    assert!(w.t.has_room(line));
    // A larger buffer reported by `$I` widens the budget.
    w.feed(b"[OPT:V,15,256]\r\n");
    assert_eq!((w.t.rx_buffer(), w.t.stream_budget()), (256, 255));
    // Lines GRBL cannot take are refused before they are counted.
    let long = "G1X".to_string() + &"1".repeat(80);
    assert!(w.t.send(&long, LineKind::Command).is_err());
    assert!(w.t.send("G1X1\nG1X2", LineKind::Command).is_err());
    assert_eq!(w.t.in_flight_bytes(), 105);
    // A write that failed is withdrawn.
    let (id, bytes) = w.t.send("G4 P0", LineKind::Command).unwrap();
    assert_eq!(bytes, b"G4 P0\n");
    w.t.unsend(id);
    assert_eq!(w.t.in_flight_bytes(), 105);
    assert_eq!(w.t.poll(id), Poll::Missing);
}

#[test]
fn lines_split_across_reads_route_once_complete() {
    let mut w = Wire::new();
    let a = w.send("$I");
    assert!(w.feed(b"[VER:1.1h.2019").is_empty());
    assert_eq!(w.feed(b"0830:]\r\n[OPT:V,15,12"), [Routed::Feedback]);
    assert!(w.feed(b"8]\r").is_empty(), "a \\r alone is no line end");
    assert_eq!(w.feed(b"\no"), [Routed::Feedback]);
    assert_eq!(w.outcome(a), None);
    assert_eq!(w.feed(b"k\r\n"), [Routed::Answer(a, Outcome::Ok)]);
    assert_eq!(w.outcome(a), Some(Outcome::Ok));
    assert_eq!(
        w.t.take_feedback(),
        ["[VER:1.1h.20190830:]", "[OPT:V,15,128]"]
    );
}

#[test]
fn garbage_is_counted_kept_and_harmless_when_nothing_is_in_flight() {
    let mut w = Wire::new();
    let r = w.feed(b"\xff\xfejunk\r\nHELLO WORLD\r\n");
    assert_eq!(r.len(), 2);
    assert!(matches!(&r[0], Routed::Garbage(g) if g.ends_with("junk")));
    assert_eq!(w.t.stats.garbage_lines, 2);
    assert!(
        !w.t.unsynced(),
        "no line in flight could have been answered"
    );
    for i in 0..10 {
        w.feed(format!("noise {i}\n").as_bytes());
    }
    let kept: Vec<&str> = w.t.garbage().collect();
    assert_eq!(kept.len(), GARBAGE_KEPT);
    assert_eq!(kept.last(), Some(&"noise 9"));
    w.t.clear_garbage();
    assert_eq!(w.t.garbage().count(), 0);
    // GRBL 0.9's comma-separated report is not a 1.1 report.
    w.feed(b"<Idle,MPos:0.000,0.000,0.000>\r\n");
    assert_eq!(w.t.stats.corrupt_reports, 1);
}

#[test]
fn settings_and_feedback_are_collected_per_command() {
    let mut w = Wire::new();
    w.t.clear_collected();
    let a = w.send("$$");
    w.feed(b"$0=10\r\n$110=3000.000\r\n$N0=\r\n>G54:ok\r\nok\r\n");
    assert_eq!(w.outcome(a), Some(Outcome::Ok));
    let s = w.t.take_settings();
    assert_eq!((s.len(), s.get(&110)), (2, Some(&3000.0)));
    assert_eq!(w.t.take_feedback(), ["$N0=", ">G54:ok"]);
    assert!(w.t.take_settings().is_empty(), "taken");
}

#[test]
fn reopening_forgets_the_old_port_but_keeps_the_counters() {
    let mut w = Wire::new();
    w.send("G4 P0");
    w.feed(b"ALARM:1\r\nGrbl 1.1h ['$' for help]\r\njunk\r\n<Idle|MPos:1,0,0>\r\n");
    w.t.mark_unsynced();
    w.t.reopen(256);
    assert_eq!(w.t.alarm(), None);
    assert_eq!(w.t.banner(), None);
    assert!(w.t.last_report().is_none());
    assert!(!w.t.unsynced());
    assert_eq!((w.t.rx_buffer(), w.t.in_flight_bytes()), (256, 0));
    assert_eq!((w.t.banners(), w.t.reports()), (1, 1));
    assert_eq!(w.t.stats.garbage_lines, 1);
    let a = w.send("G4 P0");
    w.t.forget_in_flight();
    assert_eq!(w.t.poll(a), Poll::Missing);
}

#[test]
fn a_failed_homing_cycle_is_answered_after_its_alarm() {
    // GRBL 1.1h on a failed `$H`: ALARM:8, the line's `ok` half a second later, then the reset.
    let mut w = Wire::new();
    let home = w.t.send("$H", LineKind::Homing).unwrap().0;
    w.feed(b"ALARM:8\r\n");
    assert_eq!(w.t.alarm(), Some(8));
    assert_eq!(w.outcome(home), None, "still executing: its answer comes");
    assert_eq!(
        w.feed(b"ok\r\n"),
        [Routed::Answer(home, Outcome::LostToAlarm(8))]
    );
    // The next line pairs with its own answer, not with `$H`'s.
    let unlock = w.send("$X");
    w.feed(b"\r\nGrbl 1.1h ['$' for help]\r\n[MSG:'$H'|'$X' to unlock]\r\n");
    assert_eq!(w.outcome(unlock), Some(Outcome::LostToReset));
    let unlock = w.send("$X");
    w.feed(b"[MSG:Caution: Unlocked]\r\nok\r\n");
    assert_eq!(w.outcome(unlock), Some(Outcome::Ok));
    assert_eq!(w.t.alarm(), None);
}
