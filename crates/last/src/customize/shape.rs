//! The last surface: the foot's tape-measure sections deformed by a smooth field.
//!
//! Why this construction: a last must be one smooth closed solid whatever the scan holds
//! (separate toes, a leg cut anywhere, an arch), and every rule must be met when the output
//! mesh is cut, not only on the curves. So the foot is cut by planes across its axis; each
//! section is replaced by its convex hull (the path of a tape: it bridges the arch and the
//! gaps between toes) clipped at the last's top height; the sections are deformed by a few
//! smooth fields (widths scaled about the axis, heights scaled, the midfoot's upper part widened, the
//! toe part stretched forward, the bottom lifted behind the heel allowance) and joined into a
//! closed tube. The eight field values are solved by Newton's method so that the eight rule
//! targets, measured by cutting the resulting mesh, are met. Each section stays star-shaped
//! about its centroid and the stations are parallel planes in order, so the tube cannot
//! intersect itself.

use super::measure::{cut_below, measure, Measures, ANKLE_X, ANKLE_Z, INSTEP_X, OUTLINE_Z};
use super::CustomizeError;
use crate::smoothstep;
use footscan_geom::mesh::TriMesh;
use footscan_geom::polygon::convex_hull;
use footscan_geom::{P2, P3};

/// Number of stations along the axis and points around each section.
pub const STATIONS: usize = 250;
pub const AROUND: usize = 128;
pub use super::measure::TOP_Z;

/// The foot's hull sections at the stations, before deformation.
pub struct Sections {
    pub xs: Vec<f64>,
    /// Points around each section (y, z), arc-length spaced from the bottom.
    pub rings: Vec<Vec<P2>>,
    /// The sole as the last stands on it: per station with a flat bottom, (x, lowest y,
    /// highest y) of the bottom band carried to the glass.
    pub sole: Vec<(f64, f64, f64)>,
}

/// The section segments of the mesh by the planes x = xs[k], clipped to z <= `top` (one
/// segment per crossed triangle, as (y, z) pairs; the part above the top is cut off at the
/// top, so a section's top edge is where the foot crosses the top, not its widest point).
pub(crate) fn station_points(m: &TriMesh, xs: &[f64], top: f64) -> Vec<Vec<P2>> {
    let mut out = vec![Vec::new(); xs.len()];
    for t in &m.triangles {
        let v = t.map(|i| m.vertices[i as usize]);
        let xmin = v.iter().map(|p| p.x).fold(f64::MAX, f64::min);
        let xmax = v.iter().map(|p| p.x).fold(f64::MIN, f64::max);
        let k0 = xs.partition_point(|&x| x < xmin);
        let k1 = xs.partition_point(|&x| x <= xmax);
        for (x, o) in xs[k0..k1].iter().zip(&mut out[k0..k1]) {
            cut_below(&v, *x, top, |r| o.push(P2::new(r.y, r.z)));
        }
    }
    out
}

/// [`station_points`], each section then lowered by `drop(x)` (see [`Sections::of_foot`]).
fn lowered_station_points(
    m: &TriMesh,
    xs: &[f64],
    top: f64,
    drop: &dyn Fn(f64) -> f64,
) -> Vec<Vec<P2>> {
    let mut pts = station_points(m, xs, top);
    for (x, q) in xs.iter().zip(&mut pts) {
        let dz = drop(*x);
        q.iter_mut().for_each(|p| p.y -= dz);
    }
    pts
}

/// The foot between each station and halfway to its neighbours, one list of (y, z) points
/// per station: the sections halfway between stations (each in both neighbours' lists), the
/// mesh's vertices below the top and its edges' crossings of the top (each in the list of the
/// station nearest it). The tube is ruled between consecutive rings, and a ruled surface
/// between two convex rings holds a section only if both rings hold it: with rings cut at
/// their stations only, a feature rising between two stations (the back of the hallux on
/// the simulated feet, 2.4 mm above the ruling 1.2 mm behind the next station) stood out of
/// the last. The foot between two cuts is its triangles, whose corners are those vertices and
/// the cuts' points, so each ring holds all of the foot over half an interval either side.
/// (Cuts at the quarter intervals instead of the vertices held the same on every foot of the
/// benchmark to 0.01 mm, and cost 20 ms more per foot.)
fn between_stations(m: &TriMesh, xs: &[f64], top: f64, drop: &dyn Fn(f64) -> f64) -> Vec<Vec<P2>> {
    let mids: Vec<f64> = xs.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
    let mut out = vec![Vec::new(); xs.len()];
    for (k, c) in lowered_station_points(m, &mids, top, drop)
        .into_iter()
        .enumerate()
    {
        out[k].extend_from_slice(&c);
        out[k + 1].extend(c);
    }
    let station = |x: f64| mids.partition_point(|&b| b < x);
    for v in m.vertices.iter().filter(|v| v.z <= top) {
        out[station(v.x)].push(P2::new(v.y, v.z - drop(v.x)));
    }
    for t in &m.triangles {
        // Each edge once: a closed mesh's edge is in two triangles, once each way.
        for (i, j) in (0..3)
            .map(|e| (t[e], t[(e + 1) % 3]))
            .filter(|(i, j)| i < j)
        {
            let (p, q) = (m.vertices[i as usize], m.vertices[j as usize]);
            if (p.z - top) * (q.z - top) < 0.0 {
                let r = p + (q - p) * ((top - p.z) / (q.z - p.z));
                out[station(r.x)].push(P2::new(r.y, top - drop(r.x)));
            }
        }
    }
    out
}

/// Points spaced evenly by arc length along an open polyline: `n` points from its start,
/// the end excluded.
fn along(path: &[P2], n: usize, out: &mut Vec<P2>) {
    let seg: Vec<f64> = path.windows(2).map(|w| (w[1] - w[0]).norm()).collect();
    let total: f64 = seg.iter().sum();
    let (mut i, mut walked) = (0usize, 0.0);
    for k in 0..n {
        let s = total * k as f64 / n as f64;
        while i + 1 < seg.len() && walked + seg[i] < s {
            walked += seg[i];
            i += 1;
        }
        let t = if seg[i] > 0.0 {
            ((s - walked) / seg[i]).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push(path[i] + (path[i + 1] - path[i]) * t);
    }
    // A sharp vertex of the path (where a hull's bridge across a hollow meets the wall) gets
    // the sample nearest it, the sharpest first: chords between arc-length samples cut such
    // a corner by up to half a spacing times the turn (MakeHuman's medial arch wall 0.28 mm
    // inside the ring 16.5 mm up at 0.31 L). A sample moves at most half a spacing along
    // the path, so it keeps its meaning from ring to ring.
    let first = out.len() - n;
    let step = total / n as f64;
    let mut sharp: Vec<(f64, usize, f64)> = Vec::new();
    let mut at = 0.0;
    for j in 1..path.len().saturating_sub(1) {
        at += seg[j - 1];
        let (a, b) = (path[j] - path[j - 1], path[j + 1] - path[j]);
        if seg[j - 1] <= 0.0 || seg[j] <= 0.0 {
            continue;
        }
        let turn = (a.x * b.y - a.y * b.x).atan2(a.dot(&b)).abs();
        if turn > SHARP_TURN {
            sharp.push((turn, j, at));
        }
    }
    sharp.sort_by(|u, v| v.0.total_cmp(&u.0));
    let mut taken = vec![false; n];
    for (_, j, s) in sharp {
        let k = (s / step).round() as usize;
        if (1..n).contains(&k) && !taken[k] {
            taken[k] = true;
            out[first + k] = path[j];
        }
    }
}

/// A path vertex turning by more than this (radians, 4 degrees) is a corner a ring keeps.
const SHARP_TURN: f64 = 0.07;

/// Points of the bottom chain of a ring and of each wall piece beside it (see
/// [`resample_hull`]).
pub const BOTTOM: usize = 24;
/// Two left the chords across a rounded corner (a low-poly heel's, an unloaded sole's) up to
/// 0.3 mm inside the foot: the MakeHuman heel seat at -0.31 mm, now -0.08.
const WALL: usize = 4;
/// Heights above a section's lowest point (mm) that bound its bottom chain (the corners of a
/// flat bottom lie within it) and the wall pieces beside it (twice the outline height).
const CORNER_Z: f64 = 0.05;
const WALL_Z: f64 = 2.0 * OUTLINE_Z;

/// Where a counterclockwise convex polygon crosses height `z` going down (its low-y side)
/// and going up: (edge index, point) each.
fn crossings(h: &[P2], z: f64) -> Option<[(usize, P2); 2]> {
    let m = h.len();
    let below = |i: usize| h[i % m].y <= z;
    let at = |i: usize| {
        let (a, b) = (h[i % m], h[(i + 1) % m]);
        (i, a + (b - a) * ((z - a.y) / (b.y - a.y)))
    };
    let down = (0..m).find(|&i| !below(i) && below(i + 1))?;
    let up = (0..m).find(|&i| below(i) && !below(i + 1))?;
    Some([at(down), at(up)])
}

/// The polygon's boundary from point `a` (on edge a.0) counterclockwise to `b` (on b.0).
fn arc(h: &[P2], a: (usize, P2), b: (usize, P2)) -> Vec<P2> {
    let m = h.len();
    let mut out = vec![a.1];
    let mut i = a.0 + 1;
    while i % m != (b.0 + 1) % m {
        out.push(h[i % m]);
        i += 1;
    }
    out.push(b.1);
    out
}

/// Resample a counterclockwise convex polygon (y, z) to `n` points with the same meaning in
/// every section: [`WALL`] points down the low-y wall from [`WALL_Z`] above the lowest point
/// to [`CORNER_Z`], [`BOTTOM`] along the bottom, [`WALL`] up the other wall, the rest over the
/// top. Pinning the corners of the flat bottom and the wall above them in every ring makes
/// the tube's edges run along the last's feather edge, so the 1.5 mm outline is a smooth
/// curve; with plain arc-length samples the corners fell at a different place in each
/// station and the outline was a staircase (950-1200 mm long on a 260 mm last).
fn resample_hull(h: &[P2], n: usize) -> Vec<P2> {
    let zl = h.iter().map(|p| p.y).fold(f64::MAX, f64::min);
    let zt = h.iter().map(|p| p.y).fold(f64::MIN, f64::max);
    let wall = WALL_Z.min(0.5 * (zt - zl));
    let corner = CORNER_Z.min(0.5 * wall);
    let (Some([wd, wu]), Some([cd, cu])) = (crossings(h, zl + wall), crossings(h, zl + corner))
    else {
        unreachable!("a hull with area has a bottom and a top")
    };
    let mut out = Vec::with_capacity(n);
    along(&arc(h, wd, cd), WALL, &mut out);
    along(&arc(h, cd, cu), BOTTOM, &mut out);
    along(&arc(h, cu, wu), WALL, &mut out);
    along(&arc(h, wu, wd), n - BOTTOM - 2 * WALL, &mut out);
    out
}

/// Fraction of a section's height (its lowest point to the last's top) whose extent is
/// carried down to the glass as the flat bottom.
const BAND: f64 = 0.06;
/// An unloaded foot's bottom corners: radius in band heights, points per corner.
const CORNER_BANDS: f64 = 2.0;
const CORNER_POINTS: usize = 6;
/// Half-widths of the closing and of the running mean smoothing the bottom's edges along
/// the axis (mm).
const SOLE_CLOSE: f64 = 8.0;
const SOLE_SMOOTH: f64 = 3.0;

/// Where the forefoot's plan-view convexity starts (fraction of the foot length from the heel
/// point: just behind the fifth metatarsal head).
const FOREFOOT: f64 = 0.62;

/// In front of `from` a last's bottom holds every toe and is convex in plan view: the band's
/// edges there become the convex hull of their corners (the separate toes' sections left a
/// stepped lateral edge and slots between the toes).
fn convex_forefoot(
    xs: &[f64],
    band: Vec<Option<(f64, f64)>>,
    from: f64,
) -> Vec<Option<(f64, f64)>> {
    let corners: Vec<P2> = xs
        .iter()
        .zip(&band)
        .filter(|(x, _)| **x >= from)
        .filter_map(|(x, b)| b.map(|(l, h)| [P2::new(*x, l), P2::new(*x, h)]))
        .flatten()
        .collect();
    let hull = convex_hull(&corners);
    if hull.points.len() < 3 {
        return band;
    }
    xs.iter()
        .zip(band)
        .map(|(x, b)| {
            let b = b?;
            if *x < from {
                return Some(b);
            }
            Some(vertical_extent(&hull.points, *x).unwrap_or(b))
        })
        .collect()
}

/// The lowest and highest y where the vertical line at `x` meets a convex polygon.
fn vertical_extent(h: &[P2], x: f64) -> Option<(f64, f64)> {
    let mut ys = Vec::new();
    for (i, a) in h.iter().enumerate() {
        let b = h[(i + 1) % h.len()];
        if x < a.x.min(b.x) || x > a.x.max(b.x) {
            continue;
        }
        if (b.x - a.x).abs() < 1e-12 {
            // An edge along the line: both of its ends.
            ys.extend([a.y, b.y]);
        } else {
            ys.push(a.y + (b.y - a.y) * (x - a.x) / (b.x - a.x));
        }
    }
    let lo = ys.iter().copied().reduce(f64::min)?;
    let hi = ys.iter().copied().reduce(f64::max)?;
    Some((lo, hi))
}

impl Sections {
    /// The sole outline of the foot standing on the glass, at the outline height: the
    /// bottom bands' lowest y from heel to toe, then their highest back (a closed loop).
    pub fn sole_outline(&self) -> Vec<P3> {
        let mut out: Vec<P3> = self
            .sole
            .iter()
            .map(|s| P3::new(s.0, s.1, OUTLINE_Z))
            .collect();
        out.extend(self.sole.iter().rev().map(|s| P3::new(s.0, s.2, OUTLINE_Z)));
        out
    }

    /// Cut the framed foot at cosine-spaced stations from heel to toe. `bottom_from`: where
    /// the foot's own sole outline starts (its rearmost point at 1.5 mm); the flat bottom
    /// starts there, so a rounded heel keeps its shape (no box behind it).
    ///
    /// `drop(x)`: how far the section at x is lowered after it is cut at the last's top (the
    /// curve under a raised arch, see `bottom.rs`; zero for a foot standing on the glass), so
    /// the sections are those of the foot laid flat, each with the foot's own top.
    pub fn of_foot(
        foot: &TriMesh,
        length: f64,
        bottom_from: f64,
        drop: &dyn Fn(f64) -> f64,
    ) -> Sections {
        let bb = foot.bbox();
        let (x0, x1) = (bb.min.x, bb.max.x);
        let xs: Vec<f64> = (0..STATIONS)
            .map(|k| {
                let t = (k as f64 + 0.5) / STATIONS as f64;
                x0 + (x1 - x0) * 0.5 * (1.0 - (std::f64::consts::PI * t).cos())
            })
            .collect();
        let top = TOP_Z * length;
        let pts = lowered_station_points(foot, &xs, top, drop);
        let between = between_stations(foot, &xs, top, drop);
        // A last stands on a flat bottom: each section's lower band (the lowest BAND of its
        // height) is carried down to the glass. On a pressed foot this widens the bottom a
        // little; raised toes or a hanging heel get a flat bottom under them, and the
        // bottom's edge is the sole's edge, not a rounded fin. The band used to be the lowest
        // 1.5 mm only: where a toe or the hallux was slightly raised it was one-sided, which
        // left notches in the toe bottom of the side profile and a slot in the outline. The
        // edges are smoothed along the axis (scan noise made the outline a staircase).
        // Behind the foot's own outline the heel keeps its curve.
        let mut band: Vec<Option<(f64, f64)>> = vec![None; xs.len()];
        let mut corner = vec![0.0; xs.len()];
        for (k, (x, q)) in xs.iter().zip(&pts).enumerate() {
            if *x < bottom_from || q.len() < 3 {
                continue;
            }
            let zl = q.iter().map(|r| r.y).fold(f64::MAX, f64::min);
            let zt = q.iter().map(|r| r.y).fold(f64::MIN, f64::max);
            // At the back of the sole the band's height grows from the outline's (1.5 mm)
            // one for one with the distance from the sole's rear end: a full band there
            // carried the heel's rounded flanks (5-6 mm up) to the glass and squared the
            // heel's back edge.
            let zb = zl
                + (BAND * (zt - zl))
                    .max(OUTLINE_Z)
                    .min(OUTLINE_Z + x - bottom_from);
            corner[k] = zb - zl;
            // Where the tape's section (the hull) crosses the band's top: unlike the extent
            // of the points inside the band, this moves continuously as a raised wall (the
            // arch's medial side 2-5 mm above the glass, a lifted toe) rises through the
            // band's top. The points' extent jumped from the wall to the lateral half there
            // and left a notch in the outline at the medial waist.
            let h = convex_hull(q);
            let (yl, yh) = match (zb < zt && h.points.len() >= 3)
                .then(|| crossings(&h.points, zb))
                .flatten()
            {
                Some([a, b]) => (a.1.x.min(b.1.x), a.1.x.max(b.1.x)),
                None => q
                    .iter()
                    .fold((f64::MAX, f64::MIN), |(a, b), r| (a.min(r.x), b.max(r.x))),
            };
            if yh > yl {
                band[k] = Some((yl, yh));
            }
        }
        // Gaps between toes and a one-sided band at a slightly raised toe would leave slots
        // in the bottom: a morphological closing of each edge along the axis (the widest
        // within SOLE_CLOSE, then the narrowest of those) fills dips shorter than twice
        // SOLE_CLOSE and keeps every bulge; a running mean over SOLE_SMOOTH then removes scan
        // noise.
        // Near the heel's end of the bottom the windows shrink to the distance from that end:
        // a window cut off by the end took the widest band over the next SOLE_CLOSE as the
        // end's own, which squared the heel (a straight back edge 37-42 mm long where the
        // foot's is round, 9 mm of long-heel girth on the low-poly FIND foot). At the toe's
        // end the full windows stay: shrunk there, they left the gaps between the toes in
        // the outline (a zigzag toe on the simulated feet).
        let (xs_, band_) = (&xs, &band);
        let xb0 = band
            .iter()
            .zip(&xs)
            .find(|(b, _)| b.is_some())
            .map_or(f64::MIN, |(_, x)| *x);
        let window = move |k: usize, w: f64| {
            let r = w.min(xs_[k] - xb0);
            (0..xs_.len()).filter(move |&j| (xs_[j] - xs_[k]).abs() <= r && band_[j].is_some())
        };
        let dil: Vec<Option<(f64, f64)>> = (0..xs.len())
            .map(|k| {
                band[k]?;
                Some(
                    window(k, SOLE_CLOSE)
                        .filter_map(|j| band[j])
                        .fold((f64::MAX, f64::MIN), |(a, b), (l, h)| (a.min(l), b.max(h))),
                )
            })
            .collect();
        let closed: Vec<Option<(f64, f64)>> = (0..xs.len())
            .map(|k| {
                let (l0, h0) = band[k]?;
                let (l, h) = window(k, SOLE_CLOSE)
                    .filter_map(|j| dil[j])
                    .fold((f64::MIN, f64::MAX), |(a, b), (l, h)| (a.max(l), b.min(h)));
                Some((l.min(l0), h.max(h0)))
            })
            .collect();
        let smooth: Vec<Option<(f64, f64)>> = (0..xs.len())
            .map(|k| {
                closed[k]?;
                let near: Vec<(f64, f64)> =
                    window(k, SOLE_SMOOTH).filter_map(|j| closed[j]).collect();
                let n = near.len() as f64;
                let yl = near.iter().map(|b| b.0).sum::<f64>() / n;
                let yh = near.iter().map(|b| b.1).sum::<f64>() / n;
                (yh > yl).then_some((yl, yh))
            })
            .collect();
        let smooth = convex_forefoot(&xs, smooth, FOREFOOT * length);
        let mut keep_x = Vec::new();
        let mut rings = Vec::new();
        let mut sole = Vec::new();
        // Sections too small for a ring of their own at the heel's end (slivers of a leg that
        // leans back at the last's top: 0.7 mm behind the heel on the FIND foot) go into the
        // first ring, which stands at the first of them: the last's back then holds them.
        let mut behind: Vec<P2> = Vec::new();
        let mut behind_x: Option<f64> = None;
        for ((((x, mut q), b), near), r) in xs.iter().zip(pts).zip(smooth).zip(between).zip(corner)
        {
            q.extend(near);
            if rings.is_empty() {
                if !q.is_empty() {
                    behind_x.get_or_insert(*x);
                }
                q.append(&mut behind);
            }
            if q.len() < 3 {
                if rings.is_empty() {
                    behind = q;
                }
                continue;
            }
            // The closing above fills dips in the band's edges; at the concave plan waist it
            // carried the medial edge out past the foot's own wall (0.25 mm on the simulated
            // feet), which widened the plan waist, and the solver's waist scale then pressed
            // the arch's wall. Behind the forefoot the bottom stays within the section's own
            // plan extent; in front, the convex forefoot bridges the toes' steps on purpose.
            let (qlo, qhi) = if *x < FOREFOOT * length {
                q.iter()
                    .fold((f64::MAX, f64::MIN), |(a, b), r| (a.min(r.x), b.max(r.x)))
            } else {
                (f64::MIN, f64::MAX)
            };
            if let Some((yl, yh)) = b.map(|(l, h)| (l.max(qlo), h.min(qhi))) {
                // The bottom's corners are rounded, radius twice the band's height: where
                // the sole is round across (a foot scanned without weight on it, laid flat
                // by a curve under its arch, and a real foot standing on a plate, whose
                // sole rolls up into its sides over 10-15 mm) square corners held no foot
                // and added to every girth, and the solver gave that back over the top,
                // pressing the foot's sides (FIND: the instep 2.7 mm over the rules, its
                // sides pressed 1.2 mm; the standing dupontgu left foot: instep 2.9 mm
                // over, an instep offset of -2.2 mm, the lateral midfoot wall pressed
                // 2.0 mm 32 mm up). Where the foot fills a corner (the simulated feet's
                // spread soles) its own points keep it. Radius 1, 2 and 3 bands (two points
                // per wall piece): midfoot clearance -0.30, -0.26, -0.30 mm (FIND), -2.14,
                // -1.52, -1.03 (low-poly FIND), -0.38, -0.35, -0.65 (MakeHuman); 3 and 4
                // on every foot later: the simulated heel seats to -0.16 and -0.32 mm.
                let r = (CORNER_BANDS * r).min(0.5 * (yh - yl));
                if r > 0.1 {
                    for i in 0..=CORNER_POINTS {
                        let a = std::f64::consts::FRAC_PI_2 * i as f64 / CORNER_POINTS as f64;
                        let (dy, dz) = (r * (1.0 - a.cos()), r * (1.0 - a.sin()));
                        q.push(P2::new(yl + dy, dz));
                        q.push(P2::new(yh - dy, dz));
                    }
                } else {
                    q.push(P2::new(yl, 0.0));
                    q.push(P2::new(yh, 0.0));
                }
                sole.push((*x, yl, yh));
            }
            let h = convex_hull(&q);
            if h.points.len() < 3 || h.area() < 0.5 {
                if rings.is_empty() {
                    behind = h.points;
                }
                continue;
            }
            keep_x.push(if rings.is_empty() {
                behind_x.unwrap_or(*x)
            } else {
                *x
            });
            rings.push(resample_hull(&h.points, AROUND));
        }
        Sections {
            xs: keep_x,
            rings,
            sole,
        }
    }
}

/// Nodes of the deformation fields (x stations from the foot's landmarks).
#[derive(Clone, Copy, Debug)]
pub struct Nodes {
    pub heel: f64,
    pub waist: f64,
    pub instep: f64,
    pub ball: f64,
    /// Start of the toe stretch and the foot's toe tip.
    pub stretch_from: f64,
    pub tip: f64,
    /// The ankle girth's station; the end of the heel width's window (L / 4); where the
    /// ball region starts (the widening is zero there).
    pub ankle: f64,
    pub heel_window: f64,
    pub forefoot: f64,
    /// Where the toe box starts: the heights and widths are the foot's (or more) in front
    /// of it (rule III: the forefoot as the foot), so the ball girth's reduction ends
    /// between the ball line and here.
    pub toe_box: f64,
    /// The ball line's ends along the axis (MT5 and MT1, whichever is further back first).
    pub ball_back: f64,
    pub ball_front: f64,
    pub length: f64,
    pub heel_allowance: f64,
    /// The long-heel girth's plane in the side view: from the heel point on the glass (x) to
    /// the instep's top (x, z) (see [`build`]: the ankle's offset grows the last above it
    /// only).
    pub heel_point: f64,
    pub instep_top: (f64, f64),
    /// The sections are a foot's, which must fit inside the last (the whole-foot path), not
    /// a stock last's (the clinic path). A foot's last gets a toe rounded in plan in front of
    /// `tip` (a foot's toes end square; a stock last has its own toe); its upper midfoot's
    /// widening stays inside each section's plan extent (see [`saturate`]; a stock last has
    /// little room between its upper sides and its plan extent, and its girths need the
    /// widening about the axis, its clearance being the footprint's, at the bottom); and its
    /// heel offset over the top is held at zero or more (see [`solve`]: the neutral last
    /// holds the foot, so a negative one presses it; a stock last may need to give girth
    /// back at the heel).
    pub holds_foot: bool,
}

impl Nodes {
    pub fn of(m: &Measures) -> Nodes {
        let l = m.length;
        let ball = 0.5 * (m.b.x + m.c.x);
        Nodes {
            heel: m.heel_centre.x,
            waist: (0.5 * (m.d.x + m.e.x)).clamp(m.heel_centre.x + 1.0, INSTEP_X * l - 1.0),
            instep: INSTEP_X * l,
            ball: ball.max(INSTEP_X * l + 1.0),
            stretch_from: m.b.x.max(m.c.x) + 0.04 * l,
            tip: m.a.x,
            ankle: (ANKLE_X * l).clamp(m.heel_centre.x + 1.0, INSTEP_X * l - 2.0),
            heel_window: (0.25 * l).min(ANKLE_X * l - 1.0),
            forefoot: (m.b.x.min(m.c.x) - 0.05 * l).max(INSTEP_X * l + 1.0),
            toe_box: m.b.x.max(m.c.x) + 0.08 * l,
            ball_back: m
                .b
                .x
                .min(m.c.x)
                .max((m.b.x.min(m.c.x) - 0.05 * l).max(INSTEP_X * l + 1.0)),
            ball_front: m.b.x.max(m.c.x),
            length: l,
            heel_allowance: 0.0,
            heel_point: m.o.x,
            instep_top: (m.instep_top.x, m.instep_top.z),
            holds_foot: true,
        }
    }
}

/// Zero-slope cubic Hermite through (x, v) nodes (flat outside): smooth, no overshoot.
fn blend(nodes: &[(f64, f64)], x: f64) -> f64 {
    if x <= nodes[0].0 {
        return nodes[0].1;
    }
    for w in nodes.windows(2) {
        let ((xa, va), (xb, vb)) = (w[0], w[1]);
        if x <= xb {
            return va + (vb - va) * smoothstep((x - xa) / (xb - xa));
        }
    }
    nodes[nodes.len() - 1].1
}

/// Height above the long-heel girth's plane over which the ankle's offset comes in
/// (fraction of the foot length).
const ANKLE_RAMP: f64 = 0.03;

/// Width of the last's end ring in plan, as a fraction of the toe's (see [`build`]).
const TOE_END: f64 = 0.12;

/// Number of field values.
pub const NPARAM: usize = 9;

/// The field values: toe extension (mm); width scales at the heel, waist and ball; the
/// height scale at the ball; outward offsets over the top (mm) at the heel, ankle and
/// instep stations; the widening of the upper midfoot (heel window to the ball region, as
/// a fraction).
///
/// Where the rules make the last bigger than the foot (heel seat, midfoot, ankle: II-G,
/// II-H, IV) the girths grow by offsets over the top and a widening above the lower wall,
/// so a solution with positive values holds the foot. There are more values than rules:
/// the solver moves them by the least weighted change from the foot's own shape (the
/// paper's least-change principle, eq. 9, applied to the field), so it spreads an increase
/// over the mechanisms instead of raising one and taking it back with another. The square
/// system it replaced (height scales at ankle and instep, one widening) met the long-heel
/// girth by widening 12-16 % and lowered the instep by 4-6 % to give the instep and ankle
/// girths back: the instep stood 5-11 mm out of the last (docs/method.md 10.5). The ball
/// girth (II-F: reduced for men and women) is met by a height scale flat across the ball
/// line (MT5 to MT1) and back to at least 1 at the toe box, so the toes keep their room
/// (rule III: the forefoot as the foot).
pub type Params = [f64; NPARAM];

/// What one unit of each field value moves the surface by (mm), for the least change.
fn param_scale(nd: &Nodes) -> Params {
    let w = 0.2 * nd.length;
    [0.1, w, w, w, w, 1.0, 1.0, 1.0, w]
}

/// Weight of a section point's offset over the top by its normal's z: none on the flat
/// bottom (which stays on the glass) and the walls up to the widest point (normal level),
/// full over the top. So an offset hardly moves a section's plan extreme: when it did
/// (weight 0.06 at a level normal), the width scales took the wider plan back by pulling in
/// the lower walls, which hold no offset (simulated feet: midfoot -0.18 to -0.24 mm, now
/// -0.09 to -0.17 with this alone).
fn offset_weight(nz: f64) -> f64 {
    smoothstep(nz / 0.6)
}

/// Move `y` by `m` across the section, saturating at the section's plan extent [lo, hi]:
/// a move of size a toward an extreme with room r becomes a r / (a + r), which is the move
/// itself while it is small (slope 1), smooth in the field values, and never reaches the
/// extreme. So the widening grows the girths without growing the plan width. (Saturating
/// the offsets over the top too took the heel offset's hold on the long-heel girth away: the
/// solve ran the offset past 0.1 L on the simulated feet.)
fn saturate(y: f64, m: f64, lo: f64, hi: f64) -> f64 {
    let room = if m >= 0.0 { hi - y } else { y - lo }.max(0.0);
    let a = m.abs();
    if a + room <= 0.0 {
        return y;
    }
    y + m.signum() * a * room / (a + room)
}

/// Outward unit normals of a counterclockwise ring (central differences).
fn ring_normals(ring: &[P2]) -> Vec<P2> {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let t = ring[(i + 1) % n] - ring[(i + n - 1) % n];
            let l = t.norm().max(1e-12);
            P2::new(t.y / l, -t.x / l)
        })
        .collect()
}

/// The deformed closed mesh of the last.
pub fn build(sec: &Sections, nd: &Nodes, p: &Params) -> TriMesh {
    let [ext, syh, syw, syb, szb, dh, da, di, kup] = *p;
    // The heel's width scale ends at the heel window, where the waist's starts (the waist
    // is measured in front of it), so the heel width and waist width rules pull on
    // separate stations.
    let hw = nd.heel_window.max(nd.heel + 0.5).min(nd.waist - 0.5);
    let sy = [
        (nd.heel, syh),
        (hw, syw),
        (nd.waist, syw),
        (nd.ball, syb),
        (nd.toe_box, syb.max(1.0)),
    ];
    let sz = [
        (nd.forefoot, 1.0),
        (nd.ball_back, szb),
        (nd.ball_front, szb),
        (nd.toe_box, szb.max(1.0)),
    ];
    // The ankle's offset is blended on its own: on a foot's last it grows the last only
    // above the long-heel girth's plane (the ankle girth's top, over the ankle's front
    // fold), so it meets the ankle girth rule without growing the long-heel girth, which
    // the heel's and instep's offsets meet. Growing both, it made the low-poly FIND foot's
    // long-heel girth 5 mm too big for an ankle 5.6 mm short, and the solver gave that back
    // by narrowing the upper midfoot (kup -3.8 %), which pressed the foot 1.5 mm.
    let off = [
        (nd.heel, dh),
        (nd.ankle, 0.0),
        (nd.instep, di),
        (nd.forefoot, 0.0),
    ];
    let off_ankle = [(nd.heel, 0.0), (nd.ankle, da), (nd.instep, 0.0)];
    let ramp = ANKLE_RAMP * nd.length;
    let long_heel_slope = nd.instep_top.1 / (nd.instep_top.0 - nd.heel_point).max(1.0);
    let ku = [
        (nd.heel_window.min(nd.ankle - 1.0), 0.0),
        (0.5 * (nd.ankle + nd.instep), kup),
        (nd.instep, 0.0),
    ];
    let (z0, z1) = (0.5 * ANKLE_Z * nd.length, ANKLE_Z * nd.length);
    let stretch = 1.0 + ext / (nd.tip - nd.stretch_from).max(1.0);
    let xns: Vec<f64> = sec
        .xs
        .iter()
        .map(|&x| {
            if x > nd.stretch_from {
                nd.stretch_from + (x - nd.stretch_from) * stretch
            } else {
                x
            }
        })
        .collect();
    let mut rings: Vec<Vec<P3>> = Vec::with_capacity(sec.rings.len());
    for (k, (x, ring)) in sec.xs.iter().zip(&sec.rings).enumerate() {
        let xn = xns[k];
        // The scales where the ring ends up: a ring stretched into the toe box holds the
        // foot's sections from x to xn, so the ball's reduced height taken from x pressed the
        // hallux's top 1.1 mm at the toe box (low-poly FIND), where rule III wants the foot.
        let (fy, fz, d) = (blend(&sy, xn), blend(&sz, xn), blend(&off, *x));
        let da = blend(&off_ankle, *x);
        let zp = long_heel_slope * (x - nd.heel_point);
        let above = |z: f64| {
            if nd.holds_foot {
                smoothstep((z - zp) / ramp)
            } else {
                1.0
            }
        };
        let kup = blend(&ku, *x);
        // The toe part is stretched forward, so the last at xn holds the foot's section
        // from x: where the toes widen or rise forward (the hallux's joint, the toe pads)
        // the foot's own section at xn stood out of it by 3-4 mm. The ring is the hull of
        // the foot's sections from x to xn.
        let swept;
        let ring = if xn > *x + 0.1 {
            let mut q: Vec<P2> = ring.clone();
            // Up to halfway to the next ring's place: the tube is ruled between rings, and
            // a ring holding the foot only up to its own place left the toes' top (the
            // low-poly FIND foot's, raised 60 mm up near the tip) 0.67 mm out between two
            // stretched rings.
            let reach = 0.5 * (xn + xns[(k + 1).min(xns.len() - 1)]);
            for (xj, rj) in sec.xs.iter().zip(&sec.rings).skip(k + 1) {
                if *xj > reach {
                    break;
                }
                q.extend_from_slice(rj);
            }
            let h = convex_hull(&q);
            swept = resample_hull(&h.points, AROUND);
            &swept
        } else {
            ring
        };
        let normals = ring_normals(ring);
        // The upper midfoot widens inside the section's own plan extent (see
        // [`saturate`]): the plan waist (I-C) stays the foot's, so the waist
        // width scale stays at its rule and does not pull the arch's wall in. A widening
        // about the axis widened the plan waist, which the solver took back with a waist
        // scale below 1 that pressed the medial wall 1 mm into the foot.
        let (ylo, yhi) = ring.iter().fold((f64::MAX, f64::MIN), |(a, b), q| {
            (a.min(q.x * fy), b.max(q.x * fy))
        });
        let mut pts: Vec<P3> = ring
            .iter()
            .zip(&normals)
            .map(|(q, n)| {
                // In front of the ankle station the instep's offset grows the last only
                // below the long-heel girth's plane (going out over one ramp below it), as
                // the ankle's grows it only above: so it grows the instep girth and not the
                // long heel's, whose plane runs through the instep's top. Raising that top
                // tilted the plane, and the long-heel girth grew 1.2 mm per millimetre of
                // instep girth; on the dupontgu left foot, which needs 1.4 mm more instep and
                // 0.7 mm more long heel than its neutral last, the solver then gave the long
                // heel back with a negative widening that pressed the medial wall 1-3 mm.
                let di = if nd.holds_foot && *x > nd.ankle {
                    1.0 - smoothstep((q.y - zp) / ramp + 1.0)
                } else {
                    1.0
                };
                let w = (d * di + da * above(q.y)) * offset_weight(n.y);
                let y = q.x * fy;
                let m = y * kup * smoothstep((q.y - z0) / (z1 - z0));
                // Between the heel window and the ball the offsets' sideways moves saturate
                // inside the plan extent with the widening: the plan waist is the rules'
                // (I-C), and any growth of it the waist scale takes back from the walls.
                let y = if !nd.holds_foot {
                    y + m + w * n.x
                } else if *x > hw && *x < nd.ball {
                    saturate(y, m + w * n.x, ylo, yhi)
                } else {
                    saturate(y, m, ylo, yhi) + w * n.x
                };
                P3::new(xn, y, (q.y * fz + w * n.y).max(0.0))
            })
            .collect();
        // A negative offset or widening (a girth given back) folds the ring at a sharp
        // corner, such as where the top was cut off (self-intersections at the ankle's top
        // on the FIND foot); the ring is its own hull again, resampled with the same
        // meaning per point. Not for a positive widening: the hull then bridged the band
        // between the instep's and the ankle's offsets (below and above the long-heel
        // plane) and the long-heel girth jumped by 0.7 mm as the widening left zero, which
        // the finite differences read as a slope and the solve overshot into a negative
        // widening (dupontgu left foot: midfoot -1.02 mm, now -0.24).
        if d < 0.0 || d + da < 0.0 || kup < 0.0 {
            let h = convex_hull(&pts.iter().map(|q| P2::new(q.y, q.z)).collect::<Vec<_>>());
            pts = resample_hull(&h.points, AROUND)
                .into_iter()
                .map(|q| P3::new(xn, q.x, q.y))
                .collect();
        }
        // The toe in plan view: in front of the foot's toe tip, where the toe allowance
        // adds the last's own room, each ring narrows about its middle along a quarter
        // ellipse (to TOE_END of its width at the last's end), so the toe is rounded as a
        // last's is, not the square end of the stretched toes' hull. Nothing of the foot is
        // in front of its tip, so no clearance is given up.
        if nd.holds_foot && ext > 0.5 && xn > nd.tip {
            let t = ((xn - nd.tip) / ext).min(1.0);
            let f = (1.0 - t * t).sqrt().max(TOE_END);
            let (lo, hi) = pts
                .iter()
                .fold((f64::MAX, f64::MIN), |(a, b), q| (a.min(q.y), b.max(q.y)));
            let mid = 0.5 * (lo + hi);
            for q in &mut pts {
                q.y = mid + (q.y - mid) * f;
            }
        }
        // Heel allowance: lift the bottom behind x = heel_allowance along a 45 degree
        // chamfer, squashing the section from below.
        let zc = OUTLINE_Z + (nd.heel_allowance - xn);
        if zc > 0.0 {
            let zb = pts.iter().map(|q| q.z).fold(f64::MAX, f64::min);
            let zt = pts.iter().map(|q| q.z).fold(f64::MIN, f64::max);
            if zc >= zt - 1.0 {
                continue;
            }
            if zb < zc {
                for q in &mut pts {
                    q.z = zt - (zt - q.z) * (zt - zc) / (zt - zb);
                }
            }
        }
        rings.push(pts);
    }
    tube(&rings)
}

/// Join rings (same point count, in station order) into a closed mesh with end fans.
pub fn tube(rings: &[Vec<P3>]) -> TriMesh {
    let n = rings[0].len();
    let mut vertices: Vec<P3> = rings.iter().flatten().copied().collect();
    let idx = |r: usize, i: usize| (r * n + i % n) as u32;
    let mut tris = Vec::with_capacity(2 * n * rings.len());
    for r in 0..rings.len() - 1 {
        for i in 0..n {
            tris.push([idx(r, i), idx(r, i + 1), idx(r + 1, i + 1)]);
            tris.push([idx(r, i), idx(r + 1, i + 1), idx(r + 1, i)]);
        }
    }
    for (r, back) in [(0, true), (rings.len() - 1, false)] {
        let c = rings[r]
            .iter()
            .fold(P3::origin(), |s, p| s + p.coords / n as f64);
        let ci = vertices.len() as u32;
        vertices.push(c);
        for i in 0..n {
            let (a, b) = (idx(r, i), idx(r, i + 1));
            tris.push(if back { [ci, b, a] } else { [ci, a, b] });
        }
    }
    let mut m = TriMesh::new(vertices, tris);
    if m.volume() < 0.0 {
        m.flip();
    }
    m
}

/// The measured values in rule order: bottom length, ball, waist, heel widths, ball, instep,
/// long-heel, ankle girths.
pub fn values(m: &Measures) -> [f64; 8] {
    [
        m.length,
        m.ball_width,
        m.waist_width,
        m.heel_width,
        m.ball_girth,
        m.instep_girth,
        m.long_heel_girth,
        m.ankle_girth,
    ]
}

/// Tolerances the solver works to (tighter than the acceptance bounds: 0.2 mm for lengths
/// and widths, 0.5 mm for girths).
const TOL: [f64; 8] = [0.05, 0.05, 0.05, 0.05, 0.15, 0.15, 0.15, 0.15];

/// The width-only step is tried while every other value is within this many of its
/// tolerances (at 1 the 290 mm simulated feet took 107 evaluations, at 2 they take 79).
const WIDTH_STEP_SLACK: f64 = 2.0;

/// The heel offset's place in the field: it only grows where the foot must fit (see [`solve`]).
const HEEL_OFFSET: usize = 5;

/// The least weighted change (surface millimetres) from `u` that meets the linearised rules
/// A du = -r, with field value `held` (if any) brought to zero and left out: du = -u +
/// A^T (A A^T)^-1 (A u - r) over the rest. None when the rest cannot move the rules
/// independently.
fn least_change(
    a: &nalgebra::SMatrix<f64, 8, NPARAM>,
    u: &nalgebra::SVector<f64, NPARAM>,
    r: &[f64; 8],
    held: Option<usize>,
) -> Option<nalgebra::SVector<f64, NPARAM>> {
    let (mut af, mut uf) = (*a, *u);
    let mut rv = nalgebra::SVector::<f64, 8>::from(*r);
    if let Some(j) = held {
        // Its move to zero (-u_j) is made and taken out of the system.
        rv -= a.column(j) * u[j];
        af.column_mut(j).fill(0.0);
        uf[j] = 0.0;
    }
    // A rule not applied (its target NaN, see [`solve`]) has a zero row: it is kept out of
    // the system by a unit pivot of the system's scale (its multiplier comes out zero).
    let mut g = af * af.transpose();
    let big = g.diagonal().max();
    for i in 0..8 {
        if af.row(i).iter().all(|x| *x == 0.0) {
            g[(i, i)] = big.max(1.0);
        }
    }
    if held.is_some() {
        let sv = g.singular_values();
        if sv.min() < 1e-6 * sv.max() {
            return None;
        }
    }
    let y = g.lu().solve(&(af * uf - rv))?;
    let mut du = -uf + af.transpose() * y;
    if let Some(j) = held {
        du[j] = -u[j];
    }
    Some(du)
}

/// Steps of the solver at most (finite-difference, carried-on and width-only alike).
const MAX_STEPS: usize = 40;

/// The largest surface move (mm) one solver step may make (see [`solve`]).
const TRUST_MM: f64 = 12.0;

/// Surface move of a finite-difference step in the Jacobian (mm). The values are cut from
/// a mesh (plan widths at 0.25 mm stations, extremes that jump between stations), so a step
/// of 0.02 mm differenced that noise: the Newton steps crept, 105-184 mesh evaluations on
/// some feet against 33-94 with this step.
const FD_MM: f64 = 0.3;

/// Solve the field so the last's measured values meet `target`. Returns the mesh, its
/// measures, the field and the number of mesh evaluations.
/// The last the field `p` builds, its measures, and how far each rule's value is from its
/// target (0 for a NaN target: the rule has no counterpart on this last, the clinic path's
/// ankle girth on a low-cut last, and is not solved for).
fn evaluate(
    sec: &Sections,
    nd: &Nodes,
    medial: f64,
    target: &[f64; 8],
    p: &Params,
) -> Result<(TriMesh, Measures, [f64; 8]), CustomizeError> {
    let m = build(sec, nd, p);
    let me = measure(&m, Some(nd.length), medial).map_err(|why| CustomizeError::Infeasible {
        why: format!("the deformed last cannot be measured: {why}"),
    })?;
    let v = values(&me);
    let r = std::array::from_fn(|i| {
        if target[i].is_nan() {
            0.0
        } else {
            v[i] - target[i]
        }
    });
    Ok((m, me, r))
}

/// The rule residuals of the field `p` moved by `steps[c]` in each value c, one column per
/// value, spread over the available cores.
fn fd_columns(
    sec: &Sections,
    nd: &Nodes,
    medial: f64,
    target: &[f64; 8],
    p: &Params,
    steps: &Params,
) -> Result<Vec<[f64; 8]>, CustomizeError> {
    crate::par::map(NPARAM, crate::par::cores(NPARAM), |c| {
        let mut q = *p;
        q[c] += steps[c];
        evaluate(sec, nd, medial, target, &q).map(|(_, _, r)| r)
    })
    .into_iter()
    .collect()
}

/// The neutral field (the foot's own shape) with the toe extension and the width scales set
/// from their rules (`target`: bottom length, ball, waist and heel widths), which each have
/// one mechanism of their own: where the solve starts. The toe extension: the bottom runs
/// from the heel point (the foot's, or the chamfer's foot where that lies further forward) to
/// the toe.
pub fn neutral(foot: &Measures, target: &[f64; 4], nd: &Nodes) -> Params {
    let f = values(foot);
    [
        target[0] - f[0] + foot.o.x.max(nd.heel_allowance) - foot.o.x,
        1.0 + (target[3] - f[3]) / f[3],
        1.0 + (target[2] - f[2]) / f[2],
        1.0 + (target[1] - f[1]) / f[1],
        1.0,
        0.0,
        0.0,
        0.0,
        0.0,
    ]
}

/// The rules' values against the field's parameters.
type Jac = nalgebra::SMatrix<f64, 8, NPARAM>;

/// The Jacobian of the rule values `r` at `p` by forward differences of `steps`. The columns
/// are independent: evaluated on every core at once (the clinic path spent most of its time
/// here: 9 mesh evaluations per fresh Jacobian).
fn fd_jacobian(
    sec: &Sections,
    nd: &Nodes,
    medial: f64,
    target: &[f64; 8],
    p: &Params,
    r: &[f64; 8],
    steps: &Params,
) -> Result<Jac, CustomizeError> {
    let cols = fd_columns(sec, nd, medial, target, p, steps)?;
    let mut j = Jac::zeros();
    for (c, rq) in cols.iter().enumerate() {
        for i in 0..8 {
            j[(i, c)] = (rq[i] - r[i]) / steps[c];
        }
    }
    Ok(j)
}

/// Broyden's update of the Jacobian `a` (in millimetres of surface, `scale` per parameter)
/// by the step `dp` (field units) that changed the values by `dr`.
fn broyden(a: &mut Jac, scale: &Params, dp: &Params, dr: &[f64; 8]) {
    let s = nalgebra::SVector::<f64, NPARAM>::from_fn(|j, _| dp[j] * scale[j]);
    let ss = s.norm_squared();
    if ss > 1e-18 {
        let y = nalgebra::SVector::<f64, 8>::from(*dr);
        *a += (y - *a * s) * s.transpose() / ss;
    }
}

/// The weighted misfit of the rule values: each over its tolerance.
fn misfit(r: &[f64; 8]) -> f64 {
    r.iter()
        .zip(TOL)
        .map(|(a, t)| (a / t).powi(2))
        .sum::<f64>()
        .sqrt()
}

/// The field that meets the rules: Newton steps of least weighted change from the neutral
/// field (see [`neutral`]), in a trust region, with finite-difference Jacobians carried on
/// by Broyden's update, a one-evaluation correction when only widths are left, and the heel
/// offset held at zero while the foot must fit. Returns the last, its measures, the field
/// and the evaluations it took.
pub fn solve(
    sec: &Sections,
    nd: &Nodes,
    foot: &Measures,
    target: &[f64; 8],
    medial: f64,
) -> Result<(TriMesh, Measures, Params, usize), CustomizeError> {
    let evals = std::cell::Cell::new(0usize);
    let eval = |p: &Params| -> Result<(TriMesh, Measures, [f64; 8]), CustomizeError> {
        evals.set(evals.get() + 1);
        evaluate(sec, nd, medial, target, p)
    };
    let p0 = neutral(foot, &[target[0], target[1], target[2], target[3]], nd);
    let mut p = p0;
    let scale = param_scale(nd);
    let steps: Params = std::array::from_fn(|j| FD_MM / scale[j]);
    let (mut mesh, mut me, mut r) = eval(&p)?;
    let debug = std::env::var_os("FOOTSCAN_DEBUG").is_some();
    if debug {
        eprintln!("solve start: r {r:.3?} p {p:.4?}");
        eprintln!(
            "foot d {:.2?} e {:.2?} / neutral d {:.2?} e {:.2?}",
            foot.d, foot.e, me.d, me.e
        );
    }
    let norm = misfit;
    let within = |r: &[f64; 8], i: usize| r[i].abs() <= TOL[i];
    let sinv = nalgebra::SVector::<f64, NPARAM>::from_fn(|j, _| 1.0 / scale[j]);
    // The Jacobian in millimetres of surface (A = J S^-1): by finite differences when there
    // is none or the last step did poorly, else carried on by Broyden's update from the step
    // just taken (one evaluation per step instead of ten).
    let mut jac: Option<Jac> = None;
    let mut fresh = false;
    let mut bounded = nd.holds_foot;
    for _it in 0..MAX_STEPS {
        if (0..8).all(|i| within(&r, i)) {
            return Ok((mesh, me, p, evals.get()));
        }
        // Widths left (the rest nearly met): each has its own scale and a width is nearly
        // proportional to it, so one evaluation corrects them (a width is a smallest or
        // largest breadth over a range of stations, not smooth where that station jumps,
        // and the finite-difference Newton steps crept there for ten iterations on the
        // template foot).
        if [0, 4, 5, 6, 7]
            .into_iter()
            .all(|i| r[i].abs() <= WIDTH_STEP_SLACK * TOL[i])
            && !(1..4).all(|i| within(&r, i))
        {
            let mut q = p;
            for (i, j) in [(1, 3), (2, 2), (3, 1)] {
                q[j] *= 1.0 - r[i] / (target[i] + r[i]);
            }
            let (mq, meq, rq) = eval(&q)?;
            if norm(&rq) < norm(&r) {
                if let Some(a) = &mut jac {
                    broyden(
                        a,
                        &scale,
                        &std::array::from_fn(|j| q[j] - p[j]),
                        &std::array::from_fn(|i| rq[i] - r[i]),
                    );
                }
                (p, mesh, me, r) = (q, mq, meq, rq);
                continue;
            }
        }
        let a = match jac {
            Some(a) => a,
            None => {
                evals.set(evals.get() + NPARAM);
                fresh = true;
                fd_jacobian(sec, nd, medial, target, &p, &r, &steps)?
                    * nalgebra::SMatrix::<f64, NPARAM, NPARAM>::from_diagonal(&sinv)
            }
        };
        // Least weighted change from the neutral field that meets the linearised rules:
        // with u = S (p - p0) (millimetres of surface), minimise |u + du| subject to
        // A du = -r, so du = -u + A^T (A A^T)^-1 (A u - r).
        // Where the foot must fit, the heel offset only grows the last (the neutral field
        // holds the foot): when the step would take it below zero it is held at zero and the
        // rest solved again. Unbounded, the solver gave back the FIND foot's instep and
        // ankle excess (4 and 2 mm over the rules at the start) partly with a heel offset of
        // -2.4 mm, which pressed the back of the heel 1.3 mm at the last's top; held, the
        // ankle's and instep's own offsets do it (that heel seat from -1.30 to -0.62 mm).
        let u = nalgebra::SVector::<f64, NPARAM>::from_fn(|j, _| (p[j] - p0[j]) * scale[j]);
        let free = least_change(&a, &u, &r, None);
        let mut held = false;
        let step = match free {
            Some(du) if bounded && p[HEEL_OFFSET] + du[HEEL_OFFSET] / scale[HEEL_OFFSET] < 0.0 => {
                // Without the heel offset the rest may not meet the rules: the bound goes.
                let fixed = least_change(&a, &u, &r, Some(HEEL_OFFSET));
                held = fixed.is_some();
                bounded = held;
                fixed.or(free)
            }
            other => other,
        }
        .map(|du| -> Params { std::array::from_fn(|j| du[j] / scale[j]) });
        let Some(dx) = step else {
            if !fresh {
                jac = None;
                continue;
            }
            return Err(CustomizeError::Infeasible {
                why: "the rule targets cannot be moved independently (singular Jacobian)".into(),
            });
        };
        // A trust region in millimetres of surface: a shop last far from the foot (a heeled
        // last laid flat, 22 mm over the ball girth at the start) took Newton steps of 40 mm
        // in one offset, overshot the other girths and left the field's bounds.
        let reach = (0..NPARAM)
            .map(|j| (dx[j] * scale[j]).abs())
            .fold(0.0, f64::max);
        let mut lambda = if reach > TRUST_MM {
            TRUST_MM / reach
        } else {
            1.0
        };
        let n0 = norm(&r);
        let (q, mq, meq, rq) = loop {
            let q: Params = std::array::from_fn(|i| p[i] + lambda * dx[i]);
            let (mq, meq, rq) = eval(&q)?;
            // A carried-on Jacobian gets one try: a step that does not help sends the
            // solver back to finite differences from the same point.
            if norm(&rq) < n0 || lambda < 0.1 || !fresh {
                break (q, mq, meq, rq);
            }
            lambda *= 0.5;
        };
        let n1 = norm(&rq);
        if !fresh && n1 >= n0 {
            jac = None;
            continue;
        }
        // Stuck against the bound with a fresh Jacobian: the rules cannot be met with the
        // heel only growing, so the bound goes and the solve goes on from here; the
        // clearance then reports any press.
        if bounded && fresh && n1 > 0.8 * n0 && held {
            bounded = false;
            if debug {
                eprintln!("solve: heel offset bound released at r {r:.3?}");
            }
        }
        let mut a = a;
        broyden(
            &mut a,
            &scale,
            &std::array::from_fn(|j| q[j] - p[j]),
            &std::array::from_fn(|i| rq[i] - r[i]),
        );
        // Progress slower than halving the misfit: a fresh Jacobian next time.
        jac = (n1 < 0.5 * n0).then_some(a);
        fresh = false;
        (p, mesh, me, r) = (q, mq, meq, rq);
        if debug {
            eprintln!(
                "solve: r {r:.3?} p {p:.4?} joints x {:.2} {:.2}",
                me.b.x, me.c.x
            );
        }
        let bad = p[1..5].iter().any(|s| !(0.5..=2.0).contains(s))
            || [5, 6, 7].iter().any(|&j| p[j].abs() > 0.15 * nd.length)
            || p[8].abs() > 1.0;
        if bad {
            break;
        }
    }
    if r.iter().zip(TOL).all(|(a, t)| a.abs() <= t) {
        return Ok((mesh, me, p, evals.get()));
    }
    if debug {
        eprintln!("solve: failed with field {p:?}");
    }
    Err(unmet(&r))
}

/// The rules the solve left unmet, each by how much.
fn unmet(r: &[f64; 8]) -> CustomizeError {
    let names = [
        "bottom length",
        "ball width",
        "waist width",
        "heel width",
        "ball girth",
        "instep girth",
        "long-heel girth",
        "ankle girth",
    ];
    let miss: Vec<String> = (0..8)
        .filter(|&i| r[i].abs() > TOL[i])
        .map(|i| format!("{} off by {:+.2} mm", names[i], r[i]))
        .collect();
    CustomizeError::Unmet {
        why: format!(
            "the rules cannot be met together on this foot ({})",
            miss.join(", ")
        ),
        misses: (0..8)
            .filter(|&i| r[i].abs() > TOL[i])
            .map(|i| (i, r[i]))
            .collect(),
    }
}
