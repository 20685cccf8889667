//! A foot mesh read as it comes: whatever unit, axes and orientation a scanner wrote it in,
//! brought to millimetres, heel to toe along +x, up +z, triangles facing out, an open top cut
//! closed, or refused naming what is wrong.
//!
//! It lives here, beside `TriMesh::load_solid`, because both the last stages
//! (`footscan last customize --foot`) and the simulator's mesh scene (which depends on this
//! crate only) stand a foot up from a file. The rules (docs/method.md 10.1, "Reading a foot as
//! it comes"):
//!
//! - orientation: triangles are made consistent across every manifold edge (a walk over the
//!   surface turning any triangle that runs along a shared edge the same way as its
//!   neighbour); after the top is capped, a component of negative volume is turned as a whole;
//! - holes: each boundary loop at least 15 % of the foot's longest side across that lies
//!   within 3 % of it of one plane is capped flat (a fan from its centre); after the up direction is known, a capped loop must be at the top (its
//!   plane across the up direction, its centre in the upper half), else the mesh is refused
//!   naming where the hole is;
//! - up: of the candidate directions across the long axis (the signed file axes first, then
//!   the surface's principal directions), those where the foot would stand: its lower 40 %
//!   runs at least 80 % of the longest such footprint, and its top 30 % (the leg, or the
//!   instep without one) covers under 75 % of the footprint's length (lying on a side the top
//!   is a long wall, upside down the lower part is the leg). Of these, the one with the most
//!   sole: projected area facing within 30 degrees of down in the lowest tenth;
//! - heel to toe: the principal direction of the footprint; the heel end is the one under the
//!   leg when the foot is taller than a third of its length (the top's centre is behind the
//!   middle), else the narrower end (the ball is wider than the heel);
//! - units: millimetres, centimetres or metres as given, or from the heel-to-toe length in the
//!   file (a foot is 100-360 mm: 100-360 is mm, 10-36 cm, 0.10-0.36 m), or scaled to a given
//!   length; the result must be 100-360 mm long, 1.6 to 5 times as long as it is broad.

use super::{Defect, MeshError, TriMesh, Units};
use crate::{P3, V3};
use nalgebra::{Matrix3, Rotation3};
use std::collections::HashMap;
use std::path::Path;

/// Heel-to-toe length of a foot (mm).
pub const FOOT_LENGTH_MM: (f64, f64) = (100.0, 360.0);
/// Length over footprint breadth of a foot.
pub const FOOT_ELONGATION: (f64, f64) = (1.6, 5.0);
/// A boundary loop is a planar cut when it lies within this fraction of the longest side of
/// its best-fit plane.
pub const CUT_PLANARITY: f64 = 0.03;
/// A boundary loop is a cut through the leg or ankle only when it spans at least this
/// fraction of the longest side.
pub const CUT_MIN_SPAN: f64 = 0.15;

/// Heel-to-toe and up directions, given or to be found.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Axes {
    #[default]
    Auto,
    /// Unit file directions: heel to toe, and up.
    Given { forward: V3, up: V3 },
}

/// Why an `--axes` value is refused; each names the input and what is valid.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AxesError {
    #[error("{0:?} is not an axis; valid: x, y, z, -x, -y, -z")]
    Axis(String),
    #[error(
        "axes {0:?}: give \"auto\" or two axes, heel-to-toe then up, like \"y,z\" or \"-y,z\""
    )]
    Count(String),
    #[error("axes {0:?}: heel-to-toe and up must be different axes")]
    Parallel(String),
}

fn signed_axis(s: &str) -> Result<V3, AxesError> {
    let t = s.trim();
    let (sign, name) = match t.strip_prefix('-') {
        Some(r) => (-1.0, r),
        None => (1.0, t.strip_prefix('+').unwrap_or(t)),
    };
    let v = match name {
        "x" => V3::x(),
        "y" => V3::y(),
        "z" => V3::z(),
        _ => return Err(AxesError::Axis(s.to_string())),
    };
    Ok(v * sign)
}

impl std::str::FromStr for Axes {
    type Err = AxesError;
    /// "auto", or "F,U": the file axis running heel to toe and the one pointing up, each
    /// x, y or z with an optional sign ("y,z", "-y,z", "x,-y").
    fn from_str(s: &str) -> Result<Axes, AxesError> {
        if s.trim() == "auto" {
            return Ok(Axes::Auto);
        }
        let parts: Vec<&str> = s.split(',').collect();
        if parts.len() != 2 {
            return Err(AxesError::Count(s.to_string()));
        }
        let (forward, up) = (signed_axis(parts[0])?, signed_axis(parts[1])?);
        if forward.dot(&up).abs() > 0.5 {
            return Err(AxesError::Parallel(s.to_string()));
        }
        Ok(Axes::Given { forward, up })
    }
}

impl std::fmt::Display for Axes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Axes::Auto => write!(f, "auto"),
            Axes::Given { forward, up } => write!(f, "{},{}", axis_name(forward), axis_name(up)),
        }
    }
}

/// "+x", "-z", or the components of a direction off the file axes.
pub fn axis_name(v: &V3) -> String {
    for (n, a) in [("x", V3::x()), ("y", V3::y()), ("z", V3::z())] {
        let d = v.dot(&a);
        if (d.abs() - 1.0).abs() < 1e-9 {
            return format!("{}{n}", if d > 0.0 { "+" } else { "-" });
        }
    }
    format!("({:.3}, {:.3}, {:.3})", v.x, v.y, v.z)
}

/// How to read a foot.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct IntakeOptions {
    pub units: Units,
    /// Heel-to-toe length to scale to (mm); overrides `units`.
    pub length_mm: Option<f64>,
    pub axes: Axes,
}

/// A foot as read, and what was done to it.
#[derive(Debug, Clone)]
pub struct Intake {
    /// Millimetres, heel to toe along +x, up +z, lowest point at z = 0, heel end at x = 0,
    /// the footprint's middle at y = 0; closed, outward.
    pub mesh: TriMesh,
    /// File point (file units) -> intake point: `p' = scale * rot * p + shift`.
    pub rot: Rotation3<f64>,
    pub scale: f64,
    pub shift: V3,
    /// Heel-to-toe and up in the file.
    pub forward_in_file: V3,
    pub up_in_file: V3,
    /// Heel-to-toe extent (mm).
    pub length_mm: f64,
    /// Triangles turned to agree with their neighbours, components turned outward, loops
    /// capped.
    pub turned_locally: usize,
    pub turned_inside_out: bool,
    pub capped: usize,
    /// One line per thing decided or done, for the CLI.
    pub notes: Vec<String>,
}

impl Intake {
    /// An intake point (mm) back in the file's frame, in millimetres (file units times the
    /// unit scale).
    pub fn to_file_mm(&self, p: &P3) -> P3 {
        P3::from(self.rot.inverse() * (p.coords - self.shift))
    }
    /// An intake direction back in the file's frame.
    pub fn dir_to_file(&self, v: &V3) -> V3 {
        self.rot.inverse() * v
    }
}

fn not_a_foot(path: &Path, why: impl Into<String>) -> MeshError {
    MeshError::NotAFoot {
        path: path.to_path_buf(),
        why: why.into(),
    }
}

fn fmt_p(p: &P3) -> String {
    format!("({:.4}, {:.4}, {:.4})", p.x, p.y, p.z)
}

impl TriMesh {
    /// Reads a foot mesh as it comes (see the module documentation); errors name the file.
    pub fn read_foot(path: impl AsRef<Path>, opts: &IntakeOptions) -> Result<Intake, MeshError> {
        let path = path.as_ref();
        let m = TriMesh::read(path)?;
        intake(m, path, opts)
    }
}

/// [`TriMesh::read_foot`] on a mesh already read (`path` names it in errors and notes).
pub fn intake(mut m: TriMesh, path: &Path, opts: &IntakeOptions) -> Result<Intake, MeshError> {
    let invalid = |defect| MeshError::Invalid {
        path: path.to_path_buf(),
        defect,
    };
    let mut notes = Vec::new();
    if m.triangles.is_empty() {
        return Err(invalid(Defect::Empty));
    }
    let w = m.weld(0.0);
    if w.dropped_triangles > 0 {
        notes.push(format!(
            "dropped {} triangles with a repeated corner",
            w.dropped_triangles
        ));
    }
    let size = m.bbox().extent();
    let longest = size.max();
    if !(longest.is_finite() && longest > 0.0) {
        return Err(not_a_foot(path, format!("its size is {longest}")));
    }
    // 1. Orientation made consistent across shared edges.
    let turned_locally = orient_consistently(&mut m).map_err(&invalid)?;
    if turned_locally > 0 {
        notes.push(format!(
            "orientation: {turned_locally} triangles ran the wrong way round against their neighbours; turned"
        ));
    }
    // 2. Boundary loops: planar ones capped (checked to be at the top below).
    let loops = boundary_loops(&m).map_err(&invalid)?;
    let mut caps: Vec<(&CapInfo, bool)> = Vec::new();
    let infos: Vec<CapInfo> = loops.iter().map(|lp| loop_plane(&m, lp)).collect();
    // A loop large enough is a cut; a smaller one is part of a cut when it lies in the plane
    // of a large one, within its span (an island the cut left: a fold of the top).
    let tol = CUT_PLANARITY * longest;
    let is_cut = |c: &CapInfo| c.diameter >= CUT_MIN_SPAN * longest && c.max_dev <= tol;
    for (lp, info) in loops.iter().zip(infos.iter()) {
        let on_a_cut = infos.iter().any(|big| {
            is_cut(big)
                && (info.centre - big.centre).dot(&big.normal).abs() + info.max_dev <= tol
                && (info.centre - big.centre).norm() <= big.diameter
        });
        let island = info.diameter < CUT_MIN_SPAN * longest && on_a_cut;
        if info.diameter < CUT_MIN_SPAN * longest && !on_a_cut {
            return Err(MeshError::Hole {
                path: path.to_path_buf(),
                why: format!(
                    "the mesh is open: a hole of {} edges around {} (file units), {:.4} across, \
                     is not the top cut: too small (a cut through the leg or ankle is at least \
                     {:.0} % of the foot's {:.4} across); only a flat cut at the top is closed",
                    lp.len(),
                    fmt_p(&info.centre),
                    info.diameter,
                    CUT_MIN_SPAN * 100.0,
                    longest
                ),
            });
        }
        if info.max_dev > CUT_PLANARITY * longest {
            return Err(MeshError::Hole {
                path: path.to_path_buf(),
                why: format!(
                    "the mesh is open: a hole of {} edges around {} (file units), {:.4} across, \
                     is not the top cut: not planar (off its best plane by up to {:.4}, more than \
                     {:.0} % of the foot's {:.4}); only a flat cut at the top is closed",
                    lp.len(),
                    fmt_p(&info.centre),
                    info.diameter,
                    info.max_dev,
                    CUT_PLANARITY * 100.0,
                    longest
                ),
            });
        }
        // Where the loop touches itself it is capped piece by piece.
        let mut star = true;
        for part in simple_loops(lp) {
            let pi = loop_plane(&m, &part);
            star &= cap_loop(&mut m, &part, &pi);
        }
        if !island {
            caps.push((info, star));
        }
    }
    // 3. Each component outward.
    let mut turned_inside_out = false;
    {
        let (comp, n) = m.components();
        let c = m.bbox().center();
        let mut vol = vec![0.0; n];
        for (t, tri) in m.triangles.iter().enumerate() {
            let [a, b, d] = tri.map(|i| m.vertices[i as usize] - c);
            vol[comp[t] as usize] += a.dot(&b.cross(&d));
        }
        for (t, tri) in m.triangles.iter_mut().enumerate() {
            if vol[comp[t] as usize] < 0.0 {
                tri.swap(1, 2);
                turned_inside_out = true;
            }
        }
        if turned_inside_out {
            notes.push(
                "orientation: the triangles faced inward (negative volume); turned all".into(),
            );
        }
    }
    m.check().map_err(&invalid)?;
    // 4. Up and heel to toe.
    let (forward, up, how) = match opts.axes {
        Axes::Given { forward, up } => (forward, up, "given".to_string()),
        Axes::Auto => find_axes(&m, path)?,
    };
    // Capped loops must be at the top.
    let hs: Vec<f64> = m.vertices.iter().map(|p| p.coords.dot(&up)).collect();
    let (hmin, hmax) = hs
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &h| (a.min(h), b.max(h)));
    for (c, _) in &caps {
        let at_top = c.normal.dot(&up).abs() > 45f64.to_radians().cos()
            && c.centre.coords.dot(&up) > hmin + 0.5 * (hmax - hmin);
        if !at_top {
            return Err(MeshError::Hole {
                path: path.to_path_buf(),
                why: format!(
                    "the mesh is open: a hole around {} (file units), {:.4} across, is not the top \
                     cut: it is not at the top (up is {}); a foot may be open only where it was cut \
                     at the top",
                    fmt_p(&c.centre),
                    c.diameter,
                    axis_name(&up)
                ),
            });
        }
    }
    let capped = caps.len();
    for (c, star) in &caps {
        notes.push(format!(
            "closed the open top cut: a loop of {} edges, {:.4} across, at {} (file units), capped flat{}",
            c.edges,
            c.diameter,
            fmt_p(&c.centre),
            if *star {
                ""
            } else {
                " (the loop turns back on itself: the cap folds there)"
            }
        ));
    }
    // 5. Rotate: x heel to toe, z up, y = z x x.
    let ey = up.cross(&forward).normalize();
    let ex = ey.cross(&up).normalize();
    let rot = Rotation3::from_matrix_unchecked(Matrix3::from_rows(&[
        ex.transpose(),
        ey.transpose(),
        up.transpose(),
    ]));
    for p in &mut m.vertices {
        *p = rot * *p;
    }
    notes.push(format!(
        "heel to toe: {} in the file ({how})",
        axis_name(&ex)
    ));
    // 6. Units.
    let bb = m.bbox();
    let len_file = bb.max.x - bb.min.x;
    let (scale, unit_note) = scale_for(len_file, size, opts, path)?;
    notes.insert(0, unit_note);
    let mut shift = V3::zeros();
    if scale != 1.0 {
        for p in &mut m.vertices {
            p.coords *= scale;
        }
    }
    let bb = m.bbox();
    shift -= V3::new(bb.min.x, 0.5 * (bb.min.y + bb.max.y), bb.min.z);
    m.translate(&shift);
    let length_mm = bb.max.x - bb.min.x;
    if !(FOOT_LENGTH_MM.0..=FOOT_LENGTH_MM.1).contains(&length_mm) {
        return Err(not_a_foot(
            path,
            format!(
                "heel to toe it is {length_mm:.1} mm ({:.4} in the file, scaled by {scale}); a foot is {:.0} to {:.0} mm",
                len_file, FOOT_LENGTH_MM.0, FOOT_LENGTH_MM.1
            ),
        ));
    }
    m.check().map_err(&invalid)?;
    Ok(Intake {
        mesh: m,
        rot,
        scale,
        shift,
        forward_in_file: ex,
        up_in_file: up,
        length_mm,
        turned_locally,
        turned_inside_out,
        capped,
        notes,
    })
}

/// The scale to millimetres and a note saying why.
fn scale_for(
    len_file: f64,
    size: V3,
    opts: &IntakeOptions,
    path: &Path,
) -> Result<(f64, String), MeshError> {
    if let Some(l) = opts.length_mm {
        if !(l.is_finite() && l > 0.0) {
            return Err(MeshError::BadLength {
                path: path.to_path_buf(),
                length_mm: l,
            });
        }
        let s = l / len_file;
        return Ok((
            s,
            format!("units: scaled by {s:.6} to the given length {l} mm (heel to toe {len_file:.4} in the file)"),
        ));
    }
    let (lo, hi) = FOOT_LENGTH_MM;
    let given = |s: f64, name: &str| (s, format!("units: {name} (given), scaled by {s}"));
    Ok(match opts.units {
        Units::Mm => given(1.0, "millimetres"),
        Units::Cm => given(10.0, "centimetres"),
        Units::M => given(1000.0, "metres"),
        Units::Auto => {
            let found = [
                (1.0, "millimetres"),
                (10.0, "centimetres"),
                (1000.0, "metres"),
            ]
            .into_iter()
            .find(|(s, _)| (lo..=hi).contains(&(len_file * s)));
            match found {
                Some((s, name)) => (
                    s,
                    format!(
                        "units: {name}, from the size (heel to toe {len_file:.4} in the file; a foot is {lo:.0}-{hi:.0} mm), scaled by {s}"
                    ),
                ),
                None => {
                    return Err(MeshError::Unscaled {
                        path: path.to_path_buf(),
                        size,
                        hint: format!(
                            "heel to toe it is {len_file:.4}, a foot in none of mm ({lo:.0}-{hi:.0}), cm ({:.0}-{:.0}) or m ({:.2}-{:.2}); give its unit with --units or its length with --length MM",
                            lo / 10.0, hi / 10.0, lo / 1000.0, hi / 1000.0
                        ),
                    })
                }
            }
        }
    })
}

/// Makes triangle orientation agree across every edge shared by two triangles (a walk over
/// each component from its first triangle); returns how many were turned. A non-manifold
/// edge, or a surface that cannot be oriented (a Moebius strip), is refused.
pub fn orient_consistently(m: &mut TriMesh) -> Result<usize, Defect> {
    let nt = m.triangles.len();
    let mut edges: HashMap<(u32, u32), Vec<usize>> = HashMap::with_capacity(nt * 2);
    for (t, tri) in m.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    for (&(a, b), ts) in &edges {
        if ts.len() > 2 {
            return Err(Defect::NonManifoldEdge {
                a,
                b,
                pa: m.vertices[a as usize],
                pb: m.vertices[b as usize],
                triangles: ts.len(),
            });
        }
    }
    // Whether triangle t runs a -> b.
    let runs =
        |tri: &[u32; 3], a: u32, b: u32| (0..3).any(|k| tri[k] == a && tri[(k + 1) % 3] == b);
    let mut done = vec![false; nt];
    let mut turned = 0;
    let mut stack = Vec::new();
    for seed in 0..nt {
        if done[seed] {
            continue;
        }
        done[seed] = true;
        stack.push(seed);
        while let Some(t) = stack.pop() {
            let tri = m.triangles[t];
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                for &u in &edges[&(a.min(b), a.max(b))] {
                    if u == t {
                        continue;
                    }
                    let same = runs(&m.triangles[u], a, b);
                    if done[u] {
                        if same {
                            return Err(Defect::Misoriented {
                                a,
                                b,
                                pa: m.vertices[a as usize],
                                pb: m.vertices[b as usize],
                            });
                        }
                        continue;
                    }
                    if same {
                        m.triangles[u].swap(1, 2);
                        turned += 1;
                    }
                    done[u] = true;
                    stack.push(u);
                }
            }
        }
    }
    // Count the smaller side as turned: a walk from a wrong seed turns the right ones.
    Ok(turned.min(nt - turned))
}

/// Boundary loops (edges of one triangle), each as vertex ids in the direction its triangles
/// run along it, each edge used once (a loop that touches itself at a vertex passes it
/// twice: [`simple_loops`] splits it for capping).
fn boundary_loops(m: &TriMesh) -> Result<Vec<Vec<u32>>, Defect> {
    let mut count: HashMap<(u32, u32), u32> = HashMap::new();
    for tri in &m.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    let mut next: HashMap<u32, Vec<u32>> = HashMap::new();
    let mut edges: Vec<(u32, u32)> = Vec::new();
    for tri in &m.triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if count[&(a.min(b), a.max(b))] == 1 {
                next.entry(a).or_default().push(b);
                edges.push((a, b));
            }
        }
    }
    let open = |a: u32, b: u32| Defect::OpenEdge {
        a,
        b,
        pa: m.vertices[a as usize],
        pb: m.vertices[b as usize],
    };
    let mut loops = Vec::new();
    for (s, first) in edges {
        // Skip edges already walked.
        let Some(outs) = next.get_mut(&s) else {
            continue;
        };
        let Some(pos) = outs.iter().position(|&b| b == first) else {
            continue;
        };
        outs.swap_remove(pos);
        let mut lp = vec![s];
        let mut v = first;
        while v != s {
            lp.push(v);
            let Some(n) = next.get_mut(&v).and_then(|o| o.pop()) else {
                return Err(open(lp[lp.len() - 2], v));
            };
            v = n;
            if lp.len() > m.vertices.len() {
                return Err(open(s, first));
            }
        }
        loops.push(lp);
    }
    Ok(loops)
}

/// A loop that passes a vertex twice, split there into loops that pass each vertex once
/// (fewer than three vertices: dropped).
fn simple_loops(lp: &[u32]) -> Vec<Vec<u32>> {
    let mut out = Vec::new();
    let mut stack: Vec<u32> = Vec::with_capacity(lp.len());
    let mut at: HashMap<u32, usize> = HashMap::new();
    for &v in lp {
        if let Some(&j) = at.get(&v) {
            let sub: Vec<u32> = stack.drain(j..).collect();
            for w in &sub {
                at.remove(w);
            }
            if sub.len() >= 3 {
                out.push(sub);
            }
        }
        at.insert(v, stack.len());
        stack.push(v);
    }
    if stack.len() >= 3 {
        out.push(stack);
    }
    out
}

struct CapInfo {
    centre: P3,
    /// Unit normal of the loop's plane, by the cap's orientation (pointing out of the solid).
    normal: V3,
    diameter: f64,
    max_dev: f64,
    edges: usize,
}

fn loop_plane(m: &TriMesh, lp: &[u32]) -> CapInfo {
    let pts: Vec<P3> = lp.iter().map(|&i| m.vertices[i as usize]).collect();
    let c = pts.iter().fold(V3::zeros(), |s, p| s + p.coords) / pts.len() as f64;
    // Newell normal of the loop reversed (the cap runs against its neighbours).
    let mut n = V3::zeros();
    for i in 0..pts.len() {
        let (p, q) = (pts[i].coords - c, pts[(i + 1) % pts.len()].coords - c);
        n += q.cross(&p);
    }
    let n = n.try_normalize(0.0).unwrap_or_else(V3::z);
    let max_dev = pts
        .iter()
        .map(|p| (p.coords - c).dot(&n).abs())
        .fold(0.0, f64::max);
    let mut diameter: f64 = 0.0;
    for p in &pts {
        for q in &pts {
            diameter = diameter.max((p - q).norm());
        }
    }
    CapInfo {
        centre: P3::from(c),
        normal: n,
        diameter,
        max_dev,
        edges: lp.len(),
    }
}

/// Closes a loop by a fan from a new vertex at its centre (only new edges, so the result is
/// manifold however the loop runs). Returns whether every fan triangle faces the cap's way
/// (the loop is star-shaped about its centre, as a cut through a leg or ankle is); if not,
/// the cap folds over itself where the loop turns back.
fn cap_loop(m: &mut TriMesh, lp: &[u32], info: &CapInfo) -> bool {
    let rev: Vec<u32> = lp.iter().rev().copied().collect();
    let n = rev.len();
    let p = |i: u32| m.vertices[i as usize];
    let star = (0..n).all(|k| {
        let (a, b) = (p(rev[k]), p(rev[(k + 1) % n]));
        (a - info.centre)
            .cross(&(b - info.centre))
            .dot(&info.normal)
            > 0.0
    });
    m.vertices.push(info.centre);
    let c = (m.vertices.len() - 1) as u32;
    for k in 0..n {
        m.triangles.push([c, rev[k], rev[(k + 1) % n]]);
    }
    star
}

/// How a mesh would stand with `up` up: the sole's share of the surface (projected area
/// facing within 30 degrees of down, in the lowest tenth of the longest side), the footprint
/// (the lower 40 % of the height across up: its principal axis, length and breadth), the
/// height, and how far the centre of the top 30 % of the height lies from the footprint's
/// middle along its axis (fraction of its length: a leg stands over the heel end).
struct Stance {
    up: V3,
    sole: f64,
    height: f64,
    span: f64,
    breadth: f64,
    /// Footprint axis, toward the end the top leans over.
    axis: V3,
    /// Breadth of the rear and front 35 % of the footprint along `axis`.
    breadth_ends: (f64, f64),
    /// Length of the top 30 % along the footprint's axis (fraction of its length).
    top_spread: f64,
}

type Facet = (V3, f64, V3);

fn stance(m: &TriMesh, facets: &[Facet], total_area: f64, up: V3, longest: f64) -> Option<Stance> {
    let hs: Vec<f64> = m.vertices.iter().map(|p| p.coords.dot(&up)).collect();
    let (hmin, hmax) = hs
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), &h| (a.min(h), b.max(h)));
    let cos30 = 30f64.to_radians().cos();
    let sole = facets
        .iter()
        .filter(|(c, _, n)| n.dot(&up) < -cos30 && c.dot(&up) < hmin + 0.1 * longest)
        .map(|(_, a, n)| -a * n.dot(&up))
        .sum::<f64>()
        / total_area;
    let height = hmax - hmin;
    let a0 = if up.x.abs() < 0.9 { V3::x() } else { V3::y() };
    let e1 = (a0 - up * a0.dot(&up)).normalize();
    let e2 = up.cross(&e1);
    let low: Vec<[f64; 2]> = m
        .vertices
        .iter()
        .zip(&hs)
        .filter(|(_, &h)| h < hmin + 0.4 * height.max(0.12 * longest))
        .map(|(p, _)| [p.coords.dot(&e1), p.coords.dot(&e2)])
        .collect();
    if low.len() < 3 {
        return None;
    }
    let c = low
        .iter()
        .fold([0.0, 0.0], |s, p| [s[0] + p[0], s[1] + p[1]]);
    let c = [c[0] / low.len() as f64, c[1] / low.len() as f64];
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in &low {
        let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let ang = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (ca, sa) = (ang.cos(), ang.sin());
    let mut proj: Vec<(f64, f64)> = low
        .iter()
        .map(|p| {
            let (dx, dy) = (p[0] - c[0], p[1] - c[1]);
            (dx * ca + dy * sa, -dx * sa + dy * ca)
        })
        .collect();
    let mut axis = e1 * ca + e2 * sa;
    let centre = e1 * c[0] + e2 * c[1];
    let (mut smin, mut smax) = proj
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), q| (a.min(q.0), b.max(q.0)));
    let (tmin, tmax) = proj
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), q| (a.min(q.1), b.max(q.1)));
    let top: Vec<f64> = m
        .vertices
        .iter()
        .zip(&hs)
        .filter(|(_, &h)| h > hmin + 0.7 * height)
        .map(|(p, _)| (p.coords - centre).dot(&axis))
        .collect();
    let span = smax - smin;
    let top_spread =
        top.iter().fold(f64::MIN, |a, &b| a.max(b)) - top.iter().fold(f64::MAX, |a, &b| a.min(b));
    let top_spread = top_spread / span;
    let top_offset = if top.is_empty() {
        0.0
    } else {
        (top.iter().sum::<f64>() / top.len() as f64 - 0.5 * (smin + smax)) / span
    };
    if top_offset > 0.0 {
        // The axis runs from the end the top leans over.
        axis = -axis;
        for q in &mut proj {
            q.0 = -q.0;
        }
        (smin, smax) = (-smax, -smin);
    }
    let br = |a: f64, b: f64| {
        let (lo, hi) = proj
            .iter()
            .filter(|q| q.0 >= a && q.0 <= b)
            .fold((f64::MAX, f64::MIN), |(l, h), q| (l.min(q.1), h.max(q.1)));
        hi - lo
    };
    Some(Stance {
        up,
        sole,
        height,
        span,
        breadth: tmax - tmin,
        axis,
        breadth_ends: (br(smin, smin + 0.35 * span), br(smax - 0.35 * span, smax)),
        top_spread,
    })
}

/// Up and heel to toe of a closed, outward mesh (see the module documentation), with how
/// they were found.
fn find_axes(m: &TriMesh, path: &Path) -> Result<(V3, V3, String), MeshError> {
    // Area-weighted principal directions of the surface.
    let nt = m.triangles.len();
    let facets: Vec<Facet> = (0..nt)
        .map(|t| {
            let c = m.corners(t);
            let raw = m.face_normal_raw(t);
            let n = raw.try_normalize(0.0).unwrap_or_else(V3::zeros);
            (
                (c[0].coords + c[1].coords + c[2].coords) / 3.0,
                raw.norm() / 2.0,
                n,
            )
        })
        .collect();
    let tot: f64 = facets.iter().map(|f| f.1).sum();
    let mean = facets.iter().fold(V3::zeros(), |s, (c, a, _)| s + c * *a) / tot;
    let mut cov = Matrix3::zeros();
    for (c, a, _) in &facets {
        let d = c - mean;
        cov += d * d.transpose() * *a;
    }
    let eig = cov.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let long: V3 = eig.eigenvectors.column(order[0]).into_owned();
    let longest = m.bbox().extent().max();
    // Up is across the long axis: the signed file axes not along it (scanners write feet
    // with up along a file axis; a leg tilts the principal axis by up to 20 degrees), then
    // the other two principal directions for a foot turned off the file axes.
    let across = |u: &V3| u.dot(&long).abs() < 45f64.to_radians().cos();
    let mut candidates: Vec<(V3, bool)> = [V3::x(), V3::y(), V3::z()]
        .iter()
        .flat_map(|a| [*a, -a])
        .filter(across)
        .map(|u| (u, true))
        .collect();
    for &i in &order[1..] {
        let v: V3 = eig.eigenvectors.column(i).into_owned();
        candidates.push((v, false));
        candidates.push((-v, false));
    }
    let stances: Vec<(Stance, bool)> = candidates
        .iter()
        .filter_map(|(u, file)| Some((stance(m, &facets, tot, *u, longest)?, *file)))
        .collect();
    if stances.is_empty() {
        return Err(not_a_foot(path, "no footprint across any direction"));
    }
    // Standing on its sole, a foot's lower part is its whole length, and its top (the leg, or
    // the instep without one) a compact part of it; lying on a side, its top is a long wall;
    // upside down, its lower part is the leg or the instep only. Of the stances that look like
    // standing, the one with the most sole facing down.
    let max_span = stances.iter().map(|s| s.0.span).fold(0.0, f64::max);
    let standing = |s: &Stance| s.span >= STANDING_SPAN * max_span && s.top_spread < TOP_SPREAD;
    let best = |file: bool| {
        stances
            .iter()
            .filter(|(s, f)| *f == file && standing(s))
            .map(|(s, _)| s)
            .max_by(|a, b| a.sole.total_cmp(&b.sole))
    };
    let st = best(true).or_else(|| best(false));
    let (st, why) = match st {
        Some(s) => (
            s,
            format!(
                "its lower part runs its whole length and its top 30 % covers {:.0} % of it; the sole, facing {}, is {:.0} % of the surface",
                100.0 * s.top_spread,
                axis_name(&-s.up),
                100.0 * s.sole
            ),
        ),
        None => {
            let most_sole = |file: bool| {
                stances
                    .iter()
                    .filter(|(_, f)| *f == file)
                    .map(|(s, _)| s)
                    .max_by(|a, b| a.sole.total_cmp(&b.sole))
            };
            let s = most_sole(true).or_else(|| most_sole(false)).unwrap();
            (
                s,
                format!(
                    "no way up looks like standing; the largest sole, facing {} ({:.0} % of the surface): check it, or give --axes",
                    axis_name(&-s.up),
                    100.0 * s.sole
                ),
            )
        }
    };
    let elong = st.span / st.breadth.max(1e-300);
    if !(FOOT_ELONGATION.0..=FOOT_ELONGATION.1).contains(&elong) {
        return Err(not_a_foot(
            path,
            format!(
                "its footprint is {:.4} long and {:.4} broad (file units): {elong:.2} times as long as broad, where a foot is {:.1} to {:.1} times",
                st.span, st.breadth, FOOT_ELONGATION.0, FOOT_ELONGATION.1
            ),
        ));
    }
    // Heel end: under the leg, else the narrower end.
    let (fwd, rule) = if st.height > st.span / 3.0 {
        (st.axis, "heel end under the leg")
    } else if st.breadth_ends.0 <= st.breadth_ends.1 {
        (st.axis, "heel end the narrower")
    } else {
        (-st.axis, "heel end the narrower")
    };
    let how = format!(
        "found: up {} ({why}); heel to toe the footprint's principal axis, {rule}",
        axis_name(&st.up)
    );
    Ok((fwd, st.up, how))
}

/// Standing: the lower part's length is at least this fraction of the longest footprint's,
/// and the top 30 % covers less than `TOP_SPREAD` of it (on the real feet: 0.33-0.47 standing,
/// 0.79 and more lying on a side; the simulator's foot without a leg 0.69 standing, 0.88
/// and more on a side; docs/method.md 10.1).
const STANDING_SPAN: f64 = 0.8;
const TOP_SPREAD: f64 = 0.75;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_parse() {
        assert_eq!("auto".parse::<Axes>(), Ok(Axes::Auto));
        assert_eq!(
            "-y,z".parse::<Axes>(),
            Ok(Axes::Given {
                forward: -V3::y(),
                up: V3::z()
            })
        );
        assert!("y,y".parse::<Axes>().is_err());
        assert!("y".parse::<Axes>().is_err());
        assert!("q,z".parse::<Axes>().is_err());
        assert_eq!("x,-y".parse::<Axes>().unwrap().to_string(), "+x,-y");
    }

    #[test]
    fn pinched_loops_split() {
        assert_eq!(
            simple_loops(&[1, 2, 3, 4, 2, 5, 6]),
            vec![vec![2, 3, 4], vec![1, 2, 5, 6]]
        );
        assert_eq!(simple_loops(&[1, 2, 1, 3, 4]), vec![vec![1, 3, 4]]);
    }

    #[test]
    fn orientation_repaired_and_hole_capped() {
        let mut c = TriMesh::cuboid(P3::origin(), P3::new(2.0, 1.0, 1.0));
        c.triangles[3].swap(1, 2);
        c.triangles[7].swap(1, 2);
        assert_eq!(orient_consistently(&mut c).unwrap(), 2);
        assert!(c.check().is_ok() || matches!(c.check(), Err(Defect::InsideOut { .. })));
    }
}
