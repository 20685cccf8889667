//! The foot's frame and its characteristic information, cut from a closed mesh.
//!
//! The same [`measure`] cuts the foot and the finished last (both in the foot's frame), so a
//! rule's target and its value on the last are measured by one definition.
//!
//! Frame: z up from the lowest point (the mesh is taken with z up, as scanners and mesh
//! files of feet give it); x along the foot axis, from the heel centre toward the second
//! metatarsal region; origin at the heel point (the rearmost point of the sole outline) on
//! the glass; y to the left (so medial is +y for a right foot, -y for a left one).
//!
//! Definitions (L = foot length):
//! - sole outline: the section 1.5 mm above the lowest point; heel point O and toe tip A are
//!   its rearmost and foremost points, length = A.x - O.x;
//! - plan half-widths: extremes of y per station x (cuts x = const) below the last's top (TOP_Z);
//! - MT1 (B) / MT5 (C): most medial / lateral plan points with x in [0.55 L, 0.85 L];
//!   ball width = |B.y| + |C.y| (their distances from the axis);
//! - waist inner D / outer E: the smallest medial / lateral half-width between the heel
//!   centre station (or L / 4, whichever is further forward) and B (resp. C); waist width =
//!   |D.y| + |E.y|;
//! - heel width: the largest breadth over x in [0, L / 4]; the heel centre is its midpoint;
//! - axis: through the heel centre and the point of segment BC 46 % of the way from B (where
//!   the second metatarsal lies in the simulator and in typical feet), found by iteration;
//! - hallux point P: the most medial sole-outline point in front of 0.85 L;
//! - ball girth: the vertical plane through B and C; instep girth: the plane x = 0.55 L;
//!   long-heel girth: the plane through the heel point on the glass and the instep point
//!   (top of the foot at 0.55 L), containing y; ankle girth: the plane x = 0.30 L across
//!   the ankle's front fold, below the last's top at 0.30 L (a horizontal ankle girth would
//!   cut the gently sloping dorsum at a grazing angle and swing by centimetres with a
//!   millimetre of height, and a last ends below the malleoli anyway). A girth is the perimeter of the convex hull of the section, the path of a
//!   tape pulled around the foot (it bridges the arch and the gaps between toes);
//! - side profile: the section by the plane y = 0.

use crate::customize::error::CustomizeError;
use footscan_geom::mesh::TriMesh;
use footscan_geom::plane::Plane;
use footscan_geom::polygon::convex_hull;
use footscan_geom::{P2, P3, V3};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use serde::Serialize;

/// Station step of the plan half-width profile (mm).
pub const PLAN_STEP: f64 = 0.25;

/// How far inside its widest breadth a side still counts as the joint (see
/// `PlanProfile::joint`).
const JOINT_BAND_MM: f64 = 0.5;
/// Height of the sole outline above the lowest point (mm).
pub const OUTLINE_Z: f64 = 1.5;
/// Instep station and ankle height as fractions of the foot length.
pub const INSTEP_X: f64 = 0.55;
pub const ANKLE_Z: f64 = 0.16;
/// Station of the ankle girth (across the axis, through the ankle's front fold).
pub const ANKLE_X: f64 = 0.30;
/// Top of the last above the glass, as a fraction of the foot length: above the instep of
/// real feet (0.26-0.32 L on the feet in the benchmark), below where a leg stub starts to
/// matter. Girths are measured below it on the foot and on the last alike (a tape on the
/// last cannot go higher than the last).
pub const TOP_Z: f64 = 0.35;
/// Fraction of the way from MT1 to MT5 where the axis crosses the ball line.
pub const MT2_FRACTION: f64 = 0.46;

pub use footscan_geom::Side;

/// The foot's frame: world point = origin + x ex + y ey + z ez.
#[derive(Clone, Debug, Serialize)]
pub struct FootFrame {
    pub origin: P3,
    pub ex: V3,
    pub ey: V3,
    pub side: Side,
}

impl FootFrame {
    /// The isometry taking world points into the frame.
    pub fn world_to_frame(&self) -> Isometry3<f64> {
        let (ex, ey) = (self.ex, self.ey);
        let ez = ex.cross(&ey);
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_rows(&[
            ex.transpose(),
            ey.transpose(),
            ez.transpose(),
        ]));
        let o = self.origin.coords;
        Isometry3::from_parts(
            Translation3::from(-(r * o)),
            UnitQuaternion::from_rotation_matrix(&r),
        )
    }
    /// +1 when medial is +y (right foot), -1 otherwise.
    pub fn medial_sign(&self) -> f64 {
        match self.side {
            Side::Right => 1.0,
            Side::Left => -1.0,
        }
    }
}

/// A closed cut curve: the points in order (frame coordinates).
pub type Loop3 = Vec<P3>;

/// Characteristic information of a foot or last in the foot's frame.
#[derive(Clone, Debug)]
pub struct Measures {
    pub length: f64,
    pub ball_width: f64,
    pub waist_width: f64,
    pub heel_width: f64,
    pub ball_girth: f64,
    pub instep_girth: f64,
    pub long_heel_girth: f64,
    pub ankle_girth: f64,
    /// Points O, A, P, B, C, D, E and the heel centre, instep point.
    pub o: P3,
    pub a: P3,
    pub p: P3,
    pub b: P3,
    pub c: P3,
    pub d: P3,
    pub e: P3,
    pub heel_centre: P3,
    pub instep_top: P3,
    /// The heel breadth points (medial, lateral).
    pub heel_m: P3,
    pub heel_l: P3,
    pub outline: Vec<Loop3>,
    pub ball: Loop3,
    pub instep: Loop3,
    pub long_heel: Loop3,
    pub ankle: Loop3,
    pub profile: Loop3,
}

/// Per-station plan extremes: for station k (x = x0 + k step) the lowest and highest y and
/// the points where they are reached.
pub struct PlanProfile {
    pub x0: f64,
    pub step: f64,
    pub lo: Vec<Option<P3>>,
    pub hi: Vec<Option<P3>>,
}

/// Where the plane x = `x` cuts triangle `v`, below `top`: the ends of the section segment,
/// the part above the top cut off where it crosses it (each point handed to `out`). The plan
/// profile and the last's stations cut the same way through it.
pub(crate) fn cut_below(v: &[P3; 3], x: f64, top: f64, mut out: impl FnMut(P3)) {
    let mut seg = [P3::origin(); 3];
    let mut n = 0;
    for e in 0..3 {
        let (p, q) = (v[e], v[(e + 1) % 3]);
        if (p.x - x) * (q.x - x) > 0.0 || p.x == q.x {
            continue;
        }
        seg[n] = p + (q - p) * ((x - p.x) / (q.x - p.x));
        n += 1;
    }
    if n == 2 && (seg[0].z > top) != (seg[1].z > top) {
        let (a, b) = if seg[0].z > top { (1, 0) } else { (0, 1) };
        let s = (top - seg[a].z) / (seg[b].z - seg[a].z);
        seg[b] = seg[a] + (seg[b] - seg[a]) * s;
    }
    for r in seg[..n].iter().filter(|r| r.z <= top) {
        out(*r);
    }
}

impl PlanProfile {
    /// Room across the axis for a plan point (x, y): the distance to the nearer plan extreme
    /// at its station, interpolated between stations (negative outside); ahead of or behind
    /// the outline, minus the distance beyond its end.
    pub fn side_room(&self, p: P2) -> f64 {
        let n = self.lo.len();
        let first = self.hi.iter().position(Option::is_some);
        let last = self.hi.iter().rposition(Option::is_some);
        let (Some(a), Some(b)) = (first, last) else {
            return f64::NEG_INFINITY;
        };
        let (xa, xb) = (
            self.x0 + a as f64 * self.step,
            self.x0 + b as f64 * self.step,
        );
        if p.x < xa {
            return -(xa - p.x);
        }
        if p.x > xb {
            return -(p.x - xb);
        }
        let t = (p.x - self.x0) / self.step;
        let k = (t.floor() as usize).min(n - 1);
        let k1 = (k + 1).min(b);
        let f = t - k as f64;
        let at = |v: &[Option<P3>], k: usize| v[k].map(|q| q.y);
        let lerp = |v: &[Option<P3>]| match (at(v, k), at(v, k1)) {
            (Some(u), Some(w)) => Some(u + f * (w - u)),
            (Some(u), None) | (None, Some(u)) => Some(u),
            _ => None,
        };
        match (lerp(&self.hi), lerp(&self.lo)) {
            (Some(hi), Some(lo)) => (hi - p.y).min(p.y - lo),
            _ => f64::NEG_INFINITY,
        }
    }

    /// The plan outline: the highest-y points from heel to toe, then the lowest back; the
    /// outline a last casts on the glass seen from above, as a footprint is a foot's.
    pub fn outline(&self) -> Loop3 {
        let mut out: Loop3 = self.hi.iter().flatten().copied().collect();
        out.extend(self.lo.iter().rev().flatten().copied());
        out
    }

    /// Cut every triangle by the planes x = x0 + k step, the mesh sliced once in
    /// O(triangles and crossings), keeping the sections below `top`: a foot's plan widths are
    /// those a last cut off at its top can have. On the real feet with a leg the heel's
    /// widest breadth was the malleoli's or the leg's, 87-149 mm up, and the heel width rule
    /// asked the last for 4.6 mm more heel than the foot has below the last's top.
    pub fn new(m: &TriMesh, step: f64, top: f64) -> PlanProfile {
        let bb = m.bbox();
        let x0 = (bb.min.x / step).floor() * step;
        let n = ((bb.max.x - x0) / step).ceil() as usize + 1;
        let mut lo: Vec<Option<P3>> = vec![None; n];
        let mut hi: Vec<Option<P3>> = vec![None; n];
        for t in &m.triangles {
            let v = t.map(|i| m.vertices[i as usize]);
            let xmin = v.iter().map(|p| p.x).fold(f64::MAX, f64::min);
            let xmax = v.iter().map(|p| p.x).fold(f64::MIN, f64::max);
            let k0 = ((xmin - x0) / step).ceil().max(0.0) as usize;
            let k1 = (((xmax - x0) / step).floor() as usize).min(n - 1);
            for k in k0..=k1 {
                // The section segment's ends are its extremes.
                cut_below(&v, x0 + k as f64 * step, top, |r| {
                    if lo[k].is_none_or(|o| r.y < o.y) {
                        lo[k] = Some(r);
                    }
                    if hi[k].is_none_or(|o| r.y > o.y) {
                        hi[k] = Some(r);
                    }
                });
            }
        }
        PlanProfile { x0, step, lo, hi }
    }
    fn range(&self, xa: f64, xb: f64) -> std::ops::RangeInclusive<usize> {
        let n = self.lo.len();
        let a = ((xa - self.x0) / self.step).ceil().max(0.0) as usize;
        let b = (((xb - self.x0) / self.step).floor().max(0.0) as usize).min(n - 1);
        a..=b
    }
    /// The most medial (`medial` = +1 for +y) point over x in [xa, xb].
    fn extreme(&self, xa: f64, xb: f64, dir: f64) -> Option<P3> {
        self.range(xa, xb)
            .filter_map(|k| if dir > 0.0 { self.hi[k] } else { self.lo[k] })
            .max_by(|a, b| (dir * a.y).total_cmp(&(dir * b.y)))
    }
    /// The joint point on side `dir` over x in [xa, xb]: the side's widest breadth, placed
    /// at the middle of where the side stands within [`JOINT_BAND_MM`] of it (weights falling
    /// to zero at the band's edge). The plain arg-max jumped between stations of a flat side
    /// as the last was deformed (1.5 mm on the simulated foot's lateral side), the ball girth
    /// plane with it, and the ball girth by 0.1-1 mm between solver steps: the clinic path's
    /// solve stalled 0.2 mm short of rule II-F on one run in several.
    fn joint(&self, xa: f64, xb: f64, dir: f64) -> Option<P3> {
        let top = self.extreme(xa, xb, dir)?;
        let (mut sw, mut sx) = (0.0, 0.0);
        for k in self.range(xa, xb) {
            let Some(q) = (if dir > 0.0 { self.hi[k] } else { self.lo[k] }) else {
                continue;
            };
            let w = (1.0 - dir * (top.y - q.y) / JOINT_BAND_MM).max(0.0).powi(2);
            sw += w;
            sx += w * q.x;
        }
        Some(P3::new(sx / sw, top.y, top.z))
    }
    /// The least extreme point (the waist) over x in [xa, xb] on side `dir`.
    fn narrowest(&self, xa: f64, xb: f64, dir: f64) -> Option<P3> {
        self.range(xa, xb)
            .filter_map(|k| if dir > 0.0 { self.hi[k] } else { self.lo[k] })
            .min_by(|a, b| (dir * a.y).total_cmp(&(dir * b.y)))
    }
    /// Station of the largest breadth over [xa, xb]: (lateral-side low, high).
    fn widest(&self, xa: f64, xb: f64) -> Option<(P3, P3)> {
        self.range(xa, xb)
            .filter_map(|k| Some((self.lo[k]?, self.hi[k]?)))
            .max_by(|a, b| (a.1.y - a.0.y).total_cmp(&(b.1.y - b.0.y)))
    }
}

/// Section loops by a plane (frame coordinates).
fn cut(m: &TriMesh, plane: &Plane) -> Vec<Loop3> {
    m.section(plane)
        .into_iter()
        .filter(|p| p.len() >= 3)
        .map(|p| p.points)
        .collect()
}

/// The part of closed loops at or below height `top`, with the crossing points.
fn clip_below(loops: &[Loop3], top: f64) -> Vec<P3> {
    let mut out = Vec::new();
    for l in loops {
        for (i, p) in l.iter().enumerate() {
            let q = l[(i + 1) % l.len()];
            if p.z <= top {
                out.push(*p);
            }
            if (p.z - top) * (q.z - top) < 0.0 {
                out.push(p + (q - p) * ((top - p.z) / (q.z - p.z)));
            }
        }
    }
    out
}

/// Convex hull of all loop points below `top` in the plane, as a closed 3D loop
/// (counterclockwise about the plane normal), and its perimeter.
pub fn hull_loop(loops: &[Loop3], plane: &Plane, top: f64) -> (Loop3, f64) {
    let pts: Vec<P2> = clip_below(loops, top)
        .iter()
        .map(|p| plane.to_local(p))
        .collect();
    if pts.len() < 3 {
        return (Vec::new(), 0.0);
    }
    let h = convex_hull(&pts);
    let per = h.perimeter();
    (h.points.iter().map(|q| plane.to_world(q)).collect(), per)
}

fn outline_loops(m: &TriMesh, zmin: f64) -> Vec<Loop3> {
    cut(m, &Plane::axis_aligned(2, zmin + OUTLINE_Z))
}

/// Estimate the foot frame of a world mesh (z up): see the module documentation.
///
/// Scans of real feet are not all taken standing: a foot scanned hanging ("T-pose", as the
/// FIND template) rests on nothing, its toes or its heel tens of millimetres above the
/// forefoot's lowest point. So the glass is the plane the foot would stand on (the support
/// line under the arch in the side view, see [`support_pitch`]), not the lowest point; the
/// heel end is where a leg stub stands (or the narrower end when the mesh has none); the
/// side is where the toes reach furthest (the hallux is medial), not the 1.5 mm outline's
/// toe tip (raised toes never reach that outline).
pub fn find_frame(world: &TriMesh, name: &str) -> Result<FootFrame, CustomizeError> {
    let bb = world.bbox();
    let zmin = bb.min.z;
    let height = bb.max.z - zmin;
    // Principal direction of the lower part in plan.
    let low: Vec<P3> = world
        .vertices
        .iter()
        .filter(|p| p.z < zmin + 0.4 * height.max(30.0))
        .copied()
        .collect();
    if low.len() < 10 {
        return Err(CustomizeError::NotAFoot {
            name: name.into(),
            why: "fewer than 10 vertices in the lower part of the mesh".into(),
        });
    }
    let c = low.iter().fold(V3::zeros(), |s, p| s + p.coords) / low.len() as f64;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in &low {
        let d = p.coords - c;
        sxx += d.x * d.x;
        sxy += d.x * d.y;
        syy += d.y * d.y;
    }
    let ang = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let mut ex = V3::new(ang.cos(), ang.sin(), 0.0);
    let proj: Vec<(f64, f64)> = low
        .iter()
        .map(|p| {
            let d = p.coords - c;
            (d.dot(&ex), d.x * -ex.y + d.y * ex.x)
        })
        .collect();
    let (smin, smax) = proj
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), q| (a.min(q.0), b.max(q.0)));
    let span = smax - smin;
    // Heel end: under the leg when the mesh has one (taller than a third of its length: the
    // top's centroid is over the heel), else the narrower end (the ball is wider than the
    // heel).
    let top: Vec<f64> = world
        .vertices
        .iter()
        .filter(|p| p.z > zmin + 0.7 * height)
        .map(|p| (p.coords - c).dot(&ex))
        .collect();
    let heel_first = if height > span / 3.0 && !top.is_empty() {
        let t = top.iter().sum::<f64>() / top.len() as f64;
        t < 0.5 * (smin + smax)
    } else {
        let breadth = |a: f64, b: f64| {
            let (lo, hi) = proj
                .iter()
                .filter(|q| q.0 >= a && q.0 <= b)
                .fold((f64::MAX, f64::MIN), |(l, h), q| (l.min(q.1), h.max(q.1)));
            hi - lo
        };
        breadth(smin, smin + 0.35 * span) <= breadth(smax - 0.35 * span, smax)
    };
    if !heel_first {
        ex = -ex;
    }
    let mut frame = FootFrame {
        origin: P3::new(c.x, c.y, zmin),
        ex,
        ey: V3::z().cross(&ex),
        side: Side::Right,
    };
    let no_plan = || CustomizeError::NotAFoot {
        name: name.into(),
        why: "no plan outline at the ball or heel".into(),
    };
    // Level on the support line, decide the side, then refine the axis through the heel
    // centre and the MT2 point.
    for it in 0..6 {
        level(world, &mut frame);
        let mut m = world.clone();
        m.transform(&frame.world_to_frame());
        let (o, a) = plan_ends(&m);
        let l = a.x - o.x;
        if it == 0 {
            frame.side = toe_side(&m, o.x, l);
        }
        let plan = PlanProfile::new(&m, PLAN_STEP, TOP_Z * l);
        let s = frame.medial_sign();
        let (Some(b), Some(cc), Some((hl, hm))) = (
            plan.extreme(o.x + 0.55 * l, o.x + 0.85 * l, s),
            plan.extreme(o.x + 0.55 * l, o.x + 0.85 * l, -s),
            plan.widest(o.x, o.x + 0.25 * l),
        ) else {
            return Err(no_plan());
        };
        let hc = P3::new(0.5 * (hl.x + hm.x), 0.5 * (hl.y + hm.y), 0.0);
        let t = b + (cc - b) * MT2_FRACTION;
        let dir = V3::new(t.x - hc.x, t.y - hc.y, 0.0).normalize();
        // Back to world: the new axis in plan (its pitch is found again by `level`).
        let inv = frame.world_to_frame().inverse();
        let dir_w = inv * dir;
        let ex = V3::new(dir_w.x, dir_w.y, 0.0).normalize();
        let hc_w = inv * hc;
        frame.origin = hc_w;
        frame.ex = ex;
        frame.ey = V3::z().cross(&ex);
    }
    level(world, &mut frame);
    // Final origin: the heel point (pternion) on the axis, on the glass.
    let mut m = world.clone();
    m.transform(&frame.world_to_frame());
    let (o, _) = plan_ends(&m);
    let org = frame.world_to_frame().inverse() * P3::new(o.x, 0.0, 0.0);
    frame.origin = org;
    Ok(frame)
}

/// Heights (as fractions of the heel-to-toe extent) below which the heel point is sought:
/// the heel's back bulge, not a leg stub leaning back above it.
pub const HEEL_POINT_Z: f64 = 0.15;

/// The heel point (pternion: the rearmost point of the foot below [`HEEL_POINT_Z`] of its
/// extent) and the toe tip (acropodion: the foremost point), in plan, of a mesh in its frame.
/// Foot length is their distance along the axis (the paper's OP' = OA on a pressed foot,
/// where both lie on the 1.5 mm outline; a foot scanned unloaded has its toes or heel above
/// that outline, and its length is still heel to toe).
pub fn plan_ends(m: &TriMesh) -> (P3, P3) {
    let bb = m.bbox();
    let a = *m
        .vertices
        .iter()
        .max_by(|p, q| p.x.total_cmp(&q.x))
        .unwrap_or(&P3::origin());
    let zcap = bb.min.z.max(0.0) + HEEL_POINT_Z * (bb.max.x - bb.min.x);
    let o = m
        .vertices
        .iter()
        .filter(|p| p.z <= zcap)
        .min_by(|p, q| p.x.total_cmp(&q.x))
        .copied()
        .unwrap_or(a);
    (o, a)
}

/// Which side is medial: the toes reach furthest on the hallux's side. Splits the front
/// (x > 0.8 L) at the middle of the ball breadth and compares how far forward each half goes.
fn toe_side(m: &TriMesh, x0: f64, l: f64) -> Side {
    let plan = PlanProfile::new(m, PLAN_STEP, TOP_Z * l);
    let r = plan.range(x0 + 0.6 * l, x0 + 0.8 * l);
    let (mut lo, mut hi) = (f64::MAX, f64::MIN);
    for k in r {
        if let (Some(a), Some(b)) = (plan.lo[k], plan.hi[k]) {
            lo = lo.min(a.y);
            hi = hi.max(b.y);
        }
    }
    let mid = 0.5 * (lo + hi);
    let (mut xp, mut xn) = (f64::MIN, f64::MIN);
    for p in &m.vertices {
        if p.x > x0 + 0.8 * l {
            if p.y > mid {
                xp = xp.max(p.x);
            } else {
                xn = xn.max(p.x);
            }
        }
    }
    if xp >= xn {
        Side::Right
    } else {
        Side::Left
    }
}

/// Pitch the frame about its y axis so that its x axis lies along the support line (see
/// [`support_pitch`]) and its origin on it.
fn level(world: &TriMesh, frame: &mut FootFrame) {
    let mut m = world.clone();
    m.transform(&frame.world_to_frame());
    let (slope, z0) = support_pitch(&m);
    let inv = frame.world_to_frame().inverse();
    let ex = (inv * V3::new(1.0, 0.0, slope)).normalize();
    let ey = inv * V3::y();
    let o = inv * P3::new(0.0, 0.0, z0);
    frame.ex = ex;
    frame.ey = ey;
    frame.origin = o;
}

/// The line the foot stands on, in the side view (x, z) of a mesh in a provisional frame:
/// the edge of the lower convex hull that passes under the arch (x at 45 % of the extent),
/// as (slope dz/dx, z at x = 0). Every point of the foot lies on or above it; a standing foot
/// gives the glass itself (heel and forefoot both on it), a hanging one the plane it would
/// rest on.
pub fn support_pitch(m: &TriMesh) -> (f64, f64) {
    let mut pts: Vec<(f64, f64)> = m.vertices.iter().map(|p| (p.x, p.z)).collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    // Andrew's monotone chain, lower hull.
    let mut h: Vec<(f64, f64)> = Vec::new();
    for p in pts {
        while h.len() >= 2 {
            let (a, b) = (h[h.len() - 2], h[h.len() - 1]);
            if (b.0 - a.0) * (p.1 - a.1) - (b.1 - a.1) * (p.0 - a.0) <= 0.0 {
                h.pop();
            } else {
                break;
            }
        }
        h.push(p);
    }
    if h.len() < 2 {
        return (0.0, 0.0);
    }
    let (x0, x1) = (h[0].0, h[h.len() - 1].0);
    let xm = x0 + 0.45 * (x1 - x0);
    let w = h
        .windows(2)
        .find(|w| w[0].0 <= xm && xm <= w[1].0)
        .unwrap_or(&h[0..2]);
    let (a, b) = (w[0], w[1]);
    let slope = if b.0 > a.0 {
        (b.1 - a.1) / (b.0 - a.0)
    } else {
        0.0
    };
    (slope, a.1 - slope * a.0)
}

impl Measures {
    /// Where the sole outline starts: its rearmost x.
    pub fn sole_from(&self) -> f64 {
        self.outline
            .iter()
            .flatten()
            .map(|p| p.x)
            .fold(f64::MAX, f64::min)
    }
}

/// Measures of a mesh already in the foot frame. `l_ref`: the foot length that places the
/// stations (the foot's own for the foot, the foot's for the last).
pub fn measure(m: &TriMesh, l_ref: Option<f64>, medial: f64) -> Result<Measures, String> {
    let ol = outline_loops(m, 0.0);
    let pts: Vec<P3> = ol.iter().flatten().copied().collect();
    if pts.is_empty() {
        return Err("no sole outline 1.5 mm above the lowest point".into());
    }
    // The foot: heel point to toe tip in plan; the last: its bottom, the 1.5 mm outline (the
    // last's bottom is flat, see shape::Sections, and the heel allowance is cut from it).
    let (o, a) = if l_ref.is_none() {
        plan_ends(m)
    } else {
        (
            *pts.iter().min_by(|p, q| p.x.total_cmp(&q.x)).unwrap(),
            *pts.iter().max_by(|p, q| p.x.total_cmp(&q.x)).unwrap(),
        )
    };
    let length = a.x - o.x;
    let l = l_ref.unwrap_or(length);
    // The foot's girths below the last's top (where a tape round the last can go); the
    // last's all round (its top is the last's own).
    let top = if l_ref.is_none() {
        TOP_Z * l
    } else {
        f64::INFINITY
    };
    let plan = PlanProfile::new(m, PLAN_STEP, top);
    let s = medial;
    let b = plan.joint(0.55 * l, 0.85 * l, s).ok_or("no ball region")?;
    let c = plan.joint(0.55 * l, 0.85 * l, -s).ok_or("no ball region")?;
    let (hlo, hhi) = plan.widest(0.0, 0.25 * l).ok_or("no heel region")?;
    let heel_centre = P3::new(0.5 * (hlo.x + hhi.x), 0.5 * (hlo.y + hhi.y), 0.0);
    // The waist lies in front of the heel's quarter: on feet whose sides only widen from
    // the heel forward (the low-poly FIND foot) the narrowest half-widths behind it were at
    // the heel centre, so the waist width rule and the heel width rule pulled on the same
    // stations and the solver narrowed the waist 6 % to give back what the heel's rule added.
    let waist_from = heel_centre.x.max(0.25 * l);
    let d = plan
        .narrowest(waist_from, b.x, s)
        .ok_or("no waist region")?;
    let e = plan
        .narrowest(waist_from, c.x, -s)
        .ok_or("no waist region")?;
    let p = plan.extreme(0.85 * l, l + 1.0, s).unwrap_or(a);
    let (heel_m, heel_l) = if s > 0.0 { (hhi, hlo) } else { (hlo, hhi) };
    // Girths.
    let ball_plane = Plane::with_axis(
        P3::new(b.x, b.y, 0.0),
        V3::new(c.y - b.y, -(c.x - b.x), 0.0),
        V3::new(c.x - b.x, c.y - b.y, 0.0),
    )
    .ok_or("MT1 and MT5 coincide")?;
    let (ball, ball_girth) = hull_loop(&cut(m, &ball_plane), &ball_plane, top);
    let xi = INSTEP_X * l;
    let instep_plane = Plane::with_axis(P3::new(xi, 0.0, 0.0), V3::x(), V3::y()).unwrap();
    let instep_loops = cut(m, &instep_plane);
    let (instep, instep_girth) = hull_loop(&instep_loops, &instep_plane, top);
    let instep_top = clip_below(&instep_loops, top)
        .into_iter()
        .max_by(|u, v| u.z.total_cmp(&v.z))
        .ok_or("no section at the instep station")?;
    // The long-heel girth goes round the heel at its bottom: the plane passes through the
    // rearmost point of the sole outline (the paper's O; on the last its own heel point,
    // which the heel allowance puts behind the foot's), on the glass.
    let heel_g = pts
        .iter()
        .min_by(|p, q| p.x.total_cmp(&q.x))
        .map(|p| P3::new(p.x, 0.0, 0.0))
        .unwrap();
    let dir = V3::new(instep_top.x - heel_g.x, 0.0, instep_top.z);
    let lh_plane = Plane::with_axis(heel_g, dir.cross(&V3::y()), V3::y())
        .ok_or("degenerate long-heel plane")?;
    let (long_heel, long_heel_girth) = hull_loop(&cut(m, &lh_plane), &lh_plane, top);
    let ankle_plane = Plane::with_axis(P3::new(ANKLE_X * l, 0.0, 0.0), V3::x(), V3::y()).unwrap();
    let (ankle, ankle_girth) = hull_loop(&cut(m, &ankle_plane), &ankle_plane, top);
    let prof_plane = Plane::with_axis(P3::origin(), V3::y(), V3::x()).unwrap();
    let profile = cut(m, &prof_plane)
        .into_iter()
        .max_by_key(|l| l.len())
        .map(|l| clip_below(&[l], top))
        .unwrap_or_default();
    Ok(Measures {
        length,
        ball_width: (b.y - c.y).abs(),
        waist_width: (d.y - e.y).abs(),
        heel_width: hhi.y - hlo.y,
        ball_girth,
        instep_girth,
        long_heel_girth,
        ankle_girth,
        o,
        a,
        p,
        b,
        c,
        d,
        e,
        heel_centre,
        instep_top,
        heel_m,
        heel_l,
        outline: ol,
        ball,
        instep,
        long_heel,
        ankle,
        profile,
    })
}

/// The perimeter of the actual section loops by the plane x = `x` (not the hull): what the
/// simulator's analytic girth is.
pub fn perpendicular_section_length(m: &TriMesh, x: f64) -> f64 {
    let plane = Plane::with_axis(P3::new(x, 0.0, 0.0), V3::x(), V3::y()).unwrap();
    m.section(&plane)
        .iter()
        .filter(|p| p.closed)
        .map(|p| p.length())
        .sum()
}
