//! Sections of a last by planes parallel to a cut, their guide crossings, and the aligned
//! resampling that gives every section the same parameters.
//!
//! A section is the closed loop where a plane meets the last, oriented counterclockwise about
//! the cut normal (seen from the toe) and framed by a lateral axis and an up axis in its plane.
//! Its crossings are the points where guide curves will pass: the bundle of planes through
//! the loop's centroid at fixed angles from the downward vertical (each plane gives two
//! points, one on each ray), and four sole points beside the two bottom corners of the loop.
//! Resampling puts the same number of points between consecutive crossings on every section,
//! evenly by arc length, so point j has the same parameter on every section and the crossing
//! points fall on common parameters: the curve network is compatible by construction.

// Index loops over sections and crossings read closer to the construction.
#![allow(clippy::needless_range_loop)]

use super::error::JoinError;
use footscan_geom::mesh::TriMesh;
use footscan_geom::plane::Plane;
use footscan_geom::{P2, P3, V3};

/// Which guide a crossing belongs to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum GuideKind {
    /// A ray of the plane bundle at this angle (radians, 0 = straight down, counterclockwise
    /// about the cut normal).
    Bundle(f64),
    /// A sole guide: `side` -1 for the corner on the -lateral side, +1 for the +lateral side;
    /// `up` true for the point above the corner (up the side wall), false for the one below
    /// it (in along the bottom).
    Sole { side: i8, up: bool },
}

/// One planar section of a last.
#[derive(Debug, Clone)]
pub struct Section {
    /// The cutting plane; `u` is the lateral axis, `v` the up axis, `normal` the cut normal.
    pub plane: Plane,
    /// Signed distance of the plane from the cut plane along the cut normal, mm.
    pub offset: f64,
    /// Loop points, counterclockwise about the normal, first point not repeated.
    pub points: Vec<P3>,
    /// Loop points in the plane frame centred on the centroid.
    local: Vec<P2>,
    /// Cumulative arc length: `cum[i]` at point i, `cum[n]` the perimeter.
    cum: Vec<f64>,
    /// Centroid of the loop (as a wire).
    pub centroid: P3,
}

impl Section {
    pub fn perimeter(&self) -> f64 {
        *self.cum.last().unwrap()
    }

    /// The loop point at arc length `s` (wrapped).
    pub fn at_arc(&self, s: f64) -> P3 {
        let per = self.perimeter();
        let s = s.rem_euclid(per);
        let n = self.points.len();
        let i = match self.cum.binary_search_by(|c| c.total_cmp(&s)) {
            Ok(i) => i.min(n - 1),
            Err(i) => i - 1,
        };
        let (a, b) = (self.points[i], self.points[(i + 1) % n]);
        let l = self.cum[i + 1] - self.cum[i];
        let t = if l > 0.0 { (s - self.cum[i]) / l } else { 0.0 };
        a + (b - a) * t
    }

    /// Arc length of the farthest crossing of the ray from the centroid at `angle`.
    fn ray_arc(&self, angle: f64) -> Option<f64> {
        let d = P2::new(angle.sin(), -angle.cos()).coords;
        let n = self.local.len();
        let mut best: Option<(f64, f64)> = None;
        for i in 0..n {
            let (a, b) = (self.local[i].coords, self.local[(i + 1) % n].coords);
            let e = b - a;
            let den = d.x * e.y - d.y * e.x;
            if den.abs() < 1e-15 {
                continue;
            }
            // a + s e = t d
            let t = (a.x * e.y - a.y * e.x) / den;
            let s = (a.x * d.y - a.y * d.x) / den;
            if t > 0.0 && (0.0..=1.0).contains(&s) && best.is_none_or(|(bt, _)| t > bt) {
                best = Some((t, self.cum[i] + s * (self.cum[i + 1] - self.cum[i])));
            }
        }
        best.map(|(_, s)| s)
    }

    /// Arc length of the bottom corner on `side`: the loop point farthest in the direction
    /// (side * lateral - up), i.e. where the bottom turns into the side wall.
    fn corner_arc(&self, side: f64) -> f64 {
        let mut best = (f64::NEG_INFINITY, 0.0);
        for (i, q) in self.local.iter().enumerate() {
            let h = side * q.x - q.y;
            if h > best.0 {
                best = (h, self.cum[i]);
            }
        }
        best.1
    }

    fn height(&self) -> f64 {
        let (lo, hi) = self
            .local
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), q| {
                (l.min(q.y), h.max(q.y))
            });
        hi - lo
    }
}

/// Where each guide crosses each section: arc lengths from the bottom centre crossing.
#[derive(Debug, Clone)]
pub struct Crossings {
    pub kinds: Vec<GuideKind>,
    /// `arcs[k][i]`: arc length on section k of guide i's crossing, measured
    /// counterclockwise from the bottom centre (guide 0), increasing in i.
    pub arcs: Vec<Vec<f64>>,
    /// Arc length on each section of its bottom centre point (the start).
    pub start: Vec<f64>,
}

/// Cut `mesh` by `plane` into exactly one loop, framed with lateral and up axes.
pub fn cut(mesh: &TriMesh, plane: &Plane, offset: f64, last: &str) -> Result<Section, JoinError> {
    let loops = mesh.section(plane);
    let describe = || describe_plane(plane);
    if loops.is_empty() {
        return Err(JoinError::PlaneMisses {
            last: last.to_string(),
            plane: describe(),
        });
    }
    if loops.len() > 1 {
        return Err(JoinError::ManyLoops {
            last: last.to_string(),
            plane: describe(),
            loops: loops.len(),
        });
    }
    let n = plane.normal;
    let mut up = V3::z() - n * n.z;
    if up.norm() < 1e-6 {
        up = plane.v;
    }
    let up = up.normalize();
    let lat = up.cross(&n);
    let pl = loops.into_iter().next().unwrap();
    let mut points = pl.points;
    // Centroid as a wire.
    let mut acc = V3::zeros();
    let mut total = 0.0;
    for i in 0..points.len() {
        let (a, b) = (points[i], points[(i + 1) % points.len()]);
        let l = (b - a).norm();
        acc += (a.coords + b.coords) * (0.5 * l);
        total += l;
    }
    if points.len() < 3 || total <= 0.0 {
        return Err(JoinError::PlaneMisses {
            last: last.to_string(),
            plane: describe(),
        });
    }
    let centroid = P3::from(acc / total);
    let to_local = |p: &P3| {
        let d = p - centroid;
        P2::new(d.dot(&lat), d.dot(&up))
    };
    let mut local: Vec<P2> = points.iter().map(to_local).collect();
    let area: f64 = (0..local.len())
        .map(|i| {
            let (a, b) = (local[i], local[(i + 1) % local.len()]);
            a.x * b.y - a.y * b.x
        })
        .sum();
    if area < 0.0 {
        points.reverse();
        local.reverse();
    }
    let mut cum = Vec::with_capacity(points.len() + 1);
    cum.push(0.0);
    for i in 0..points.len() {
        let l = (points[(i + 1) % points.len()] - points[i]).norm();
        cum.push(cum[i] + l);
    }
    let frame = Plane {
        origin: centroid,
        normal: n,
        u: lat,
        v: up,
    };
    Ok(Section {
        plane: frame,
        offset,
        points,
        local,
        cum,
        centroid,
    })
}

pub(crate) fn describe_plane(p: &Plane) -> String {
    format!(
        "plane through ({:.1}, {:.1}, {:.1}) mm with normal ({:.3}, {:.3}, {:.3})",
        p.origin.x, p.origin.y, p.origin.z, p.normal.x, p.normal.y, p.normal.z
    )
}

/// The bundle ray angles: planes every `angle_deg` from the vertical, each giving a ray down
/// and a ray up, so angle 0 (straight down: the bottom centre line) always comes first.
pub fn bundle_angles(angle_deg: f64) -> Vec<f64> {
    let planes = (180.0 / angle_deg - 1e-9).ceil().max(1.0) as usize;
    let mut a: Vec<f64> = (0..planes)
        .flat_map(|k| {
            let t = (k as f64 * angle_deg).to_radians();
            [t, t + std::f64::consts::PI]
        })
        .collect();
    a.sort_by(|x, y| x.total_cmp(y));
    a
}

/// Find every guide's crossing on every section, drop bundle rays that would cross a sole
/// guide somewhere along the network, and check the order is the same on every section.
/// `what` names each section for errors.
pub fn crossings(
    sections: &[&Section],
    angle_deg: f64,
    sole_fraction: f64,
    what: &dyn Fn(usize) -> String,
) -> Result<Crossings, JoinError> {
    let angles = bundle_angles(angle_deg);
    let k = sections.len();
    // Per section: start arc, bundle arcs (relative to the start), sole arcs.
    let mut bundle: Vec<Vec<f64>> = Vec::with_capacity(k);
    let mut sole: Vec<[f64; 4]> = Vec::with_capacity(k);
    let mut start = Vec::with_capacity(k);
    for (s, sec) in sections.iter().enumerate() {
        let per = sec.perimeter();
        let s0 = sec.ray_arc(0.0).ok_or_else(|| JoinError::NotAligned {
            section: what(s),
            reason: "the downward ray from the centroid misses the loop".into(),
        })?;
        let rel = |x: f64| (x - s0).rem_euclid(per);
        let mut b = Vec::with_capacity(angles.len());
        for &a in &angles {
            let x = sec.ray_arc(a).ok_or_else(|| JoinError::NotAligned {
                section: what(s),
                reason: format!("the ray at {:.1} deg misses the loop", a.to_degrees()),
            })?;
            b.push(if a == 0.0 { 0.0 } else { rel(x) });
        }
        for w in b.windows(2) {
            if w[1] <= w[0] {
                return Err(JoinError::NotAligned {
                    section: what(s),
                    reason: "the loop is not star-shaped about its centroid: bundle rays \
                             cross it out of order"
                        .into(),
                });
            }
        }
        let dh = sole_fraction * sec.height();
        // +lateral corner comes first counterclockwise from the bottom.
        let cp = rel(sec.corner_arc(1.0));
        let cm = rel(sec.corner_arc(-1.0));
        sole.push([cp - dh, cp + dh, cm - dh, cm + dh]);
        if !(0.0 < cp - dh && cp + dh < cm - dh && cm + dh < per) {
            return Err(JoinError::NotAligned {
                section: what(s),
                reason: "its bottom corners are not on either side of the bottom centre".into(),
            });
        }
        bundle.push(b);
        start.push(s0);
    }
    // Keep a bundle ray only if it lies in the same gap between sole points on every section,
    // at least `margin` of arc from them.
    let slot = |x: f64, so: &[f64; 4]| so.iter().filter(|&&q| q < x).count();
    let mut keep = vec![true; angles.len()];
    for (i, kp) in keep.iter_mut().enumerate() {
        let s0 = slot(bundle[0][i], &sole[0]);
        for s in 0..k {
            let x = bundle[s][i];
            let margin = 0.01 * sections[s].perimeter();
            if slot(x, &sole[s]) != s0 || sole[s].iter().any(|&q| (q - x).abs() < margin) {
                *kp = false;
            }
        }
    }
    keep[0] = true;
    let mut kinds: Vec<(GuideKind, usize)> = Vec::new();
    for (i, &a) in angles.iter().enumerate() {
        if keep[i] {
            kinds.push((GuideKind::Bundle(a), i));
        }
    }
    let sole_kinds = [
        GuideKind::Sole { side: 1, up: false },
        GuideKind::Sole { side: 1, up: true },
        GuideKind::Sole { side: -1, up: true },
        GuideKind::Sole {
            side: -1,
            up: false,
        },
    ];
    // Order by position on section 0, then check the order everywhere.
    let pos = |s: usize, g: &(GuideKind, usize), j: usize| match g.0 {
        GuideKind::Bundle(_) => bundle[s][g.1],
        GuideKind::Sole { .. } => sole[s][j],
    };
    let mut all: Vec<((GuideKind, usize), usize)> =
        kinds.iter().map(|g| (*g, usize::MAX)).collect();
    for (j, sk) in sole_kinds.iter().enumerate() {
        all.push(((*sk, usize::MAX), j));
    }
    all.sort_by(|a, b| pos(0, &a.0, a.1).total_cmp(&pos(0, &b.0, b.1)));
    let mut arcs = vec![Vec::with_capacity(all.len()); k];
    for s in 0..k {
        for g in &all {
            arcs[s].push(pos(s, &g.0, g.1));
        }
        for w in arcs[s].windows(2) {
            if w[1] <= w[0] {
                return Err(JoinError::NotAligned {
                    section: what(s),
                    reason: "its guide crossings come in another order than on the first \
                             section (the guides would cross)"
                        .into(),
                });
            }
        }
    }
    Ok(Crossings {
        kinds: all.iter().map(|g| g.0 .0).collect(),
        arcs,
        start,
    })
}

/// Aligned resampling of all sections: `np` points each, the same number between
/// consecutive crossings on every section. Returns the common parameters in [0, 1) of the
/// points, the index of each crossing among the points, and the points (section-major).
pub fn resample(
    sections: &[&Section],
    cr: &Crossings,
    np: usize,
) -> (Vec<f64>, Vec<usize>, Vec<Vec<P3>>) {
    let m = cr.kinds.len();
    let k = sections.len();
    // Mean fraction of the perimeter of each crossing and each interval.
    let frac = |s: usize, i: usize| {
        let per = sections[s].perimeter();
        if i == m {
            1.0
        } else {
            cr.arcs[s][i] / per
        }
    };
    let big_u: Vec<f64> = (0..=m)
        .map(|i| (0..k).map(|s| frac(s, i)).sum::<f64>() / k as f64)
        .collect();
    // Points per interval, proportional to the mean interval, at least 2, summing to np.
    let np = np.max(2 * m);
    let mut counts: Vec<usize> = (0..m)
        .map(|i| (((big_u[i + 1] - big_u[i]) * np as f64).round() as usize).max(2))
        .collect();
    loop {
        let total: usize = counts.iter().sum();
        if total == np {
            break;
        }
        let i = (0..m).max_by_key(|&i| counts[i]).unwrap();
        if total > np {
            counts[i] -= 1;
        } else {
            counts[i] += 1;
        }
    }
    let mut params = Vec::with_capacity(np);
    let mut cross_idx = Vec::with_capacity(m);
    for i in 0..m {
        cross_idx.push(params.len());
        for j in 0..counts[i] {
            let t = j as f64 / counts[i] as f64;
            params.push(big_u[i] + t * (big_u[i + 1] - big_u[i]));
        }
    }
    let pts = (0..k)
        .map(|s| {
            let sec = sections[s];
            let per = sec.perimeter();
            let mut out = Vec::with_capacity(np);
            for i in 0..m {
                let a = cr.arcs[s][i];
                let b = if i + 1 == m { per } else { cr.arcs[s][i + 1] };
                for j in 0..counts[i] {
                    let t = j as f64 / counts[i] as f64;
                    out.push(sec.at_arc(cr.start[s] + a + t * (b - a)));
                }
            }
            out
        })
        .collect();
    (params, cross_idx, pts)
}

/// The crossing points of one section (for guide data on sections that are not resampled).
pub fn crossing_points(sec: &Section, cr: &Crossings, s: usize) -> Vec<P3> {
    cr.arcs[s]
        .iter()
        .map(|&a| sec.at_arc(cr.start[s] + a))
        .collect()
}

impl Crossings {
    /// The crossings of the sections with the given indices, in that order.
    pub fn select(&self, idx: &[usize]) -> Crossings {
        Crossings {
            kinds: self.kinds.clone(),
            arcs: idx.iter().map(|&i| self.arcs[i].clone()).collect(),
            start: idx.iter().map(|&i| self.start[i]).collect(),
        }
    }
}
