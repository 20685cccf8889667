//! Last bottom adjustment: a last's bottom made to fit a scanned foot sole.
//!
//! After the plantar scanner paper (end of its section 5), with the departures noted in
//! docs/method.md. Inputs are plain data, so the scanner converts a scan in a few lines:
//! a [`FootPlantar`] (the sole outline, toe pads, landmarks and height grid of a scan) and a
//! [`LastBottom`] (outline and heights of a last's bottom, from a bottom scan or from a last
//! mesh via [`last::prepare_last`]). [`adjust`] runs the steps; [`last::deform_last`] carries
//! the result into the whole last; [`output::write_outputs`] writes everything or nothing.
//!
//! Steps of [`adjust`]:
//! 1. Landmarks of the bottom by the rules of [`outline::outline_landmarks`]; a bottom of
//!    the other foot is mirrored.
//! 2. Rigid least-squares fit of the bottom's heel point, toe tip and ball points to the
//!    foot's (heel point, toe tip, first and fifth metatarsal heads).
//! 3. eps = (r_s + d)/r_s at the largest excursion d of the foot outline outside the bottom,
//!    measured along rays from the landmarks' centroid (the paper measures across the foot,
//!    y; along rays the rule is exact for any similar pair of outlines); the bottom is scaled
//!    by eps about that centroid.
//! 4. The landmarks are moved onto the foot's, and the outline pieces between them onto the
//!    foot's outline at equal arc-length fractions; the displacements along the outline are
//!    smoothed by Taubin's lambda/mu scheme with the landmarks pinned (the paper's neighbour
//!    mean of the positions shrinks a convex outline: the tests measure both); a thin-plate
//!    spline through these correspondences carries the bottom's interior along (smooth,
//!    exact at the points).
//! 5. Heights: zeta = (z_s + d_z)/z_s at the largest excursion d_z = z_f - z_s over the
//!    footprint; heights scaled by zeta; the arch point set to the foot's arch height, and
//!    the remaining difference to the plantar surface added as a correction field (filled
//!    in where the foot has no surface: between the toes, beyond the footprint); then the
//!    4-neighbour mean, landmark cells pinned.
//! 6. Deviation (bottom minus foot) before (rigid fit only) and after: heights over the
//!    footprint, outline, landmarks.

pub mod last;
pub mod outline;
pub mod output;
pub mod side;
pub mod surface;
pub mod synthetic;
pub mod tps;

pub use footscan_geom::HeightMap;
pub use outline::{outline_landmarks, OutlineLandmarks};
pub use side::Side;

use footscan_geom::{dist_by_hypot, P2, V2};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A scanned foot's landmarks (scan frame, mm), as the scanner's measurements give them.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FootLandmarks {
    pub heel_point: P2,
    pub toe_tip: P2,
    pub hallux: P2,
    pub mt1_head: P2,
    pub mt5_head: P2,
    pub waist_inner: P2,
    pub waist_outer: P2,
    pub arch_point: P2,
    pub arch_height_mm: f64,
}

/// A foot sole as the adjustment needs it: scan frame (x heel to toe, y across, z up from
/// the glass), millimetres. Mirrors the scanner's measurements (body outline, toe outlines,
/// landmarks) and its height map (NaN outside the footprint).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FootPlantar {
    /// What the foot came from (a scan directory), for error messages.
    pub source: String,
    pub side: Side,
    /// Body outline (toes excluded), closed.
    pub outline: Vec<P2>,
    /// Toe pad outlines, hallux first (may be empty).
    pub toe_outlines: Vec<Vec<P2>>,
    pub landmarks: FootLandmarks,
    pub heights: HeightMap,
}

/// A last's bottom: its outline and heights in its own frame (x heel to toe, z up from the
/// lowest bottom point), millimetres.
#[derive(Clone, Debug, PartialEq)]
pub struct LastBottom {
    /// What the bottom came from (a last file), for error messages.
    pub source: String,
    pub outline: Vec<P2>,
    pub heights: HeightMap,
}

/// Knobs of [`adjust`]; the defaults are what the tests and benches use.
#[derive(Clone, Copy, Debug)]
pub struct AdjustOptions {
    /// Cell of the adjusted height grid (mm).
    pub cell_mm: f64,
    /// Spacing of outline correspondences (mm).
    pub contour_spacing_mm: f64,
    /// Taubin smoothing of the target outline: iterations, lambda, mu.
    pub taubin: (usize, f64, f64),
    /// Passes of the 4-neighbour mean over the heights.
    pub smooth_passes: usize,
    /// A bottom shorter than this fraction of the foot is refused.
    pub min_length_ratio: f64,
    /// Node spacing of the tabulated thin-plate map (mm).
    pub table_step_mm: f64,
    /// Bottom heights below this are not used for zeta (the ratio is unstable near 0).
    pub zeta_min_height_mm: f64,
    /// zeta is measured this far inside the outline (mm).
    pub zeta_edge_mm: f64,
}

impl Default for AdjustOptions {
    fn default() -> Self {
        AdjustOptions {
            cell_mm: 0.5,
            contour_spacing_mm: 3.0,
            taubin: (4, 0.5, -0.53),
            smooth_passes: 2,
            min_length_ratio: 0.7,
            table_step_mm: 4.0,
            zeta_min_height_mm: 1.0,
            zeta_edge_mm: 3.0,
        }
    }
}

/// Why an adjustment could not be made; every variant names its input.
#[derive(Debug, thiserror::Error)]
pub enum AdjustError {
    #[error("foot {input}: {why}")]
    Foot { input: String, why: String },
    #[error("last {input}: {why}")]
    Last { input: String, why: String },
    #[error("last {}", path.display())]
    Mesh {
        path: PathBuf,
        #[source]
        source: Box<footscan_geom::mesh::MeshError>,
    },
    #[error(
        "last {input}: its bottom is {last_mm:.1} mm long, more than 30 % shorter than the foot \
         ({foot_mm:.1} mm); pass a last of the foot's size (or its real length with --length)"
    )]
    TooShort {
        input: String,
        last_mm: f64,
        foot_mm: f64,
    },
    #[error("{}: {why}", path.display())]
    Output { path: PathBuf, why: String },
}

/// An affine map of the plane, p -> A p + t (a similarity here, possibly mirrored).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Affine2 {
    pub a: [[f64; 2]; 2],
    pub t: V2,
}

impl Affine2 {
    pub fn identity() -> Affine2 {
        Affine2 {
            a: [[1.0, 0.0], [0.0, 1.0]],
            t: V2::zeros(),
        }
    }
    pub fn apply(&self, p: P2) -> P2 {
        P2::new(
            self.a[0][0] * p.x + self.a[0][1] * p.y + self.t.x,
            self.a[1][0] * p.x + self.a[1][1] * p.y + self.t.y,
        )
    }
    pub fn det(&self) -> f64 {
        self.a[0][0] * self.a[1][1] - self.a[0][1] * self.a[1][0]
    }
    pub fn inverse(&self) -> Affine2 {
        let d = self.det();
        let a = [
            [self.a[1][1] / d, -self.a[0][1] / d],
            [-self.a[1][0] / d, self.a[0][0] / d],
        ];
        let t = V2::new(
            -(a[0][0] * self.t.x + a[0][1] * self.t.y),
            -(a[1][0] * self.t.x + a[1][1] * self.t.y),
        );
        Affine2 { a, t }
    }
    /// `self` after `first`.
    pub fn after(&self, first: &Affine2) -> Affine2 {
        let m = |r: usize, c: usize| self.a[r][0] * first.a[0][c] + self.a[r][1] * first.a[1][c];
        Affine2 {
            a: [[m(0, 0), m(0, 1)], [m(1, 0), m(1, 1)]],
            t: self.apply(P2::from(first.t)).coords,
        }
    }
}

/// Deviation of a bottom from the foot (bottom minus foot, mm).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Deviation {
    /// Heights over the footprint cells the bottom covers.
    pub height_rms_mm: f64,
    pub height_max_mm: f64,
    /// Share of the footprint beyond 0.5 mm (uncovered cells count as beyond).
    pub share_beyond_0_5: f64,
    /// Share of the footprint the bottom does not cover.
    pub uncovered_share: f64,
    /// Bottom outline to foot outline distance.
    pub outline_rms_mm: f64,
    pub outline_max_mm: f64,
    /// Largest landmark distance (bottom's to foot's).
    pub landmark_max_mm: f64,
}

/// One landmark of the foot and where the bottom's matching landmark is before and after.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LandmarkPair {
    pub name: String,
    pub foot: P2,
    pub before: P2,
    pub after: P2,
}

/// The adjusted bottom and what it took.
#[derive(Clone, Debug)]
pub struct Adjustment {
    pub eps: f64,
    pub zeta: f64,
    /// Where the largest excursions were found (foot frame).
    pub eps_at: P2,
    pub zeta_at: P2,
    /// Whether the bottom was mirrored (a last of the other side).
    pub mirrored: bool,
    pub bottom_side: Side,
    /// Rigid fit: rotation (deg, counterclockwise) and translation of the bottom frame.
    pub rotation_deg: f64,
    pub shift: V2,
    /// Landmarks' centroid, the centre of the eps scaling.
    pub centre: P2,
    /// Bottom frame -> foot frame: the rigid fit, and the rigid fit then eps.
    pub rigid: Affine2,
    pub to_foot: Affine2,
    /// The thin-plate map from the scaled bottom to the adjusted one.
    pub forward: tps::Tps,
    /// Adjusted heights over the working rectangle (continued beyond the outline).
    pub heights: HeightMap,
    /// Cells inside the adjusted outline.
    pub inside: Vec<bool>,
    pub outline: Vec<P2>,
    /// The foot's sole outline (body and toe pads).
    pub foot_outline: Vec<P2>,
    pub bottom_outline_before: Vec<P2>,
    pub landmarks: Vec<LandmarkPair>,
    pub before: Deviation,
    pub after: Deviation,
    /// Signed deviation maps (bottom minus foot) on the working grid, NaN off the footprint.
    pub before_map: HeightMap,
    pub after_map: HeightMap,
    /// Correspondences used (after smoothing of the targets).
    pub correspondences: usize,
    pub notes: Vec<String>,
}

fn finite(p: P2) -> bool {
    p.x.is_finite() && p.y.is_finite()
}

fn check_foot(foot: &FootPlantar) -> Result<(), AdjustError> {
    let bad = |why: String| AdjustError::Foot {
        input: foot.source.clone(),
        why,
    };
    if foot.outline.len() < 8 {
        return Err(bad(format!(
            "no measurements: the sole outline has {} points (a measured foot has hundreds); run the measurement first",
            foot.outline.len()
        )));
    }
    let l = &foot.landmarks;
    for (name, p) in [
        ("heel point", l.heel_point),
        ("toe tip", l.toe_tip),
        ("MT1 head", l.mt1_head),
        ("MT5 head", l.mt5_head),
        ("inner waist", l.waist_inner),
        ("outer waist", l.waist_outer),
        ("arch point", l.arch_point),
    ] {
        if !finite(p) {
            return Err(bad(format!(
                "no measurements: the {name} is missing (not finite)"
            )));
        }
    }
    if !l.arch_height_mm.is_finite() {
        return Err(bad("no measurements: the arch height is missing".into()));
    }
    if dist_by_hypot(&l.heel_point, &l.toe_tip) < 50.0 {
        return Err(bad(format!(
            "heel point and toe tip are {:.1} mm apart; a foot is 50 mm long at least",
            dist_by_hypot(&l.heel_point, &l.toe_tip)
        )));
    }
    let g = &foot.heights;
    if g.nx < 2 || g.ny < 2 || g.z.len() != g.nx * g.ny || g.cell_mm.is_nan() || g.cell_mm <= 0.0 {
        return Err(bad(format!(
            "height grid {} x {} with {} values and cell {} mm is malformed",
            g.nx,
            g.ny,
            g.z.len(),
            g.cell_mm
        )));
    }
    if g.valid_count() == 0 {
        return Err(bad(
            "the height grid has no valid cell: no plantar surface".into()
        ));
    }
    Ok(())
}

/// Rigid 2D least squares: the rotation and translation taking `p[k]` nearest `q[k]`.
pub fn rigid_fit(p: &[P2], q: &[P2]) -> Affine2 {
    let n = p.len() as f64;
    let pc = P2::from(p.iter().fold(V2::zeros(), |a, b| a + b.coords) * (1.0 / n));
    let qc = P2::from(q.iter().fold(V2::zeros(), |a, b| a + b.coords) * (1.0 / n));
    let (mut sc, mut ss) = (0.0, 0.0);
    for (a, b) in p.iter().zip(q) {
        let (a, b) = (a - pc, b - qc);
        sc += a.dot(&b);
        ss += a.perp(&b);
    }
    let th = ss.atan2(sc);
    let (c, s) = (th.cos(), th.sin());
    let a = [[c, -s], [s, c]];
    let r = Affine2 { a, t: V2::zeros() };
    Affine2 {
        a,
        t: qc - r.apply(pc),
    }
}

/// Adjusts `bottom` to `foot` (see the module documentation for the steps).
// Several grids of the same shape are walked together by cell index.
#[allow(clippy::needless_range_loop)]
pub fn adjust(
    foot: &FootPlantar,
    bottom: &LastBottom,
    opts: &AdjustOptions,
) -> Result<Adjustment, AdjustError> {
    check_foot(foot)?;
    if bottom.outline.len() < 8 || bottom.heights.valid_count() == 0 {
        return Err(last_err(
            bottom,
            format!(
                "the bottom has {} outline points and {} height cells; no bottom to adjust",
                bottom.outline.len(),
                bottom.heights.valid_count()
            ),
        ));
    }
    let mut notes = Vec::new();
    let sole = Sole::of(foot, &mut notes);
    let plan = BottomPlan::of(bottom, foot, sole.length, opts, &mut notes)?;
    // Steps 2 and 3 on the foot outline resampled (also the working grid's extent).
    let f_rs = outline::resample_closed(&sole.outline, 512);
    let placed = Placement::of(&plan, &sole, &f_rs);
    let to_plan = placed.scale_m.after(&placed.rigid_m);
    let scaled: Vec<P2> = plan.outline.iter().map(|&p| to_plan.apply(p)).collect();
    let scaled_lm: Vec<P2> = plan.landmarks.iter().map(|&p| to_plan.apply(p)).collect();
    let warp = Warp::fit(&scaled, &scaled_lm, &sole, opts, bottom)?;
    let grid = Grid::sample(foot, bottom, &f_rs, opts, &placed, &scaled, &warp);
    let (zeta, zeta_at, heights) =
        fit_heights(&grid, foot, &sole, opts, placed.centre, bottom, &mut notes)?;
    let dev = Deviations::of(&grid, &heights, &sole, &plan, &placed, &warp, &scaled_lm);
    let rigid_m = placed.rigid_m;
    Ok(Adjustment {
        eps: placed.eps,
        zeta,
        eps_at: placed.eps_at,
        zeta_at,
        mirrored: plan.mirrored,
        bottom_side: plan.side_before,
        rotation_deg: rigid_m.a[1][0].atan2(rigid_m.a[0][0]).to_degrees(),
        shift: rigid_m.t,
        centre: placed.centre,
        rigid: placed.rigid,
        to_foot: placed.to_foot,
        forward: warp.fwd,
        heights,
        inside: grid.inside,
        outline: grid.adj_outline,
        foot_outline: sole.outline,
        bottom_outline_before: placed.aligned,
        landmarks: dev.landmarks,
        before: dev.before,
        after: dev.after,
        before_map: dev.before_map,
        after_map: dev.after_map,
        correspondences: warp.correspondences,
        notes,
    })
}

fn last_err(bottom: &LastBottom, why: String) -> AdjustError {
    AdjustError::Last {
        input: bottom.source.clone(),
        why,
    }
}

/// The foot's side of the fit: its sole outline (body and toe pads) and six landmarks
/// (heel point, toe tip, MT1 and MT5 heads, inner and outer waist) as measured and moved
/// onto that outline.
struct Sole {
    outline: Vec<P2>,
    raw: [P2; 6],
    on: Vec<P2>,
    /// Heel point to toe tip along the foot's axis (mm).
    length: f64,
}

impl Sole {
    fn of(foot: &FootPlantar, notes: &mut Vec<String>) -> Sole {
        let fl = &foot.landmarks;
        let axis_f =
            (fl.toe_tip - fl.heel_point) * (1.0 / dist_by_hypot(&fl.toe_tip, &fl.heel_point));
        let cut = if fl.mt1_head.coords.dot(&axis_f) < fl.mt5_head.coords.dot(&axis_f) {
            fl.mt1_head
        } else {
            fl.mt5_head
        };
        let outline = outline::sole_envelope(&foot.outline, &foot.toe_outlines, axis_f, cut);
        let raw = [
            fl.heel_point,
            fl.toe_tip,
            fl.mt1_head,
            fl.mt5_head,
            fl.waist_inner,
            fl.waist_outer,
        ];
        let on: Vec<P2> = raw
            .iter()
            .map(|&q| outline::closest_on(&outline, q).0)
            .collect();
        let off = raw
            .iter()
            .zip(&on)
            .map(|(a, b)| dist_by_hypot(a, b))
            .fold(0.0, f64::max);
        if off > 0.05 {
            notes.push(format!(
                "foot landmarks moved up to {off:.2} mm onto the sole outline (toe pads included)"
            ));
        }
        Sole {
            outline,
            raw,
            on,
            length: (fl.toe_tip - fl.heel_point).dot(&axis_f),
        }
    }
}

/// Step 1: the bottom's outline (counterclockwise) and landmarks, mirrored when it is a
/// last of the other foot.
struct BottomPlan {
    outline: Vec<P2>,
    landmarks: Vec<P2>,
    /// The side the bottom was before any mirroring.
    side_before: Side,
    mirrored: bool,
    mirror: Affine2,
}

impl BottomPlan {
    fn of(
        bottom: &LastBottom,
        foot: &FootPlantar,
        foot_len: f64,
        opts: &AdjustOptions,
        notes: &mut Vec<String>,
    ) -> Result<BottomPlan, AdjustError> {
        let mut b_out = bottom.outline.clone();
        outline::make_ccw(&mut b_out);
        let lm0 = outline_landmarks(&b_out, V2::x(), None)
            .map_err(|e| last_err(bottom, format!("bottom landmarks: {e}")))?;
        let mirrored = lm0.side != foot.side;
        let mirror = if mirrored {
            Affine2 {
                a: [[1.0, 0.0], [0.0, -1.0]],
                t: V2::zeros(),
            }
        } else {
            Affine2::identity()
        };
        if mirrored {
            b_out = b_out.iter().map(|&p| mirror.apply(p)).collect();
            outline::make_ccw(&mut b_out);
            notes.push(format!(
                "the last is a {:?} last and the foot a {:?} foot: the last was mirrored",
                lm0.side, foot.side
            ));
        }
        let lb = outline_landmarks(&b_out, V2::x(), Some(foot.side))
            .map_err(|e| last_err(bottom, format!("bottom landmarks: {e}")))?;
        if lb.length < opts.min_length_ratio * foot_len {
            return Err(AdjustError::TooShort {
                input: bottom.source.clone(),
                last_mm: lb.length,
                foot_mm: foot_len,
            });
        }
        Ok(BottomPlan {
            outline: b_out,
            landmarks: lb.named().iter().map(|x| x.1).collect(),
            side_before: lm0.side,
            mirrored,
            mirror,
        })
    }
}

/// Steps 2 and 3: the rigid fit of the bottom's heel, toe and ball points to the foot's,
/// and eps from the largest excursion of the foot outline outside the fitted bottom.
struct Placement {
    /// The rigid fit of the (mirrored) plan, and of the bottom's own frame.
    rigid_m: Affine2,
    rigid: Affine2,
    /// The landmarks' centroid, the centre of the eps scaling.
    centre: P2,
    /// The plan's outline after the rigid fit.
    aligned: Vec<P2>,
    eps: f64,
    eps_at: P2,
    scale_m: Affine2,
    /// Bottom frame -> foot frame: the rigid fit, then eps.
    to_foot: Affine2,
}

impl Placement {
    fn of(plan: &BottomPlan, sole: &Sole, f_rs: &[P2]) -> Placement {
        let rigid_m = rigid_fit(&plan.landmarks[..4], &sole.raw[..4]);
        let rigid = rigid_m.after(&plan.mirror);
        let centre = P2::from(sole.raw[..4].iter().fold(V2::zeros(), |a, b| a + b.coords) * 0.25);
        let aligned: Vec<P2> = plan.outline.iter().map(|&p| rigid_m.apply(p)).collect();
        let a_rs = outline::resample_closed(&aligned, 512);
        let (mut best_d, mut eps, mut eps_at) = (f64::NEG_INFINITY, 1.0, centre);
        for &q in f_rs {
            let d = q - centre;
            let rf = d.x.hypot(d.y);
            if rf < 1e-9 {
                continue;
            }
            if let Some(t) = outline::ray_exit(&a_rs, centre, d * (1.0 / rf)) {
                if rf - t > best_d {
                    (best_d, eps, eps_at) = (rf - t, rf / t, q);
                }
            }
        }
        let scale_m = Affine2 {
            a: [[eps, 0.0], [0.0, eps]],
            t: centre - centre * eps,
        };
        Placement {
            rigid_m,
            rigid,
            centre,
            aligned,
            eps,
            eps_at,
            scale_m,
            to_foot: scale_m.after(&rigid),
        }
    }
}

/// Step 4: landmarks and outline onto the foot's, the targets smoothed with the landmarks
/// pinned, and the thin-plate splines through them both ways.
struct Warp {
    fwd: tps::Tps,
    inv: tps::Tps,
    correspondences: usize,
}

impl Warp {
    fn fit(
        scaled: &[P2],
        scaled_lm: &[P2],
        sole: &Sole,
        opts: &AdjustOptions,
        bottom: &LastBottom,
    ) -> Result<Warp, AdjustError> {
        let (src, mut tgt, idx) = outline::correspond(
            scaled,
            scaled_lm,
            &sole.outline,
            &sole.on,
            opts.contour_spacing_mm,
        )
        .map_err(|e| last_err(bottom, format!("outline correspondence with the foot: {e}")))?;
        let mut pinned = vec![false; tgt.len()];
        for &i in &idx {
            pinned[i] = true;
        }
        // Smooth the displacements (not the positions): a contour that already fits is left
        // alone, and the smoothing cannot shrink the outline.
        let (it, lam, mu) = opts.taubin;
        let mut disp: Vec<V2> = tgt.iter().zip(&src).map(|(t, s)| t - s).collect();
        outline::taubin(&mut disp, &pinned, it, lam, mu);
        for k in 0..tgt.len() {
            tgt[k] = src[k] + disp[k];
        }
        let degenerate = || last_err(bottom, "the outline correspondences are degenerate".into());
        Ok(Warp {
            fwd: tps::Tps::fit(&src, &tgt).ok_or_else(degenerate)?,
            inv: tps::Tps::fit(&tgt, &src).ok_or_else(degenerate)?,
            correspondences: src.len(),
        })
    }
}

/// The working grid over the foot outline: the foot's heights, the bottom's carried onto
/// it by the adjustment's plan map, and the bottom's after the rigid fit alone.
struct Grid {
    x0: f64,
    y0: f64,
    c: f64,
    nx: usize,
    ny: usize,
    /// Cells inside the adjusted outline.
    inside: Vec<bool>,
    adj_outline: Vec<P2>,
    /// Foot heights, and the bottom's heights carried along.
    hf: HeightMap,
    hs: HeightMap,
    h_before: Vec<f64>,
    /// Cells where both heights come from four finite corners (no blending at an edge).
    full: Vec<bool>,
}

impl Grid {
    fn sample(
        foot: &FootPlantar,
        bottom: &LastBottom,
        f_rs: &[P2],
        opts: &AdjustOptions,
        placed: &Placement,
        scaled: &[P2],
        warp: &Warp,
    ) -> Grid {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in f_rs {
            for d in 0..2 {
                lo[d] = lo[d].min(p[d]);
                hi[d] = hi[d].max(p[d]);
            }
        }
        let margin = 4.0;
        let c = opts.cell_mm;
        let (x0, y0) = (lo[0] - margin, lo[1] - margin);
        let nx = ((hi[0] - lo[0] + 2.0 * margin) / c).ceil() as usize + 1;
        let ny = ((hi[1] - lo[1] + 2.0 * margin) / c).ceil() as usize + 1;
        let n = nx * ny;
        let inv_tab = tps::Tabulated::new(
            &warp.inv,
            P2::new(x0, y0),
            P2::new(x0 + nx as f64 * c, y0 + ny as f64 * c),
            opts.table_step_mm,
        );
        let back = placed.to_foot.inverse();
        let rigid_back = placed.rigid.inverse();
        let adj_outline: Vec<P2> = outline::resample_closed(scaled, 1024)
            .iter()
            .map(|&p| warp.fwd.apply(p))
            .collect();
        let inside = outline::inside_mask(&adj_outline, x0, y0, c, nx, ny);
        let mut hf = HeightMap::new(x0, y0, c, nx, ny);
        let mut hs = HeightMap::new(x0, y0, c, nx, ny);
        let mut h_before = vec![f64::NAN; n];
        let mut full = vec![false; n];
        let fg = &foot.heights;
        for j in 0..ny {
            for i in 0..nx {
                let p = P2::new(x0 + i as f64 * c, y0 + j as f64 * c);
                let k = j * nx + i;
                if let Some((a, b)) = fg.cell_of(p.x, p.y) {
                    if fg.get(a, b).is_finite() {
                        match fg.sample_full(p.x, p.y) {
                            Some(z) => (hf.z[k], full[k]) = (z, true),
                            None => hf.z[k] = fg.sample(p.x, p.y),
                        }
                        let pb = rigid_back.apply(p);
                        h_before[k] = bottom.heights.sample(pb.x, pb.y);
                    }
                }
                if inside[k] || hf.z[k].is_finite() {
                    let pb = back.apply(inv_tab.apply(p));
                    match bottom.heights.sample_full(pb.x, pb.y) {
                        Some(z) => hs.z[k] = z,
                        None => {
                            hs.z[k] = bottom.heights.sample(pb.x, pb.y);
                            full[k] = false;
                        }
                    }
                }
            }
        }
        Grid {
            x0,
            y0,
            c,
            nx,
            ny,
            inside,
            adj_outline,
            hf,
            hs,
            h_before,
            full,
        }
    }

    fn map(&self) -> HeightMap {
        HeightMap::new(self.x0, self.y0, self.c, self.nx, self.ny)
    }
}

/// Step 5: zeta at the largest excursion of the plantar surface beyond the bottom, the
/// heights scaled by it and corrected to the plantar surface (exact at the arch point),
/// then smoothed with the landmark cells pinned. Returns zeta, where it was found and the
/// adjusted heights.
fn fit_heights(
    g: &Grid,
    foot: &FootPlantar,
    sole: &Sole,
    opts: &AdjustOptions,
    centre: P2,
    bottom: &LastBottom,
    notes: &mut Vec<String>,
) -> Result<(f64, P2, HeightMap), AdjustError> {
    let fl = &foot.landmarks;
    let (nx, ny, c) = (g.nx, g.ny, g.c);
    let n = nx * ny;
    let (hf, hs, full, inside) = (&g.hf, &g.hs, &g.full, &g.inside);
    // Only cells `zeta_edge_mm` inside the outline: the sole turns up steeply at its edge,
    // where a hundredth of a millimetre in plan is a large change in height.
    let e = (opts.zeta_edge_mm / c).ceil() as usize;
    let (mut best_dz, mut zeta, mut zeta_at) = (f64::NEG_INFINITY, 1.0, centre);
    for j in 1..ny - 1 {
        for i in 1..nx - 1 {
            let k = j * nx + i;
            let (zf, zs) = (hf.z[k], hs.z[k]);
            let interior = [k, k - 1, k + 1, k - nx, k + nx].iter().all(|&m| full[m])
                && (i >= e && j >= e && i + e < nx && j + e < ny)
                && [k - e, k + e, k - e * nx, k + e * nx]
                    .iter()
                    .all(|&m| inside[m]);
            if !interior || zs < opts.zeta_min_height_mm || !zf.is_finite() {
                continue;
            }
            if zf - zs > best_dz {
                (best_dz, zeta, zeta_at) = (
                    zf - zs,
                    zf / zs,
                    P2::new(g.x0 + i as f64 * c, g.y0 + j as f64 * c),
                );
            }
        }
    }
    if !(0.25..=4.0).contains(&zeta) {
        notes.push(format!("zeta {zeta:.3} clamped to [0.25, 4]"));
        zeta = zeta.clamp(0.25, 4.0);
    }
    let mut corr = g.map();
    let mut pin = vec![false; n];
    for k in 0..n {
        if hf.z[k].is_finite() && hs.z[k].is_finite() {
            corr.z[k] = hf.z[k] - zeta * hs.z[k];
        }
    }
    let mut pin_cells = Vec::new();
    for p in sole.raw.iter().chain(std::iter::once(&fl.arch_point)) {
        if let Some((i, j)) = corr.cell_of(p.x, p.y) {
            pin_cells.push(j * nx + i);
        }
    }
    if let Some((i, j)) = corr.cell_of(fl.arch_point.x, fl.arch_point.y) {
        let k = j * nx + i;
        if hs.z[k].is_finite() {
            corr.z[k] = fl.arch_height_mm - zeta * hs.z[k];
        }
    }
    if corr.valid_count() == 0 {
        return Err(last_err(
            bottom,
            "the bottom and the footprint do not overlap after alignment".into(),
        ));
    }
    corr.fill();
    let mut heights = g.map();
    for k in 0..n {
        heights.z[k] = if hs.z[k].is_finite() {
            zeta * hs.z[k] + corr.z[k]
        } else {
            hf.z[k]
        };
    }
    if let Some((i, j)) = heights.cell_of(fl.arch_point.x, fl.arch_point.y) {
        heights.set(i, j, fl.arch_height_mm);
    }
    heights.fill();
    for &k in &pin_cells {
        pin[k] = true;
    }
    heights.smooth4(inside, &pin, opts.smooth_passes);
    Ok((zeta, zeta_at, heights))
}

/// Step 6: the deviation (bottom minus foot) before (rigid fit only) and after: heights
/// over the footprint, outline, landmarks.
struct Deviations {
    before: Deviation,
    after: Deviation,
    before_map: HeightMap,
    after_map: HeightMap,
    landmarks: Vec<LandmarkPair>,
}

impl Deviations {
    fn of(
        g: &Grid,
        heights: &HeightMap,
        sole: &Sole,
        plan: &BottomPlan,
        placed: &Placement,
        warp: &Warp,
        scaled_lm: &[P2],
    ) -> Deviations {
        let mut before_map = g.map();
        let mut after_map = g.map();
        let (mut sb, mut sa) = (Stats::default(), Stats::default());
        for k in 0..g.nx * g.ny {
            if !g.hf.z[k].is_finite() {
                continue;
            }
            let b = g.h_before[k] - g.hf.z[k];
            before_map.z[k] = b;
            sb.add(b);
            let a = heights.z[k] - g.hf.z[k];
            after_map.z[k] = a;
            sa.add(a);
        }
        let foot_small = outline::resample_closed(&sole.outline, 512);
        let outline_dev = |o: &[P2]| {
            let mut s = Stats::default();
            for q in outline::resample_closed(o, 512) {
                s.add(outline::distance_to(&foot_small, q));
            }
            (s.rms(), s.max)
        };
        let names = [
            "heel point",
            "toe tip",
            "MT1 head",
            "MT5 head",
            "inner waist",
            "outer waist",
        ];
        let landmarks: Vec<LandmarkPair> = (0..6)
            .map(|k| LandmarkPair {
                name: names[k].into(),
                foot: sole.raw[k],
                before: placed.rigid_m.apply(plan.landmarks[k]),
                after: warp.fwd.apply(scaled_lm[k]),
            })
            .collect();
        let lmax = |f: &dyn Fn(&LandmarkPair) -> P2| {
            landmarks
                .iter()
                .map(|l| dist_by_hypot(&l.foot, &f(l)))
                .fold(0.0, f64::max)
        };
        let (ob_rms, ob_max) = outline_dev(&placed.aligned);
        let (oa_rms, oa_max) = outline_dev(&g.adj_outline);
        Deviations {
            before: sb.deviation(ob_rms, ob_max, lmax(&|l| l.before)),
            after: sa.deviation(oa_rms, oa_max, lmax(&|l| l.after)),
            before_map,
            after_map,
            landmarks,
        }
    }
}

/// Running statistics of signed deviations; NaN counts as an uncovered cell.
#[derive(Default)]
struct Stats {
    n: usize,
    uncovered: usize,
    beyond: usize,
    sum2: f64,
    max: f64,
}

impl Stats {
    fn add(&mut self, d: f64) {
        self.n += 1;
        if !d.is_finite() {
            self.uncovered += 1;
            self.beyond += 1;
            return;
        }
        self.sum2 += d * d;
        self.max = self.max.max(d.abs());
        if d.abs() > 0.5 {
            self.beyond += 1;
        }
    }
    fn rms(&self) -> f64 {
        let m = self.n - self.uncovered;
        if m == 0 {
            f64::NAN
        } else {
            (self.sum2 / m as f64).sqrt()
        }
    }
    fn deviation(&self, outline_rms: f64, outline_max: f64, landmark_max: f64) -> Deviation {
        let n = self.n.max(1) as f64;
        Deviation {
            height_rms_mm: self.rms(),
            height_max_mm: self.max,
            share_beyond_0_5: self.beyond as f64 / n,
            uncovered_share: self.uncovered as f64 / n,
            outline_rms_mm: outline_rms,
            outline_max_mm: outline_max,
            landmark_max_mm: landmark_max,
        }
    }
}
