//! Analytic motion model: a timeline of monotonic moves made of constant-acceleration phases.
//!
//! Every move is planned the moment it enters the planner, so the machine position is a closed
//! form function of time for the whole plan, past (a retained history) and future alike. Blocks
//! are joined with a full stop (no junction look-ahead): each block accelerates from rest at
//! `$120` to its feed (capped at `$110`), cruises and decelerates to rest at its end point. Real
//! GRBL blends junctions; for a single-axis scanner doing one long move per pass the difference
//! is immaterial and the full-stop profile is exactly reproducible in tests.
//!
//! Times are seconds on `CLOCK_MONOTONIC` as `f64` (sub-nanosecond resolution over years of
//! uptime), positions in mm.

use std::collections::VecDeque;

/// Below this (mm) a move has no length.
pub(crate) const EPS_MM: f64 = 1e-7;

#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Phase {
    pub dur: f64,
    /// Signed acceleration, mm/s².
    pub acc: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum MoveKind {
    /// G0/G1 block.
    Line,
    /// `$J=` jog block.
    Jog,
    /// The simulated homing cycle.
    Homing,
}

/// What a planner block asks for; kept to re-plan the remainder after a feed hold.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Spec {
    pub kind: MoveKind,
    pub target: f64,
    /// mm/min, already capped at the max rate.
    pub feed: f64,
}

/// One monotonic motion: starts at (t0, x0, v0) and integrates its phases.
#[derive(Clone, Debug)]
pub(crate) struct Move {
    pub t0: f64,
    pub x0: f64,
    pub v0: f64,
    pub phases: Vec<Phase>,
    /// Backlash play state at the start (see [`Timeline::play_at`]).
    pub p0: f64,
    pub spec: Spec,
    pub t_end: f64,
    pub x_end: f64,
    /// Velocity at the end of the last phase (non-zero only after an instant stop).
    pub v_end: f64,
}

fn integrate(x0: f64, v0: f64, phases: &[Phase], mut dt: f64) -> (f64, f64) {
    let (mut x, mut v) = (x0, v0);
    for ph in phases {
        if dt <= 0.0 {
            break;
        }
        let d = dt.min(ph.dur);
        x += v * d + 0.5 * ph.acc * d * d;
        v += ph.acc * d;
        dt -= d;
    }
    (x, v)
}

/// The backlash play operator for monotonic motion: the carriage position `p` stays within
/// `[m - b, m]` of the motor position `m`, moving only when pushed by either edge.
pub(crate) fn play(p0: f64, m: f64, b: f64) -> f64 {
    p0.clamp(m - b, m)
}

impl Move {
    pub fn new(t0: f64, x0: f64, v0: f64, phases: Vec<Phase>, p0: f64, spec: Spec) -> Move {
        let mut m = Move {
            t0,
            x0,
            v0,
            phases,
            p0,
            spec,
            t_end: t0,
            x_end: x0,
            v_end: v0,
        };
        m.recompute();
        m
    }

    fn recompute(&mut self) {
        let total: f64 = self.phases.iter().map(|p| p.dur).sum();
        self.t_end = self.t0 + total;
        let (x, v) = integrate(self.x0, self.v0, &self.phases, f64::INFINITY);
        self.x_end = x;
        self.v_end = v;
    }

    /// Position and velocity at `t` (clamped to the move; at rest after its end).
    pub fn eval(&self, t: f64) -> (f64, f64) {
        if t >= self.t_end {
            return (self.x_end, 0.0);
        }
        integrate(self.x0, self.v0, &self.phases, t - self.t0)
    }

    /// Keep only the part of the move before `t`.
    pub fn truncate(&mut self, t: f64) {
        let mut left = (t - self.t0).max(0.0);
        let mut kept = Vec::with_capacity(self.phases.len());
        for ph in &self.phases {
            if left <= 0.0 {
                break;
            }
            let d = left.min(ph.dur);
            kept.push(Phase {
                dur: d,
                acc: ph.acc,
            });
            left -= d;
        }
        self.phases = kept;
        self.recompute();
    }

    /// Play state at the end of this move.
    pub fn p_end(&self, b: f64) -> f64 {
        play(self.p0, self.x_end, b)
    }
}

/// Phases of a rest-to-rest trapezoid (or triangle) over signed `dist` at peak speed `vmax`
/// (mm/s) and acceleration `a` (mm/s²).
pub(crate) fn trapezoid(dist: f64, vmax: f64, a: f64) -> Vec<Phase> {
    let d = dist.abs();
    if d < EPS_MM || vmax <= 0.0 || a <= 0.0 {
        return Vec::new();
    }
    let s = dist.signum();
    let d_ramp = vmax * vmax / a; // accelerate + decelerate
    if d >= d_ramp {
        let ta = vmax / a;
        let tc = (d - d_ramp) / vmax;
        vec![
            Phase {
                dur: ta,
                acc: s * a,
            },
            Phase { dur: tc, acc: 0.0 },
            Phase {
                dur: ta,
                acc: -s * a,
            },
        ]
    } else {
        let ta = (d / a).sqrt();
        vec![
            Phase {
                dur: ta,
                acc: s * a,
            },
            Phase {
                dur: ta,
                acc: -s * a,
            },
        ]
    }
}

/// Duration of [`trapezoid`].
pub fn trapezoid_time(dist: f64, feed_mm_min: f64, accel: f64) -> f64 {
    trapezoid(dist, feed_mm_min / 60.0, accel)
        .iter()
        .map(|p| p.dur)
        .sum()
}

/// The planned and executed motion.
#[derive(Clone, Debug)]
pub(crate) struct Timeline {
    moves: VecDeque<Move>,
    /// Position and play state before the first retained move.
    rest_x: f64,
    rest_p: f64,
    pub backlash: f64,
    pub scale: f64,
}

impl Timeline {
    pub fn new(x: f64, backlash: f64, scale: f64) -> Timeline {
        Timeline {
            moves: VecDeque::new(),
            rest_x: x,
            rest_p: x,
            backlash: backlash.abs(),
            scale,
        }
    }

    /// Index of the last move that started at or before `t`.
    fn index_at(&self, t: f64) -> Option<usize> {
        let n = self.moves.partition_point(|m| m.t0 <= t);
        n.checked_sub(1)
    }

    pub fn machine_at(&self, t: f64) -> f64 {
        match self.index_at(t) {
            None => self.moves.front().map(|m| m.x0).unwrap_or(self.rest_x),
            Some(i) => self.moves[i].eval(t).0,
        }
    }

    pub fn velocity_at(&self, t: f64) -> f64 {
        self.index_at(t)
            .map(|i| self.moves[i].eval(t).1)
            .unwrap_or(0.0)
    }

    /// Carriage position in machine units: the motor position filtered by the backlash play.
    pub fn play_at(&self, t: f64) -> f64 {
        match self.index_at(t) {
            None => self.moves.front().map(|m| m.p0).unwrap_or(self.rest_p),
            Some(i) => {
                let m = &self.moves[i];
                play(m.p0, m.eval(t).0, self.backlash)
            }
        }
    }

    pub fn physical_at(&self, t: f64) -> f64 {
        self.scale * self.play_at(t)
    }

    pub fn end_x(&self) -> f64 {
        self.moves.back().map(|m| m.x_end).unwrap_or(self.rest_x)
    }

    pub fn end_t(&self) -> f64 {
        self.moves
            .back()
            .map(|m| m.t_end)
            .unwrap_or(f64::NEG_INFINITY)
    }

    fn end_p(&self) -> f64 {
        self.moves
            .back()
            .map(|m| m.p_end(self.backlash))
            .unwrap_or(self.rest_p)
    }

    /// The move executing at `t`, if any.
    pub fn active(&self, t: f64) -> Option<&Move> {
        self.index_at(t)
            .map(|i| &self.moves[i])
            .filter(|m| t < m.t_end)
    }

    /// Moves not yet finished at `t` (planner occupancy).
    pub fn busy_count(&self, t: f64) -> usize {
        self.moves.iter().rev().take_while(|m| m.t_end > t).count()
    }

    /// End time of the move executing at `t`, for the server's wake-up schedule.
    pub fn next_end_after(&self, t: f64) -> Option<f64> {
        self.active(t).map(|m| m.t_end)
    }

    /// Plan `spec` after everything already planned (not before `now`), from rest.
    pub fn push(&mut self, now: f64, spec: Spec, accel: f64) {
        let x0 = self.end_x();
        let phases = match spec.kind {
            MoveKind::Homing => Vec::new(),
            _ => trapezoid(spec.target - x0, spec.feed / 60.0, accel),
        };
        if phases.is_empty() {
            return;
        }
        let t0 = self.end_t().max(now);
        let p0 = self.end_p();
        self.moves
            .push_back(Move::new(t0, x0, 0.0, phases, p0, spec));
    }

    /// Plan a constant-speed move to `target` taking `secs` (the simulated homing cycle).
    pub fn push_linear(&mut self, now: f64, target: f64, secs: f64) {
        let x0 = self.end_x();
        if (target - x0).abs() < EPS_MM || secs <= 0.0 {
            return;
        }
        let t0 = self.end_t().max(now);
        let p0 = self.end_p();
        let spec = Spec {
            kind: MoveKind::Homing,
            target,
            feed: (target - x0).abs() / secs * 60.0,
        };
        let phases = vec![Phase {
            dur: secs,
            acc: 0.0,
        }];
        self.moves
            .push_back(Move::new(t0, x0, (target - x0) / secs, phases, p0, spec));
    }

    /// Stop dead at `t` (steppers killed): drop everything planned after `t`.
    pub fn stop_now(&mut self, t: f64) {
        while self.moves.back().is_some_and(|m| m.t0 > t) {
            self.moves.pop_back();
        }
        if let Some(m) = self.moves.back_mut() {
            if m.t_end > t {
                m.truncate(t);
            }
        }
    }

    /// Decelerate at `a` from `t` to a stop. Returns the stop time and the specs of what was
    /// left undone, in order: the remainder of the interrupted block (to its original target),
    /// then every block planned after it.
    pub fn decel_stop(&mut self, t: f64, a: f64) -> (f64, Vec<Spec>) {
        let mut later = Vec::new();
        while self.moves.back().is_some_and(|m| m.t0 > t) {
            later.push(self.moves.pop_back().expect("checked").spec);
        }
        later.reverse();
        let mut undone = Vec::new();
        let mut t_stop = t;
        if let Some(m) = self.moves.back_mut() {
            if m.t_end > t {
                let (_, v) = m.eval(t);
                m.truncate(t);
                if v.abs() > 0.0 && a > 0.0 {
                    let dur = v.abs() / a;
                    m.phases.push(Phase {
                        dur,
                        acc: -v.signum() * a,
                    });
                    m.recompute();
                    // Guard against rounding: a decelerating move ends at rest.
                    m.v_end = 0.0;
                }
                t_stop = m.t_end;
                if (m.spec.target - m.x_end).abs() > 1e-6 && m.spec.kind != MoveKind::Homing {
                    undone.push(m.spec);
                }
            }
        }
        undone.extend(later);
        (t_stop, undone)
    }

    /// Forget moves that ended before `before` (keeping their end as the rest position).
    pub fn prune(&mut self, before: f64) {
        while self.moves.front().is_some_and(|m| m.t_end < before) {
            let m = self.moves.pop_front().expect("checked");
            self.rest_x = m.x_end;
            self.rest_p = m.p_end(self.backlash);
        }
    }

    /// Oldest instant the timeline still describes exactly.
    #[allow(dead_code)]
    pub fn history_start(&self) -> f64 {
        self.moves
            .front()
            .map(|m| m.t0)
            .unwrap_or(f64::NEG_INFINITY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINE: MoveKind = MoveKind::Line;

    #[test]
    fn trapezoid_matches_closed_form() {
        // 100 mm at 3000 mm/min (50 mm/s), 500 mm/s²: 0.1 s ramps of 2.5 mm, 95 mm cruise.
        let t = trapezoid_time(100.0, 3000.0, 500.0);
        assert!((t - 2.1).abs() < 1e-12, "{t}");
        // Triangle: 1 mm cannot reach 50 mm/s.
        let t = trapezoid_time(1.0, 3000.0, 500.0);
        assert!((t - 2.0 * (1.0f64 / 500.0).sqrt()).abs() < 1e-12);
    }

    #[test]
    fn timeline_positions() {
        let mut tl = Timeline::new(0.0, 0.0, 1.0);
        let spec = Spec {
            kind: LINE,
            target: 100.0,
            feed: 3000.0,
        };
        tl.push(10.0, spec, 500.0);
        assert_eq!(tl.machine_at(9.0), 0.0);
        assert!((tl.machine_at(10.1) - 2.5).abs() < 1e-9);
        assert!((tl.machine_at(11.0) - (2.5 + 0.9 * 50.0)).abs() < 1e-9);
        assert!((tl.machine_at(12.1) - 100.0).abs() < 1e-9);
        assert_eq!(tl.machine_at(20.0), tl.end_x());
        assert_eq!(tl.busy_count(12.0), 1);
        assert_eq!(tl.busy_count(12.2), 0);
        // Second block queues behind the first.
        tl.push(
            10.5,
            Spec {
                kind: LINE,
                target: 50.0,
                feed: 3000.0,
            },
            500.0,
        );
        assert!((tl.machine_at(12.1 + 1.1) - 50.0).abs() < 1e-9);
    }

    #[test]
    fn decel_stop_and_remainder() {
        let mut tl = Timeline::new(0.0, 0.0, 1.0);
        let spec = Spec {
            kind: LINE,
            target: 100.0,
            feed: 3000.0,
        };
        tl.push(0.0, spec, 500.0);
        tl.push(
            0.0,
            Spec {
                kind: LINE,
                target: 0.0,
                feed: 3000.0,
            },
            500.0,
        );
        let (t_stop, undone) = tl.decel_stop(1.0, 500.0);
        assert!((t_stop - 1.1).abs() < 1e-9);
        let x_hold = 2.5 + 0.9 * 50.0 + 2.5;
        assert!((tl.machine_at(5.0) - x_hold).abs() < 1e-9);
        assert_eq!(undone.len(), 2);
        assert_eq!(undone[0].target, 100.0);
        assert_eq!(tl.busy_count(1.05), 1);
    }

    #[test]
    fn backlash_and_scale() {
        let mut tl = Timeline::new(0.0, 0.2, 1.01);
        tl.push(
            0.0,
            Spec {
                kind: LINE,
                target: 10.0,
                feed: 600.0,
            },
            500.0,
        );
        let t1 = tl.end_t();
        // Moving +X the carriage trails by the backlash.
        assert!((tl.play_at(t1 + 1.0) - 9.8).abs() < 1e-9);
        tl.push(
            t1 + 1.0,
            Spec {
                kind: LINE,
                target: 9.9,
                feed: 600.0,
            },
            500.0,
        );
        // Reversal by less than the play: the carriage does not move.
        assert!((tl.play_at(tl.end_t() + 1.0) - 9.8).abs() < 1e-9);
        tl.push(
            0.0,
            Spec {
                kind: LINE,
                target: 5.0,
                feed: 600.0,
            },
            500.0,
        );
        assert!((tl.play_at(tl.end_t() + 1.0) - 5.0).abs() < 1e-9);
        assert!((tl.physical_at(tl.end_t() + 1.0) - 5.05).abs() < 1e-9);
    }
}
