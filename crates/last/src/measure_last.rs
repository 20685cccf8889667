//! A last measured as shoemakers measure it (docs/method.md 9.3): its landmarks (heel point,
//! toe point, the joint points MT1 and MT5 on the featherline, tread, instep and top points),
//! the bottom (stick and bottom length, heel height, toe spring), the bottom's widths (joint,
//! waist, heel seat) and the girths (joint, waist, instep, long heel, short heel, top), on any
//! closed last mesh, with the picture that shows where each was taken.
//!
//! The frame the measures are given in: x heel to toe along the bottom's long axis, z up
//! with the ground (the plane the last stands on, touching the tread under the joint line)
//! at z = 0, y to the left (so a right last's medial side is +y), the heel point at x = 0,
//! y = 0. Every measure is a length or a point in
//! this frame, so a last turned, moved, mirrored (a right last from a left one: its side
//! flips, nothing else) or written in another format measures the same.

use crate::adjust::last::orient_last;
use crate::customize::measure::hull_loop;
use crate::draw::{self, Canvas, Colour, View};
use crate::size::{check_last_size, SizeError};
use footscan_geom::mesh::{MeshError, TriMesh, Units};
use footscan_geom::plane::Plane;
use footscan_geom::{Side, P3, V3};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Station spacing along the last (mm).
pub const STEP_MM: f64 = 0.5;
/// The joint points are the widest featherline points between these fractions of the stick
/// length: MT1 on the medial side, MT5 on the lateral (around the trade's 0.72 and 0.64 of
/// the last's length), both in the wider window where the side is not known from the toe.
pub const MT1_WINDOW: (f64, f64) = (0.62, 0.80);
pub const MT5_WINDOW: (f64, f64) = (0.55, 0.72);
pub const JOINT_WINDOW: (f64, f64) = (0.55, 0.85);
/// The instep point's station (fraction of the stick length).
pub const INSTEP_AT: f64 = 0.55;
/// The heel seat width's station (fraction of the stick length).
pub const HEEL_SEAT_AT: f64 = 0.18;
/// The bottom's waist width's station (fraction of the stick length).
pub const WAIST_AT: f64 = 0.40;
/// Half-length of the bottom's piece under the joint line whose tangent is the ground (mm).
pub const TANGENT_HALF_MM: f64 = 3.0;
/// The tread point is the lowest point within this of the joint line (mm).
pub const TREAD_HALF_MM: f64 = 10.0;
/// The top girth lies this far below the top point (mm).
pub const TOP_GIRTH_BELOW_MM: f64 = 10.0;
/// The toe's swing to the medial side: the forepart's midline over these fractions of the
/// stick length against the joint's, and the least swing that decides the side (mm).
pub const TOE_SWING: (f64, f64) = (0.80, 0.95);
pub const JOINT_MID: (f64, f64) = (0.60, 0.70);
pub const MIN_SWING_MM: f64 = 0.5;
/// A taut tape's plane is looked for within this tilt of the upright one (deg).
pub const TAPE_TILT_DEG: f64 = 60.0;
/// A triangle faces down (the bottom) when its normal's z is below minus this.
const DOWN_COS: f64 = 0.5;

/// The landmarks in the measuring frame (mm).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LastLandmarks {
    /// Back of the heel seat at the featherline, in the centre plane.
    pub heel_point: P3,
    /// The foremost point of the last.
    pub toe_point: P3,
    /// Front end of the bottom at the featherline, in the centre plane.
    pub toe_end: P3,
    /// Joint points on the featherline: inside (first metatarsal) and outside (fifth).
    pub mt1: P3,
    pub mt5: P3,
    /// Where the bottom touches the ground under the joint line.
    pub tread: P3,
    /// Top of the centre profile at `INSTEP_AT` of the stick length.
    pub instep: P3,
    /// The highest point of the centre profile (the top of the cone).
    pub top: P3,
    /// Where the short heel girth's plane leaves the top of the centre profile.
    pub short_heel_top: P3,
    /// The featherline points at the waist width's station, left and right.
    pub waist_left: P3,
    pub waist_right: P3,
}

impl LastLandmarks {
    /// The landmarks a last maker names, with their names (the picture's labels and the
    /// command's lines).
    pub fn named(&self) -> [(&'static str, P3); 8] {
        [
            ("heel point", self.heel_point),
            ("toe point", self.toe_point),
            ("toe end", self.toe_end),
            ("MT1", self.mt1),
            ("MT5", self.mt5),
            ("tread", self.tread),
            ("instep", self.instep),
            ("top", self.top),
        ]
    }
}

/// A last's measures (mm unless named otherwise).
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct LastMeasures {
    /// The file or name measured.
    pub source: String,
    pub side: Option<Side>,
    /// Heel point to toe point in plan (a size stick laid on the ground from one to the other).
    pub stick_length: f64,
    /// Along the bottom's centre line from the heel point to the toe end (a tape on it).
    pub bottom_length: f64,
    /// Height of the heel point above the ground.
    pub heel_height: f64,
    /// Height of the toe end above the ground.
    pub toe_spring: f64,
    /// MT1 to MT5 across the axis.
    pub joint_width: f64,
    /// The bottom's narrowest width (featherline to featherline) behind the joint.
    pub waist_width: f64,
    /// The bottom's width at `HEEL_SEAT_AT` of the stick length.
    pub heel_seat_width: f64,
    pub joint_girth: f64,
    pub waist_girth: f64,
    pub instep_girth: f64,
    pub long_heel_girth: f64,
    pub short_heel_girth: f64,
    pub top_girth: f64,
    /// MT1 and MT5 and the waist station along the axis, as fractions of the stick length.
    pub mt1_at: f64,
    pub mt5_at: f64,
    pub waist_at: f64,
    /// Height of the top point above the ground.
    pub top_height: f64,
    /// Pitch of the standing frame against the bottom's best-fit plane (deg, toe down +).
    pub pitch_deg: f64,
    pub landmarks: LastLandmarks,
    /// The plane each girth was taken in (measuring frame).
    pub girth_planes: Vec<GirthPlane>,
    /// The rigid map from the mesh as given (mm) to the measuring frame, row-major 4 x 4.
    pub frame: [[f64; 4]; 4],
    /// What the picture draws (not serialised).
    #[serde(skip)]
    pub figure: LastFigure,
}

/// A girth's plane: a point on it and its unit normal (measuring frame, mm).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GirthPlane {
    pub name: String,
    pub origin: P3,
    pub normal: V3,
}

/// The rigid map taking `from` onto `to` (the same vertices moved; least squares).
fn rigid_map(from: &[P3], to: &[P3]) -> [[f64; 4]; 4] {
    let n = from.len().max(1) as f64;
    let ca = from.iter().map(|p| p.coords).sum::<V3>() / n;
    let cb = to.iter().map(|p| p.coords).sum::<V3>() / n;
    let mut h = nalgebra::Matrix3::zeros();
    for (a, b) in from.iter().zip(to) {
        h += (a.coords - ca) * (b.coords - cb).transpose();
    }
    let svd = h.svd(true, true);
    let (u, vt) = (svd.u.expect("u"), svd.v_t.expect("v_t"));
    let mut d = nalgebra::Matrix3::identity();
    if (vt.transpose() * u.transpose()).determinant() < 0.0 {
        d[(2, 2)] = -1.0;
    }
    let r = vt.transpose() * d * u.transpose();
    let t = cb - r * ca;
    let mut out = [[0.0; 4]; 4];
    for i in 0..3 {
        for j in 0..3 {
            out[i][j] = r[(i, j)];
        }
        out[i][3] = t[i];
    }
    out[3][3] = 1.0;
    out
}

/// The curves behind the measures, in the measuring frame, for the picture.
#[derive(Clone, Debug, Default)]
pub struct LastFigure {
    /// Centre profile (section y = 0, through the heel point), closed.
    pub profile: Vec<P3>,
    /// Featherline points per station, left (+y) and right (-y).
    pub feather_left: Vec<P3>,
    pub feather_right: Vec<P3>,
    /// Plan outline of the whole last per station: most left and most right points.
    pub plan_left: Vec<P3>,
    pub plan_right: Vec<P3>,
    /// Girth loops (the tape's convex path), with their names.
    pub girths: Vec<(&'static str, Vec<P3>)>,
}

#[derive(Debug, thiserror::Error)]
pub enum MeasureError {
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Size(#[from] SizeError),
    #[error("last {input}: {why}")]
    Last { input: String, why: String },
}

/// Reads a last file (STL, OBJ, PLY; closed; `units` and `length_mm` as every last command
/// takes them), refuses it unless it has a last's size, and measures it.
pub fn measure_last_file(
    path: &Path,
    units: Units,
    length_mm: Option<f64>,
) -> Result<LastMeasures, MeasureError> {
    let (m, _) = TriMesh::load_solid(path, units, length_mm)?;
    check_last_size(path, &m)?;
    measure_last(m, &path.display().to_string())
}

/// Per-station supports of the section x = const.
#[derive(Clone, Copy)]
struct Station {
    x: f64,
    /// argmax (y - z), argmax (-y - z): the featherline corners (45 degrees).
    left: Option<P3>,
    right: Option<P3>,
    /// Lowest point and most left / right points of the section.
    low: Option<P3>,
    ymax: Option<P3>,
    ymin: Option<P3>,
}

fn better(cur: &mut Option<P3>, p: P3, score: impl Fn(&P3) -> f64) {
    if cur.is_none_or(|c| score(&p) > score(&c)) {
        *cur = Some(p);
    }
}

/// Every triangle cut by the planes x = x0 + k STEP_MM, each crossing point offered to its
/// station's supports (a section's support in a direction is one of its vertices, which lie
/// on the triangles' edges, so no loop need be built).
fn stations(m: &TriMesh, x0: f64, x1: f64) -> Vec<Station> {
    let n = ((x1 - x0) / STEP_MM).floor().max(0.0) as usize + 1;
    let mut st: Vec<Station> = (0..n)
        .map(|k| Station {
            x: x0 + k as f64 * STEP_MM,
            left: None,
            right: None,
            low: None,
            ymax: None,
            ymin: None,
        })
        .collect();
    for t in 0..m.triangles.len() {
        let v = m.corners(t);
        let lo = v.iter().map(|p| p.x).fold(f64::INFINITY, f64::min);
        let hi = v.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max);
        let k0 = ((lo - x0) / STEP_MM).ceil().max(0.0) as usize;
        let k1 = ((hi - x0) / STEP_MM).floor();
        if k1 < 0.0 {
            continue;
        }
        let k1 = (k1 as usize).min(n - 1);
        for s in st.iter_mut().take(k1 + 1).skip(k0) {
            let x = s.x;
            for e in 0..3 {
                let (p, q) = (v[e], v[(e + 1) % 3]);
                if (p.x - x) * (q.x - x) > 0.0 || p.x == q.x {
                    continue;
                }
                let c = p + (q - p) * ((x - p.x) / (q.x - p.x));
                better(&mut s.left, c, |r| r.y - r.z);
                better(&mut s.right, c, |r| -r.y - r.z);
                better(&mut s.low, c, |r| -r.z);
                better(&mut s.ymax, c, |r| r.y);
                better(&mut s.ymin, c, |r| -r.y);
            }
        }
    }
    st
}

/// The centre profile: the loop of the section y = `y` (through the heel point) with the
/// largest extent along x.
fn centre_profile(m: &TriMesh, y: f64) -> Option<Vec<P3>> {
    let plane = Plane::axis_aligned(1, y);
    m.section(&plane)
        .into_iter()
        .filter(|p| p.points.len() >= 3)
        .map(|p| p.points)
        .max_by(|a, b| extent_x(a).total_cmp(&extent_x(b)))
}

fn extent_x(l: &[P3]) -> f64 {
    let (lo, hi) = l.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |a, p| {
        (a.0.min(p.x), a.1.max(p.x))
    });
    hi - lo
}

fn argmax(l: &[P3], f: impl Fn(&P3) -> f64) -> usize {
    (0..l.len())
        .max_by(|&a, &b| f(&l[a]).total_cmp(&f(&l[b])))
        .unwrap_or(0)
}

/// Highest crossing of the closed loop `l` (in the xz plane) with the line x = `x`.
fn top_at(l: &[P3], x: f64) -> Option<P3> {
    let mut best: Option<P3> = None;
    for i in 0..l.len() {
        let (p, q) = (l[i], l[(i + 1) % l.len()]);
        if (p.x - x) * (q.x - x) > 0.0 || p.x == q.x {
            continue;
        }
        let c = p + (q - p) * ((x - p.x) / (q.x - p.x));
        better(&mut best, c, |r| r.z);
    }
    best
}

/// What one pass finds (in the current frame of the mesh).
struct Pass {
    profile: Vec<P3>,
    heel: P3,
    toe: P3,
    toe_end: P3,
    length: f64,
    st: Vec<Station>,
    left_joint: P3,
    right_joint: P3,
    left_medial: bool,
    joint_x: f64,
    slope: f64,
    /// Further slope to level so the forepart (negative) or the heel (positive) rests on
    /// the ground too.
    rock: f64,
    tread: P3,
}

fn pass(m: &TriMesh, input: &str) -> Result<Pass, MeasureError> {
    let err = |why: &str| MeasureError::Last {
        input: input.to_string(),
        why: why.to_string(),
    };
    // The heel point: the back of the heel seat at its featherline, the last's support
    // point backwards and down at 45 degrees (wherever it lies across).
    let heel = m.vertices[argmax(&m.vertices, |p| -p.x - p.z)];
    let profile =
        centre_profile(m, heel.y).ok_or_else(|| err("the centre plane misses the last"))?;
    let toe_end = profile[argmax(&profile, |p| p.x - p.z)];
    let toe = m.vertices[argmax(&m.vertices, |p| p.x)];
    // The size stick is laid from the heel point to the toe point: their distance in plan.
    let length = (toe.x - heel.x).hypot(toe.y - heel.y);
    if length <= 0.0 {
        return Err(err("the heel point is not behind the toe"));
    }
    let st = stations(m, heel.x, toe.x);
    let window = |a: f64, b: f64| {
        st.iter()
            .filter(move |s| s.x >= heel.x + a * length && s.x <= heel.x + b * length)
    };
    // The side first (the toe's swing), then each joint point as the widest featherline
    // point in its side's window of the trade's proportions.
    let mid = |a: f64, b: f64| {
        let v: Vec<f64> = st
            .iter()
            .filter(|s| s.x > heel.x + a * length && s.x < heel.x + b * length)
            .filter_map(|s| Some(0.5 * (s.left?.y + s.right?.y)))
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    let toe_swing = mid(TOE_SWING.0, TOE_SWING.1) - mid(JOINT_MID.0, JOINT_MID.1);
    let swing_medial = (toe_swing.abs() >= MIN_SWING_MM).then_some(toe_swing > 0.0);
    let (lw, rw) = match swing_medial {
        Some(true) => (MT1_WINDOW, MT5_WINDOW),
        Some(false) => (MT5_WINDOW, MT1_WINDOW),
        None => (JOINT_WINDOW, JOINT_WINDOW),
    };
    let left_joint = window(lw.0, lw.1)
        .filter_map(|s| s.left)
        .max_by(|a, b| a.y.total_cmp(&b.y))
        .ok_or_else(|| err("no featherline in the joint's window"))?;
    let right_joint = window(rw.0, rw.1)
        .filter_map(|s| s.right)
        .min_by(|a, b| a.y.total_cmp(&b.y))
        .ok_or_else(|| err("no featherline in the joint's window"))?;
    // Where the toe does not swing, the medial side's joint is the one further forward.
    let left_medial = swing_medial.unwrap_or(left_joint.x > right_joint.x);
    let joint_x = 0.5 * (left_joint.x + right_joint.x);
    // The ground's slope: the least-squares line through the lowest point of each station
    // within TANGENT_HALF_MM of the joint line (the bottom's tangent under the joint).
    let pts: Vec<(f64, f64)> = st
        .iter()
        .filter(|s| (s.x - joint_x).abs() <= TANGENT_HALF_MM)
        .filter_map(|s| s.low.map(|p| (p.x, p.z)))
        .collect();
    if pts.len() < 3 {
        return Err(err("too few stations under the joint line"));
    }
    let n = pts.len() as f64;
    let (mx, mz) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxz: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - mz)).sum();
    let slope = sxz / sxx;
    let tread = st
        .iter()
        .filter(|s| (s.x - joint_x).abs() <= TREAD_HALF_MM)
        .filter_map(|s| s.low)
        .min_by(|a, b| a.z.total_cmp(&b.z))
        .expect("stations under the joint line");
    // A forepart that dips below the tangent (no toe spring, a flat or hollow tread) rocks
    // the last forward until it rests on its tread and the forepart's lowest point.
    // A heel seat that dips below it rocks it back onto the heel.
    let rel = |q: P3| (q.z - tread.z) / (q.x - tread.x) - slope;
    let lows = || st.iter().filter_map(|s| s.low);
    let front = lows()
        .filter(|q| q.x > tread.x + TREAD_HALF_MM)
        .map(rel)
        .fold(0.0, f64::min);
    let back = lows()
        .filter(|q| q.x < tread.x - TREAD_HALF_MM)
        .map(rel)
        .fold(0.0, f64::max);
    let rock = if front < 0.0 { front } else { back };
    Ok(Pass {
        profile,
        heel,
        toe,
        toe_end,
        length,
        st,
        left_joint,
        right_joint,
        left_medial,
        joint_x,
        slope,
        rock,
        tread,
    })
}

/// Turns the mesh about the y axis through `pivot` so a line of slope `slope` (dz/dx)
/// becomes level.
fn pitch(m: &mut TriMesh, pivot: P3, slope: f64) {
    let a = slope.atan();
    let (c, s) = (a.cos(), a.sin());
    for p in &mut m.vertices {
        let (dx, dz) = (p.x - pivot.x, p.z - pivot.z);
        p.x = pivot.x + dx * c + dz * s;
        p.z = pivot.z - dx * s + dz * c;
    }
}

/// Girth: the perimeter of the convex hull of the section by `plane` (a tape's path).
fn girth(m: &TriMesh, plane: &Plane) -> (Vec<P3>, f64) {
    let loops: Vec<Vec<P3>> = m
        .section(plane)
        .into_iter()
        .filter(|p| p.points.len() >= 3)
        .map(|p| p.points)
        .collect();
    hull_loop(&loops, plane, f64::INFINITY)
}

/// The smallest of `f` over [a, b]: 24 samples, then golden-section search around the
/// best (a girth against a plane's tilt has one broad minimum). Returns the argument and
/// `f`'s value there.
fn shortest(a: f64, b: f64, f: impl Fn(f64) -> (Vec<P3>, f64)) -> (f64, Vec<P3>, f64) {
    let k = 24;
    let ts: Vec<f64> = (0..=k).map(|i| a + (b - a) * i as f64 / k as f64).collect();
    let gs: Vec<f64> = ts.iter().map(|&t| f(t).1).collect();
    let best = (0..=k)
        .min_by(|&i, &j| gs[i].total_cmp(&gs[j]))
        .unwrap_or(0);
    let (mut lo, mut hi) = (ts[best.saturating_sub(1)], ts[(best + 1).min(k)]);
    let phi = 0.5 * (5f64.sqrt() - 1.0);
    for _ in 0..30 {
        let (c, d) = (hi - phi * (hi - lo), lo + phi * (hi - lo));
        if f(c).1 <= f(d).1 {
            hi = d;
        } else {
            lo = c;
        }
    }
    let t = 0.5 * (lo + hi);
    let (lp, g) = f(t);
    if g <= gs[best] {
        (t, lp, g)
    } else {
        let (lp, g) = f(ts[best]);
        (ts[best], lp, g)
    }
}

/// Linear interpolation of the bottom width (left minus right featherline y) at x.
fn width_at(st: &[Station], x: f64) -> Option<f64> {
    let w = |s: &Station| Some(s.left?.y - s.right?.y);
    let k = st.iter().position(|s| s.x >= x)?;
    if k == 0 {
        return w(&st[0]);
    }
    let (a, b) = (&st[k - 1], &st[k]);
    let t = (x - a.x) / (b.x - a.x);
    Some(w(a)? + t * (w(b)? - w(a)?))
}

/// Measures a closed last mesh in millimetres (z roughly up in the file; any turn about z,
/// any position, either side): see the module documentation and docs/method.md 9.3.
pub fn measure_last(mut m: TriMesh, input: &str) -> Result<LastMeasures, MeasureError> {
    let err = |why: String| MeasureError::Last {
        input: input.to_string(),
        why,
    };
    let given = m.vertices.clone();
    orient_last(&mut m, DOWN_COS).map_err(err)?;
    // Stand the last on its tread: the bottom's tangent under the joint line level. The
    // joint line moves a little with the pitch, so a few passes.
    let mut pitch_rad = 0.0;
    for _ in 0..4 {
        let p = pass(&m, input)?;
        pitch(&mut m, p.tread, p.slope);
        pitch_rad += p.slope.atan();
    }
    let p = pass(&m, input)?;
    if p.rock != 0.0 {
        pitch(&mut m, p.tread, p.rock);
        pitch_rad += p.rock.atan();
    }
    let p = pass(&m, input)?;
    m.translate(&V3::new(-p.heel.x, -p.heel.y, -p.tread.z));
    let p = pass(&m, input)?;
    let l = p.length;
    let left_medial = p.left_medial;
    let (mt1, mt5) = if left_medial {
        (p.left_joint, p.right_joint)
    } else {
        (p.right_joint, p.left_joint)
    };
    // y is to the left: a right last's medial side is +y.
    let side = if left_medial { Side::Right } else { Side::Left };
    let waist_width = width_at(&p.st, WAIST_AT * l)
        .ok_or_else(|| err("no bottom at the waist station".into()))?;
    let ws =
        p.st.iter()
            .min_by(|a, b| {
                (a.x - WAIST_AT * l)
                    .abs()
                    .total_cmp(&(b.x - WAIST_AT * l).abs())
            })
            .copied()
            .expect("stations");
    let heel_seat_width = width_at(&p.st, HEEL_SEAT_AT * l)
        .ok_or_else(|| err("no bottom at the heel seat station".into()))?;
    // Bottom length: the profile's lower chain from the heel point to the toe end (the
    // chain through the profile's lowest point).
    let pr = &p.profile;
    let n = pr.len();
    let ih = argmax(pr, |q| -q.x - q.z);
    let it = argmax(pr, |q| q.x - q.z);
    let il = argmax(pr, |q| -q.z);
    let chain = |from: usize, to: usize| -> (f64, bool) {
        let (mut len, mut has_low, mut i) = (0.0, from == il, from);
        while i != to {
            let j = (i + 1) % n;
            len += (pr[j] - pr[i]).norm();
            has_low |= j == il;
            i = j;
        }
        (len, has_low)
    };
    let (a, a_low) = chain(ih, it);
    let (b, _) = chain(it, ih);
    let bottom_length = if a_low { a } else { b };
    let lower: Vec<P3> = {
        let (from, to) = if a_low { (ih, it) } else { (it, ih) };
        let mut v = vec![pr[from]];
        let mut i = from;
        while i != to {
            i = (i + 1) % n;
            v.push(pr[i]);
        }
        v
    };
    let instep = top_at(pr, INSTEP_AT * l)
        .ok_or_else(|| err("the centre profile has no top at the instep".into()))?;
    let top = pr[argmax(pr, |q| q.z)];
    let heel = p.heel;
    // Girths: a tape pulled tight round the last through the points that place it, the
    // shortest loop among the planes through them.
    let bad = |what: &str| err(format!("no plane for the {what} girth"));
    let tilt = TAPE_TILT_DEG.to_radians();
    let cut = |plane: Option<Plane>| match plane {
        Some(pl) => girth(&m, &pl),
        None => (Vec::new(), f64::INFINITY),
    };
    // Joint: planes through MT1 and MT5, tilted about the line through them.
    let u = (mt1 - mt5).normalize();
    let upright = u.cross(&V3::z());
    if upright.norm() < 1e-9 {
        return Err(bad("joint"));
    }
    let upright = upright.normalize();
    let joint_normal = |t: f64| {
        nalgebra::Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(u), t) * upright
    };
    let (t_joint, joint_loop, joint_girth) =
        shortest(-tilt, tilt, |t| cut(Plane::new(mt5, joint_normal(t))));
    // Waist and instep: planes through the top point, tilted about the line across (y).
    // A plane that misses the bottom's centre line is not round the last (near the top's
    // tangent plane it cuts a small cap off the top).
    let across = |q: P3| {
        let lower = &lower;
        let cut = &cut;
        move |t: f64| -> (Vec<P3>, f64) {
            let nrm = V3::new(t.cos(), 0.0, t.sin());
            let side = |r: &P3| (r - q).dot(&nrm);
            if !lower.windows(2).any(|w| side(&w[0]) * side(&w[1]) <= 0.0) {
                return (Vec::new(), f64::INFINITY);
            }
            cut(Plane::new(q, nrm))
        }
    };
    let waist_x = 0.5 * (p.joint_x + instep.x);
    let waist_top = top_at(pr, waist_x)
        .ok_or_else(|| err("the centre profile has no top at the waist girth".into()))?;
    let (t_waist, waist_loop, waist_girth) = shortest(-tilt, tilt, across(waist_top));
    let (t_instep, instep_loop, instep_girth) = shortest(-tilt, tilt, across(instep));
    let tilted = |t: f64| V3::new(t.cos(), 0.0, t.sin());
    let through_heel = |q: P3| Plane::new(heel, (q - heel).cross(&V3::y()));
    let (long_loop, long_heel_girth) =
        girth(&m, &through_heel(instep).ok_or_else(|| bad("long heel"))?);
    // Short heel girth: the shortest loop round the heel point over the top between the
    // instep point and the top point (planes containing y).
    let ang = |q: P3| (q.z - heel.z).atan2(q.x - heel.x);
    let (a0, a1) = (ang(instep), ang(top).max(ang(instep)));
    let (t_short, short_loop, short_heel_girth) = shortest(a0, a1, |t| {
        let d = V3::new(t.cos(), 0.0, t.sin());
        cut(Plane::new(heel, d.cross(&V3::y())))
    });
    let short_heel_top = short_loop
        .iter()
        .copied()
        .max_by(|a, b| (a - heel).norm().total_cmp(&(b - heel).norm()))
        .unwrap_or(top);
    let (top_loop, top_girth) = girth(&m, &Plane::axis_aligned(2, top.z - TOP_GIRTH_BELOW_MM));
    let gp = |name: &str, o: P3, nrm: V3| GirthPlane {
        name: name.to_string(),
        origin: o,
        normal: nrm.normalize(),
    };
    let girth_planes = vec![
        gp("joint", mt5, joint_normal(t_joint)),
        gp("waist", waist_top, tilted(t_waist)),
        gp("instep", instep, tilted(t_instep)),
        gp("long heel", heel, (instep - heel).cross(&V3::y())),
        gp(
            "short heel",
            heel,
            V3::new(t_short.cos(), 0.0, t_short.sin()).cross(&V3::y()),
        ),
        gp(
            "top",
            P3::new(top.x, 0.0, top.z - TOP_GIRTH_BELOW_MM),
            V3::z(),
        ),
    ];
    let fl = |f: fn(&Station) -> Option<P3>| -> Vec<P3> { p.st.iter().filter_map(f).collect() };
    let figure = LastFigure {
        profile: p.profile.clone(),
        feather_left: fl(|s| s.left),
        feather_right: fl(|s| s.right),
        plan_left: fl(|s| s.ymax),
        plan_right: fl(|s| s.ymin),
        girths: vec![
            ("joint", joint_loop),
            ("waist", waist_loop),
            ("instep", instep_loop),
            ("long heel", long_loop),
            ("short heel", short_loop),
            ("top", top_loop),
        ],
    };
    Ok(LastMeasures {
        source: input.to_string(),
        side: Some(side),
        stick_length: l,
        bottom_length,
        heel_height: heel.z,
        toe_spring: p.toe_end.z,
        joint_width: (mt1.y - mt5.y).abs(),
        waist_width,
        heel_seat_width,
        joint_girth,
        waist_girth,
        instep_girth,
        long_heel_girth,
        short_heel_girth,
        top_girth,
        mt1_at: mt1.x / l,
        mt5_at: mt5.x / l,
        waist_at: WAIST_AT,
        top_height: top.z,
        pitch_deg: pitch_rad.to_degrees(),
        landmarks: LastLandmarks {
            heel_point: heel,
            toe_point: p.toe,
            toe_end: p.toe_end,
            mt1,
            mt5,
            tread: p.tread,
            instep,
            top,
            short_heel_top,
            waist_left: ws.left.unwrap_or_default(),
            waist_right: ws.right.unwrap_or_default(),
        },
        girth_planes,
        frame: rigid_map(&given, &m.vertices),
        figure,
    })
}

impl LastMeasures {
    /// The measures as rows (name, value, unit) for a table.
    pub fn rows(&self) -> Vec<(&'static str, f64)> {
        vec![
            ("stick length", self.stick_length),
            ("bottom length", self.bottom_length),
            ("heel height", self.heel_height),
            ("toe spring", self.toe_spring),
            ("joint width", self.joint_width),
            ("waist width", self.waist_width),
            ("heel seat width", self.heel_seat_width),
            ("joint girth", self.joint_girth),
            ("waist girth", self.waist_girth),
            ("instep girth", self.instep_girth),
            ("long heel girth", self.long_heel_girth),
            ("short heel girth", self.short_heel_girth),
            ("top girth", self.top_girth),
            ("top height", self.top_height),
        ]
    }
}

const ORANGE: Colour = image::Rgb([230, 120, 0]);
const PURPLE: Colour = image::Rgb([130, 40, 170]);

/// The picture of a measured last: the side view (centre profile, featherlines, ground,
/// girth planes seen edge on) above the top view (plan outline, featherlines, girth lines),
/// landmarks dotted and labelled, the measures listed.
pub fn draw_measures(lm: &LastMeasures, path: &Path) -> std::io::Result<()> {
    let name = Path::new(&lm.source)
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| lm.source.clone());
    let f = &lm.figure;
    let (w, h) = (1500u32, 1100u32);
    let mut cv = Canvas::new(w, h, draw::WHITE);
    let all: Vec<&P3> = f
        .profile
        .iter()
        .chain(&f.plan_left)
        .chain(&f.plan_right)
        .collect();
    let xmin = all.iter().map(|p| p.x).fold(f64::INFINITY, f64::min) - 10.0;
    let xmax = all.iter().map(|p| p.x).fold(f64::NEG_INFINITY, f64::max) + 10.0;
    let zmax = f.profile.iter().map(|p| p.z).fold(0.0, f64::max) + 5.0;
    let ymin = f.plan_right.iter().map(|p| p.y).fold(0.0, f64::min) - 5.0;
    let ymax = f.plan_left.iter().map(|p| p.y).fold(0.0, f64::max) + 5.0;
    let panel_w = 1000.0;
    let side = View::fit([xmin, xmax, -8.0, zmax], 40.0, 560.0, panel_w, 500.0);
    let top = View::fit([xmin, xmax, ymin, ymax], 40.0, 1060.0, panel_w, 460.0);
    // Same scale in both views.
    let s = side.scale.min(top.scale);
    let side = View { scale: s, ..side };
    let top = View {
        scale: s,
        left: side.left,
        ..top
    };
    cv.text(40, 20, &format!("{name} - side view"), draw::BLACK, 2);
    cv.text(40, 590, "top view", draw::BLACK, 2);
    let xz = |p: &P3| (p.x, p.z);
    let xy = |p: &P3| (p.x, p.y);
    // Side view.
    cv.line(&side, (xmin, 0.0), (xmax, 0.0), draw::GREY, 1);
    let prof: Vec<(f64, f64)> = f.profile.iter().map(xz).collect();
    cv.polyline(&side, &prof, true, draw::BLACK, 2);
    for fl in [&f.feather_left, &f.feather_right] {
        let pts: Vec<(f64, f64)> = fl.iter().map(xz).collect();
        cv.polyline(&side, &pts, false, draw::BLUE, 1);
    }
    // Top view.
    for pl in [&f.plan_left, &f.plan_right] {
        let pts: Vec<(f64, f64)> = pl.iter().map(xy).collect();
        cv.polyline(&top, &pts, false, draw::GREY, 1);
    }
    for fl in [&f.feather_left, &f.feather_right] {
        let pts: Vec<(f64, f64)> = fl.iter().map(xy).collect();
        cv.polyline(&top, &pts, false, draw::BLUE, 2);
    }
    cv.line(&top, (xmin, 0.0), (xmax, 0.0), draw::GREY, 1);
    let colours = [
        draw::RED,
        ORANGE,
        draw::GREEN,
        PURPLE,
        image::Rgb([0, 150, 160]),
        image::Rgb([120, 80, 30]),
    ];
    for ((name, lp), c) in f.girths.iter().zip(colours) {
        if lp.is_empty() {
            continue;
        }
        let a: Vec<(f64, f64)> = lp.iter().map(xz).collect();
        cv.polyline(&side, &a, true, c, 2);
        let b: Vec<(f64, f64)> = lp.iter().map(xy).collect();
        cv.polyline(&top, &b, true, c, 1);
        // Label at the loop's highest point in the side view.
        let hi = lp.iter().max_by(|p, q| p.z.total_cmp(&q.z)).expect("loop");
        let (c0, r0) = side.px(hi.x, hi.z);
        cv.text(c0 as i64 - 20, r0 as i64 - 14, name, c, 1);
    }
    let l = &lm.landmarks;
    let marks = l.named().into_iter().chain([("waist", l.waist_left)]);
    for (name, q) in marks {
        for (v, pos) in [(&side, xz(&q)), (&top, xy(&q))] {
            cv.dot(v, pos, 4, draw::BLACK);
            let (c0, r0) = v.px(pos.0, pos.1);
            cv.text(c0 as i64 + 6, r0 as i64 + 4, name, draw::BLACK, 1);
        }
    }
    cv.dot(&top, xy(&l.waist_right), 4, draw::BLACK);
    // The measures, listed on the right.
    let x0 = 1080;
    let mut y = 60;
    let side_s = match lm.side {
        Some(Side::Left) => "left last",
        Some(Side::Right) => "right last",
        None => "side unknown",
    };
    cv.text(x0, y, side_s, draw::BLACK, 2);
    y += 30;
    for (name, v) in lm.rows() {
        cv.text(x0, y, &format!("{name:17}{v:8.1} mm"), draw::BLACK, 1);
        y += 16;
    }
    y += 10;
    for (name, v) in [
        ("MT1 at", lm.mt1_at),
        ("MT5 at", lm.mt5_at),
        ("waist at", lm.waist_at),
    ] {
        cv.text(
            x0,
            y,
            &format!("{name:17}{:8.1} % stick", 100.0 * v),
            draw::BLACK,
            1,
        );
        y += 16;
    }
    cv.text(
        x0,
        y + 10,
        &format!("pitch {:+.2} deg", lm.pitch_deg),
        draw::BLACK,
        1,
    );
    y += 50;
    cv.text(x0, y, "black: centre profile", draw::BLACK, 1);
    cv.text(x0, y + 16, "blue: featherline", draw::BLUE, 1);
    cv.text(x0, y + 32, "grey: ground / plan outline", draw::GREY, 1);
    cv.text(x0, y + 48, "colours: girths (tape path)", draw::RED, 1);
    cv.save_png(path)
}
