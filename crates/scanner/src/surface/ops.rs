//! Operation counting: the evaluators are generic over [`Scalar`], so the same code runs on
//! `f64` for speed and on [`Counted`] to count the floating-point operations it performs.
//!
//! Counted: every `+`, `-`, `*`, `/` on floats (and `sqrt`). Not counted: loads, stores,
//! index arithmetic, comparisons and the `floor` that picks a segment or knot span (one per
//! direction per point, the same for every method).

use std::cell::Cell;
use std::ops::{Add, Div, Mul, Sub};

/// `From<f64>` lets the shared Bernstein basis (`footscan_geom::bernstein`) take its
/// constants in either type, uncounted as [`Scalar::from_f64`] is.
pub trait Scalar:
    Copy + From<f64> + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    fn from_f64(v: f64) -> Self;
    fn to_f64(self) -> f64;
}

impl Scalar for f64 {
    #[inline(always)]
    fn from_f64(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self
    }
}

thread_local! {
    static OPS: Cell<OpCount> = const { Cell::new(OpCount { add: 0, mul: 0, div: 0 }) };
}

/// Floating-point operations counted on this thread.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OpCount {
    /// Additions and subtractions.
    pub add: u64,
    pub mul: u64,
    pub div: u64,
}

impl OpCount {
    pub fn total(&self) -> u64 {
        self.add + self.mul + self.div
    }
}

/// An `f64` that counts the operations done on it (per thread).
#[derive(Clone, Copy, Debug, PartialEq, PartialOrd)]
pub struct Counted(pub f64);

impl Counted {
    /// Reset this thread's counter and return what it held.
    pub fn take() -> OpCount {
        OPS.with(|c| c.replace(OpCount::default()))
    }
}

fn bump(f: impl FnOnce(&mut OpCount)) {
    OPS.with(|c| {
        let mut v = c.get();
        f(&mut v);
        c.set(v);
    });
}

#[allow(clippy::suspicious_arithmetic_impl)] // the counter, not the value
impl Add for Counted {
    type Output = Counted;
    fn add(self, o: Counted) -> Counted {
        bump(|c| c.add += 1);
        Counted(self.0 + o.0)
    }
}
#[allow(clippy::suspicious_arithmetic_impl)] // the counter, not the value
impl Sub for Counted {
    type Output = Counted;
    fn sub(self, o: Counted) -> Counted {
        bump(|c| c.add += 1);
        Counted(self.0 - o.0)
    }
}
#[allow(clippy::suspicious_arithmetic_impl)] // the counter, not the value
impl Mul for Counted {
    type Output = Counted;
    fn mul(self, o: Counted) -> Counted {
        bump(|c| c.mul += 1);
        Counted(self.0 * o.0)
    }
}
#[allow(clippy::suspicious_arithmetic_impl)] // the counter, not the value
impl Div for Counted {
    type Output = Counted;
    fn div(self, o: Counted) -> Counted {
        bump(|c| c.div += 1);
        Counted(self.0 / o.0)
    }
}

impl From<f64> for Counted {
    /// A constant, not an operation: not counted.
    fn from(v: f64) -> Self {
        Counted(v)
    }
}

impl Scalar for Counted {
    fn from_f64(v: f64) -> Self {
        Counted(v)
    }
    fn to_f64(self) -> f64 {
        self.0
    }
}

/// Sum of `a[i] * b[i]`: n multiplications and n - 1 additions.
#[inline(always)]
pub fn dot<T: Scalar, const N: usize>(a: &[T; N], b: &[T; N]) -> T {
    let mut s = a[0] * b[0];
    for i in 1..N {
        s = s + a[i] * b[i];
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_each_operation() {
        Counted::take();
        let a = Counted(2.0);
        let b = Counted(3.0);
        let c = (a + b) * a - b / a;
        assert_eq!(c.0, 8.5);
        let n = Counted::take();
        assert_eq!((n.add, n.mul, n.div), (2, 1, 1));
        assert_eq!(Counted::take().total(), 0);
    }
}
