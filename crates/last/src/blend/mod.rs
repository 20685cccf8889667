//! Filling the gap between the back part of one last and the toe part of another with
//! planar slices that blend a linear morph with a discrete G1/G2 extension of both parts,
//! after "Gap Filling Using a Blend of Morphing and Extension with Application in Footwear
//! Design" (Li, Joneja). The second joining method beside the Gordon join of [`crate::join`]:
//! it takes the same lasts, placement and cutting planes, cuts and aligns its slices with
//! the join's section code, and is measured by the join's seam figures.
//!
//! Steps (docs/method.md section 12 says why each one is there):
//! 1. Both lasts placed in one frame and cut by planes parallel to the cut: slices every
//!    step d next to the gap (the last three feed the extension), coarser further in, all
//!    resampled to the same number of aligned points ([`crate::join::sections`]).
//! 2. From both ends in turn: one morphed slice (between the two current boundary slices)
//!    and one extended slice ([`extend`]) at half a step and at a whole step into the gap,
//!    mixed by the blending function b ([`weight`]); the new slices become the parts'
//!    boundary, until the two fronts meet in the middle.
//! 3. Or the blend chosen by fairing: b as a table searched greedily for the least
//!    curvature variation of the fill (or least curvature, for reference) ([`fair`]).
//! 4. Back part, fill and toe part each skinned through their own slices ([`surface`]);
//!    seam figures, IGES, STEP, a closed STL and pictures ([`output`]).

pub mod extend;
pub mod fair;
pub mod output;
pub mod surface;
pub mod weight;

use crate::join::sections::{self, Section};
use crate::join::{place, JoinError, Placement};
use fair::Functional;
use footscan_geom::mesh::TriMesh;
use footscan_geom::nurbs::{NurbsError, NurbsSurface};
use footscan_geom::plane::Plane;
use footscan_geom::{P3, V3};
use std::time::Instant;
use weight::Weight;

/// Why a fill failed; every variant names the plane, last or parameter at fault.
#[derive(Debug, thiserror::Error)]
pub enum BlendError {
    #[error(transparent)]
    Join(#[from] JoinError),
    #[error(
        "the back plane (normal {back}) and the toe plane (normal {toe}) are not parallel; \
         the gap is filled with slices parallel to one cut, so give planes with one normal"
    )]
    NotParallel { back: String, toe: String },
    #[error("invalid parameter {name} = {value}: {valid}")]
    Param {
        name: &'static str,
        value: String,
        valid: &'static str,
    },
    #[error(transparent)]
    Table(#[from] weight::TableError),
    #[error("surface construction failed")]
    Nurbs(#[from] NurbsError),
}

/// How the blending function is chosen.
#[derive(Debug, Clone, PartialEq)]
pub enum Blend {
    /// A given function b(t).
    Fixed(Weight),
    /// A table of b searched for the least curvature variation (`Variation`, the fairing
    /// of the method) or the least curvature (`Energy`, the reference).
    Fair(Functional),
}

impl Blend {
    /// The blend a command-line word names: `linear`, `poly`, `morph`, `extension`, `fair`
    /// (least curvature variation), `fair-energy` (least curvature, the reference) or
    /// `table:FILE` (a file of `t b` rows, [`Weight::read_table`]).
    pub fn from_arg(s: &str) -> Result<Blend, BlendError> {
        Ok(match s.trim() {
            "linear" => Blend::Fixed(Weight::Linear),
            "poly" => Blend::Fixed(Weight::Poly),
            "morph" => Blend::Fixed(Weight::Morph),
            "extension" => Blend::Fixed(Weight::Extension),
            "fair" => Blend::Fair(Functional::Variation),
            "fair-energy" => Blend::Fair(Functional::Energy),
            t => match t.strip_prefix("table:") {
                Some(f) if !f.is_empty() => Blend::Fixed(Weight::read_table(f.as_ref())?),
                _ => {
                    return Err(param_err(
                        "blend",
                        t,
                        "linear, poly, morph, extension, fair, fair-energy or table:FILE",
                    ))
                }
            },
        })
    }

    pub fn name(&self) -> String {
        match self {
            Blend::Fixed(w) => w.name(),
            Blend::Fair(Functional::Variation) => "fair".into(),
            Blend::Fair(Functional::Energy) => "fair-energy".into(),
        }
    }
}

/// How the slices become surfaces.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Skin {
    /// One cubic skin through every slice from heel to toe, split at the two boundary
    /// slices (as the Gordon join splits its one surface): the seams are interior to a C2
    /// surface, and what the fill's slices do at the seam shows as the kept parts' ends
    /// bending away from the original lasts (measured against them, [`crate::join::reference`]).
    #[default]
    One,
    /// Back part, fill and toe part each skinned through their own slices, cubic across with
    /// the end derivatives the chords to the neighbour slices: the seam figures then measure
    /// what the fill's slices carry across the seam (the morph's tangent break as the paper
    /// shows it), with no second-derivative condition.
    Pieces,
}

/// Parameters of a fill; `Default` takes the Gordon join's placement and planes.
#[derive(Debug, Clone)]
pub struct BlendParams {
    /// Back plane (normal towards the toe); default as the Gordon join: across the back
    /// last at 62 % of its length from the heel.
    pub back_plane: Option<Plane>,
    /// Toe plane, parallel to the back plane; default at 70 % of the toe last's length.
    pub toe_plane: Option<Plane>,
    /// Target slice step next to and in the gap, mm; the step used divides the gap into an
    /// even number of steps.
    pub step_mm: f64,
    /// Slice step further into the kept parts, mm.
    pub part_step_mm: f64,
    /// Points per slice.
    pub points: usize,
    /// Angle of the plane bundle that aligns the slices (crossings at common parameters).
    pub angle_deg: f64,
    pub sole_fraction: f64,
    /// Distance of the last slice from each part's end, mm.
    pub end_margin_mm: f64,
    pub placement_back: Placement,
    pub placement_toe: Placement,
    pub blend: Blend,
    /// Points per slice while the fairing searches (every k-th point).
    pub fair_points: usize,
    pub skin: Skin,
}

impl Default for BlendParams {
    fn default() -> Self {
        BlendParams {
            back_plane: None,
            toe_plane: None,
            step_mm: 2.0,
            part_step_mm: 2.5,
            points: 240,
            angle_deg: 45.0,
            sole_fraction: 0.05,
            end_margin_mm: 1.0,
            placement_back: Placement::Ball,
            placement_toe: Placement::Ball,
            blend: Blend::Fixed(Weight::Poly),
            fair_points: 60,
            skin: Skin::One,
        }
    }
}

/// Which piece a slice belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub enum Piece {
    Back,
    Fill,
    Toe,
}

/// One planar slice: its position along the cut normal (mm from the back plane) and points.
#[derive(Debug, Clone)]
pub struct Slice {
    pub z: f64,
    pub piece: Piece,
    pub points: Vec<P3>,
}

/// What the fairing found.
#[derive(Debug, Clone, serde::Serialize)]
pub struct FairReport {
    pub functional: String,
    /// The chosen b as (t, b) knots.
    pub table: Vec<(f64, f64)>,
    /// The functional on the slice grid for the chosen blend and for the morph alone (the
    /// search's start).
    pub cost: f64,
    pub cost_morph: f64,
    pub evaluations: usize,
}

/// Time spent in each step, ms.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct Timings {
    pub slices: f64,
    pub blend: f64,
    pub surfaces: f64,
    pub total: f64,
}

/// The filled last.
#[derive(Debug, Clone)]
pub struct Filled {
    /// Back part, fill, toe part: v from heel to toe on [0, 1] each, u periodic from the
    /// bottom centre line.
    pub back: NurbsSurface,
    pub fill: NurbsSurface,
    pub toe: NurbsSurface,
    /// Every slice from heel to toe; the fill's boundary slices belong to the parts.
    pub slices: Vec<Slice>,
    /// The common parameters of the slice points.
    pub u: Vec<f64>,
    /// The blend's name and its b at each fill slice: the slice's position across the gap,
    /// the position b was read at ([`step_position`], [`slice_position`]) and b.
    pub blend: String,
    pub weights: Vec<[f64; 3]>,
    pub fair: Option<FairReport>,
    /// Gap between the planes, the slice step used, and the index shift the morph's
    /// correspondence put on the toe slices.
    pub gap_mm: f64,
    pub step_mm: f64,
    pub morph_shift: usize,
    /// Points where the extension's closed forms broke (moved with their neighbours, see
    /// [`extend::extend`]; seams.json still names them `points_by_curve_extension`).
    pub by_curve: usize,
    pub back_plane: Plane,
    pub toe_plane: Plane,
    pub heel_end: P3,
    pub toe_end: P3,
    pub back_mesh: TriMesh,
    pub toe_mesh: TriMesh,
    pub timings: Timings,
}

fn param_err(name: &'static str, value: impl ToString, valid: &'static str) -> BlendError {
    BlendError::Param {
        name,
        value: value.to_string(),
        valid,
    }
}

fn check(p: &BlendParams) -> Result<(), BlendError> {
    if !(p.step_mm >= 0.25 && p.step_mm <= 10.0) {
        return Err(param_err("step", p.step_mm, "0.25 to 10 mm"));
    }
    if !(p.part_step_mm >= p.step_mm && p.part_step_mm <= 20.0) {
        return Err(param_err("part_step", p.part_step_mm, "the step to 20 mm"));
    }
    if !(24..=20000).contains(&p.points) {
        return Err(param_err(
            "points",
            p.points,
            "24 to 20000 points per slice",
        ));
    }
    if !(p.angle_deg >= 2.0 && p.angle_deg <= 90.0) {
        return Err(param_err("angle", p.angle_deg, "2 to 90 degrees"));
    }
    if p.fair_points < 12 {
        return Err(param_err("fair_points", p.fair_points, "12 or more"));
    }
    Ok(())
}

/// Offsets of one part's slices from its plane, going into the part: four slices a step
/// apart at the cut (the extension reads the last three), then `part_step` to the end,
/// finer just before it.
fn part_offsets(extent: f64, d: f64, p: &BlendParams) -> Vec<f64> {
    let end = extent - p.end_margin_mm;
    let mut o: Vec<f64> = (0..4).map(|k| k as f64 * d).collect();
    let mut x = 3.0 * d + p.part_step_mm;
    while x < end - 0.5 * p.part_step_mm {
        o.push(x);
        x += p.part_step_mm;
    }
    for f in [1.0, 0.5, 0.0] {
        let x = end - f * p.part_step_mm.min(4.0) * 0.5;
        if x > o.last().unwrap() + 0.25 {
            o.push(x);
        }
    }
    o
}

fn shifted(p: &Plane, d: f64) -> Plane {
    Plane {
        origin: p.origin + p.normal * d,
        ..*p
    }
}

fn describe_normal(n: &V3) -> String {
    format!("({:.4}, {:.4}, {:.4})", n.x, n.y, n.z)
}

/// The slices of a fill from z = 0 to z = gap (both boundary slices included), for each the
/// position t where b was read and the morph's weight b(t) it was built with (the boundary
/// slices are the parts' own: t = 0 and 1, b(0) and b(1) reported only), and how many points
/// came from curve extension.
#[derive(Debug, Clone)]
pub struct Fronts {
    pub slices: Vec<(f64, Vec<P3>)>,
    pub weights: Vec<(f64, f64)>,
    pub by_curve: usize,
}

/// Where across the gap the blending function is read for step `j` (0 at the boundary) of
/// `k` steps of a front: the first step at t = 0, the last at t = 1/2 (the middle), so the
/// first step is the discrete extension itself wherever b(0) = 0 (the slices R and S that
/// the paper builds for G1 and G2) and the last step is the morph wherever b(1/2) = 1.
pub fn step_position(j: usize, k: usize) -> f64 {
    if k <= 1 {
        0.0
    } else {
        0.5 * j as f64 / (k - 1) as f64
    }
}

/// Where across the gap b is read for slice `l` (1 = R of the first step, 2 = its S, ...,
/// 2k = the last S) of a front of `k` steps: 0 for both slices of the first step, then
/// evenly up to 1/2 at the last S.
pub fn slice_position(l: usize, k: usize) -> f64 {
    if k <= 1 {
        0.0
    } else {
        0.5 * l.saturating_sub(2) as f64 / (2 * k - 2) as f64
    }
}

/// The blended fill between the back part's slices (`back`: ..., O, P, Q towards the gap,
/// Q at z = 0, a step `d` apart) and the toe part's (`toe`: ..., O, P, Q towards the gap, Q at
/// z = `gap`), gap = 2 k d. Each front takes k steps of two slices (R at half a step, S at a
/// whole step past its current boundary), both b(t) morph + (1 - b(t)) extension, S with t
/// from [`step_position`] and R from [`slice_position`] (1 - t on the toe side); the fronts
/// meet in the middle, whose slice is the mean of the two sides' S.
pub fn blend_slices(
    back: [&[P3]; 3],
    toe: [&[P3]; 3],
    gap: f64,
    k: usize,
    b: &dyn Fn(f64) -> f64,
) -> Fronts {
    let d = gap / (2 * k) as f64;
    let (mut bo, mut bp, mut bq) = (back[0].to_vec(), back[1].to_vec(), back[2].to_vec());
    let (mut to, mut tp, mut tq) = (toe[0].to_vec(), toe[1].to_vec(), toe[2].to_vec());
    let (mut zb, mut zt) = (0.0, gap);
    let mut left = vec![(zb, (0.0, b(0.0)), bq.clone())];
    let mut right = vec![(zt, (1.0, b(1.0)), tq.clone())];
    let mut by_curve = 0;
    for it in 0..k {
        let mut eb = extend::extend(&bo, &bp, &bq, true);
        let mut et = extend::extend(&to, &tp, &tq, true);
        if it > 0 {
            // Past the first step R on the quadratic through P, Q and S: eq. 4's linear R
            // and the S built on it zig-zag from step to step ([`extend::extend`]).
            eb.r = eb.r_on_quadratic(&bp, &bq);
            et.r = et.r_on_quadratic(&tp, &tq);
        }
        by_curve += eb.by_curve + et.by_curve;
        let t = step_position(it, k);
        let (wb, wt) = (b(t), b(1.0 - t));
        // R reads b halfway between the previous step's S and this one's: read at the step's
        // t, R and S of a step shared b and the fill's slices went in pairs, a stripe every
        // slice where the morph and the extension lie apart (the RoundTip pair's toe side).
        let tr = slice_position(2 * it + 1, k);
        let (wbr, wtr) = (b(tr), b(1.0 - tr));
        let mixed = |z: f64, e: &[P3], w: f64| {
            let m = extend::morph(&bq, zb, &tq, zt, z);
            extend::mix(&m, e, w)
        };
        let (rb, sb) = (mixed(zb + 0.5 * d, &eb.r, wbr), mixed(zb + d, &eb.s, wb));
        let (rt, st) = (mixed(zt - 0.5 * d, &et.r, wtr), mixed(zt - d, &et.s, wt));
        left.push((zb + 0.5 * d, (tr, wbr), rb));
        right.push((zt - 0.5 * d, (1.0 - tr, wtr), rt));
        if it + 1 == k {
            // The fronts meet: the middle slice from both sides (t = 1/2 on both when k > 1).
            let mid = (0.5 * (t + 1.0 - t), 0.5 * (wb + wt));
            left.push((zb + d, mid, extend::mix(&sb, &st, 0.5)));
        } else {
            left.push((zb + d, (t, wb), sb.clone()));
            right.push((zt - d, (1.0 - t, wt), st.clone()));
            (bo, bp, bq) = (bp, bq, sb);
            (to, tp, tq) = (tp, tq, st);
            zb += d;
            zt -= d;
        }
    }
    right.reverse();
    left.extend(right);
    Fronts {
        weights: left.iter().map(|s| s.1).collect(),
        slices: left.into_iter().map(|s| (s.0, s.2)).collect(),
        by_curve,
    }
}

/// Knots of the fairing's blend table (t across the gap).
const FAIR_KNOTS: [f64; 7] = [0.0, 1.0 / 6.0, 1.0 / 3.0, 0.5, 2.0 / 3.0, 5.0 / 6.0, 1.0];

/// Fill the gap between the back part of `back` and the toe part of `toe`.
pub fn fill(back: &TriMesh, toe: &TriMesh, p: &BlendParams) -> Result<Filled, BlendError> {
    check(p)?;
    let t0 = Instant::now();
    let bm = place(back, &p.placement_back);
    let tm = place(toe, &p.placement_toe);
    let (bb, tb) = (bm.bbox(), tm.bbox());
    if bb.max.x <= tb.min.x || tb.max.x <= bb.min.x {
        return Err(JoinError::NoOverlap {
            back_lo: bb.min.x,
            back_hi: bb.max.x,
            toe_lo: tb.min.x,
            toe_hi: tb.max.x,
        }
        .into());
    }
    let default_plane = |b: &footscan_geom::bbox::Aabb, f: f64| {
        let x = b.min.x + f * b.extent().x;
        Plane::with_axis(P3::new(x, 0.5 * (b.min.y + b.max.y), 0.0), V3::x(), V3::y()).unwrap()
    };
    let back_plane = p.back_plane.unwrap_or_else(|| default_plane(&bb, 0.62));
    let toe_plane = p.toe_plane.unwrap_or_else(|| default_plane(&tb, 0.70));
    let n = back_plane.normal;
    if n.dot(&toe_plane.normal) < 1.0 - 1e-9 {
        return Err(BlendError::NotParallel {
            back: describe_normal(&n),
            toe: describe_normal(&toe_plane.normal),
        });
    }
    let gap = back_plane.signed_distance(&toe_plane.origin);
    if gap <= 0.0 {
        return Err(JoinError::PlanesOverlap {
            back: sections::describe_plane(&back_plane),
            toe: sections::describe_plane(&toe_plane),
            gap,
        }
        .into());
    }
    let k = ((gap / (2.0 * p.step_mm)).round() as usize).max(1);
    let d = gap / (2 * k) as f64;
    // Extents of the parts beyond their planes, and their end points.
    let far = |m: &TriMesh, pl: &Plane, sign: f64| {
        m.vertices
            .iter()
            .map(|v| (sign * pl.signed_distance(v), *v))
            .fold((f64::NEG_INFINITY, P3::origin()), |a, b| {
                if b.0 > a.0 {
                    b
                } else {
                    a
                }
            })
    };
    let (back_extent, heel_end) = far(&bm, &back_plane, -1.0);
    let (toe_extent, toe_end) = far(&tm, &toe_plane, 1.0);
    if back_extent <= 0.0 {
        return Err(JoinError::PlaneMisses {
            last: "back".into(),
            plane: sections::describe_plane(&back_plane),
        }
        .into());
    }
    if toe_extent <= 0.0 {
        return Err(JoinError::PlaneMisses {
            last: "toe".into(),
            plane: sections::describe_plane(&toe_plane),
        }
        .into());
    }
    let mut b_off = part_offsets(back_extent, d, p);
    b_off.reverse();
    let t_off = part_offsets(toe_extent, d, p);
    let nb = b_off.len();
    // The cutting planes first, so a plane cutting a last into several loops is named as given.
    sections::cut(&bm, &back_plane, 0.0, "back")?;
    sections::cut(&tm, &toe_plane, 0.0, "toe")?;
    let mut secs: Vec<Section> = Vec::with_capacity(nb + t_off.len());
    for &o in &b_off {
        secs.push(sections::cut(&bm, &shifted(&back_plane, -o), -o, "back")?);
    }
    for &o in &t_off {
        secs.push(sections::cut(&tm, &shifted(&toe_plane, o), o, "toe")?);
    }
    let zs: Vec<f64> = b_off
        .iter()
        .map(|o| -o)
        .chain(t_off.iter().map(|o| gap + o))
        .collect();
    let refs: Vec<&Section> = secs.iter().collect();
    let what = |s: usize| {
        if s < nb {
            format!(
                "of the back last at {:+.1} mm from the back plane",
                -b_off[s]
            )
        } else {
            format!(
                "of the toe last at {:+.1} mm from the toe plane",
                t_off[s - nb]
            )
        }
    };
    let cr = sections::crossings(&refs, p.angle_deg, p.sole_fraction, &what)?;
    let (u, _, mut pts) = sections::resample(&refs, &cr, p.points);
    // The morph's correspondence: the top of the back boundary slice and its nearest
    // neighbour on the toe boundary slice; the toe slices are renumbered by the shift.
    let up = secs[nb - 1].plane.v;
    let shift = extend::morph_shift(&pts[nb - 1], &pts[nb], &up);
    if shift != 0 {
        for s in pts.iter_mut().skip(nb) {
            s.rotate_left(shift);
        }
    }
    let t_slices = t0.elapsed();

    // The blend.
    let back3 = [&pts[nb - 3][..], &pts[nb - 2][..], &pts[nb - 1][..]];
    let toe3 = [&pts[nb + 2][..], &pts[nb + 1][..], &pts[nb][..]];
    let (table, fair_report): (Weight, Option<FairReport>) = match &p.blend {
        Blend::Fixed(w) => (w.clone(), None),
        Blend::Fair(f) => {
            let r = search(&pts, nb, gap, k, *f, p.fair_points);
            (Weight::Table(r.table.clone()), Some(r))
        }
    };
    let fronts = blend_slices(back3, toe3, gap, k, &|t| table.at(t));
    let by_curve = fronts.by_curve;
    let fill_slices = fronts.slices;
    let weights: Vec<[f64; 3]> = fill_slices
        .iter()
        .zip(&fronts.weights)
        .map(|((z, _), w)| [z / gap, w.0, w.1])
        .collect();
    let t_blend = t0.elapsed();

    // Every slice from heel to toe; the fill's boundary slices are the parts'.
    let mut slices: Vec<Slice> = Vec::new();
    for (s, pt) in pts.iter().enumerate().take(nb) {
        slices.push(Slice {
            z: zs[s],
            piece: Piece::Back,
            points: pt.clone(),
        });
    }
    let nf = fill_slices.len();
    for (z, pt) in &fill_slices[1..nf - 1] {
        slices.push(Slice {
            z: *z,
            piece: Piece::Fill,
            points: pt.clone(),
        });
    }
    for (s, pt) in pts.iter().enumerate().skip(nb) {
        slices.push(Slice {
            z: zs[s],
            piece: Piece::Toe,
            points: pt.clone(),
        });
    }
    let (back_s, fill_s, toe_s) = match p.skin {
        Skin::One => surface::skin_split(&slices, &u, 0.0, gap)?,
        Skin::Pieces => {
            let skin = |a: &[Vec<P3>], z: &[f64]| surface::skin_slices(a, &u, z);
            let fz: Vec<f64> = fill_slices.iter().map(|f| f.0).collect();
            let fp: Vec<Vec<P3>> = fill_slices.into_iter().map(|f| f.1).collect();
            (
                skin(&pts[..nb], &zs[..nb])?,
                skin(&fp, &fz)?,
                skin(&pts[nb..], &zs[nb..])?,
            )
        }
    };
    let t_surf = t0.elapsed();
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    Ok(Filled {
        back: back_s,
        fill: fill_s,
        toe: toe_s,
        slices,
        u,
        blend: p.blend.name(),
        weights,
        fair: fair_report,
        gap_mm: gap,
        step_mm: d,
        morph_shift: shift,
        by_curve,
        back_plane,
        toe_plane,
        heel_end,
        toe_end,
        back_mesh: bm,
        toe_mesh: tm,
        timings: Timings {
            slices: ms(t_slices),
            blend: ms(t_blend - t_slices),
            surfaces: ms(t_surf - t_blend),
            total: ms(t_surf),
        },
    })
}

/// What the fairing measures a blend on: the kept parts' last four slices either side of
/// the gap, every k-th point of them.
struct FairGrid {
    back: Vec<Vec<P3>>,
    toe: Vec<Vec<P3>>,
    gap: f64,
    k: usize,
}

impl FairGrid {
    fn new(pts: &[Vec<P3>], nb: usize, gap: f64, k: usize, fair_points: usize) -> FairGrid {
        let step = (pts[0].len() / fair_points).max(1);
        let sub = |s: &Vec<P3>| -> Vec<P3> { s.iter().step_by(step).copied().collect() };
        FairGrid {
            back: pts[nb - 4..nb].iter().map(sub).collect(),
            toe: pts[nb..nb + 4].iter().map(sub).collect(),
            gap,
            k,
        }
    }

    /// The functional over the fill built with `b` and three kept slices either side.
    fn cost(&self, b: &dyn Fn(f64) -> f64, f: Functional) -> f64 {
        let (bk, t) = (&self.back, &self.toe);
        let fs = blend_slices(
            [&bk[1], &bk[2], &bk[3]],
            [&t[2], &t[1], &t[0]],
            self.gap,
            self.k,
            b,
        );
        let mut grid: Vec<Vec<P3>> = bk[..3].to_vec();
        grid.extend(fs.slices.into_iter().map(|s| s.1));
        grid.extend(t[1..].iter().cloned());
        let nl = grid.len();
        fair::grid_functional(&grid, 2, nl - 3, f)
    }
}

/// The fairing: b as a table at [`FAIR_KNOTS`], searched greedily from the morph alone in
/// the gap (b = 1, as the fairing paper starts from the morphed mesh) for the least
/// functional over the fill and the kept parts' three slices either side, on every k-th
/// point of the slices. b stays 0 at both ends (t = 0 and 1): the first step of each front
/// is then the discrete G1/G2 extension, where the paper claims continuity with the parts;
/// the search shapes the rest of the gap.
fn search(
    pts: &[Vec<P3>],
    nb: usize,
    gap: f64,
    k: usize,
    f: Functional,
    fair_points: usize,
) -> FairReport {
    let g = FairGrid::new(pts, nb, gap, k, fair_points);
    let n = FAIR_KNOTS.len();
    let rows = |x: &[f64]| -> Vec<(f64, f64)> {
        FAIR_KNOTS
            .iter()
            .enumerate()
            .map(|(i, &t)| (t, if i == 0 || i == n - 1 { 0.0 } else { x[i - 1] }))
            .collect()
    };
    let cost = |x: &[f64]| {
        let r = rows(x);
        g.cost(&|tt| weight::table_at(&r, tt), f)
    };
    let start = vec![1.0; n - 2];
    let cost_morph = g.cost(&|_| 1.0, f);
    let (x, c, evals) = fair::greedy(start, 0.5, 1.0 / 64.0, &cost);
    FairReport {
        functional: match f {
            Functional::Variation => "curvature variation".into(),
            Functional::Energy => "curvature energy".into(),
        },
        table: rows(&x),
        cost: c,
        cost_morph,
        evaluations: evals + 1,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Slices of a tube along x whose elliptic section changes with x by `shape` (half axes
    /// across and up at x) with a bump of the bottom that the two parts place differently,
    /// so the morph and the extensions disagree in the gap.
    fn slices(zs: &[f64], shape: &dyn Fn(f64) -> (f64, f64, f64), n: usize) -> Vec<Vec<P3>> {
        zs.iter()
            .map(|&z| {
                let (a, c, bump) = shape(z);
                (0..n)
                    .map(|k| {
                        let th = std::f64::consts::TAU * k as f64 / n as f64;
                        let r = 1.0 + bump * (2.0 * th).cos().powi(2);
                        P3::new(z, a * th.sin() * r, -c * th.cos() * r)
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn fairing_picks_the_least_functional_among_the_blends() {
        let (gap, k, d, n) = (20.0, 5, 2.0, 48);
        let back_z: Vec<f64> = (0..4).map(|i| -3.0 * d + i as f64 * d).collect();
        let toe_z: Vec<f64> = (0..4).map(|i| gap + i as f64 * d).collect();
        let mut pts = slices(
            &back_z,
            &|z| (40.0 + 0.3 * z + 0.01 * z * z, 35.0 - 0.1 * z, 0.05),
            n,
        );
        pts.extend(slices(
            &toe_z,
            &|z| {
                let s = z - gap;
                (36.0 - 0.5 * s - 0.02 * s * s, 28.0 - 0.4 * s, 0.12)
            },
            n,
        ));
        let nb = 4;
        let grid = FairGrid::new(&pts, nb, gap, k, n);
        let candidates = [
            Weight::Morph,
            Weight::Extension,
            Weight::Linear,
            Weight::Poly,
            Weight::Table(vec![(0.0, 0.0), (0.5, 0.5), (1.0, 0.0)]),
        ];
        let mut chosen = Vec::new();
        for f in [Functional::Variation, Functional::Energy] {
            let r = search(&pts, nb, gap, k, f, n);
            // b stays 0 at the seams: the first step of each front is the extension.
            assert_eq!((r.table[0].1, r.table[r.table.len() - 1].1), (0.0, 0.0));
            let table = Weight::Table(r.table.clone());
            // The report's cost is the functional of the table it reports.
            let own = grid.cost(&|t| table.at(t), f);
            assert!(
                (own - r.cost).abs() <= 1e-9 * own.abs(),
                "{own} vs {}",
                r.cost
            );
            for w in &candidates {
                let c = grid.cost(&|t| w.at(t), f);
                println!("{f:?}: {} {c:.6e} (fair {:.6e})", w.name(), r.cost);
                assert!(
                    r.cost <= c * (1.0 + 1e-12),
                    "{f:?}: the fairing's {:.6e} is above {}'s {c:.6e}",
                    r.cost,
                    w.name()
                );
            }
            chosen.push(table);
        }
        // Each fairing beats the other on its own functional (or ties).
        let (var_t, en_t) = (&chosen[0], &chosen[1]);
        let v = |w: &Weight, f| grid.cost(&|t| w.at(t), f);
        assert!(v(var_t, Functional::Variation) <= v(en_t, Functional::Variation));
        assert!(v(en_t, Functional::Energy) <= v(var_t, Functional::Energy));
    }

    #[test]
    fn blend_words_of_the_command_line() {
        assert_eq!(
            Blend::from_arg("linear").unwrap(),
            Blend::Fixed(Weight::Linear)
        );
        assert_eq!(Blend::from_arg("poly").unwrap(), Blend::Fixed(Weight::Poly));
        assert_eq!(
            Blend::from_arg("fair").unwrap(),
            Blend::Fair(Functional::Variation)
        );
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("b.txt");
        std::fs::write(&f, "0 0\n0.5 0.9\n1 0\n").unwrap();
        assert_eq!(
            Blend::from_arg(&format!("table:{}", f.display())).unwrap(),
            Blend::Fixed(Weight::Table(vec![(0.0, 0.0), (0.5, 0.9), (1.0, 0.0)]))
        );
        std::fs::write(&f, "0 0\n0.5 0.9\n0.4 0\n").unwrap();
        let e = Blend::from_arg(&format!("table:{}", f.display()))
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("{}, line 3", f.display())), "{e}");
        for bad in ["cubic", "table:", "Linear"] {
            let e = Blend::from_arg(bad).unwrap_err().to_string();
            assert!(e.contains("table:FILE"), "{bad}: {e}");
        }
    }
}
