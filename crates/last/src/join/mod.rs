//! Joining the toe part of one last to the back part of another through a Gordon surface on
//! a curve network, after the last-joining method of "A new surface joining technique for
//! the design of shoe lasts" (Amorós-González, Jimeno-Morenilla, Salas-Pérez).
//!
//! Steps (docs/method.md section 11 says why each one is there):
//! 1. Place both lasts in one frame ([`Placement`]) and cut them by their planes: the main
//!    sections. Auxiliary sections follow every 5 mm into the kept parts, then the rest of
//!    each kept part is sectioned at a coarser step up to its end ([`sections`]).
//! 2. On every section, the crossings of a bundle of planes through its centroid (every
//!    `angle_deg` from the vertical) and four sole points beside its bottom corners; each
//!    section is resampled to `points` points with the same number between consecutive
//!    crossings, so the crossings sit at common parameters.
//! 3. Guide curves through the crossings from the heel end of the back part through the gap
//!    to the tip end of the toe part ([`guides`]).
//! 4. The Gordon surface of sections and guides ([`gordon`]); it is one C2 surface, split at
//!    the two main sections into the back part, the join patch and the toe part.
//! 5. Seam figures and deviation from the original meshes ([`seam`]), pictures ([`zebra`]),
//!    IGES, STEP, a closed STL and JSON ([`output`]).

pub mod compare;
pub mod error;
pub mod fit_cache;
pub mod gordon;
pub mod guides;
pub mod keep;
pub mod landmarks;
pub mod output;
pub mod reference;
pub mod seam;
pub mod sections;
pub mod study;
pub mod tessellation;
pub mod zebra;

pub use error::JoinError;
use footscan_geom::mesh::TriMesh;
use footscan_geom::nurbs::skin::interpolate_grid;
use footscan_geom::nurbs::NurbsSurface;
use footscan_geom::plane::Plane;
use footscan_geom::{P3, V3};
use sections::{describe_plane, Section};
use std::time::Instant;

/// How a last is brought into the common frame (x from heel to toe, z up, mm).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Placement {
    /// Already in the common frame.
    AsIs,
    /// Apply this transform (e.g. from the user's alignment).
    Transform(nalgebra::Affine3<f64>),
    /// The file's x axis runs along the last and z up (the heel end is found, and the last
    /// turned about z if the heel is at +x); it is moved so its heel point is at x = 0, the
    /// centre of its ball section (where the forepart is widest) at y = 0 and the bottom of
    /// that section at z = 0. Last makers superimpose lasts at the ball for a toe join.
    #[default]
    Ball,
}

/// Parameters of a join; `Default` gives the paper's settings (2 + 2 auxiliary sections,
/// 45 deg, 500 points per section).
#[derive(Debug, Clone)]
pub struct JoinParams {
    /// Back plane (normal towards the toe); default: across the last at 62 % of the back
    /// last's length from its heel point.
    pub back_plane: Option<Plane>,
    /// Toe plane (normal towards the toe); default: at 70 % of the toe last's length.
    pub toe_plane: Option<Plane>,
    pub aux_back: usize,
    pub aux_toe: usize,
    /// Points per section.
    pub points: usize,
    /// Rotation angle of the plane bundle, degrees.
    pub angle_deg: f64,
    /// Spacing of the auxiliary sections, mm (5 in the paper).
    pub aux_step_mm: f64,
    /// Spacing of the further sections of the kept parts, mm. The kept parts are resurfaced
    /// through their sections, so this sets their fit: 2.5 mm halves the deviation from the
    /// meshes of 5 mm (docs/method.md section 11) for about 5 ms more.
    pub part_step_mm: f64,
    /// Offset of the sole guides from the bottom corners along the section, as a fraction of
    /// the section height (0.05 in the paper).
    pub sole_fraction: f64,
    /// The last section of each kept part is this far from the part's end, mm; the end is
    /// closed by a fan to the end point in the STL.
    pub end_margin_mm: f64,
    pub placement_back: Placement,
    pub placement_toe: Placement,
    /// Also pass the guides through their crossings on mid sections halfway between the
    /// network sections of the kept parts (off by default: on the faceted real lasts those
    /// points zig-zag and the cubic guides then swing by millimetres across the gap).
    pub mid_guide_points: bool,
    /// Refit the kept parts to their meshes' facets ([`keep`]) and bend the patch to meet
    /// them ([`keep::Continuity`]). Off by default: the fitted parts are within 0.1 mm of
    /// their meshes on the fit's check grid (0.16-0.31 mm on a denser one) and the fits take
    /// 0.25-0.9 s per part in a release build, where the whole join takes tens of
    /// milliseconds (docs/method.md 11.7.3); [`JoinParams::fit_cache`] keeps them.
    pub fit_parts: bool,
    /// Continuity of the patch against the fitted parts.
    pub continuity: keep::Continuity,
    /// Where fitted kept parts are stored and looked up ([`fit_cache`]); `None` fits every
    /// time. The command line's default is [`fit_cache::default_dir`].
    pub fit_cache: Option<std::path::PathBuf>,
}

impl Default for JoinParams {
    fn default() -> Self {
        JoinParams {
            back_plane: None,
            toe_plane: None,
            aux_back: 2,
            aux_toe: 2,
            points: 500,
            angle_deg: 45.0,
            aux_step_mm: 5.0,
            part_step_mm: 2.5,
            sole_fraction: 0.05,
            end_margin_mm: 1.0,
            placement_back: Placement::Ball,
            placement_toe: Placement::Ball,
            mid_guide_points: false,
            fit_parts: false,
            continuity: keep::Continuity::G1,
            fit_cache: None,
        }
    }
}

/// Which part a network section belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    Back,
    Toe,
}

/// The joined last.
#[derive(Debug, Clone)]
pub struct Joined {
    /// Back part, join patch, toe part: v from heel to toe on [0, 1] each, u periodic
    /// counterclockwise about the toe direction from the bottom centre line.
    pub back: NurbsSurface,
    pub patch: NurbsSurface,
    pub toe: NurbsSurface,
    /// The whole Gordon surface (back part, patch and toe part in one).
    pub gordon: gordon::Gordon,
    pub network: gordon::Network,
    /// Part and offset (mm from its cut plane) of each network section.
    pub section_info: Vec<(Part, f64)>,
    /// Kinds of the guides, in u order.
    pub guide_kinds: Vec<sections::GuideKind>,
    /// v of the back and toe main sections on the whole surface.
    pub v_back_main: f64,
    pub v_toe_main: f64,
    /// End points that close the heel and toe ends (for the STL).
    pub heel_end: P3,
    pub toe_end: P3,
    pub back_plane: Plane,
    pub toe_plane: Plane,
    /// The two lasts as placed in the common frame.
    pub back_mesh: TriMesh,
    pub toe_mesh: TriMesh,
    /// How the kept parts were fitted to their meshes (back, toe); `None` when
    /// [`JoinParams::fit_parts`] is off.
    pub fits: Option<[keep::PartFit; 2]>,
    /// Time of each step, ms.
    pub timings: Timings,
}

/// Time spent in each step of a join, ms.
#[derive(Debug, Clone, Copy, Default, serde::Serialize)]
pub struct Timings {
    pub place: f64,
    pub sections: f64,
    pub curves: f64,
    pub gordon: f64,
    pub split: f64,
    /// Fitting the kept parts to their meshes in this run, or reading them from the fit
    /// cache ([`keep::PartFit::cached`]; the fit's own time is [`keep::PartFit::ms`]).
    pub fit_back: f64,
    pub fit_toe: f64,
    pub meet: f64,
    /// The join without the fits of the kept parts.
    pub join: f64,
    pub total: f64,
}

fn param_err(name: &'static str, value: impl ToString, valid: &'static str) -> JoinError {
    JoinError::Param {
        name,
        value: value.to_string(),
        valid,
    }
}

fn check_params(p: &JoinParams) -> Result<(), JoinError> {
    if !(p.angle_deg >= 2.0 && p.angle_deg <= 90.0) {
        return Err(param_err("angle", p.angle_deg, "2 to 90 degrees"));
    }
    if !(20..=20000).contains(&p.points) {
        return Err(param_err(
            "points",
            p.points,
            "20 to 20000 points per section",
        ));
    }
    if p.aux_back == 0 || p.aux_toe == 0 || p.aux_back > 20 || p.aux_toe > 20 {
        return Err(param_err(
            "aux",
            format!("{},{}", p.aux_back, p.aux_toe),
            "1 to 20 auxiliary sections on each side",
        ));
    }
    if !(p.aux_step_mm > 0.5 && p.part_step_mm > 0.5) {
        return Err(param_err(
            "step",
            p.aux_step_mm,
            "section steps over 0.5 mm",
        ));
    }
    if !(0.0..0.2).contains(&p.sole_fraction) || p.sole_fraction <= 0.0 {
        return Err(param_err("sole_fraction", p.sole_fraction, "0 to 0.2"));
    }
    Ok(())
}

/// Move a last into the common frame.
pub fn place(mesh: &TriMesh, how: &Placement) -> TriMesh {
    let mut m = mesh.clone();
    match how {
        Placement::AsIs => {}
        Placement::Transform(t) => m.transform_affine(t),
        Placement::Ball => {
            let b = m.bbox();
            let (x0, x1) = (b.min.x, b.max.x);
            let l = x1 - x0;
            let height_at = |m: &TriMesh, t: f64| {
                let x = x0 + t * l;
                let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
                for v in &m.vertices {
                    if (v.x - x).abs() < 0.03 * l {
                        lo = lo.min(v.z);
                        hi = hi.max(v.z);
                    }
                }
                hi - lo
            };
            if height_at(&m, 0.85) > height_at(&m, 0.15) {
                // Heel at +x: turn half a turn about z.
                let r = nalgebra::Rotation3::from_axis_angle(&V3::z_axis(), std::f64::consts::PI);
                m.transform(&nalgebra::Isometry3::from_parts(
                    nalgebra::Translation3::identity(),
                    r.into(),
                ));
            }
            let b = m.bbox();
            let (x0, l) = (b.min.x, b.extent().x);
            // Ball: the widest station of the forepart (55 to 85 % of the length).
            let mut best = (f64::NEG_INFINITY, 0.0, 0.0, 0.0);
            for s in 0..=30 {
                let x = x0 + l * (0.55 + 0.30 * s as f64 / 30.0);
                let (mut ylo, mut yhi, mut zlo) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
                for v in &m.vertices {
                    if (v.x - x).abs() < 0.01 * l {
                        ylo = ylo.min(v.y);
                        yhi = yhi.max(v.y);
                        zlo = zlo.min(v.z);
                    }
                }
                if yhi - ylo > best.0 {
                    best = (yhi - ylo, 0.5 * (ylo + yhi), zlo, x);
                }
            }
            m.translate(&V3::new(-x0, -best.1, -best.2));
        }
    }
    m
}

/// Offsets of the sections of one kept part from its cut plane, going into the part
/// (positive), the main section (0) first.
fn part_offsets(extent: f64, aux: usize, p: &JoinParams) -> Vec<f64> {
    let end = extent - p.end_margin_mm;
    let mut d: Vec<f64> = vec![0.0];
    for k in 1..=aux {
        let x = k as f64 * p.aux_step_mm;
        if x < end - 0.5 * p.aux_step_mm {
            d.push(x);
        }
    }
    let mut x = *d.last().unwrap() + p.part_step_mm;
    while x < end - 0.5 * p.part_step_mm {
        d.push(x);
        x += p.part_step_mm;
    }
    // Finer near the end, where the sections shrink fast: 4, 2, 1 and 0 mm before it whatever
    // the step (closer end sections made the toe tip overshoot by 0.8 mm at a 2.5 mm step).
    for f in [2.0, 1.0, 0.5, 0.0] {
        let x = end - f * 2.0;
        if x > d.last().unwrap() + 0.25 {
            d.push(x);
        }
    }
    d
}

/// Signed distances of a mesh's vertices from a plane: (min, max) and the extreme points.
fn extent_along(m: &TriMesh, plane: &Plane) -> (f64, f64, P3, P3) {
    let mut r = (f64::INFINITY, f64::NEG_INFINITY, P3::origin(), P3::origin());
    for v in &m.vertices {
        let d = plane.signed_distance(v);
        if d < r.0 {
            r.0 = d;
            r.2 = *v;
        }
        if d > r.1 {
            r.1 = d;
            r.3 = *v;
        }
    }
    r
}

fn shifted(p: &Plane, d: f64) -> Plane {
    Plane {
        origin: p.origin + p.normal * d,
        ..*p
    }
}

/// Join the toe part of `toe` to the back part of `back`.
pub fn join(back: &TriMesh, toe: &TriMesh, p: &JoinParams) -> Result<Joined, JoinError> {
    check_params(p)?;
    // The sections are spaced in millimetres along each last, so their number (and the
    // memory of the join) grows with its length: a last in millimetres read as metres grew a
    // join to 8.6 GB. Refused here too, for callers other than the CLI (which checks files).
    for (last, m) in [("back", back), ("toe", toe)] {
        let l = crate::size::last_length_mm(m);
        let (lo, hi) = crate::size::LAST_LENGTH_MM;
        if !(l.is_finite() && (lo..=hi).contains(&l)) {
            return Err(JoinError::NotALast { last, length_mm: l });
        }
    }
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
        });
    }
    let default_plane = |b: &footscan_geom::bbox::Aabb, f: f64| {
        let x = b.min.x + f * b.extent().x;
        Plane::with_axis(P3::new(x, 0.5 * (b.min.y + b.max.y), 0.0), V3::x(), V3::y()).unwrap()
    };
    let back_plane = p.back_plane.unwrap_or_else(|| default_plane(&bb, 0.62));
    let toe_plane = p.toe_plane.unwrap_or_else(|| default_plane(&tb, 0.70));
    let gap = back_plane.signed_distance(&toe_plane.origin);
    if gap <= 0.0 || back_plane.normal.dot(&toe_plane.normal) <= 0.0 {
        return Err(JoinError::PlanesOverlap {
            back: describe_plane(&back_plane),
            toe: describe_plane(&toe_plane),
            gap,
        });
    }
    let t_place = t0.elapsed();

    // Sections: back part from the heel end to its main section, then the toe part.
    let (b_lo, _, heel_end, _) = extent_along(&bm, &back_plane);
    let (_, t_hi, _, toe_end) = extent_along(&tm, &toe_plane);
    if b_lo >= 0.0 {
        return Err(JoinError::PlaneMisses {
            last: "back".into(),
            plane: describe_plane(&back_plane),
        });
    }
    if t_hi <= 0.0 {
        return Err(JoinError::PlaneMisses {
            last: "toe".into(),
            plane: describe_plane(&toe_plane),
        });
    }
    let mut back_off = part_offsets(-b_lo, p.aux_back, p);
    back_off.reverse();
    let toe_off = part_offsets(t_hi, p.aux_toe, p);
    // Network sections, then mid sections (guide data), in v order within each part.
    let mut specs: Vec<(Part, f64)> = back_off.iter().map(|&d| (Part::Back, -d)).collect();
    specs.extend(toe_off.iter().map(|&d| (Part::Toe, d)));
    let nnet = specs.len();
    let mut mids: Vec<(Part, f64, usize)> = Vec::new();
    for k in 0..nnet - 1 {
        let (a, b) = (specs[k], specs[k + 1]);
        if p.mid_guide_points && a.0 == b.0 {
            mids.push((a.0, 0.5 * (a.1 + b.1), k));
        }
    }
    let mut all: Vec<Section> = Vec::with_capacity(nnet + mids.len());
    let name = |part: Part, off: f64| {
        format!(
            "{} at {:+.1} mm from the {} plane",
            match part {
                Part::Back => "of the back last",
                Part::Toe => "of the toe last",
            },
            off,
            match part {
                Part::Back => "back",
                Part::Toe => "toe",
            }
        )
    };
    // The cutting planes themselves first, so a plane that cuts a last into several loops is
    // named as given rather than by the first section behind it that falls apart.
    sections::cut(&bm, &back_plane, 0.0, "back")?;
    sections::cut(&tm, &toe_plane, 0.0, "toe")?;
    for &(part, off) in specs
        .iter()
        .chain(mids.iter().map(|m| (m.0, m.1)).collect::<Vec<_>>().iter())
    {
        let (mesh, plane, last) = match part {
            Part::Back => (&bm, &back_plane, "back"),
            Part::Toe => (&tm, &toe_plane, "toe"),
        };
        all.push(sections::cut(mesh, &shifted(plane, off), off, last)?);
    }
    let info: Vec<(Part, f64)> = specs
        .iter()
        .copied()
        .chain(mids.iter().map(|m| (m.0, m.1)))
        .collect();
    let refs: Vec<&Section> = all.iter().collect();
    let what = |s: usize| name(info[s].0, info[s].1);
    let cr = sections::crossings(&refs, p.angle_deg, p.sole_fraction, &what)?;
    let net_idx: Vec<usize> = (0..nnet).collect();
    let cr_net = cr.select(&net_idx);
    let (u_params, cross_idx, pts) = sections::resample(&refs[..nnet], &cr_net, p.points);
    let t_sections = t0.elapsed();

    // Section curves: periodic cubic interpolation at the common parameters (one system for
    // all sections), taken back as exact iso-curves.
    let v_net = guides::section_params(&pts);
    let np = u_params.len();
    let mut grid = Vec::with_capacity(np * nnet);
    for j in 0..np {
        for s in &pts {
            grid.push(s[j]);
        }
    }
    let skin0 = interpolate_grid(&grid, &u_params, &v_net, 3, 3, true)?;
    let section_curves: Vec<_> = v_net.iter().map(|&v| gordon::iso_v(&skin0, v)).collect();
    // Guide data: network crossings and mid-section crossings at the halfway parameters.
    let m = cr.kinds.len();
    let mut gparams: Vec<(f64, Vec<P3>)> = (0..nnet)
        .map(|s| (v_net[s], cross_idx.iter().map(|&j| pts[s][j]).collect()))
        .collect();
    for (q, mid) in mids.iter().enumerate() {
        let s = nnet + q;
        let v = 0.5 * (v_net[mid.2] + v_net[mid.2 + 1]);
        gparams.push((v, sections::crossing_points(&all[s], &cr, s)));
    }
    gparams.sort_by(|a, b| a.0.total_cmp(&b.0));
    let gd = guides::GuideData {
        params: gparams.iter().map(|g| g.0).collect(),
        points: (0..m)
            .map(|i| gparams.iter().map(|g| g.1[i]).collect())
            .collect(),
    };
    let guide_curves = guides::guide_curves(&gd)?;
    let network = gordon::Network {
        sections: section_curves,
        u_cross: cross_idx.iter().map(|&j| u_params[j]).collect(),
        guides: guide_curves,
        v_cross: v_net.clone(),
    };
    let t_curves = t0.elapsed();
    let g = gordon::gordon(&network, 1e-6)?;
    let t_gordon = t0.elapsed();

    let i_bm = back_off.len() - 1;
    let (v_bm, v_tm) = (v_net[i_bm], v_net[i_bm + 1]);
    let (back_s, rest) = gordon::split_v(&g.surface, v_bm)?;
    let (patch, toe_s) = gordon::split_v(&rest, v_tm)?;
    let unit = |s: NurbsSurface| s.reparametrized((0.0, 1.0), (0.0, 1.0));
    let (mut back_s, mut patch, mut toe_s) = (unit(back_s), unit(patch), unit(toe_s));
    let t_split = t0.elapsed();
    let mut fits = None;
    let (mut fit_back, mut fit_toe) = (0.0, 0.0);
    if p.fit_parts {
        let deepest = |o: &[f64]| o.iter().copied().fold(0.0, f64::max);
        // Each fit, or its copy in the cache; the time is this run's (a cache hit's is the
        // reading), the fit's own time stays in its PartFit.
        let fit = |s0: &NurbsSurface, mesh: &TriMesh, plane: &Plane, side: f64, within: f64| {
            let t = Instant::now();
            let key = p.fit_cache.as_ref().map(|d| {
                let k = fit_cache::key(s0, mesh, plane, side, within, &keep::rules());
                (d, k)
            });
            if let Some((d, k)) = &key {
                if let Some((s, mut f)) = fit_cache::load(d, k) {
                    f.cached = true;
                    return Ok((s, f, t.elapsed().as_secs_f64() * 1e3));
                }
            }
            let (s, f) = keep::fit_part(s0, mesh, plane, side, within)?;
            if let Some((d, k)) = &key {
                // A cache that cannot be written only misses next time.
                let _ = fit_cache::store(d, k, &s, &f);
            }
            Ok::<_, JoinError>((s, f, t.elapsed().as_secs_f64() * 1e3))
        };
        let (b, fb, mb) = fit(&back_s, &bm, &back_plane, -1.0, deepest(&back_off))?;
        let (t, ft, mt) = fit(&toe_s, &tm, &toe_plane, 1.0, deepest(&toe_off))?;
        let (v0, v1) = g.surface.domain_v();
        patch = keep::meet(
            &patch,
            &b,
            &t,
            [v_bm - v0, v_tm - v_bm, v1 - v_tm],
            p.continuity,
        )?;
        (fit_back, fit_toe) = (mb, mt);
        (back_s, toe_s) = (b, t);
        fits = Some([fb, ft]);
    }
    let t_meet = t0.elapsed();
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    let timings = Timings {
        place: ms(t_place),
        sections: ms(t_sections - t_place),
        curves: ms(t_curves - t_sections),
        gordon: ms(t_gordon - t_curves),
        split: ms(t_split - t_gordon),
        fit_back,
        fit_toe,
        meet: ms(t_meet - t_split) - fit_back - fit_toe,
        join: ms(t_meet) - fit_back - fit_toe,
        total: ms(t_meet),
    };
    Ok(Joined {
        back: back_s,
        patch,
        toe: toe_s,
        gordon: g,
        network,
        section_info: specs,
        guide_kinds: cr.kinds.clone(),
        v_back_main: v_bm,
        v_toe_main: v_tm,
        heel_end,
        toe_end,
        back_plane,
        toe_plane,
        back_mesh: bm,
        toe_mesh: tm,
        fits,
        timings,
    })
}
