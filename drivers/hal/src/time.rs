use serde::{Deserialize, Serialize};
use std::time::Duration;

/// A point on the monotonic clock (`CLOCK_MONOTONIC`), in nanoseconds.
///
/// `std::time::Instant` is monotonic too but opaque; V4L2 buffer timestamps arrive as raw
/// `CLOCK_MONOTONIC` values, so the whole system shares this plain representation.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize,
)]
pub struct Timestamp {
    pub nanos: u64,
}

impl Timestamp {
    pub fn now() -> Self {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes into the timespec we own; CLOCK_MONOTONIC always exists on Linux.
        let rc = unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
        debug_assert_eq!(rc, 0);
        // time_t and c_long are i32 on 32-bit targets.
        #[allow(clippy::unnecessary_cast)]
        Self::from_timespec(ts.tv_sec as i64, ts.tv_nsec as i64)
    }

    pub fn from_timespec(sec: i64, nsec: i64) -> Self {
        Self {
            nanos: (sec.max(0) as u64) * 1_000_000_000 + nsec.max(0) as u64,
        }
    }

    pub fn from_secs_f64(s: f64) -> Self {
        Self {
            nanos: (s.max(0.0) * 1e9).round() as u64,
        }
    }

    pub fn as_secs_f64(self) -> f64 {
        self.nanos as f64 * 1e-9
    }

    /// `self - earlier`, saturating at zero.
    pub fn since(self, earlier: Timestamp) -> Duration {
        Duration::from_nanos(self.nanos.saturating_sub(earlier.nanos))
    }

    /// Signed difference `self - other` in seconds.
    pub fn secs_after(self, other: Timestamp) -> f64 {
        (self.nanos as i128 - other.nanos as i128) as f64 * 1e-9
    }

    /// Sleep until this instant (returns at once if it has passed).
    pub fn sleep_until(self) {
        let now = Timestamp::now();
        if self > now {
            std::thread::sleep(self.since(now));
        }
    }
}

impl std::ops::Add<Duration> for Timestamp {
    type Output = Timestamp;
    fn add(self, d: Duration) -> Self {
        Self {
            nanos: self.nanos + d.as_nanos() as u64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn monotonic_and_arithmetic() {
        let a = Timestamp::now();
        std::thread::sleep(Duration::from_millis(2));
        let b = Timestamp::now();
        assert!(b > a);
        assert!(b.since(a) >= Duration::from_millis(2));
        assert_eq!(a.since(b), Duration::ZERO);
        assert!((b.secs_after(a) - b.since(a).as_secs_f64()).abs() < 1e-9);
        assert!(a.secs_after(b) < 0.0);
        let c = a + Duration::from_micros(1500);
        assert_eq!(c.nanos - a.nanos, 1_500_000);
        assert_eq!(Timestamp::from_timespec(2, 5).nanos, 2_000_000_005);
    }
}
