//! The measurement procedure of docs/method.md section 8 on a height map (definitions in the
//! module doc of [`crate::measure`]).

use super::fit::{fit_circle, local_quadratic, peak_vertex};
use super::outline::{line_crossings, regions, simplify, Region};
use super::profile::{peaks, pick, valleys, Crossings, Profiles};
use super::MeasureError;
use crate::geom::HeightMap;
use footscan_geom::{quarter_turn, unit_by_hypot, P2, V2};
use serde::{Deserialize, Serialize};

/// Which foot (one type for every crate, in footscan-geom).
pub use footscan_geom::Side;

/// Foot measurements, world millimetres; points are on the glass, written `[x, y]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Measurements {
    pub side: Side,
    pub heel_point: P2,
    pub toe_tip: P2,
    /// The foot axis: heel centre to second metatarsal head, and its unit direction.
    pub heel_centre: P2,
    pub mt2_head: P2,
    pub axis_dir: V2,
    /// Axis direction counterclockwise from +x, degrees.
    pub axis_angle_deg: f64,
    pub foot_length_mm: f64,
    pub mt1_head: P2,
    pub mt5_head: P2,
    pub ball_width_mm: f64,
    pub waist_inner: P2,
    pub waist_outer: P2,
    pub midfoot_width_mm: f64,
    pub midfoot_inner: P2,
    pub midfoot_outer: P2,
    pub heel_width_mm: f64,
    pub heel_width_inner: P2,
    pub heel_width_outer: P2,
    pub hallux_point: P2,
    pub arch_height_mm: f64,
    pub arch_point: P2,
    pub arch_index: f64,
    /// Toe-less contact area (h <= 1 mm) and its thirds, heel first (mm^2).
    pub contact_area_mm2: f64,
    pub contact_thirds_mm2: [f64; 3],
    /// Most anterior point of the toe-less footprint along the axis (end of the arch-index
    /// interval).
    pub body_front: P2,
    /// Body outline (toes excluded), counterclockwise, simplified to 0.02 mm.
    pub outline: Vec<P2>,
    /// Toe pad outlines, hallux first.
    pub toe_outlines: Vec<Vec<P2>>,
    /// Cell size of the height map measured (mm).
    pub cell_mm: f64,
    /// Where the heights came from ("height map", "scan grid", "bezier model ...").
    #[serde(default)]
    pub heights_from: String,
    /// Why some figures may be wrong (e.g. the footprint is cut off); empty when none.
    #[serde(default)]
    pub warnings: Vec<String>,
}

/// Contact threshold of the arch index (mm).
const CONTACT_MM: f64 = 1.0;
/// Toe pads: regions of at least this fraction of the body's area.
const MIN_TOE_FRACTION: f64 = 0.005;
/// Smallest body accepted as a foot (mm^2).
const MIN_BODY_MM2: f64 = 4000.0;
/// Arch vault: slope limit and plane-fit radius (mm).
const ARCH_SLOPE: f64 = 0.1;
/// Looser slope limits tried in turn when no point of the medial midfoot slopes under
/// [`ARCH_SLOPE`] (a foot not bearing weight: the real FIND meshes slope 9 and 14 degrees at
/// the flattest), each noted in the warnings.
const ARCH_SLOPE_FALLBACK: [f64; 4] = [0.2, 0.3, 0.4, 0.5];
const ARCH_FIT_RADIUS: f64 = 1.0;
/// Depth of the body front used to locate its most anterior point (mm).
const FRONT_DEPTH: f64 = 3.0;
/// Side profile stations (mm) and the least prominence of a head or depth of a waist (mm):
/// the outline's steps are 0.1 mm and the smoothing leaves wiggles of about 0.1 mm.
const PROFILE_STEP: f64 = 0.25;
const MIN_PROMINENCE: f64 = 0.5;
/// The extremes are refined over the outline where the profile stays this close to the peak
/// (mm): more than the parabola's own depth (0.7 mm), so it sees both flanks whole.
const REFINE_DEPTH: f64 = 1.5;
/// Where the heads are sought, as fractions of the length from the heel point (first,
/// fifth), and where they are plausible (docs/method.md section 8.2).
const MT1_WINDOW: (f64, f64) = (0.50, 0.88);
const MT5_WINDOW: (f64, f64) = (0.50, 0.85);
const HEADS_PLAUSIBLE: (f64, f64) = (0.60, 0.80);
/// The second metatarsal head's place on the ball line, as a fraction of the way from the
/// first head to the fifth (the simulator's foot has it at 0.46; real feet 0.35-0.5).
const MT2_ON_BALL_LINE: f64 = 0.46;
/// Where a foot has its first and fifth metatarsal heads and its inner and outer waists
/// (fractions of the length): only to choose between bulges (or hollows) within `TIE_MM` of
/// each other's height.
const PRIOR: (f64, f64, f64, f64) = (0.72, 0.64, 0.42, 0.35);
const TIE_MM: f64 = 2.0;
/// The waists are sought from a fifth of the length (or the heel centre) to a tenth of the
/// length behind the head.
const WAIST_FROM: f64 = 0.20;
const WAIST_BEHIND_HEAD: f64 = 0.10;
/// A heel breadth this close to the end of the rear quarter (mm) is the foot still widening.
const HEEL_EDGE_MM: f64 = 3.0;
/// Plausible widths over the length, and the arch height under which the arch lies on the
/// glass (mm).
const BALL_RATIO: (f64, f64) = (0.33, 0.47);
const HEEL_RATIO: (f64, f64) = (0.20, 0.32);
const FLAT_ARCH_MM: f64 = 2.0;
/// A standing foot touches the glass (h <= 1 mm) over at least this share of its footprint,
/// and no arch index (middle third's share of the contact) exceeds about 0.4.
const MIN_CONTACT_SHARE: f64 = 0.3;
const MAX_ARCH_INDEX: f64 = 0.45;

fn missing_landmark(what: &'static str) -> MeasureError {
    MeasureError::Landmark {
        what,
        why: "no outline point in its search region".into(),
    }
}

/// Where the side profiles put the metatarsal heads and the waists: stations along the axis
/// (mm from the heel point) and the heads' points at their profile values.
struct Heads {
    mt1: P2,
    mt5: P2,
    /// The stretch of each side around its station where the profile stays within
    /// `REFINE_DEPTH` of it (mm from the heel point): the extreme is refined there.
    mt1_x: (f64, f64),
    mt5_x: (f64, f64),
    waist_inner_x: (f64, f64),
    waist_outer_x: (f64, f64),
}

/// The stations around `k` down the flanks of its peak (or up those of its valley when not
/// `peak`) by at most `tol`, as positions (mm).
fn basin(prof: &Profiles, y: &[f64], k: usize, tol: f64, peak: bool) -> (f64, f64) {
    // The peak's own flanks: down from it by at most `tol`, and only while the profile keeps
    // falling (past a hollow lies the next bulge, a big toe past the head, not this one).
    let fall = |j: usize| if peak { y[k] - y[j] } else { y[j] - y[k] };
    let flank =
        |j: usize, prev: usize| y[j].is_finite() && fall(j) <= tol && fall(j) >= fall(prev) - 0.02;
    let (mut a, mut b) = (k, k);
    while a > 0 && flank(a - 1, a) {
        a -= 1;
    }
    while b + 1 < y.len() && flank(b + 1, b) {
        b += 1;
    }
    (prof.x(a) - 0.5, prof.x(b) + 0.5)
}

impl Heads {
    /// The heads as the most prominent peaks of the medial and lateral profiles in the
    /// forefoot, the waists as the deepest valleys between the heel centre and each head;
    /// where a side has no such peak or valley (a border running straight, or still rising
    /// toward the heel) the extreme in the window is taken and a warning says so.
    fn find(
        bo: &[P2],
        tips: &[&[P2]],
        centre: P2,
        radius: f64,
        u: V2,
        sign: f64,
        warnings: &mut Vec<String>,
    ) -> Option<Heads> {
        let m = V2::new(sign * -u.y, sign * u.x);
        let heel = centre + u * -radius;
        let length = tips
            .iter()
            .flat_map(|o| o.iter())
            .map(|&p| (p - heel).dot(&u))
            .fold(f64::NEG_INFINITY, f64::max);
        if length.is_nan() || length <= 0.0 {
            return None;
        }
        let prof = Profiles::of(&[bo], heel, u, m, length, PROFILE_STEP);
        let k = |f: f64| prof.index(f * length);
        let pct = |k: usize| 100.0 * prof.x(k) / length;
        let extreme_in = |y: &[f64], k0: usize, k1: usize, hi: bool| {
            (k0..=k1.min(y.len() - 1))
                .filter(|&j| y[j].is_finite())
                .max_by(|&a, &b| {
                    let o = y[a].total_cmp(&y[b]);
                    if hi {
                        o
                    } else {
                        o.reverse()
                    }
                })
        };
        let mut head = |y: &[f64], win: (f64, f64), prior: f64, name: &str, border: &str| {
            let found = peaks(y, k(win.0), k(win.1), MIN_PROMINENCE);
            match pick(y, &found, k(prior), TIE_MM) {
                Some(p) => Some(p.k),
                None => {
                    // A footprint cut short (a partial scan) may not reach the window: the
                    // extreme of what there is, said in the warning's figure.
                    let j = extreme_in(y, k(win.0), k(win.1), true)
                        .or_else(|| extreme_in(y, k(0.4), y.len() - 1, true))
                        .or_else(|| extreme_in(y, 0, y.len() - 1, true))?;
                    warnings.push(format!(
                        "{name} head: the {border} border has no prominence between {:.0} % and \
                         {:.0} % of the length (it runs straight or widens toward the heel); \
                         taken at its {border}-most point there, {:.0} % of the length",
                        100.0 * win.0,
                        100.0 * win.1,
                        pct(j)
                    ));
                    Some(j)
                }
            }
        };
        let k1 = head(&prof.med, MT1_WINDOW, PRIOR.0, "first metatarsal", "medial")?;
        let k5 = head(
            &prof.lat,
            MT5_WINDOW,
            PRIOR.1,
            "fifth metatarsal",
            "lateral",
        )?;
        // The waists lie in the midfoot: behind the head by a tenth of the length, in front
        // of the heel's own bulge and of a fifth of the length.
        let kc = prof.index(radius.max(WAIST_FROM * length));
        let mut waist = |y: &[f64], kh: usize, prior: f64, name: &str| {
            let kh = kh.saturating_sub(k(WAIST_BEHIND_HEAD));
            if kh <= kc + 1 {
                return Some(kc);
            }
            let found = valleys(y, kc, kh, MIN_PROMINENCE);
            let neg: Vec<f64> = y.iter().map(|v| -v).collect();
            match pick(&neg, &found, k(prior), TIE_MM) {
                Some(p) => Some(p.k),
                None => {
                    let j = extreme_in(y, kc, kh, false).unwrap_or(kc);
                    warnings.push(format!(
                        "{name} waist: the border does not curve in between the heel and the \
                         metatarsal head (a flat or full midfoot); taken at its narrowest point \
                         there, {:.0} % of the length",
                        pct(j)
                    ));
                    Some(j)
                }
            }
        };
        let ki = waist(&prof.med, k1, PRIOR.2, "inner")?;
        let ko = waist(&prof.lat, k5, PRIOR.3, "outer")?;
        let at = |k: usize, w: f64| heel + u * prof.x(k) + m * w;
        Some(Heads {
            mt1: at(k1, prof.med[k1]),
            mt5: at(k5, -prof.lat[k5]),
            mt1_x: basin(&prof, &prof.med, k1, REFINE_DEPTH, true),
            mt5_x: basin(&prof, &prof.lat, k5, REFINE_DEPTH, true),
            waist_inner_x: basin(&prof, &prof.med, ki, REFINE_DEPTH, false),
            waist_outer_x: basin(&prof, &prof.lat, ko, REFINE_DEPTH, false),
        })
    }

    /// Where the second metatarsal head lies on the line from the first head to the fifth.
    fn mt2_on_ball_line(&self) -> P2 {
        self.mt1 + (self.mt5 - self.mt1) * MT2_ON_BALL_LINE
    }
}

/// Extreme point of a closed outline in direction `dir`, among vertices passing `keep`: the
/// best vertex, then a two-sided parabola over the contiguous run of kept vertices within
/// `depth` mm of it. None when no vertex is kept.
fn extreme(
    outline: &[P2],
    dir: V2,
    depth: f64,
    quartic: bool,
    keep: impl Fn(P2) -> bool,
) -> Option<P2> {
    let n = outline.len();
    let s = |k: usize| outline[k % n].coords.dot(&dir);
    let best = (0..n)
        .filter(|&k| keep(outline[k]))
        .max_by(|&a, &b| s(a).total_cmp(&s(b)))?;
    let top = s(best);
    let within = |k: usize| keep(outline[k % n]) && s(k) >= top - depth;
    let mut ks = vec![best];
    let mut k = best;
    while ks.len() < n && within(k + 1) {
        k += 1;
        ks.push(k % n);
    }
    let mut k = best + n;
    while ks.len() < n && within(k - 1) {
        k -= 1;
        ks.push(k % n);
    }
    let across = quarter_turn(&dir);
    let ts: Vec<f64> = ks.iter().map(|&k| outline[k].coords.dot(&across)).collect();
    let ss: Vec<f64> = ks.iter().map(|&k| outline[k].coords.dot(&dir)).collect();
    let (t0, s0) =
        peak_vertex(&ts, &ss, quartic).unwrap_or((outline[best].coords.dot(&across), top));
    Some(P2::from(dir * s0 + across * t0))
}

/// Principal direction of a region's cells (unit, sign arbitrary).
fn principal_axis(map: &HeightMap, r: &Region) -> V2 {
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for (_, i, j) in r.cells_ij(map.nx) {
        let (dx, dy) = (map.x(i) - r.centroid.x, map.y(j) - r.centroid.y);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    V2::new(angle.cos(), angle.sin())
}

/// Measure a foot on `map` (see the module doc of [`crate::measure`] for every definition).
pub fn measure_foot(map: &HeightMap) -> Result<Measurements, MeasureError> {
    // The Planar's side was found on these very heights: no second look.
    with_marks(map, Planar::of(map)?, false)
}

/// What a map's footprint alone decides (which cells are valid, not their heights): its
/// regions, the axis and, when a toe stands apart (so the medial side needs no heights),
/// every landmark on the outline. A scan computes it from the footprint while the model is
/// built, and only the arch and the contact wait for the model's heights (issue 34 item 2).
#[derive(Debug)]
pub struct Planar {
    /// The map's lattice (nx, ny, x0, y0, cell): the regions' cells index it.
    lattice: (usize, usize, f64, f64, f64),
    body: Region,
    toes: Vec<Region>,
    extent: f64,
    axis: Axis,
    /// With toes joined to the ball the medial side is the higher midfoot, which the
    /// heights decide: the landmarks are then found for the side the map's own heights give
    /// (a scan's footprint has the grid's), and found again if the model's give the other.
    /// None when they could not be found for that side.
    marks: Option<Marks>,
}

/// The axis as the heel circle and the body front put it.
#[derive(Clone, Copy, Debug)]
struct Axis {
    u: V2,
    centre: P2,
    radius: f64,
    band: f64,
    front: P2,
}

/// The landmarks on the outline, with the axis they settled.
#[derive(Debug)]
struct Marks {
    sign: f64,
    axis: Axis,
    heel_point: P2,
    toe_tip: P2,
    mt1: P2,
    mt5: P2,
    mt2: P2,
    yc: f64,
    waist_inner: P2,
    waist_outer: P2,
    midfoot: (f64, f64),
    mid: P2,
    heel_width: (f64, P2, P2),
    hallux_point: P2,
    /// Said while the landmarks were found (joined toes, heads taken without a peak).
    warnings: Vec<String>,
    /// The outline's plausibility checks, said after the arch's.
    checks: Vec<String>,
}

impl Planar {
    /// The footprint of `map` measured as far as its outline goes.
    pub fn of(map: &HeightMap) -> Result<Planar, MeasureError> {
        let mut regs = regions(map);
        if regs.is_empty() {
            return Err(MeasureError::NoFootprint);
        }
        let body = regs.remove(0);
        if body.area_mm2 < MIN_BODY_MM2 {
            return Err(MeasureError::TooSmall {
                area_mm2: body.area_mm2,
                min_mm2: MIN_BODY_MM2,
            });
        }
        let bo = &body.outline;
        // Initial axis: principal direction, toes (or else +x, the scanner's heel-to-toe
        // direction) in front.
        let mut u = principal_axis(map, &body);
        let extent = {
            let s: Vec<f64> = bo.iter().map(|p| p.coords.dot(&u)).collect();
            s.iter().copied().fold(f64::NEG_INFINITY, f64::max)
                - s.iter().copied().fold(f64::INFINITY, f64::min)
        };
        let big: Vec<&Region> = regs
            .iter()
            .filter(|r| r.area_mm2 >= MIN_TOE_FRACTION * body.area_mm2)
            .collect();
        let toe_pull = big.iter().fold(V2::zeros(), |acc, r| {
            acc + (r.centroid - body.centroid) * r.area_mm2
        });
        let forward = if big.is_empty() { V2::x() } else { toe_pull };
        if u.dot(&forward) < 0.0 {
            u = -u;
        }
        let keep: Vec<bool> = regs
            .iter()
            .map(|r| {
                r.area_mm2 >= MIN_TOE_FRACTION * body.area_mm2
                    && (r.centroid - body.centroid).dot(&u) > 0.25 * extent
            })
            .collect();
        let mut toes: Vec<Region> = regs
            .into_iter()
            .zip(keep)
            .filter_map(|(r, k)| k.then_some(r))
            .collect();
        toes.sort_by(|a, b| b.area_mm2.total_cmp(&a.area_mm2));

        // Axis: heel circle centre to the body front, iterated to the fixed point. Toes
        // joined to the ball (a weight-bearing foot seen from below: no toe pad stands
        // apart) put the body front on a toe, so there the axis runs to the second metatarsal
        // head's place on the ball line instead (`Planar::marks`).
        let joined = toes.is_empty();
        let mut axis = Axis {
            u,
            centre: body.centroid,
            radius: 0.0,
            band: 0.12 * extent,
            front: body.centroid,
        };
        // The iteration contracts by about a half a step (the heel circle follows the axis):
        // 24 steps to 1e-9 on a scanned foot. Every third step is Aitken's extrapolation of
        // the angle from the two before (Steffensen), taken only where it stays near them;
        // the stopping test is still the step's own change.
        let mut seen: Vec<f64> = Vec::with_capacity(3);
        for it in 0..60 {
            let (c, r) = heel_circle(bo, axis.u, axis.band)?;
            (axis.centre, axis.radius, axis.band) = (c, r, r.min(0.3 * extent));
            axis.front =
                extreme(bo, axis.u, FRONT_DEPTH, true, |_| true).expect("non-empty outline");
            if joined {
                break;
            }
            let nu = unit_by_hypot(&(axis.front - axis.centre));
            let change = nu.perp(&axis.u).abs();
            if seen.is_empty() {
                seen.push(axis.u.y.atan2(axis.u.x));
            }
            seen.push(nu.y.atan2(nu.x));
            axis.u = nu;
            if it > 2 && change < 1e-9 {
                break;
            }
            if let [a0, a1, a2] = seen[..] {
                let (d1, d2) = (a1 - a0, a2 - a1);
                let a = a2 - d2 * d2 / (d2 - d1);
                if a.is_finite() && (a - a2).abs() <= 10.0 * d2.abs() {
                    axis.u = V2::new(a.cos(), a.sin());
                }
                seen.clear();
            }
        }
        let mut planar = Planar {
            lattice: lattice(map),
            body,
            toes,
            extent,
            axis,
            marks: None,
        };
        // Medial side: the hallux side, else the higher midfoot (checked again on the final
        // heights by `measure_foot_with`).
        if let Some(h) = planar.toes.first() {
            let sign = (h.centroid - axis.centre)
                .dot(&quarter_turn(&axis.u))
                .signum();
            planar.marks = Some(planar.marks(map.cell_mm, sign)?);
        } else {
            let sign = arch_side(map, &planar.body, axis.centre, axis.u, extent);
            planar.marks = planar.marks(map.cell_mm, sign).ok();
        }
        Ok(planar)
    }

    /// The landmarks with the medial side on `sign` (+1: left of the axis).
    fn marks(&self, cell_mm: f64, sign: f64) -> Result<Marks, MeasureError> {
        let (body, toes, extent) = (&self.body, &self.toes, self.extent);
        let bo = &body.outline;
        let joined = toes.is_empty();
        let tips: Vec<&[P2]> = std::iter::once(bo.as_slice())
            .chain(toes.iter().map(|t| t.outline.as_slice()))
            .collect();
        let Axis {
            mut u,
            mut centre,
            mut radius,
            mut band,
            front,
        } = self.axis;
        let mut warnings = Vec::new();

        // The metatarsal heads from the side profiles; with joined toes the axis follows them.
        if joined {
            let mut heads = Heads::find(bo, &tips, centre, radius, u, sign, &mut Vec::new());
            for _ in 0..30 {
                let Some(h) = &heads else { break };
                let (c, r) = heel_circle(bo, u, band)?;
                (centre, radius, band) = (c, r, r.min(0.3 * extent));
                let nu = unit_by_hypot(&(h.mt2_on_ball_line() - centre));
                let change = nu.perp(&u).abs();
                u = nu;
                heads = Heads::find(bo, &tips, centre, radius, u, sign, &mut Vec::new());
                if change < 1e-9 {
                    break;
                }
            }
            warnings.push(
                "the toes are joined to the ball in the footprint (no toe stands apart): the axis \
                 runs to the second metatarsal head's place on the ball line, the arch index's \
                 thirds include the toes' contact and there is no hallux point"
                    .to_string(),
            );
        }
        let heads = Heads::find(bo, &tips, centre, radius, u, sign, &mut warnings)
            .ok_or_else(|| missing_landmark("metatarsal heads"))?;
        let m = V2::new(sign * -u.y, sign * u.x);

        // Rearmost point of the heel circle along the axis (on the axis by construction).
        let heel_point = centre + u * -radius;
        // Toe tip: most anterior point over the body and the toe pads.
        let mut toe_tip = extreme(bo, u, 1.0, false, |_| true).expect("non-empty outline");
        for t in toes {
            let p = extreme(&t.outline, u, 1.0, false, |_| true).expect("non-empty outline");
            if p.coords.dot(&u) > toe_tip.coords.dot(&u) {
                toe_tip = p;
            }
        }
        let xl = |p: P2| (p - heel_point).dot(&u);
        let yl = |p: P2| (p - heel_point).dot(&m);
        let to_world = |x: f64, y: f64| heel_point + u * x + m * y;
        let length = xl(toe_tip);
        let missing = missing_landmark;
        let neg_m = -m;
        // Each extreme refined on the outline near the station the profile found it at.
        let near = |r: (f64, f64)| move |p: P2| (r.0..=r.1).contains(&xl(p));
        let mt1 =
            extreme(bo, m, 0.7, false, near(heads.mt1_x)).ok_or_else(|| missing("MT1 head"))?;
        let mt5 =
            extreme(bo, neg_m, 0.7, false, near(heads.mt5_x)).ok_or_else(|| missing("MT5 head"))?;
        let ball_width = yl(mt1) - yl(mt5);
        // The axis passes through the heel centre; coordinates relative to the heel point,
        // which lies on it.
        let yc = yl(centre);
        let mt2 = to_world(xl(mt1), yc);
        let waist_inner = extreme(bo, neg_m, 0.5, false, |p| {
            yl(p) > yc && near(heads.waist_inner_x)(p)
        })
        .ok_or_else(|| missing("inner waist point"))?;
        let waist_outer = extreme(bo, m, 0.5, false, |p| {
            yl(p) < yc && near(heads.waist_outer_x)(p)
        })
        .ok_or_else(|| missing("outer waist point"))?;

        // Mid-foot width over every outline (body and toes).
        let mid = to_world(length / 2.0, 0.0);
        let ts: Vec<f64> = tips
            .iter()
            .flat_map(|o| line_crossings(o, mid, m))
            .collect();
        if ts.len() < 2 {
            return Err(missing("mid-foot breadth"));
        }
        let (t_lo, t_hi) = (
            ts.iter().copied().fold(f64::INFINITY, f64::min),
            ts.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        );

        let heel_width = heel_width(bo, cell_mm, length, radius, to_world, (u, m))
            .ok_or_else(|| missing("heel width"))?;

        let hallux_point = match toes.first() {
            Some(h) => extreme(&h.outline, m, 1.0, false, |_| true).expect("non-empty outline"),
            None => toe_tip,
        };

        // Plausibility: a figure that breaks what holds for feet is said, never passed on
        // silently.
        let mut checks = Vec::new();
        let frac = |p: P2| xl(p) / length;
        for (name, p) in [("first", mt1), ("fifth", mt5)] {
            let f = frac(p);
            if !(HEADS_PLAUSIBLE.0..=HEADS_PLAUSIBLE.1).contains(&f) {
                checks.push(format!(
                    "the {name} metatarsal head is at {:.1} % of the length from the heel; heads \
                     lie between {:.0} % and {:.0} %: the ball width and the axis may be wrong",
                    100.0 * f,
                    100.0 * HEADS_PLAUSIBLE.0,
                    100.0 * HEADS_PLAUSIBLE.1
                ));
            }
        }
        let forefoot = Profiles::of(&tips, heel_point, u, m, length, PROFILE_STEP);
        let (kf0, kf1) = (forefoot.index(0.5 * length), forefoot.index(0.9 * length));
        if let Some((x, b)) = (kf0..=kf1)
            .map(|k| (forefoot.x(k), forefoot.breadth(k)))
            .filter(|(_, b)| b.is_finite())
            .max_by(|a, b| a.1.total_cmp(&b.1))
        {
            if b > ball_width + 1.0 {
                checks.push(format!(
                    "the forefoot is {b:.1} mm wide at {:.0} % of the length, wider than the \
                     ball ({ball_width:.1} mm between the metatarsal heads): the heads may be \
                     misplaced",
                    100.0 * x / length
                ));
            }
        }
        for (name, w, h) in [("inner", waist_inner, mt1), ("outer", waist_outer, mt5)] {
            if xl(w) > xl(h) - 0.05 * length {
                checks.push(format!(
                    "the {name} waist point ({:.0} % of the length) is not behind its metatarsal \
                     head ({:.0} %)",
                    100.0 * frac(w),
                    100.0 * frac(h)
                ));
            }
        }
        let midfoot_width = t_hi - t_lo;
        let hw = heel_width.0;
        if hw >= ball_width || midfoot_width > ball_width + 1.0 {
            checks.push(format!(
                "the widths are out of order: heel {hw:.1}, mid-foot {midfoot_width:.1}, \
                 ball {ball_width:.1} mm (a foot is widest at the ball)"
            ));
        }
        for (name, w, (lo, hi)) in [("ball", ball_width, BALL_RATIO), ("heel", hw, HEEL_RATIO)] {
            let r = w / length;
            if !(lo..=hi).contains(&r) {
                checks.push(format!(
                    "the {name} width is {:.2} of the length ({w:.1} of {length:.1} mm); feet \
                     have {lo:.2} to {hi:.2}",
                    r
                ));
            }
        }
        Ok(Marks {
            sign,
            axis: Axis {
                u,
                centre,
                radius,
                band,
                front,
            },
            heel_point,
            toe_tip,
            mt1,
            mt5,
            mt2,
            yc,
            waist_inner,
            waist_outer,
            midfoot: (t_lo, t_hi),
            mid,
            heel_width,
            hallux_point,
            warnings,
            checks,
        })
    }
}

fn lattice(map: &HeightMap) -> (usize, usize, f64, f64, f64) {
    (map.nx, map.ny, map.x0, map.y0, map.cell_mm)
}

/// The circle fitted to the outline's points within `band` of its rearmost point along `u`.
fn heel_circle(bo: &[P2], u: V2, band: f64) -> Result<(P2, f64), MeasureError> {
    let s_min = bo
        .iter()
        .map(|p| p.coords.dot(&u))
        .fold(f64::INFINITY, f64::min);
    let heel: Vec<P2> = bo
        .iter()
        .copied()
        .filter(|p| p.coords.dot(&u) <= s_min + band)
        .collect();
    fit_circle(&heel).ok_or_else(|| MeasureError::Landmark {
        what: "heel centre",
        why: format!("{} heel outline points do not fit a circle", heel.len()),
    })
}

/// [`measure_foot`] of `map` with its footprint's [`Planar::of`] given (computed from a map
/// with the same valid cells: the footprint before the model's heights went into it).
pub fn measure_foot_with(
    map: &HeightMap,
    mut planar: Planar,
) -> Result<Measurements, MeasureError> {
    if planar.lattice != lattice(map) {
        // Another map's footprint: its cells would index this one wrongly.
        planar = Planar::of(map)?;
    }
    with_marks(map, planar, true)
}

/// The measurements from `planar`; with toes joined and `recheck`, its side is taken again on
/// `map`'s heights (the Planar's came from the footprint's) and the landmarks found again if
/// it differs.
fn with_marks(
    map: &HeightMap,
    mut planar: Planar,
    recheck: bool,
) -> Result<Measurements, MeasureError> {
    let marks = match planar.marks.take() {
        Some(k) if !planar.toes.is_empty() || !recheck => k,
        found => {
            let (a, b) = (&planar.body, &planar.axis);
            let sign = arch_side(map, a, b.centre, b.u, planar.extent);
            match found {
                Some(k) if k.sign == sign => k,
                _ => planar.marks(map.cell_mm, sign)?,
            }
        }
    };
    finish(map, &planar.body, &planar.toes, marks)
}

/// The measurements from the landmarks and the heights: the arch and the contact.
fn finish(
    map: &HeightMap,
    body: &Region,
    toes: &[Region],
    marks: Marks,
) -> Result<Measurements, MeasureError> {
    let Marks {
        sign,
        axis,
        heel_point,
        toe_tip,
        mt1,
        mt5,
        mt2,
        yc,
        waist_inner,
        waist_outer,
        midfoot: (t_lo, t_hi),
        mid,
        heel_width: (heel_width, hw_in, hw_out),
        hallux_point,
        mut warnings,
        checks,
    } = marks;
    let u = axis.u;
    let m = V2::new(sign * -u.y, sign * u.x);
    let side = if sign > 0.0 { Side::Right } else { Side::Left };
    let xl = |p: P2| (p - heel_point).dot(&u);
    let yl = |p: P2| (p - heel_point).dot(&m);
    let missing = missing_landmark;
    let length = xl(toe_tip);
    let ball_width = yl(mt1) - yl(mt5);
    let x_front = xl(axis.front);
    // The arch: where the medial midfoot faces the glass; on a foot that bears no weight the
    // whole vault may slope more, and a looser limit is taken (said in the warnings) rather
    // than losing every other measurement and the side with it.
    // The arch fit and the contact thirds read the map independently: side by side (a
    // scan's results wait on them, issue 34 item 2).
    let (arch, thirds) = std::thread::scope(|s| {
        let thirds = s.spawn(|| contact_thirds(map, body, x_front, &xl));
        let fits = arch_fits(map, body, x_front, &xl, &yl, yc);
        let mut arch = arch_height(&fits, ARCH_SLOPE);
        for limit in ARCH_SLOPE_FALLBACK {
            if arch.is_some() {
                break;
            }
            arch = arch_height(&fits, limit);
            if arch.is_some() {
                warnings.push(format!(
                    "arch height taken where the medial midfoot slopes under {:.0} degrees: it \
                     slopes over {:.0} everywhere (a foot not bearing weight?)",
                    limit.atan().to_degrees(),
                    ARCH_SLOPE.atan().to_degrees()
                ));
            }
        }
        let thirds = thirds
            .join()
            .unwrap_or_else(|p| std::panic::resume_unwind(p));
        (arch, thirds)
    });
    let (arch_height, arch_point) =
        arch.ok_or_else(|| missing("arch height (no gently sloping medial midfoot)"))?;
    let total: f64 = thirds.iter().sum();
    if total <= 0.0 {
        return Err(missing("contact area"));
    }
    warnings.extend(checks);
    let share = total / body.area_mm2;
    if share < MIN_CONTACT_SHARE || thirds[1] / total > MAX_ARCH_INDEX {
        warnings.push(format!(
            "{:.0} % of the footprint touches the glass and the arch index is {:.2}: the foot \
             did not stand on the glass with its weight, so the arch index describes its pose, \
             not its arch",
            100.0 * share,
            thirds[1] / total
        ));
    }
    if arch_height < FLAT_ARCH_MM {
        warnings.push(format!(
            "arch height {arch_height:.1} mm: the medial midfoot lies on the glass (a flat foot, \
             or an arch the scan did not see); judge the arch by eye"
        ));
    }

    Ok(Measurements {
        side,
        heel_point,
        toe_tip,
        heel_centre: axis.centre,
        mt2_head: mt2,
        axis_dir: u,
        axis_angle_deg: u.y.atan2(u.x).to_degrees(),
        foot_length_mm: length,
        mt1_head: mt1,
        mt5_head: mt5,
        ball_width_mm: ball_width,
        waist_inner,
        waist_outer,
        midfoot_width_mm: t_hi - t_lo,
        midfoot_inner: mid + m * t_hi,
        midfoot_outer: mid + m * t_lo,
        heel_width_mm: heel_width,
        heel_width_inner: hw_in,
        heel_width_outer: hw_out,
        hallux_point,
        arch_height_mm: arch_height,
        arch_point,
        arch_index: thirds[1] / total,
        contact_area_mm2: total,
        contact_thirds_mm2: thirds,
        body_front: axis.front,
        outline: simplify(&body.outline, 0.02),
        toe_outlines: toes.iter().map(|t| simplify(&t.outline, 0.02)).collect(),
        cell_mm: map.cell_mm,
        heights_from: "height map".into(),
        warnings,
    })
}

/// +1 when the midfoot is higher to the left of the axis `u` than to the right, else -1.
fn arch_side(map: &HeightMap, body: &Region, c: P2, u: V2, extent: f64) -> f64 {
    let left = quarter_turn(&u);
    let (mut l, mut r) = (0.0, 0.0);
    for (k, i, j) in body.cells_ij(map.nx) {
        let p = P2::new(map.x(i), map.y(j));
        let x = (p - c).dot(&u);
        if (0.15 * extent..0.45 * extent).contains(&x) {
            if (p - c).dot(&left) > 0.0 {
                l += map.z[k];
            } else {
                r += map.z[k];
            }
        }
    }
    if l >= r {
        1.0
    } else {
        -1.0
    }
}

/// Maximum breadth perpendicular to the axis over the rear quarter, on side profiles
/// smoothed over +-2 mm; where the foot still widens at the quarter (no heel bulge: many
/// real feet widen steadily from heel to ball), the breadth through the heel centre
/// (`x_centre` from the heel point) instead, so the figure stays the heel's own. Returns
/// (width, medial end, lateral end).
fn heel_width(
    bo: &[P2],
    cell: f64,
    length: f64,
    x_centre: f64,
    to_world: impl Fn(f64, f64) -> P2,
    (u, m): (V2, V2),
) -> Option<(f64, P2, P2)> {
    let step = (cell / 2.0).max(0.05);
    let n = (length / 4.0 / step).ceil() as usize;
    let (mut xs, mut med, mut lat) = (Vec::new(), Vec::new(), Vec::new());
    // Stations from 2 mm behind the heel point (none cross) to 2 mm past the quarter, so the
    // smoothing has samples on both sides of the range.
    let extra = (2.0 / step).ceil() as usize;
    let c = Crossings::of(&[bo], to_world(0.0, 0.0), u, m, n + extra + 1, step);
    for q in 0..=n + extra {
        if c.count[q] >= 2 {
            xs.push(q as f64 * step);
            med.push(c.hi[q]);
            lat.push(c.lo[q]);
        }
    }
    let at = |x: f64| {
        Some((
            local_quadratic(&xs, &med, x, 2.0)?,
            local_quadratic(&xs, &lat, x, 2.0)?,
        ))
    };
    let mut best: Option<(f64, f64, f64, f64)> = None;
    for &x in xs.iter().filter(|&&x| x <= length / 4.0) {
        let Some((a, b)) = at(x) else {
            continue;
        };
        if best.is_none_or(|bw| a - b > bw.0) {
            best = Some((a - b, x, a, b));
        }
    }
    let (mut w, mut x, mut a, mut b) = best?;
    if x > length / 4.0 - HEEL_EDGE_MM {
        x = x_centre;
        (a, b) = at(x)?;
        w = a - b;
    }
    Some((w, to_world(x, a), to_world(x, b)))
}

/// The plane fits of the arch: over the medial half of the middle third of the body (x' in
/// [x_f/3, 2 x_f/3], medial of the axis), on cells about 0.2 mm apart, a plane fitted to the
/// heights within ARCH_FIT_RADIUS wherever that disc lies wholly on the sole. Each as (height
/// of the plane at its centre, slope, centre), in the order of the body's cells.
fn arch_fits(
    map: &HeightMap,
    body: &Region,
    x_front: f64,
    xl: &impl Fn(P2) -> f64,
    yl: &impl Fn(P2) -> f64,
    y_axis: f64,
) -> Vec<(f64, f64, P2)> {
    let cell = map.cell_mm;
    let rad = (ARCH_FIT_RADIUS / cell).ceil() as isize;
    // Evaluate on cells about 0.2 mm apart.
    let stride = ((0.2 / cell).round() as usize).max(1);
    // The disc's cells in the order the sums take them. A fit counts only with the whole disc
    // on the sole, so the sums of 1, dx, dy, dx^2, dx dy and dy^2 are the same for every
    // candidate: taken once here, in the same order, they are the per-candidate sums bit for
    // bit (and so is the one factorisation), and a candidate adds only its heights
    // (docs/method.md 8.4).
    let mut disc = Vec::new();
    let mut s0 = [0.0f64; 6];
    for dj in -rad..=rad {
        for di in -rad..=rad {
            let (dx, dy) = (di as f64 * cell, dj as f64 * cell);
            if dx * dx + dy * dy > ARCH_FIT_RADIUS * ARCH_FIT_RADIUS {
                continue;
            }
            disc.push((di, dj, dx, dy));
            for (v, add) in s0.iter_mut().zip([1.0, dx, dy, dx * dx, dx * dy, dy * dy]) {
                *v += add;
            }
        }
    }
    let lu = nalgebra::Matrix3::new(
        s0[0], s0[1], s0[2], s0[1], s0[3], s0[4], s0[2], s0[4], s0[5],
    )
    .lu();
    // A disc reaching past the map is no fit; its reach is that of its farthest cells.
    let (ri, rj) = disc.iter().fold((0, 0), |(a, b), &(di, dj, _, _)| {
        (a.max(di.abs()), b.max(dj.abs()))
    });
    let (nx, ny) = (map.nx as isize, map.ny as isize);
    let centres: Vec<(isize, P2)> = body
        .cells_ij(map.nx)
        .filter(|&(_, i, j)| i % stride == 0 && j % stride == 0)
        .filter_map(|(k, i, j)| {
            let p = P2::new(map.x(i), map.y(j));
            let x = xl(p);
            let (i, j) = (i as isize, j as isize);
            let inside = i >= ri && j >= rj && i + ri < nx && j + rj < ny;
            (x >= x_front / 3.0 && x <= 2.0 * x_front / 3.0 && yl(p) >= y_axis && inside)
                .then_some((k as isize, p))
        })
        .collect();
    // The disc as index offsets from its centre.
    let offs: Vec<(isize, f64, f64)> = disc
        .iter()
        .map(|&(di, dj, dx, dy)| (dj * nx + di, dx, dy))
        .collect();
    // Plane z = a + b dx + c dy over the disc; no fit across the outline (a height that is
    // not finite makes the sums so). LANES discs at once, each summed in the disc's order:
    // one disc's sums are a chain of dependent additions, and the results of a scan wait on
    // them (issue 34 item 2).
    const LANES: usize = 4;
    let z = &map.z;
    let mut out = Vec::with_capacity(centres.len());
    for group in centres.chunks(LANES) {
        let mut zs = [[0.0f64; 3]; LANES];
        let ks: [isize; LANES] = std::array::from_fn(|l| group.get(l).map_or(group[0].0, |c| c.0));
        for &(o, dx, dy) in &offs {
            for l in 0..LANES {
                let v = z[(ks[l] + o) as usize];
                zs[l][0] += v;
                zs[l][1] += v * dx;
                zs[l][2] += v * dy;
            }
        }
        for (l, &(_, p)) in group.iter().enumerate() {
            let [a, b, c] = zs[l];
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                continue;
            }
            let Some(c) = lu.solve(&nalgebra::Vector3::new(a, b, c)) else {
                continue;
            };
            out.push((c[0], c[1].hypot(c[2]), p));
        }
    }
    out
}

/// Highest sole point among the arch's plane fits sloping under `max_slope`.
fn arch_height(fits: &[(f64, f64, P2)], max_slope: f64) -> Option<(f64, P2)> {
    let mut best: Option<(f64, P2)> = None;
    for &(h, slope, p) in fits {
        if slope > max_slope {
            continue;
        }
        if best.is_none_or(|b| h > b.0) {
            best = Some((h, p));
        }
    }
    best
}

/// Contact area (h <= 1 mm) of the body in the three equal thirds of [0, x_front].
fn contact_thirds(
    map: &HeightMap,
    body: &Region,
    x_front: f64,
    xl: &impl Fn(P2) -> f64,
) -> [f64; 3] {
    let mut t = [0.0; 3];
    let a = map.cell_mm * map.cell_mm;
    for (k, i, j) in body.cells_ij(map.nx) {
        if map.z[k] > CONTACT_MM {
            continue;
        }
        let x = xl(P2::new(map.x(i), map.y(j)));
        if !(0.0..x_front).contains(&x) {
            continue;
        }
        t[((3.0 * x / x_front) as usize).min(2)] += a;
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A point or direction of any type made from `[x, y]`: the sample below is built the
    /// same whatever type the fields have.
    fn p<T: From<[f64; 2]>>(x: f64, y: f64) -> T {
        [x, y].into()
    }

    /// A measurements value with awkward numbers: thirds, negative zero, tiny and huge
    /// magnitudes, integers, and outlines of several lengths.
    fn sample() -> Measurements {
        Measurements {
            side: Side::Left,
            heel_point: p(1.0 / 3.0, -0.0),
            toe_tip: p(251.25, 1e-300),
            heel_centre: p(31.000000000000004, -12.5),
            mt2_head: p(180.0, 2.0f64.sqrt()),
            axis_dir: p(0.9999999999999999, -1.2246467991473532e-16),
            axis_angle_deg: -7.016709298534876e-15,
            foot_length_mm: 250.91666666666666,
            mt1_head: p(177.3, 48.7),
            mt5_head: p(160.1, -45.9),
            ball_width_mm: 94.6,
            waist_inner: p(1e21, -1e-7),
            waist_outer: p(90.0, -30.000000000000004),
            midfoot_width_mm: 80.5,
            midfoot_inner: p(125.0, 40.25),
            midfoot_outer: p(125.0, -40.25),
            heel_width_mm: 62.0,
            heel_width_inner: p(40.0, 31.0),
            heel_width_outer: p(40.0, -31.0),
            hallux_point: p(240.0, 30.0),
            arch_height_mm: 12.345678901234567,
            arch_point: p(100.0, 25.0),
            arch_index: 0.2345,
            contact_area_mm2: 9876.5,
            contact_thirds_mm2: [3000.0, 2345.5, 4531.0],
            body_front: p(230.0, 0.0),
            outline: vec![p(0.0, 0.0), p(1.5, -2.25), p(f64::MIN_POSITIVE, f64::MAX)],
            toe_outlines: vec![vec![p(240.0, 30.0), p(241.0, 31.0)], vec![]],
            cell_mm: 0.2,
            heights_from: "scan grid".into(),
            warnings: vec!["a warning".into()],
        }
    }

    /// measurements.json as written before the points became footscan-geom's `P2`: each point
    /// an `[x, y]` array, every number in the same digits.
    const SAMPLE_JSON: &str = r#"{
  "side": "left",
  "heel_point": [
    0.3333333333333333,
    -0.0
  ],
  "toe_tip": [
    251.25,
    1e-300
  ],
  "heel_centre": [
    31.000000000000004,
    -12.5
  ],
  "mt2_head": [
    180.0,
    1.4142135623730951
  ],
  "axis_dir": [
    0.9999999999999999,
    -1.2246467991473532e-16
  ],
  "axis_angle_deg": -7.016709298534876e-15,
  "foot_length_mm": 250.91666666666666,
  "mt1_head": [
    177.3,
    48.7
  ],
  "mt5_head": [
    160.1,
    -45.9
  ],
  "ball_width_mm": 94.6,
  "waist_inner": [
    1e+21,
    -1e-7
  ],
  "waist_outer": [
    90.0,
    -30.000000000000004
  ],
  "midfoot_width_mm": 80.5,
  "midfoot_inner": [
    125.0,
    40.25
  ],
  "midfoot_outer": [
    125.0,
    -40.25
  ],
  "heel_width_mm": 62.0,
  "heel_width_inner": [
    40.0,
    31.0
  ],
  "heel_width_outer": [
    40.0,
    -31.0
  ],
  "hallux_point": [
    240.0,
    30.0
  ],
  "arch_height_mm": 12.345678901234567,
  "arch_point": [
    100.0,
    25.0
  ],
  "arch_index": 0.2345,
  "contact_area_mm2": 9876.5,
  "contact_thirds_mm2": [
    3000.0,
    2345.5,
    4531.0
  ],
  "body_front": [
    230.0,
    0.0
  ],
  "outline": [
    [
      0.0,
      0.0
    ],
    [
      1.5,
      -2.25
    ],
    [
      2.2250738585072014e-308,
      1.7976931348623157e+308
    ]
  ],
  "toe_outlines": [
    [
      [
        240.0,
        30.0
      ],
      [
        241.0,
        31.0
      ]
    ],
    []
  ],
  "cell_mm": 0.2,
  "heights_from": "scan grid",
  "warnings": [
    "a warning"
  ]
}"#;

    /// The compact form (the daemon's messages).
    const COMPACT_JSON: &str = r#"{"side":"left","heel_point":[0.3333333333333333,-0.0],"toe_tip":[251.25,1e-300],"heel_centre":[31.000000000000004,-12.5],"mt2_head":[180.0,1.4142135623730951],"axis_dir":[0.9999999999999999,-1.2246467991473532e-16],"axis_angle_deg":-7.016709298534876e-15,"foot_length_mm":250.91666666666666,"mt1_head":[177.3,48.7],"mt5_head":[160.1,-45.9],"ball_width_mm":94.6,"waist_inner":[1e+21,-1e-7],"waist_outer":[90.0,-30.000000000000004],"midfoot_width_mm":80.5,"midfoot_inner":[125.0,40.25],"midfoot_outer":[125.0,-40.25],"heel_width_mm":62.0,"heel_width_inner":[40.0,31.0],"heel_width_outer":[40.0,-31.0],"hallux_point":[240.0,30.0],"arch_height_mm":12.345678901234567,"arch_point":[100.0,25.0],"arch_index":0.2345,"contact_area_mm2":9876.5,"contact_thirds_mm2":[3000.0,2345.5,4531.0],"body_front":[230.0,0.0],"outline":[[0.0,0.0],[1.5,-2.25],[2.2250738585072014e-308,1.7976931348623157e+308]],"toe_outlines":[[[240.0,30.0],[241.0,31.0]],[]],"cell_mm":0.2,"heights_from":"scan grid","warnings":["a warning"]}"#;

    #[test]
    fn measurements_json_is_unchanged() {
        let m = sample();
        assert_eq!(serde_json::to_string_pretty(&m).unwrap(), SAMPLE_JSON);
        assert_eq!(serde_json::to_string(&m).unwrap(), COMPACT_JSON);
        // Read back bit for bit (serde_json's float_roundtrip: the default parser missed the
        // last bit of some numbers, 0.9999999999999999 read as 1.0).
        let back: Measurements = serde_json::from_str(SAMPLE_JSON).unwrap();
        assert_eq!(serde_json::to_string_pretty(&back).unwrap(), SAMPLE_JSON);
        let back: Measurements = serde_json::from_str(COMPACT_JSON).unwrap();
        assert_eq!(serde_json::to_string_pretty(&back).unwrap(), SAMPLE_JSON);
        // A point of the wrong length is refused.
        let bad = COMPACT_JSON.replace("[251.25,1e-300]", "[251.25]");
        assert!(serde_json::from_str::<Measurements>(&bad).is_err());
    }
}
