//! Brent's root finder (inverse quadratic interpolation, secant and bisection steps), used
//! for the exact row crossings of the ground truth.

/// Brent's method on `f(eval(y))` over [a, b] (f changes sign there): the sample at the root,
/// |f| < 1e-10 or the bracket narrower than 1e-13; None where `eval` has no sample. `a` and
/// `b` are (y, sample at y).
pub(super) fn brent<S: Copy>(
    eval: impl Fn(f64) -> Option<S>,
    f: impl Fn(&S) -> f64,
    (ya, a): (f64, S),
    (yb, b): (f64, S),
) -> Option<S> {
    let (mut xa, mut fa) = (ya, f(&a));
    let (mut xb, mut fb) = (yb, f(&b));
    let mut sb = b;
    if fa * fb > 0.0 {
        return None;
    }
    if fa.abs() < fb.abs() {
        std::mem::swap(&mut xa, &mut xb);
        std::mem::swap(&mut fa, &mut fb);
        sb = a;
    }
    let (mut xc, mut fc) = (xa, fa);
    let mut mflag = true;
    let mut xd = xc;
    for _ in 0..100 {
        if fb.abs() < 1e-10 || (xb - xa).abs() < 1e-13 {
            return Some(sb);
        }
        let mut s = if fa != fc && fb != fc {
            xa * fb * fc / ((fa - fb) * (fa - fc))
                + xb * fa * fc / ((fb - fa) * (fb - fc))
                + xc * fa * fb / ((fc - fa) * (fc - fb))
        } else {
            xb - fb * (xb - xa) / (fb - fa)
        };
        let q = (3.0 * xa + xb) / 4.0;
        let out = !((s > q.min(xb)) && (s < q.max(xb)));
        if out
            || (mflag && (s - xb).abs() >= (xb - xc).abs() / 2.0)
            || (!mflag && (s - xb).abs() >= (xc - xd).abs() / 2.0)
            || (mflag && (xb - xc).abs() < 1e-14)
            || (!mflag && (xc - xd).abs() < 1e-14)
        {
            s = 0.5 * (xa + xb);
            mflag = true;
        } else {
            mflag = false;
        }
        let ss = eval(s)?;
        let fs = f(&ss);
        xd = xc;
        xc = xb;
        fc = fb;
        if fa * fs < 0.0 {
            xb = s;
            fb = fs;
            sb = ss;
        } else {
            xa = s;
            fa = fs;
        }
        if fa.abs() < fb.abs() {
            std::mem::swap(&mut xa, &mut xb);
            std::mem::swap(&mut fa, &mut fb);
            // Keep the sample of the new best point.
            sb = eval(xb)?;
        }
    }
    Some(sb)
}
