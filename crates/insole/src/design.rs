//! The insole's top as fields over the foot frame, and its solid.

use crate::params::{Length, Params, PostSide};
use crate::InsoleError;
use footscan::cad::{sample_height, sole_outline, FootFrame};
use footscan::geom::HeightMap;
use footscan::measure::{measure_grid, Measurements, Side, DEFAULT_CELL_MM};
use footscan::scandata::ScanDir;
use footscan::surface::solid::{outline_solid, OutlineSolid};
use footscan_geom::mesh::TriMesh;
use footscan_geom::polygon::Polygon;
use footscan_geom::{P2, V2};
use std::path::Path;

/// Cell of the foot's heights in the foot frame (mm): the solid samples them bilinearly.
const FOOT_CELL_MM: f64 = 0.5;
/// Width of the heel cup's rise inside the outline (mm): the rim is at the outline, the cup
/// meets the foot this far inside it.
pub const CUP_WIDTH_MM: f64 = 12.0;
/// How fast the heel cup's cap on the foot's own heights lifts inward: at cup weight g the
/// top may stand (1 - g) times this above the rim (mm). Small, so a mesh node a cell inside
/// the rim does not stand above it (at 1 mm: 0.2 mm).
const CUP_CLAMP_MM: f64 = 10.0;
/// Metatarsal pad: half its length along the foot and half its width (mm).
pub const PAD_HALF_LENGTH_MM: f64 = 20.0;
pub const PAD_HALF_WIDTH_MM: f64 = 12.0;
/// The first ray cut-out starts this far behind the first metatarsal head (mm).
pub const CUTOUT_BEHIND_MM: f64 = 15.0;
/// In front of the metatarsal heads (from [`TOE_LINE_MM`] ahead of the foremost) the foot's
/// heights are capped at this (mm): the toe pads' centres stand on the glass, but their
/// rims and the gaps between them and the ball (filled from those rims) would stand as
/// ridges of 5-11 mm around each toe, which no toe can use.
pub const TOE_CAP_MM: f64 = 2.0;
pub const TOE_LINE_MM: f64 = 5.0;
/// Width over which a correction's edge blends in (mm).
const BLEND_MM: f64 = 3.0;
/// A bottom curve rising less than this is no curve: the foot stood on the glass (mm), as
/// in the last stage (crates/last customize/bottom.rs).
const FLAT_TOL_MM: f64 = 0.5;
/// Half-window of the curve under the arch (mm), as in the last stage.
const ARCH_SMOOTH_MM: f64 = 8.0;
/// Outline simplification before the margin's offset (mm): the measured outline has a
/// vertex per 0.1 mm cell, whose steps would fold an offset polygon.
const OUTLINE_TOL_MM: f64 = 0.2;

/// A measured plantar scan: its height map (world, the glass at z = 0) and measurements.
#[derive(Clone, Debug)]
pub struct Plantar {
    pub map: HeightMap,
    pub m: Measurements,
    /// Where it came from, for messages.
    pub source: String,
}

impl Plantar {
    /// A scan directory's grid.bin, modelled and measured as `footscan model` does.
    pub fn from_scan_dir(dir: &Path) -> Result<Plantar, InsoleError> {
        let scan = ScanDir::new(dir);
        let grid = scan.load_grid().map_err(|source| InsoleError::Read {
            path: scan.grid_path(),
            source,
        })?;
        let what = || format!("{} (grid.bin)", dir.display());
        let (net, _) =
            footscan::surface::build_scan_model(&grid).map_err(|e| InsoleError::Foot {
                what: what(),
                why: format!("no plantar model: {e}"),
            })?;
        let (map, m) =
            measure_grid(&grid, Some(&net), DEFAULT_CELL_MM).map_err(|e| InsoleError::Foot {
                what: what(),
                why: format!("the foot could not be measured: {e}"),
            })?;
        Ok(Plantar {
            map,
            m,
            source: dir.display().to_string(),
        })
    }
}

/// The shoe's inside bottom: the last `footscan last adjust` deformed to the foot
/// (last_adjusted.stl of its output directory, in the scan's frame), whose bottom outline
/// becomes the insole's.
#[derive(Clone, Debug)]
pub struct ShoeBottom {
    pub last: footscan_geom::mesh::TriMesh,
    pub source: String,
}

/// Bottom faces of the last: those whose normal points down more steeply than this (its
/// z component below -0.5, i.e. within 60 degrees of straight down).
const BOTTOM_NZ: f64 = -0.5;

impl ShoeBottom {
    /// `dir`/last_adjusted.stl, as `footscan last adjust` wrote it.
    pub fn from_adjust_dir(dir: &Path) -> Result<ShoeBottom, InsoleError> {
        let path = dir.join(footscan_last::adjust::output::LAST_STL);
        if !path.exists() {
            return Err(InsoleError::Foot {
                what: format!("--shoe-bottom {}", dir.display()),
                why: format!(
                    "no {} there: give the output directory of `footscan last adjust` run \
                     with a whole last (a scanned last bottom has no last to take the \
                     shoe's bottom from)",
                    footscan_last::adjust::output::LAST_STL
                ),
            });
        }
        let last = footscan_geom::mesh::TriMesh::read(&path).map_err(|e| InsoleError::Foot {
            what: path.display().to_string(),
            why: e.to_string(),
        })?;
        Ok(ShoeBottom {
            last,
            source: path.display().to_string(),
        })
    }

    /// The outline of the last's bottom seen from below, in the foot frame: its downward
    /// faces rasterised on 0.5 mm cells, the largest region's outline.
    fn outline(&self, frame: &FootFrame) -> Result<Vec<P2>, InsoleError> {
        let m = &self.last;
        let pts: Vec<P2> = m.vertices.iter().map(|v| frame.to_foot(v.xy())).collect();
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for q in &pts {
            x0 = x0.min(q.x);
            x1 = x1.max(q.x);
            y0 = y0.min(q.y);
            y1 = y1.max(q.y);
        }
        let c = FOOT_CELL_MM;
        let nx = ((x1 - x0) / c).ceil() as usize + 3;
        let ny = ((y1 - y0) / c).ceil() as usize + 3;
        let mut mask = HeightMap::new(x0 - c, y0 - c, c, nx, ny);
        for (t, tri) in m.triangles.iter().enumerate() {
            if m.face_normal(t).z >= BOTTOM_NZ {
                continue;
            }
            let q = tri.map(|k| pts[k as usize]);
            let (lo_x, hi_x) = (
                q[0].x.min(q[1].x).min(q[2].x),
                q[0].x.max(q[1].x).max(q[2].x),
            );
            let (lo_y, hi_y) = (
                q[0].y.min(q[1].y).min(q[2].y),
                q[0].y.max(q[1].y).max(q[2].y),
            );
            let i0 = ((lo_x - mask.x0) / c).floor().max(0.0) as usize;
            let i1 = (((hi_x - mask.x0) / c).ceil() as usize).min(nx - 1);
            let j0 = ((lo_y - mask.y0) / c).floor().max(0.0) as usize;
            let j1 = (((hi_y - mask.y0) / c).ceil() as usize).min(ny - 1);
            let det = (q[1].x - q[0].x) * (q[2].y - q[0].y) - (q[2].x - q[0].x) * (q[1].y - q[0].y);
            if det.abs() < 1e-12 {
                continue;
            }
            for j in j0..=j1 {
                for i in i0..=i1 {
                    let (x, y) = (mask.x(i), mask.y(j));
                    let l1 =
                        ((x - q[0].x) * (q[2].y - q[0].y) - (q[2].x - q[0].x) * (y - q[0].y)) / det;
                    let l2 =
                        ((q[1].x - q[0].x) * (y - q[0].y) - (x - q[0].x) * (q[1].y - q[0].y)) / det;
                    if l1 >= -1e-9 && l2 >= -1e-9 && l1 + l2 <= 1.0 + 1e-9 {
                        mask.set(i, j, 0.0);
                    }
                }
            }
        }
        // The bottom's edge interleaves with the last's sides in hairs a cell or two wide,
        // which would leave the outline necks thinner than a mesh cell: opened by 1 mm; then
        // closed and opened by 2 mm, which fills the notches between hairs and takes off
        // the spikes that the smoothing below would leave as bumps.
        for (grow, times) in [(false, 2), (true, 2), (true, 4), (false, 8), (true, 4)] {
            for _ in 0..times {
                let z = mask.z.clone();
                for j in 0..ny {
                    for i in 0..nx {
                        let mut any = false;
                        let mut all = true;
                        for dj in -1i64..=1 {
                            for di in -1i64..=1 {
                                let (a, b) = (i as i64 + di, j as i64 + dj);
                                let inside = a >= 0
                                    && b >= 0
                                    && (a as usize) < nx
                                    && (b as usize) < ny
                                    && z[b as usize * nx + a as usize].is_finite();
                                any |= inside;
                                all &= inside;
                            }
                        }
                        let keep = if grow { any } else { all };
                        mask.set(i, j, if keep { 0.0 } else { f64::NAN });
                    }
                }
            }
        }
        let regions = footscan::measure::regions(&mask);
        let Some(r) = regions.first() else {
            return Err(InsoleError::Foot {
                what: self.source.clone(),
                why: "the last has no face looking down: no bottom to take the outline from".into(),
            });
        };
        // The raster's half-cell steps and the hairs of the last's edge made fair: a
        // periodic smoothing spline through the edge (see [`fair_closed`]).
        let mut poly = Polygon::new(fair_closed(&r.outline, FAIR_SPACING_MM, FAIR_WAVELENGTH_MM));
        poly.make_ccw();
        Ok(poly.points)
    }
}

/// The part of the last's bottom, from its heel end, whose sections' lowest points make its
/// bottom curve (as crates/last's `BottomCurve::of`): behind and in front of it the lowest
/// point is the heel's and the toe's rounding, so the curve is carried on along its end
/// slopes (over 10 mm) there.
const SPRING_SPAN: (f64, f64) = (0.15, 0.9);
/// Half-window of the mean along the bottom curve (mm), as the last stage's.
const SPRING_SMOOTH_MM: usize = 5;

/// The shoe's bottom curve under the insole: how far its bottom stands above the tread (the
/// curve's lowest point) every millimetre along x of the foot frame. The insole is bent onto
/// it (a vertical shear: each point raised by the curve at its x), so its bottom follows the
/// last's heel and toe spring and every height measured back is taken in the insole's own
/// frame, the curve taken off again.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Spring {
    /// x of the first sample (foot frame, mm); the samples are 1 mm apart.
    pub x0: f64,
    pub z: Vec<f64>,
    /// The curve at the insole's rear and front ends (mm above the tread).
    pub heel_mm: f64,
    pub toe_mm: f64,
}

impl Spring {
    /// The curve at x, linear between samples, its end values beyond them.
    pub fn at(&self, x: f64) -> f64 {
        let n = self.z.len();
        let t = (x - self.x0).clamp(0.0, (n - 1) as f64);
        let i = (t.floor() as usize).min(n - 2);
        let f = t - i as f64;
        self.z[i] * (1.0 - f) + self.z[i + 1] * f
    }
}

impl ShoeBottom {
    /// The last's bottom curve in the foot frame over `x_range` (the insole's), or None when
    /// it rises less than the last stage's flat tolerance over it: the lowest point of the
    /// last's bottom (its downward faces, met by rays cast up from below every millimetre)
    /// in each 1 mm station, over [`SPRING_SPAN`] of the bottom's length, averaged over
    /// +-[`SPRING_SMOOTH_MM`], carried on along its end slopes.
    fn spring(&self, frame: &FootFrame, x_range: (f64, f64)) -> Option<Spring> {
        use footscan_geom::{mesh::Bvh, P3, V3};
        let m = &self.last;
        let bvh = Bvh::new(m);
        let bb = m.bbox();
        let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
        for t in 0..m.triangles.len() {
            if m.face_normal(t).z < BOTTOM_NZ {
                for p in m.corners(t) {
                    let q = frame.to_foot(P2::new(p.x, p.y));
                    x0 = x0.min(q.x);
                    x1 = x1.max(q.x);
                    y0 = y0.min(q.y);
                    y1 = y1.max(q.y);
                }
            }
        }
        if x1 - x0 < 50.0 {
            return None;
        }
        let n = (x1 - x0).floor() as usize + 1;
        let low: Vec<Option<f64>> = (0..n)
            .map(|i| {
                let x = x0 + i as f64;
                let mut lo: Option<f64> = None;
                let mut y = y0.floor();
                while y <= y1 {
                    let w = frame.to_world(P2::new(x, y));
                    let hit = bvh.ray_cast(
                        &P3::new(w.x, w.y, bb.min.z - 10.0),
                        &V3::z(),
                        bb.max.z - bb.min.z + 20.0,
                    );
                    if let Some(h) = hit.filter(|h| h.normal.z < BOTTOM_NZ) {
                        lo = Some(lo.map_or(h.point.z, |l: f64| l.min(h.point.z)));
                    }
                    y += 1.0;
                }
                lo
            })
            .collect();
        let (a, b) = (
            (SPRING_SPAN.0 * n as f64) as usize,
            ((SPRING_SPAN.1 * n as f64) as usize).min(n - 1),
        );
        let z = footscan_last::smoothed_lowest(&low, a, b, SPRING_SMOOTH_MM)?;
        let mut s = Spring {
            x0,
            z,
            heel_mm: 0.0,
            toe_mm: 0.0,
        };
        // Heights above the tread: the curve's lowest point under the insole.
        let k = ((x_range.1 - x_range.0).ceil() as usize).max(1);
        let under: Vec<f64> = (0..=k)
            .map(|i| s.at(x_range.0 + (x_range.1 - x_range.0) * i as f64 / k as f64))
            .collect();
        let lo = under.iter().copied().fold(f64::MAX, f64::min);
        let hi = under.iter().copied().fold(f64::MIN, f64::max);
        if hi - lo < FLAT_TOL_MM {
            return None;
        }
        for v in &mut s.z {
            *v -= lo;
        }
        s.heel_mm = s.at(x_range.0);
        s.toe_mm = s.at(x_range.1);
        Some(s)
    }
}

/// Spacing of the shoe bottom's fair outline (mm).
const FAIR_SPACING_MM: f64 = 1.0;
/// Wavelength along the shoe bottom's outline passed at half amplitude by its smoothing
/// (mm): the raster's 0.5 mm steps and the edge's kinks (a few millimetres) go, a last's
/// toe and heel curves (radii of 15-40 mm, bends over 25-60 mm of outline) stay.
const FAIR_WAVELENGTH_MM: f64 = 20.0;

/// A closed outline made fair: resampled every `spacing` mm of its length, then the
/// periodic smoothing spline through those points (the closed curve p minimising
/// sum |p_i - q_i|^2 + lambda sum |p_(i-1) - 2 p_i + p_(i+1)|^2, the discrete cubic smoothing
/// spline). Its system is circulant, so it is solved exactly in the Fourier basis: each
/// harmonic k is divided by 1 + lambda (2 - 2 cos(2 pi k / n))^2, with lambda set so the
/// harmonic of wavelength `wavelength` keeps half its amplitude. A few hundred points: the
/// direct transform is cheap and needs no crate.
pub fn fair_closed(outline: &[P2], spacing: f64, wavelength: f64) -> Vec<P2> {
    let q = resample_closed(outline, spacing);
    let n = q.len();
    if n < 8 {
        return q;
    }
    let w = 2.0 * std::f64::consts::PI * spacing / wavelength;
    let lambda = 1.0 / (2.0 - 2.0 * w.cos()).powi(2);
    let mut out = vec![P2::origin(); n];
    let (cos, sin): (Vec<f64>, Vec<f64>) = (0..n)
        .map(|m| {
            let a = 2.0 * std::f64::consts::PI * m as f64 / n as f64;
            (a.cos(), a.sin())
        })
        .unzip();
    for k in 0..n {
        let mut c = [[0.0; 2]; 2]; // [re, im] per coordinate
        for (i, p) in q.iter().enumerate() {
            let m = (i * k) % n;
            for d in 0..2 {
                c[d][0] += p[d] * cos[m];
                c[d][1] -= p[d] * sin[m];
            }
        }
        let g = 1.0 / (1.0 + lambda * (2.0 - 2.0 * cos[k]).powi(2));
        for (i, o) in out.iter_mut().enumerate() {
            let m = (i * k) % n;
            for d in 0..2 {
                o[d] += g * (c[d][0] * cos[m] - c[d][1] * sin[m]) / n as f64;
            }
        }
    }
    out
}

/// A closed polyline resampled at equal steps of about `step` along its length.
fn resample_closed(p: &[P2], step: f64) -> Vec<P2> {
    let k = p.len();
    if k < 3 {
        return p.to_vec();
    }
    let seg = |i: usize| {
        let (a, b) = (p[i], p[(i + 1) % k]);
        ((b.x - a.x).powi(2) + (b.y - a.y).powi(2)).sqrt()
    };
    let total: f64 = (0..k).map(seg).sum();
    let n = ((total / step).round() as usize).max(3);
    let h = total / n as f64;
    let mut out = Vec::with_capacity(n);
    let (mut i, mut at) = (0usize, 0.0f64); // segment i starts `at` along the outline
    for m in 0..n {
        let s = m as f64 * h;
        while i < k - 1 && at + seg(i) < s {
            at += seg(i);
            i += 1;
        }
        let (a, b) = (p[i], p[(i + 1) % k]);
        let t = if seg(i) > 0.0 {
            ((s - at) / seg(i)).clamp(0.0, 1.0)
        } else {
            0.0
        };
        out.push(a + (b - a) * t);
    }
    out
}

/// Landmarks in the foot frame (mm).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct Marks {
    pub heel_centre: P2,
    pub arch_point: P2,
    pub mt1_head: P2,
    pub mt2_head: P2,
    pub mt3_head: P2,
    pub mt5_head: P2,
    pub toe_tip: P2,
}

/// The designed insole: its outline, the foot's heights and every correction, in the foot
/// frame. [`Design::shell_top`] is the mesh's top.
#[derive(Clone, Debug)]
pub struct Design {
    pub params: Params,
    pub side: Side,
    pub frame: FootFrame,
    pub foot_length_mm: f64,
    pub heel_width_mm: f64,
    pub ball_width_mm: f64,
    pub marks: Marks,
    /// +1 when +y is medial (a right foot), -1 otherwise.
    pub medial: f64,
    /// The insole's outline, counterclockwise.
    pub outline: Vec<P2>,
    outline_poly: Polygon,
    /// The foot's heights in the foot frame, laid flat ([`Self::bottom_rise_mm`]), filled
    /// beyond the footprint; `measured[k]` is whether cell k had a scanned height.
    foot: HeightMap,
    pub measured: Vec<bool>,
    /// The curve under the arch (per foot-grid column) subtracted from the heights: zero for
    /// a foot that stood on the glass.
    bottom: Vec<f64>,
    /// How far the midfoot stood off the glass (mm; 0 when it stood on it).
    pub bottom_rise_mm: f64,
    /// x of the line in front of which the foot's heights are capped ([`TOE_CAP_MM`]).
    pub toe_line_x: f64,
    /// Scanned arch height (laid flat) at the arch point and the insole's asked one (mm).
    pub scanned_arch_mm: f64,
    pub arch_target_mm: f64,
    /// The foot's height at the heel centre: the heel seat (mm).
    pub seat_mm: f64,
    /// Pad apex (foot frame) and where the 3/4 insole ends (x, mm) if it does.
    pub pad_apex: P2,
    /// The shoe's bottom curve the insole is bent onto (None: a flat bottom).
    pub spring: Option<Spring>,
    pub warnings: Vec<String>,
}

fn smoothstep(t: f64) -> f64 {
    let t = t.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A dome of height 1 at the centre, 0 beyond the ellipse of half-axes (a, b): (1 - r^2)^2,
/// flat at its apex so the apex is where it is asked.
fn dome(dx: f64, dy: f64, a: f64, b: f64) -> f64 {
    let r2 = (dx / a).powi(2) + (dy / b).powi(2);
    if r2 >= 1.0 {
        0.0
    } else {
        (1.0 - r2).powi(2)
    }
}

/// Designs the insole for `p` with `params` (validated here, the foot's own limits too), its
/// outline the footprint plus the margin.
pub fn design(p: &Plantar, params: &Params) -> Result<Design, InsoleError> {
    design_in(p, params, None)
}

/// [`design`], its outline the bottom of `shoe` when given (the margin then unused).
pub fn design_in(
    p: &Plantar,
    params: &Params,
    shoe: Option<&ShoeBottom>,
) -> Result<Design, InsoleError> {
    params.validate()?;
    let m = &p.m;
    let frame = FootFrame::of(m);
    let to = |q: P2| frame.to_foot(q);
    let medial = if m.side == Side::Right { 1.0 } else { -1.0 };
    let (mt1, mt2, mt5) = (to(m.mt1_head), to(m.mt2_head), to(m.mt5_head));
    let mt3 = mt2 + (mt5 - mt2) / 3.0;
    let marks = Marks {
        heel_centre: to(m.heel_centre),
        arch_point: to(m.arch_point),
        mt1_head: mt1,
        mt2_head: mt2,
        mt3_head: mt3,
        mt5_head: mt5,
        toe_tip: to(m.toe_tip),
    };
    let l = m.foot_length_mm;
    let heads_missing: Vec<&String> = m
        .warnings
        .iter()
        .filter(|w| {
            w.starts_with("first metatarsal head") || w.starts_with("fifth metatarsal head")
        })
        .collect();
    let needs_heads = params.length == Length::ThreeQuarter
        || params.met_pad_height_mm > 0.0
        || params.first_ray_cutout_mm > 0.0;
    if needs_heads && !heads_missing.is_empty() {
        let name = if params.length == Length::ThreeQuarter {
            "length = \"three_quarter\""
        } else if params.met_pad_height_mm > 0.0 {
            "met_pad_height_mm"
        } else {
            "first_ray_cutout_mm"
        };
        return Err(InsoleError::Foot {
            what: format!("{name} on {}", p.source),
            why: format!(
                "it is placed from the metatarsal heads, which this scan does not show ({}); \
                 valid: a full-length insole without pad or cut-out",
                heads_missing
                    .iter()
                    .map(|s| s.as_str())
                    .collect::<Vec<_>>()
                    .join("; ")
            ),
        });
    }

    // Outline: the sole (body and toe pads joined), simplified, moved out by the margin.
    let sole = sole_outline(m, &frame);
    let mut warnings: Vec<String> = m
        .warnings
        .iter()
        .map(|w| format!("measurements: {w}"))
        .chain(sole.warnings.iter().cloned())
        .collect();
    let mut outline = match shoe {
        Some(shoe) => shoe.outline(&frame)?,
        None => {
            let mut poly = Polygon::new(sole.points.clone()).simplify(OUTLINE_TOL_MM);
            poly.make_ccw();
            if params.margin_mm > 0.0 {
                poly = poly.offset(params.margin_mm);
            }
            poly.points
        }
    };
    let heads_x = mt1.x.min(mt5.x);
    match params.length {
        Length::Full => {
            if params.extra_length_mm > 0.0 {
                let tip = outline.iter().map(|q| q.x).fold(f64::MIN, f64::max);
                for q in &mut outline {
                    if q.x > heads_x {
                        q.x +=
                            params.extra_length_mm * smoothstep((q.x - heads_x) / (tip - heads_x));
                    }
                }
            }
        }
        Length::ThreeQuarter => {
            // Behind the line through the first and fifth heads, moved back along the axis.
            let back = V2::new(params.three_quarter_behind_mm, 0.0);
            let (a, b) = (mt1 - back, mt5 - back);
            outline = clip_behind(&outline, a, b).ok_or_else(|| InsoleError::Param {
                name: "three_quarter_behind_mm",
                value: params.three_quarter_behind_mm,
                lo: 0.0,
                hi: 30.0,
                why: format!(
                    "the line {:.0} mm behind the metatarsal heads does not cross this \
                     outline once from side to side",
                    params.three_quarter_behind_mm
                ),
            })?;
        }
    }
    let outline_poly = Polygon::new(outline.clone());

    // The foot's heights on the foot frame's grid over the outline.
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for q in &outline {
        x0 = x0.min(q.x);
        x1 = x1.max(q.x);
        y0 = y0.min(q.y);
        y1 = y1.max(q.y);
    }
    let c = FOOT_CELL_MM;
    let (gx0, gy0) = (
        (x0 / c).floor() * c - 2.0 * c,
        (y0 / c).floor() * c - 2.0 * c,
    );
    let nx = ((x1 - gx0) / c).ceil() as usize + 3;
    let ny = ((y1 - gy0) / c).ceil() as usize + 3;
    let mut foot = HeightMap::new(gx0, gy0, c, nx, ny);
    let mut measured = vec![false; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let w = frame.to_world(P2::new(foot.x(i), foot.y(j)));
            let cell = p.map.cell_of(w.x, w.y);
            let inside = cell.is_some_and(|(a, b)| p.map.get(a, b).is_finite());
            if inside {
                if let Some(z) = sample_height(&p.map, w.x, w.y) {
                    foot.set(i, j, z.max(0.0));
                    measured[foot.index(i, j)] = true;
                }
            }
        }
    }
    if !measured.iter().any(|&b| b) {
        return Err(InsoleError::Foot {
            what: p.source.clone(),
            why: "no scanned height inside the insole's outline".into(),
        });
    }
    fill_outside(&mut foot, &measured);

    // A foot scanned without weight: laid flat by the curve under its arch.
    let bottom = under_arch(&foot, &measured, l);
    let rise = bottom.iter().copied().fold(0.0, f64::max);
    let (bottom, bottom_rise_mm) = if rise > FLAT_TOL_MM {
        warnings.push(format!(
            "the midfoot stood up to {rise:.1} mm off the glass (a foot scanned without \
             weight): its heights are taken above the curve under its arch, as the last stage \
             lays such a foot flat"
        ));
        (bottom, rise)
    } else {
        (vec![0.0; nx], 0.0)
    };
    let toe_line_x = mt1.x.max(mt5.x) + TOE_LINE_MM;
    for j in 0..ny {
        for (i, b) in bottom.iter().enumerate() {
            let mut z = (foot.get(i, j) - b).max(0.0);
            if foot.x(i) > toe_line_x {
                z = z.min(TOE_CAP_MM);
            }
            foot.set(i, j, z);
        }
    }

    let mut d = Design {
        params: params.clone(),
        side: m.side,
        frame,
        foot_length_mm: l,
        heel_width_mm: m.heel_width_mm,
        ball_width_mm: m.ball_width_mm,
        marks,
        medial,
        outline,
        outline_poly,
        foot,
        measured,
        bottom,
        bottom_rise_mm,
        toe_line_x,
        scanned_arch_mm: 0.0,
        arch_target_mm: 0.0,
        seat_mm: 0.0,
        pad_apex: P2::new(mt3.x - params.met_pad_behind_mm, mt3.y),
        spring: None,
        warnings,
    };
    if let Some(shoe) = shoe {
        let xs = d.outline.iter().map(|q| q.x);
        let range = (
            xs.clone().fold(f64::MAX, f64::min),
            xs.fold(f64::MIN, f64::max),
        );
        d.spring = shoe.spring(&d.frame, range);
        d.warnings.push(match &d.spring {
            Some(sp) => format!(
                "outline from the shoe's bottom ({}); the insole bent onto its bottom curve: \
                 heel {:.1} mm and toe {:.1} mm above the tread",
                shoe.source, sp.heel_mm, sp.toe_mm
            ),
            None => format!(
                "outline from the shoe's bottom ({}); its bottom curve rises less than {} mm \
                 under the insole: the insole's bottom is flat",
                shoe.source, FLAT_TOL_MM
            ),
        });
    }
    d.seat_mm = d.foot_at(marks.heel_centre.x, marks.heel_centre.y);
    d.scanned_arch_mm = d.foot_at(marks.arch_point.x, marks.arch_point.y);
    d.arch_target_mm = params
        .arch_height_mm
        .unwrap_or(params.arch_share * d.scanned_arch_mm);
    if params.met_pad_height_mm > d.arch_target_mm {
        return Err(InsoleError::Param {
            name: "met_pad_height_mm",
            value: params.met_pad_height_mm,
            lo: 0.0,
            hi: (d.arch_target_mm * 100.0).floor() / 100.0,
            why: format!(
                "a pad higher than the insole's arch ({:.2} mm on this foot) lifts the \
                 forefoot off it",
                d.arch_target_mm
            ),
        });
    }
    if params.length == Length::ThreeQuarter && params.met_pad_height_mm > 0.0 {
        // The end line at the pad's y; the apex must lie a pad's half-length behind it, or
        // the end cuts the pad through its top.
        let (a, b) = (mt1, mt5);
        let t = (d.pad_apex.y - a.y) / (b.y - a.y);
        let end_x = a.x + t * (b.x - a.x) - params.three_quarter_behind_mm;
        let lo = mt3.x - end_x + 0.5 * PAD_HALF_LENGTH_MM;
        if d.pad_apex.x > end_x - 0.5 * PAD_HALF_LENGTH_MM {
            return Err(InsoleError::Param {
                name: "met_pad_behind_mm",
                value: params.met_pad_behind_mm,
                lo: (lo * 10.0).ceil() / 10.0,
                hi: 25.0,
                why: format!(
                    "on a 3/4 insole ending {} mm behind the heads the pad's apex must lie at \
                     least half its half-length ({} mm) behind the end, or the end cuts its top",
                    params.three_quarter_behind_mm,
                    0.5 * PAD_HALF_LENGTH_MM
                ),
            });
        }
    }
    Ok(d)
}

/// `outline` behind the line a-b (the side away from the toes); None unless the line crosses
/// it exactly twice.
fn clip_behind(outline: &[P2], a: P2, b: P2) -> Option<Vec<P2>> {
    // n points toward the toes (+x).
    let mut n = V2::new(b.y - a.y, a.x - b.x);
    if n.x < 0.0 {
        n = -n;
    }
    let side = |q: P2| (q - a).dot(&n);
    let k = outline.len();
    let mut out = Vec::with_capacity(k);
    let mut crossings = 0;
    for i in 0..k {
        let (p, q) = (outline[i], outline[(i + 1) % k]);
        let (sp, sq) = (side(p), side(q));
        if sp <= 0.0 {
            out.push(p);
        }
        if (sp <= 0.0) != (sq <= 0.0) {
            let t = sp / (sp - sq);
            out.push(p + (q - p) * t);
            crossings += 1;
        }
    }
    (crossings == 2 && out.len() >= 3).then_some(out)
}

/// Heights beyond the footprint (and between the toes and the ball) from its edge: each
/// unmeasured cell takes the mean of its nearer measured neighbours, front by front
/// (breadth first), then is smoothed by a few neighbour-mean passes (a membrane over the
/// gap, measured cells held).
fn fill_outside(f: &mut HeightMap, measured: &[bool]) {
    let (nx, ny) = (f.nx, f.ny);
    let mut known: Vec<bool> = measured.to_vec();
    let mut front: Vec<usize> = (0..nx * ny).filter(|&k| !known[k]).collect();
    while !front.is_empty() {
        let mut set = Vec::new();
        for &k in &front {
            let (i, j) = f.cell(k);
            let (mut s, mut n) = (0.0, 0);
            for (di, dj) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                let (a, b) = (i as i64 + di, j as i64 + dj);
                if a < 0 || b < 0 || a as usize >= nx || b as usize >= ny {
                    continue;
                }
                let kk = f.index(a as usize, b as usize);
                if known[kk] {
                    s += f.z[kk];
                    n += 1;
                }
            }
            if n > 0 {
                set.push((k, s / n as f64));
            }
        }
        if set.is_empty() {
            break;
        }
        for &(k, z) in &set {
            f.z[k] = z;
            known[k] = true;
        }
        front.retain(|&k| !known[k]);
    }
    for _ in 0..20 {
        let z = f.z.clone();
        for (k, &held) in measured.iter().enumerate() {
            if held {
                continue;
            }
            let (i, j) = f.cell(k);
            let (mut s, mut n) = (0.0, 0);
            for (di, dj) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                let (a, b) = (i as i64 + di, j as i64 + dj);
                if a < 0 || b < 0 || a as usize >= nx || b as usize >= ny {
                    continue;
                }
                s += z[f.index(a as usize, b as usize)];
                n += 1;
            }
            f.z[k] = s / n as f64;
        }
    }
}

/// The curve under the arch per grid column, as the last stage draws it under a foot mesh
/// (crates/last customize/bottom.rs `BottomCurve::under_arch`): zero behind the heel's
/// lowest station (rear 30 %) and in front of the forefoot's (50-85 % of the length), and
/// between them the lowest scanned height of each station, its minimum over
/// +-[`ARCH_SMOOTH_MM`] averaged over as much again, never above the station's own.
fn under_arch(f: &HeightMap, measured: &[bool], length: f64) -> Vec<f64> {
    let nx = f.nx;
    let low: Vec<Option<f64>> = (0..nx)
        .map(|i| {
            (0..f.ny)
                .filter(|&j| measured[f.index(i, j)])
                .map(|j| f.get(i, j))
                .reduce(f64::min)
        })
        .collect();
    let col = |x: f64| (((x - f.x0) / f.cell_mm).round().max(0.0) as usize).min(nx - 1);
    let argmin = |a: f64, b: f64| {
        (col(a * length)..=col(b * length))
            .filter(|&i| low[i].is_some())
            .min_by(|&i, &j| low[i].unwrap().total_cmp(&low[j].unwrap()))
    };
    let (Some(h), Some(fr)) = (argmin(0.0, 0.3), argmin(0.5, 0.85)) else {
        return vec![0.0; nx];
    };
    let low: Vec<f64> = low.iter().map(|z| z.unwrap_or(0.0).max(0.0)).collect();
    let w = (ARCH_SMOOTH_MM / f.cell_mm).round() as usize;
    let floor: Vec<f64> = (0..nx)
        .map(|i| {
            if i <= h || i >= fr {
                return 0.0;
            }
            low[i.saturating_sub(w)..=(i + w).min(nx - 1)]
                .iter()
                .copied()
                .fold(f64::MAX, f64::min)
        })
        .collect();
    (0..nx)
        .map(|i| {
            if i <= h || i >= fr {
                return 0.0;
            }
            let near = &floor[i.saturating_sub(w)..=(i + w).min(nx - 1)];
            let mean = near.iter().sum::<f64>() / near.len() as f64;
            mean.min(low[i]).max(0.0)
        })
        .collect()
}

impl Design {
    /// The foot's height (laid flat, filled beyond the footprint) at (x, y), foot frame.
    pub fn foot_at(&self, x: f64, y: f64) -> f64 {
        let z = self.foot.sample(x, y);
        if z.is_finite() {
            z
        } else {
            0.0
        }
    }

    /// The curve under the arch at x (0 for a foot that stood on the glass).
    pub fn bottom_at(&self, x: f64) -> f64 {
        let f = &self.foot;
        let t = ((x - f.x0) / f.cell_mm).clamp(0.0, (f.nx - 1) as f64);
        let i = (t.floor() as usize).min(f.nx - 2);
        let s = t - i as f64;
        self.bottom[i] * (1.0 - s) + self.bottom[i + 1] * s
    }

    /// Whether (x, y) had a scanned height (foot frame).
    pub fn is_measured(&self, x: f64, y: f64) -> bool {
        self.foot
            .cell_of(x, y)
            .is_some_and(|(i, j)| self.measured[self.foot.index(i, j)])
    }

    pub fn outline_polygon(&self) -> &Polygon {
        &self.outline_poly
    }

    fn heads_x(&self) -> f64 {
        self.marks.mt1_head.x.min(self.marks.mt5_head.x)
    }

    /// Heel lift at x: full under the rear 35 % of the length, tapering smoothly to nothing
    /// 10 mm behind the metatarsal heads.
    pub fn lift(&self, x: f64) -> f64 {
        let (a, b) = (0.35 * self.foot_length_mm, self.heads_x() - 10.0);
        self.params.heel_lift_mm * (1.0 - smoothstep((x - a) / (b - a).max(1.0)))
    }

    /// Rearfoot post at (x, y): the top tilted across the heel by the post angle about the
    /// unraised side of the heel (half the heel width from the heel centre), full behind
    /// 0.3 of the length and fading out by half of it.
    pub fn rear_post(&self, x: f64, y: f64) -> f64 {
        if self.params.rearfoot_post_deg == 0.0 {
            return 0.0;
        }
        let sigma = self.post_sign(self.params.rearfoot_post_side);
        let hw = 0.5 * self.heel_width_mm;
        let across = (sigma * (y - self.marks.heel_centre.y) + hw).max(0.0);
        let l = self.foot_length_mm;
        let w = 1.0 - smoothstep((x - 0.3 * l) / (0.2 * l));
        self.params.rearfoot_post_deg.to_radians().tan() * across * w
    }

    /// Forefoot post at (x, y): the top tilted across the forefoot about its unraised side
    /// (half the ball width from the middle of the first and fifth heads), full from 20 mm
    /// behind the heads forward, fading in over 20 mm behind that.
    pub fn fore_post(&self, x: f64, y: f64) -> f64 {
        if self.params.forefoot_post_deg == 0.0 {
            return 0.0;
        }
        let sigma = self.post_sign(self.params.forefoot_post_side);
        let mid = 0.5 * (self.marks.mt1_head.y + self.marks.mt5_head.y);
        let across = (sigma * (y - mid) + 0.5 * self.ball_width_mm).max(0.0);
        let w = smoothstep((x - (self.heads_x() - 40.0)) / 20.0);
        self.params.forefoot_post_deg.to_radians().tan() * across * w
    }

    fn post_sign(&self, s: PostSide) -> f64 {
        match s {
            PostSide::Medial => self.medial,
            PostSide::Lateral => -self.medial,
        }
    }

    /// Weight of the heel cup at (x, y): 1 at the outline behind the heel centre (plus 5 %
    /// of the length), 0 from [`CUP_WIDTH_MM`] inside it and in front of 0.2 of the length
    /// past the heel centre.
    pub fn cup_weight(&self, x: f64, y: f64) -> f64 {
        if self.params.heel_cup_depth_mm == 0.0 {
            return 0.0;
        }
        let l = self.foot_length_mm;
        let a = self.marks.heel_centre.x + 0.05 * l;
        let wr = 1.0 - smoothstep((x - a) / (0.15 * l));
        if wr == 0.0 {
            return 0.0;
        }
        let d = self.outline_poly.distance_to_boundary(&P2::new(x, y));
        wr * smoothstep(1.0 - d / CUP_WIDTH_MM)
    }

    /// Weight of the arch support at (x, y): a dome on the arch point, along the foot over
    /// 0.14 of the length each way, across it from the axis to past the medial border.
    pub fn arch_weight(&self, x: f64, y: f64) -> f64 {
        let ap = self.marks.arch_point;
        let ay = ap.y.abs().max(15.0);
        dome(x - ap.x, y - ap.y, 0.14 * self.foot_length_mm, ay)
    }

    /// The metatarsal pad's height at (x, y).
    pub fn pad(&self, x: f64, y: f64) -> f64 {
        let h = self.params.met_pad_height_mm;
        if h == 0.0 {
            return 0.0;
        }
        h * dome(
            x - self.pad_apex.x,
            y - self.pad_apex.y,
            PAD_HALF_LENGTH_MM,
            PAD_HALF_WIDTH_MM,
        )
    }

    /// The first ray cut-out's depth at (x, y): medial of the middle line between the first
    /// and second heads, from [`CUTOUT_BEHIND_MM`] behind the first head forward, edges
    /// blended over 3 mm.
    pub fn cutout(&self, x: f64, y: f64) -> f64 {
        let d = self.params.first_ray_cutout_mm;
        if d == 0.0 {
            return 0.0;
        }
        let (m1, m2) = (self.marks.mt1_head, self.marks.mt2_head);
        let mid = 0.5 * (m1.y + m2.y);
        let sx = smoothstep((x - (m1.x - CUTOUT_BEHIND_MM)) / BLEND_MM);
        let sy = smoothstep(self.medial * (y - mid) / BLEND_MM);
        d * sx * sy
    }

    /// The surface the foot stands on, above the foot's own height and the seat: heel cup
    /// and arch support applied (mm). Never below the shoe's floor.
    pub fn contact(&self, x: f64, y: f64) -> f64 {
        let f = self.foot_at(x, y);
        let mut r = f;
        let g = self.cup_weight(x, y);
        if g > 0.0 {
            let d = self.params.heel_cup_depth_mm;
            // Up to the cup's surface, and never above its rim (the cup's edge cuts the
            // foot's side where the scan rises higher than the rim).
            r = r.max(self.seat_mm + d * g);
            r = r.min(self.seat_mm + d + (1.0 - g) * CUP_CLAMP_MM);
        }
        let a = self.arch_weight(x, y);
        if a > 0.0 {
            r += (self.arch_target_mm - self.scanned_arch_mm) * a;
        }
        r.max(0.0)
    }

    /// Top of the insole with its cover (what the foot touches), above the shoe's floor.
    pub fn top(&self, x: f64, y: f64) -> f64 {
        self.params.base_thickness_mm
            + self.lift(x)
            + self.rear_post(x, y)
            + self.fore_post(x, y)
            + self.contact(x, y)
            + self.pad(x, y)
            - self.cutout(x, y)
    }

    /// Top of the shell (the mesh's top).
    pub fn shell_top(&self, x: f64, y: f64) -> f64 {
        self.top(x, y) - self.params.top_cover_mm
    }

    /// Whether a correction other than the lift and the posts acts at (x, y) (the heel cup,
    /// the arch support, the pad or the cut-out): elsewhere the top follows the foot.
    pub fn corrected(&self, x: f64, y: f64) -> bool {
        self.cup_weight(x, y) > 0.0
            || (self.arch_weight(x, y) > 0.0 && self.arch_target_mm != self.scanned_arch_mm)
            || self.pad(x, y) > 0.0
            || self.cutout(x, y) > 0.0
            || (x > self.toe_line_x - self.foot.cell_mm && self.foot_at(x, y) >= TOE_CAP_MM - 1e-3)
    }

    /// The solid on cells of `cell_mm`, bottom at z = 0.
    pub fn solid(&self, cell_mm: f64) -> Result<OutlineSolid, InsoleError> {
        outline_solid(&self.outline, cell_mm, Some(0.0), |x, y| {
            Some(self.shell_top(x, y))
        })
        .map_err(|e| InsoleError::Solid(e.to_string()))
    }

    /// The shoe's bottom curve at x (0 when the bottom is flat).
    pub fn spring_at(&self, x: f64) -> f64 {
        self.spring.as_ref().map_or(0.0, |s| s.at(x))
    }

    /// [`Self::solid`] bent onto the shoe's bottom curve: every vertex raised by the curve
    /// at its x. The walls stay vertical (each wall quad keeps two vertical edges, so it
    /// stays planar); the top and bottom follow the curve.
    pub fn bent_solid(&self, cell_mm: f64) -> Result<OutlineSolid, InsoleError> {
        let mut s = self.solid(cell_mm)?;
        if self.spring.is_some() {
            for v in &mut s.vertices {
                v[2] += self.spring_at(v.x);
            }
        }
        Ok(s)
    }

    /// A written (bent) mesh in the insole's own frame: the bottom curve taken off every
    /// vertex again, exactly, so heights and angles are measured as designed.
    pub fn unbent(&self, mesh: &TriMesh) -> TriMesh {
        let mut m = mesh.clone();
        if self.spring.is_some() {
            for v in &mut m.vertices {
                v.z -= self.spring_at(v.x);
            }
        }
        m
    }
}

/// How sharply a closed outline turns: the largest turning over any `window` mm of it, in
/// degrees per millimetre, and its total absolute turning in degrees (360 for a convex
/// outline). Measured on the outline resampled every 0.5 mm, so it sees corners however the
/// outline's vertices lie.
pub fn outline_turning(outline: &[P2], window: f64) -> (f64, f64) {
    let t = outline_turning_behind(outline, window, f64::INFINITY);
    (t.max, t.total)
}

/// How an outline turns (see [`outline_turning_behind`]).
#[derive(Clone, Copy, Debug)]
pub struct Turning {
    /// The largest turning over the window (deg/mm).
    pub max: f64,
    /// Where it is (mm, the outline's frame).
    pub at: P2,
    /// The total absolute turning (deg).
    pub total: f64,
}

/// [`outline_turning`] with the largest turning taken only where x < `x_max` (behind the
/// toes, whose lobes are the foot's own shape), with where it is; the total over the whole
/// outline.
pub fn outline_turning_behind(outline: &[P2], window: f64, x_max: f64) -> Turning {
    let step = 0.5;
    let q = resample_closed(outline, step);
    let n = q.len();
    let w = ((window / step).round() as usize).max(1);
    let heading = |i: usize| {
        let (a, b) = (q[i % n], q[(i + w) % n]);
        (b.y - a.y).atan2(b.x - a.x)
    };
    let wrap = |a: f64| {
        let t = std::f64::consts::TAU;
        (a + t / 2.0).rem_euclid(t) - t / 2.0
    };
    let mut max = 0.0f64;
    let mut at = P2::new(f64::NAN, f64::NAN);
    let mut total = 0.0;
    for i in 0..n {
        // The heading of the chord behind the point and of the one ahead of it.
        let turn = wrap(heading(i + n - w) - heading(i)).abs();
        let rate = turn.to_degrees() / (w as f64 * step);
        if q[i].x < x_max && rate > max {
            (max, at) = (rate, q[i]);
        }
        let one = wrap({
            let (a, b, c) = (q[(i + n - 1) % n], q[i], q[(i + 1) % n]);
            (c.y - b.y).atan2(c.x - b.x) - (b.y - a.y).atan2(b.x - a.x)
        });
        total += one.abs();
    }
    Turning {
        max,
        at,
        total: total.to_degrees(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An ellipse 240 x 90 mm drawn as a 0.5 mm raster's staircase, with a kink (a 2 mm
    /// notch over 1.5 mm) as the last's edge leaves one: the fair outline turns no faster
    /// than a 10 mm radius anywhere and about once in all, and stays within 0.6 mm of the
    /// ellipse.
    #[test]
    fn fair_outline_smooths_steps_and_kinks() {
        let (a, b) = (120.0, 45.0);
        let mut raw = Vec::new();
        for i in 0..2000 {
            let t = i as f64 / 2000.0 * std::f64::consts::TAU;
            let mut p = P2::new(a * t.cos(), b * t.sin());
            if (200..203).contains(&i) {
                p.y -= 2.0;
            }
            raw.push(P2::new(
                (p.x / 0.5).round() * 0.5,
                (p.y / 0.5).round() * 0.5,
            ));
        }
        raw.dedup();
        let (max_raw, total_raw) = outline_turning(&raw, 2.0);
        // The earlier smoothing (8 passes of neighbour means 1/4, 1/2, 1/4, simplified to
        // 0.2 mm) left the kink: the notch is 4 raster vertices wide, the means spread 1 mm.
        let mut old = raw.clone();
        let k = old.len();
        for _ in 0..8 {
            let prev = old.clone();
            for i in 0..k {
                let (a, b, c) = (prev[(i + k - 1) % k], prev[i], prev[(i + 1) % k]);
                old[i] = P2::new(
                    0.25 * a.x + 0.5 * b.x + 0.25 * c.x,
                    0.25 * a.y + 0.5 * b.y + 0.25 * c.y,
                );
            }
        }
        let old = Polygon::new(old).simplify(OUTLINE_TOL_MM).points;
        let (max_old, _) = outline_turning(&old, 2.0);
        assert!(max_old > 5.7, "the earlier smoothing: {max_old} deg/mm");
        let fair = fair_closed(&raw, FAIR_SPACING_MM, FAIR_WAVELENGTH_MM);
        let (max, total) = outline_turning(&fair, 2.0);
        println!(
            "turning: raw {max_raw:.1} deg/mm, {total_raw:.0} deg in all; earlier smoothing \
             {max_old:.1} deg/mm; fair {max:.2} deg/mm, {total:.1} deg"
        );
        // A 10 mm radius turns 5.7 deg a millimetre; the ellipse's tightest is a = 120,
        // b = 45: radius b^2 / a = 16.9 mm (3.4 deg/mm).
        assert!(max_raw > 20.0, "the raw outline has its kink: {max_raw}");
        assert!(max < 5.7, "{max} deg/mm");
        // The notch leaves a shallow dent (two gentle inflections), not a kink.
        assert!((total - 360.0).abs() < 30.0, "{total} deg in all");
        let ellipse: Vec<P2> = (0..4000)
            .map(|i| i as f64 / 4000.0 * std::f64::consts::TAU)
            .map(|t| P2::new(a * t.cos(), b * t.sin()))
            .collect();
        let off = fair
            .iter()
            .map(|p| {
                ellipse
                    .iter()
                    .map(|e| (e.x - p.x).hypot(e.y - p.y))
                    .fold(f64::MAX, f64::min)
            })
            .fold(0.0f64, f64::max);
        assert!(off < 0.6, "{off} mm off the ellipse");
    }
}
