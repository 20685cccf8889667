//! Knot-vector algorithms on curves in homogeneous form (w x, w y, w z, w), shared by curves
//! and by the rows and columns of surfaces: single-knot insertion, knot refinement, degree
//! elevation, end clamping, and the periodic variants built on a periodic extension.

use nalgebra::Vector4;

use super::basis::binomial;

pub(crate) type H = Vector4<f64>;

/// A B-spline in homogeneous coordinates (open, any knot vector).
#[derive(Debug, Clone)]
pub(crate) struct HCurve {
    pub p: usize,
    pub knots: Vec<f64>,
    pub pw: Vec<H>,
}

/// What to do to a curve's knot vector (the same for every row of a surface).
#[derive(Debug, Clone)]
pub(crate) enum Op {
    /// Insert these knots (sorted, each inside the domain).
    Refine(Vec<f64>),
    /// Raise the degree by this much.
    Elevate(usize),
}

impl HCurve {
    fn n(&self) -> usize {
        self.pw.len() - 1
    }

    /// Insert knot `u` `r` times (capped so multiplicity stays <= degree).
    pub fn insert(&self, u: f64, r: usize) -> HCurve {
        let p = self.p;
        let up = &self.knots;
        let np = self.n();
        let s = up.iter().filter(|&&k| k == u).count();
        let r = r.min(p.saturating_sub(s));
        if r == 0 {
            return self.clone();
        }
        // k: last index with knots[k] <= u.
        let k = up.partition_point(|&x| x <= u) - 1;
        let mp = np + p + 1;
        let mut uq = Vec::with_capacity(mp + r + 1);
        uq.extend_from_slice(&up[..=k]);
        uq.extend(std::iter::repeat_n(u, r));
        uq.extend_from_slice(&up[k + 1..]);
        let mut qw = vec![H::zeros(); np + r + 1];
        qw[..=(k - p)].copy_from_slice(&self.pw[..=(k - p)]);
        for i in (k - s)..=np {
            qw[i + r] = self.pw[i];
        }
        let mut rw: Vec<H> = (0..=(p - s)).map(|i| self.pw[k - p + i]).collect();
        let mut l = 0;
        for j in 1..=r {
            l = k - p + j;
            for i in 0..=(p - j - s) {
                let alpha = (u - up[l + i]) / (up[i + k + 1] - up[l + i]);
                rw[i] = alpha * rw[i + 1] + (1.0 - alpha) * rw[i];
            }
            qw[l] = rw[0];
            qw[k + r - j - s] = rw[p - j - s];
        }
        for i in (l + 1)..(k - s) {
            qw[i] = rw[i - l];
        }
        HCurve {
            p,
            knots: uq,
            pw: qw,
        }
    }

    /// Insert many knots at once (sorted; each within [knots[p], knots[n + 1]]).
    pub fn refine(&self, x: &[f64]) -> HCurve {
        if x.is_empty() {
            return self.clone();
        }
        let p = self.p;
        let n = self.n();
        let u = &self.knots;
        let m = n + p + 1;
        let r = x.len() - 1;
        let a = super::basis::find_span(n, p, x[0], u);
        let b = super::basis::find_span(n, p, x[r], u) + 1;
        let mut qw = vec![H::zeros(); n + r + 2];
        let mut ub = vec![0.0; m + r + 2];
        qw[..=(a - p)].copy_from_slice(&self.pw[..=(a - p)]);
        for j in (b - 1)..=n {
            qw[j + r + 1] = self.pw[j];
        }
        ub[..=a].copy_from_slice(&u[..=a]);
        for j in (b + p)..=m {
            ub[j + r + 1] = u[j];
        }
        let mut i = b + p - 1;
        let mut k = b + p + r;
        for j in (0..=r).rev() {
            while x[j] <= u[i] && i > a {
                qw[k - p - 1] = self.pw[i - p - 1];
                ub[k] = u[i];
                k -= 1;
                i -= 1;
            }
            qw[k - p - 1] = qw[k - p];
            for l in 1..=p {
                let ind = k - p + l;
                let alfa = ub[k + l] - x[j];
                if alfa.abs() == 0.0 {
                    qw[ind - 1] = qw[ind];
                } else {
                    let alfa = alfa / (ub[k + l] - u[i + l - p]);
                    qw[ind - 1] = alfa * qw[ind - 1] + (1.0 - alfa) * qw[ind];
                }
            }
            ub[k] = x[j];
            k = k.wrapping_sub(1);
        }
        HCurve {
            p,
            knots: ub,
            pw: qw,
        }
    }

    /// Clamp both ends: p + 1 equal knots at each end of the domain, shape unchanged there.
    pub fn clamp(&self) -> HCurve {
        let p = self.p;
        let n = self.n();
        let (a, b) = (self.knots[p], self.knots[n + 1]);
        let mut c = self.insert(a, p);
        if !c.knots[..=p].iter().all(|&k| k == a) {
            let f = c.knots.iter().position(|&k| k == a).unwrap();
            let mut knots = vec![a];
            knots.extend_from_slice(&c.knots[f..]);
            c = HCurve {
                p,
                knots,
                pw: c.pw[f - 1..].to_vec(),
            };
        }
        let mut c = c.insert(b, p);
        let len = c.knots.len();
        if !c.knots[len - p - 1..].iter().all(|&k| k == b) {
            let g = c.knots.iter().position(|&k| k == b).unwrap();
            let mut knots = c.knots[..g + p].to_vec();
            knots.push(b);
            c = HCurve {
                p,
                knots,
                pw: c.pw[..g].to_vec(),
            };
        }
        c
    }

    /// Raise the degree by `t` (the curve must be clamped).
    pub fn elevate(&self, t: usize) -> HCurve {
        if t == 0 {
            return self.clone();
        }
        let p = self.p;
        let n = self.n();
        let u = &self.knots;
        let pw = &self.pw;
        let m = n + p + 1;
        let ph = p + t;
        let ph2 = ph / 2;
        let mut bezalfs = vec![vec![0.0; p + 1]; ph + 1];
        bezalfs[0][0] = 1.0;
        bezalfs[ph][p] = 1.0;
        for i in 1..=ph2 {
            let inv = 1.0 / binomial(ph, i);
            let mpi = p.min(i);
            for j in i.saturating_sub(t)..=mpi {
                bezalfs[i][j] = inv * binomial(p, j) * binomial(t, i - j);
            }
        }
        for i in (ph2 + 1)..ph {
            let mpi = p.min(i);
            for j in i.saturating_sub(t)..=mpi {
                bezalfs[i][j] = bezalfs[ph - i][p - j];
            }
        }
        // Upper bounds on the output size: every distinct interior knot gains t copies.
        let distinct = {
            let mut d = 0;
            for i in (p + 1)..=n {
                if u[i] != u[i - 1] || i == p + 1 {
                    d += 1;
                }
            }
            d
        };
        let cap = n + 1 + t * (distinct + 2) + 1;
        let mut qw = vec![H::zeros(); cap];
        let mut uh = vec![0.0; cap + ph + 1];
        let mut bpts = vec![H::zeros(); p + 1];
        let mut ebpts = vec![H::zeros(); ph + 1];
        let mut next_bpts = vec![H::zeros(); p.saturating_sub(1).max(1)];
        let mut alfs = vec![0.0; p.saturating_sub(1).max(1)];
        let mut mh = ph;
        let mut kind = ph + 1;
        let mut r: isize = -1;
        let mut a = p;
        let mut b = p + 1;
        let mut cind = 1;
        let mut ua = u[0];
        qw[0] = pw[0];
        for x in uh.iter_mut().take(ph + 1) {
            *x = ua;
        }
        bpts.copy_from_slice(&pw[..=p]);
        while b < m {
            let i0 = b;
            while b < m && u[b] == u[b + 1] {
                b += 1;
            }
            let mul = b - i0 + 1;
            mh += mul + t;
            let ub = u[b];
            let oldr = r;
            r = p as isize - mul as isize;
            let lbz = if oldr > 0 {
                ((oldr + 2) / 2) as usize
            } else {
                1
            };
            let rbz = if r > 0 {
                ph - ((r + 1) / 2) as usize
            } else {
                ph
            };
            if r > 0 {
                let numer = ub - ua;
                for k in ((mul + 1)..=p).rev() {
                    alfs[k - mul - 1] = numer / (u[a + k] - ua);
                }
                for j in 1..=(r as usize) {
                    let save = r as usize - j;
                    let s = mul + j;
                    for k in (s..=p).rev() {
                        bpts[k] = alfs[k - s] * bpts[k] + (1.0 - alfs[k - s]) * bpts[k - 1];
                    }
                    next_bpts[save] = bpts[p];
                }
            }
            for (i, e) in ebpts.iter_mut().enumerate().skip(lbz) {
                *e = H::zeros();
                let mpi = p.min(i);
                for j in i.saturating_sub(t)..=mpi {
                    *e += bezalfs[i][j] * bpts[j];
                }
            }
            if oldr > 1 {
                let oldr = oldr as usize;
                let mut first = kind - 2;
                let mut last = kind;
                let den = ub - ua;
                let bet = (ub - uh[kind - 1]) / den;
                for tr in 1..oldr {
                    let mut i = first;
                    let mut j = last;
                    let mut kj = j as isize - kind as isize + 1;
                    while j as isize - i as isize > tr as isize {
                        if i < cind {
                            let alf = (ub - uh[i]) / (ua - uh[i]);
                            qw[i] = alf * qw[i] + (1.0 - alf) * qw[i - 1];
                        }
                        if j >= lbz {
                            let kju = kj as usize;
                            if j as isize - tr as isize
                                <= kind as isize - ph as isize + oldr as isize
                            {
                                let gam = (ub - uh[j - tr]) / den;
                                ebpts[kju] = gam * ebpts[kju] + (1.0 - gam) * ebpts[kju + 1];
                            } else {
                                ebpts[kju] = bet * ebpts[kju] + (1.0 - bet) * ebpts[kju + 1];
                            }
                        }
                        i += 1;
                        j -= 1;
                        kj -= 1;
                    }
                    first -= 1;
                    last += 1;
                }
            }
            if a != p {
                for _ in 0..(ph as isize - oldr) {
                    uh[kind] = ua;
                    kind += 1;
                }
            }
            for e in ebpts.iter().take(rbz + 1).skip(lbz) {
                qw[cind] = *e;
                cind += 1;
            }
            if b < m {
                let ru = r.max(0) as usize;
                bpts[..ru].copy_from_slice(&next_bpts[..ru]);
                for j in ru..=p {
                    bpts[j] = pw[b - p + j];
                }
                a = b;
                b += 1;
                ua = ub;
            } else {
                for i in 0..=ph {
                    uh[kind + i] = ub;
                }
            }
        }
        let nh = mh - ph - 1;
        qw.truncate(nh + 1);
        uh.truncate(nh + ph + 2);
        HCurve {
            p: ph,
            knots: uh,
            pw: qw,
        }
    }

    /// Apply `op` to an open curve (clamping first when elevating an unclamped one).
    pub fn apply_open(&self, op: &Op) -> HCurve {
        match op {
            Op::Refine(x) => self.refine(x),
            Op::Elevate(t) => {
                let p = self.p;
                let n = self.n();
                let clamped = self.knots[..=p].iter().all(|&k| k == self.knots[0])
                    && self.knots[n + 1..].iter().all(|&k| k == self.knots[n + 1]);
                if clamped {
                    self.elevate(*t)
                } else {
                    self.clamp().elevate(*t)
                }
            }
        }
    }

    /// Apply `op` to a periodic curve in the stored unclamped form (last p points wrap the
    /// first p). The result is periodic in the same form. Works on a periodic extension of
    /// the curve a few spans beyond each end, so the window that forms the result sees the
    /// infinite periodic spline.
    pub fn apply_periodic(&self, op: &Op) -> HCurve {
        let p = self.p;
        let npts = self.pw.len();
        let nu = npts - p; // unique control points
        let t_per = self.knots[npts] - self.knots[p];
        let a0 = self.knots[p];
        let e = p + 2;
        let knot = |i: isize| -> f64 {
            let q = i.div_euclid(nu as isize);
            let j = i.rem_euclid(nu as isize) as usize;
            self.knots[j] + q as f64 * t_per
        };
        let ext_knots: Vec<f64> = (-(e as isize)..=(npts + p + e) as isize)
            .map(knot)
            .collect();
        let ext_pw: Vec<H> = (-(e as isize)..(npts + e) as isize)
            .map(|i| self.pw[i.rem_euclid(nu as isize) as usize])
            .collect();
        let ext = HCurve {
            p,
            knots: ext_knots,
            pw: ext_pw,
        };
        // Period knots (one period starting at the domain start), then the new ones.
        let period: Vec<f64> = self.knots[p..p + nu].to_vec();
        let (new_p, new_period, ext_new) = match op {
            Op::Refine(x) => {
                let xs: Vec<f64> = x
                    .iter()
                    .map(|&v| super::norm_param(v, (a0, a0 + t_per), true))
                    .collect();
                let mut np: Vec<f64> = period.clone();
                np.extend_from_slice(&xs);
                np.sort_by(|a, b| a.total_cmp(b));
                // Every image of each new knot inside the extension's domain.
                let (lo, hi) = (ext.knots[p], ext.knots[ext.pw.len()]);
                let mut imgs = Vec::new();
                for &v in &xs {
                    let mut k = ((lo - v) / t_per).floor() as i64 - 1;
                    loop {
                        let w = v + k as f64 * t_per;
                        if w >= hi {
                            break;
                        }
                        if w > lo {
                            imgs.push(w);
                        }
                        k += 1;
                    }
                }
                imgs.sort_by(|a, b| a.total_cmp(b));
                (p, np, ext.refine(&imgs))
            }
            Op::Elevate(t) => {
                let mut np = Vec::new();
                let mut i = 0;
                while i < period.len() {
                    let v = period[i];
                    let mut j = i;
                    while j < period.len() && period[j] == v {
                        np.push(v);
                        j += 1;
                    }
                    for _ in 0..*t {
                        np.push(v);
                    }
                    i = j;
                }
                (p + t, np, ext.clamp().elevate(*t))
            }
        };
        // The new full knot vector from its period list.
        let nu2 = new_period.len();
        let full: Vec<f64> = (0..(nu2 + 2 * new_p + 1) as isize)
            .map(|i| {
                let j = i - new_p as isize;
                let q = j.div_euclid(nu2 as isize);
                new_period[j.rem_euclid(nu2 as isize) as usize] + q as f64 * t_per
            })
            .collect();
        let tol = 1e-11 * t_per.abs().max(1.0);
        let start = (0..ext_new.knots.len().saturating_sub(full.len()) + 1)
            .find(|&s| {
                full.iter()
                    .zip(&ext_new.knots[s..])
                    .all(|(a, b)| (a - b).abs() <= tol)
            })
            .expect("periodic window found in the extended curve");
        let mut pw: Vec<H> = ext_new.pw[start..start + nu2 + new_p].to_vec();
        for k in 0..new_p {
            pw[nu2 + k] = pw[k];
        }
        HCurve {
            p: new_p,
            knots: full,
            pw,
        }
    }

    pub fn apply(&self, op: &Op, periodic: bool) -> HCurve {
        if periodic {
            self.apply_periodic(op)
        } else {
            self.apply_open(op)
        }
    }
}
