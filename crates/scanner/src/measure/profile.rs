//! The footprint's side profiles along the foot axis, and the peaks and valleys in them that
//! locate the metatarsal heads, the waists and the heel's widest part from the shape itself.

use super::fit::local_quadratic;
use footscan_geom::{P2, V2};

/// Half-widths of the footprint either side of an axis, at stations `step` apart from the
/// origin: `med[k]` the farthest outline crossing on the medial side of the line across the
/// axis at x = k step, `lat[k]` on the lateral side (both positive outward; NaN where the
/// line misses the outline), smoothed by local quadratics over +-2 mm (the outline's
/// cell steps would otherwise make peaks of their own).
pub struct Profiles {
    pub step: f64,
    pub med: Vec<f64>,
    pub lat: Vec<f64>,
}

/// Smoothing half-window of the profiles (mm).
const SMOOTH_MM: f64 = 2.0;

impl Profiles {
    /// Profiles of `outlines` along the axis from `origin` in direction `u`, medial `m`,
    /// for x in [0, length]: one pass over the edges, each adding its crossings.
    pub fn of(outlines: &[&[P2]], origin: P2, u: V2, m: V2, length: f64, step: f64) -> Profiles {
        let n = (length / step).floor() as usize + 1;
        let c = Crossings::of(outlines, origin, u, m, n, step);
        let (hi, lo) = (c.hi, c.lo);
        let raw_med: Vec<f64> = hi
            .iter()
            .map(|&t| if t.is_finite() { t } else { f64::NAN })
            .collect();
        let raw_lat: Vec<f64> = lo
            .iter()
            .map(|&t| if t.is_finite() { -t } else { f64::NAN })
            .collect();
        Profiles {
            step,
            med: smooth(&raw_med, step),
            lat: smooth(&raw_lat, step),
        }
    }

    pub fn x(&self, k: usize) -> f64 {
        k as f64 * self.step
    }

    /// Station index nearest x, clamped to the profile.
    pub fn index(&self, x: f64) -> usize {
        ((x / self.step).round().max(0.0) as usize).min(self.med.len() - 1)
    }

    /// Breadth (medial plus lateral half-width) at station k.
    pub fn breadth(&self, k: usize) -> f64 {
        self.med[k] + self.lat[k]
    }
}

/// Where lines across the axis cross outlines: at stations x = k step (k < n) from `origin`
/// along `u`, the farthest crossing toward `m` (`hi`), toward -m (`lo`), and how many there
/// are. One pass over the edges, each adding its crossings: a line at a time over every edge
/// was 7 M edge tests for the heel width alone.
pub struct Crossings {
    pub hi: Vec<f64>,
    pub lo: Vec<f64>,
    pub count: Vec<u32>,
}

impl Crossings {
    pub fn of(outlines: &[&[P2]], origin: P2, u: V2, m: V2, n: usize, step: f64) -> Crossings {
        let (mut hi, mut lo) = (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]);
        let mut count = vec![0u32; n];
        for o in outlines {
            let xt = |p: P2| {
                let d = p - origin;
                (d.dot(&u), d.dot(&m))
            };
            for i in 0..o.len() {
                let (a, b) = (xt(o[i]), xt(o[(i + 1) % o.len()]));
                let (x0, x1) = (a.0.min(b.0), a.0.max(b.0));
                if x1 <= x0 {
                    continue;
                }
                let k0 = (x0 / step).ceil().max(0.0) as usize;
                let mut k = k0;
                while k < n && (k as f64) * step < x1 {
                    let x = k as f64 * step;
                    let t = a.1 + (x - a.0) / (b.0 - a.0) * (b.1 - a.1);
                    hi[k] = hi[k].max(t);
                    lo[k] = lo[k].min(t);
                    count[k] += 1;
                    k += 1;
                }
            }
        }
        Crossings { hi, lo, count }
    }
}

fn smooth(raw: &[f64], step: f64) -> Vec<f64> {
    let (xs, ys): (Vec<f64>, Vec<f64>) = raw
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_finite())
        .map(|(k, &v)| (k as f64 * step, v))
        .unzip();
    raw.iter()
        .enumerate()
        .map(|(k, v)| {
            if !v.is_finite() {
                return f64::NAN;
            }
            let x = k as f64 * step;
            // The samples within the window, found by bisection on the sorted stations.
            let a = xs.partition_point(|&s| s < x - SMOOTH_MM);
            let b = xs.partition_point(|&s| s <= x + SMOOTH_MM);
            local_quadratic(&xs[a..b], &ys[a..b], x, SMOOTH_MM).unwrap_or(*v)
        })
        .collect()
}

/// A peak of a profile: its station and how far it stands above the higher of the two
/// lowest points between it and the nearest higher ground on either side (its prominence).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peak {
    pub k: usize,
    pub prominence: f64,
}

/// The peaks of `y` with their stations in `[k0, k1]` that stand at least `min_prom` above
/// their surroundings (which reach over the whole profile, so a window edge where the profile
/// is still rising is not a peak); empty when the profile rises or falls through the window,
/// or is flat to within `min_prom`. One station per plateau (its rear end).
pub fn peaks(y: &[f64], k0: usize, k1: usize, min_prom: f64) -> Vec<Peak> {
    let k1 = k1.min(y.len().saturating_sub(1));
    let mut out = Vec::new();
    for k in k0..=k1 {
        let v = y[k];
        if !v.is_finite() {
            continue;
        }
        // The rear end of a maximum or of its plateau (a gap counts as lower).
        let below = |j: usize, strict: bool| {
            let w = y[j];
            !w.is_finite() || w < v || (!strict && w == v)
        };
        let left_ok = k == 0 || below(k - 1, true);
        let right_ok = k + 1 >= y.len() || below(k + 1, false);
        if !(left_ok && right_ok) {
            continue;
        }
        // The lowest point between the peak and the nearest higher ground (or a gap, or
        // the profile's end) on each side.
        let base = |js: &mut dyn Iterator<Item = usize>| {
            let mut low = v;
            for j in js {
                let w = y[j];
                if !w.is_finite() || w > v {
                    break;
                }
                low = low.min(w);
            }
            low
        };
        let l = base(&mut (0..k).rev());
        let r = base(&mut (k + 1..y.len()));
        let prominence = v - l.max(r);
        if prominence >= min_prom {
            out.push(Peak { k, prominence });
        }
    }
    out
}

/// The valleys of `y` in `[k0, k1]` at least `min_depth` deep (peaks of -y).
pub fn valleys(y: &[f64], k0: usize, k1: usize, min_depth: f64) -> Vec<Peak> {
    let neg: Vec<f64> = y.iter().map(|v| -v).collect();
    peaks(&neg, k0, k1, min_depth)
}

/// Of `found` (peaks of `y`), the one nearest station `k_prior` among those within `tie` of
/// the highest: two bulges of nearly one height (a metatarsal head and the big toe beside
/// it) are told apart by where a foot has the one sought.
pub fn pick(y: &[f64], found: &[Peak], k_prior: usize, tie: f64) -> Option<Peak> {
    let top = found
        .iter()
        .map(|p| y[p.k])
        .fold(f64::NEG_INFINITY, f64::max);
    found
        .iter()
        .filter(|p| y[p.k] >= top - tie)
        .min_by_key(|p| p.k.abs_diff(k_prior))
        .copied()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn peaks_need_prominence_and_higher_ground_ends_them() {
        // A rise through the window's start (not a peak there), a bump of 2 at 6, a bump of
        // 0.2 at 10 on a slope.
        let y = [
            0.0, 1.0, 2.0, 3.0, 2.0, 3.0, 5.0, 3.0, 3.0, 3.1, 3.3, 3.2, 1.0,
        ];
        let ks = |v: Vec<Peak>| v.iter().map(|p| p.k).collect::<Vec<_>>();
        assert_eq!(ks(peaks(&y, 2, 12, 0.5)), [3, 6]);
        assert_eq!(
            ks(peaks(&y, 7, 12, 0.5)),
            Vec::<usize>::new(),
            "3.3 stands 0.2 over 3.1"
        );
        assert_eq!(ks(peaks(&y, 7, 12, 0.1)), [10]);
        // The profile rising through [0, 2] has no peak there.
        assert!(peaks(&y, 0, 2, 0.1).is_empty());
        assert_eq!(ks(valleys(&y, 0, 12, 0.5)), [4]);
        // Of two peaks within 2 of the highest, the one nearer the prior station.
        let found = peaks(&y, 0, 12, 0.5);
        assert_eq!(pick(&y, &found, 2, 2.0).map(|p| p.k), Some(3));
        assert_eq!(pick(&y, &found, 2, 1.0).map(|p| p.k), Some(6));
    }

    #[test]
    fn profiles_of_a_rectangle() {
        let r = [
            P2::new(0.0, -10.0),
            P2::new(100.0, -10.0),
            P2::new(100.0, 20.0),
            P2::new(0.0, 20.0),
        ];
        let (o, u, m) = (P2::origin(), V2::x(), V2::y());
        let p = Profiles::of(&[&r], o, u, m, 100.0, 0.5);
        assert!((p.med[50] - 20.0).abs() < 1e-9 && (p.lat[50] - 10.0).abs() < 1e-9);
        assert!((p.breadth(100) - 30.0).abs() < 1e-9 || p.med[200].is_nan());
    }
}
