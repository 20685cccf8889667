//! A height map from the scan grid itself (before, or instead of, the plantar model).
//!
//! Each frame is a profile across the platform: runs of consecutive rows with a sole return
//! (single missing rows inside a run are bridged). A run's ends are taken half a row pitch
//! beyond its first and last point, or, along the sides of the foot, at the outer envelope of
//! the ends of the same run in the neighbouring frames (see [`envelope_ends`]). Between two
//! frames the footprint is interpolated run by
//! run: runs of neighbouring frames that overlap across y are the same piece of sole; for a
//! one-to-one pair the run's centre moves linearly and its squared half-width changes
//! linearly with x (exact for the rounded end of a heel or a toe, and indistinguishable from
//! linear along the sides). A run with no partner in the next frame (the end of a heel, a
//! toe or the ball) closes where its squared half-width, extrapolated from the previous
//! frame, reaches zero (at most at the next frame); one without a trend closes halfway. Runs
//! that split or merge between frames take the nearer frame's runs. Heights are interpolated
//! along each frame's profile and linearly between the two frames.

use super::MeasureError;
use crate::geom::HeightMap;
use crate::scandata::ScanGrid;
use footscan_geom::P3;

/// Missing rows bridged inside a run (a detector may drop a row or two in the sole).
const MAX_GAP_ROWS: usize = 2;
/// Fewer rows than this are a detector's stray (a reflection, a blotch of lit texture taken
/// for the line), not a piece of sole: one such row far off the glass triangulates metres
/// away and would stretch the map over the whole room.
const MIN_RUN_ROWS: usize = 3;

#[derive(Clone, Debug)]
struct Run {
    /// Points (x, y, h) by increasing y.
    pts: Vec<P3>,
    lo: f64,
    hi: f64,
}

impl Run {
    fn centre(&self) -> f64 {
        0.5 * (self.lo + self.hi)
    }
    fn half(&self) -> f64 {
        0.5 * (self.hi - self.lo)
    }
    /// Height at y, linear between points, constant beyond the ends. `k` is a cursor into
    /// the points for calls with non-decreasing y (start it at 0): a column's cells walk the
    /// run once instead of searching it per cell (the results of a scan wait on this, issue
    /// 34 item 2); it finds the point a binary search would.
    fn height(&self, y: f64, k: &mut usize) -> f64 {
        let p = &self.pts;
        while *k < p.len() && p[*k][1] < y {
            *k += 1;
        }
        let k = *k;
        if k == 0 {
            return p[0][2];
        }
        if k == p.len() {
            return p[k - 1][2];
        }
        let (a, b) = (p[k - 1], p[k]);
        let f = if b[1] > a[1] {
            (y - a[1]) / (b[1] - a[1])
        } else {
            0.0
        };
        a[2] + f * (b[2] - a[2])
    }
}

struct Frame {
    x: f64,
    runs: Vec<Run>,
}

/// How one group of runs fills the cells between two frames at a given x.
enum Piece<'a> {
    /// Interpolated pair: interval and heights blend from `a` (w = 0) to `b` (w = 1).
    Pair(&'a Run, &'a Run),
    /// A run that ends (or starts) between the frames: interval (centre, squared half-width)
    /// linear in x from `at` until `end`, heights of `run`.
    Tip {
        run: &'a Run,
        at: f64,
        end: f64,
        dc: f64,
        dh2: f64,
    },
    /// Split or merge: the runs of the nearer frame.
    Nearest(Vec<&'a Run>, Vec<&'a Run>),
}

/// Rasterise the valid points of `grid` into `cell_mm` cells (see the module doc).
pub fn rasterize_grid(grid: &ScanGrid, cell_mm: f64) -> Result<HeightMap, MeasureError> {
    if !(cell_mm > 0.0 && cell_mm <= 5.0) {
        return Err(MeasureError::Grid(format!(
            "cell_mm = {cell_mm}: valid range is (0, 5]"
        )));
    }
    let frames = frames_of(grid)?;
    let (mut x_lo, mut x_hi, mut y_lo, mut y_hi) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (k, f) in frames.iter().enumerate() {
        for r in &f.runs {
            let dx_prev = if k > 0 { f.x - frames[k - 1].x } else { 1.0 };
            let dx_next = frames.get(k + 1).map_or(1.0, |n| n.x - f.x);
            x_lo = x_lo.min(f.x - dx_prev);
            x_hi = x_hi.max(f.x + dx_next);
            y_lo = y_lo.min(r.lo);
            y_hi = y_hi.max(r.hi);
        }
    }
    let pad = 2.0 * cell_mm;
    let x0 = ((x_lo - pad) / cell_mm).floor() * cell_mm;
    let y0 = ((y_lo - pad) / cell_mm).floor() * cell_mm;
    let nx = ((x_hi + pad - x0) / cell_mm).ceil() as usize + 1;
    let ny = ((y_hi + pad - y0) / cell_mm).ceil() as usize + 1;
    if nx * ny > 50_000_000 {
        return Err(MeasureError::Grid(format!(
            "{nx} x {ny} cells of {cell_mm} mm: too many, use larger cells"
        )));
    }
    let mut map = HeightMap::new(x0, y0, cell_mm, nx, ny);
    // Empty frames one step beyond both ends, so runs in the first and last frame close.
    let first = Frame {
        x: frames[0].x - (frames.get(1).map_or(0.5, |f| f.x) - frames[0].x),
        runs: Vec::new(),
    };
    let n = frames.len();
    let last = Frame {
        x: frames[n - 1].x + (frames[n - 1].x - frames[n.saturating_sub(2)].x).max(0.01),
        runs: Vec::new(),
    };
    let all: Vec<&Frame> = std::iter::once(&first)
        .chain(frames.iter())
        .chain(std::iter::once(&last))
        .collect();
    for k in 0..all.len() - 1 {
        let (fa, fb) = (all[k], all[k + 1]);
        let pieces = pieces(&all, k);
        let i_start = ((fa.x - x0) / cell_mm).ceil().max(0.0) as usize;
        for i in i_start..nx {
            let x = map.x(i);
            if x >= fb.x {
                break;
            }
            let w = (x - fa.x) / (fb.x - fa.x);
            for piece in &pieces {
                fill_piece(&mut map, i, x, w, piece);
            }
        }
    }
    Ok(map)
}

/// Why a footprint from `grid` may be cut off: sole returns in the first or last image row
/// (the foot reaches the camera's field of view) or in the first or last frame (it extends
/// beyond the scanned travel). Measurements near a cut are wrong; empty when none.
pub fn grid_truncation(grid: &ScanGrid) -> Vec<String> {
    let (rows, nf) = (grid.rows, grid.frames.len());
    let mut out = Vec::new();
    if rows == 0 || nf == 0 {
        return out;
    }
    let valid = |f: usize, j: usize| grid.point(f, j)[0].is_finite();
    // A stray point is not a cut: at least 3 frames (rows) must touch.
    for (j, which) in [(0, "first"), (rows - 1, "last")] {
        let frames: Vec<usize> = (0..nf).filter(|&f| valid(f, j)).collect();
        if frames.len() >= 3 {
            let y = grid.point(frames[0], j)[1];
            out.push(format!(
                "the footprint reaches the {which} image row (y about {y:.0} mm) in {} frames: \
                 the foot is cut off at the edge of the camera's view; centre it across the platform",
                frames.len()
            ));
        }
    }
    for (f, which) in [(0, "first"), (nf - 1, "last")] {
        if (0..rows).filter(|&j| valid(f, j)).count() >= 3 {
            out.push(format!(
                "the footprint reaches the {which} frame (slider at {:.1} mm): the foot extends \
                 beyond the scanned travel",
                grid.frames[f].x_mm
            ));
        }
    }
    out
}

/// Runs per frame, frames by increasing x.
fn frames_of(grid: &ScanGrid) -> Result<Vec<Frame>, MeasureError> {
    let rows = grid.rows;
    let nf = grid.frames.len();
    if nf == 0 || grid.valid_count() == 0 {
        return Err(MeasureError::Grid("no valid points".into()));
    }
    // Nominal row pitch: median spacing of neighbouring valid rows.
    let mut pitches = Vec::new();
    for f in (0..nf).step_by((nf / 50).max(1)) {
        for j in 1..rows {
            let (a, b) = (grid.point(f, j - 1), grid.point(f, j));
            if a[1].is_finite() && b[1].is_finite() {
                pitches.push((b[1] - a[1]).abs());
            }
        }
    }
    pitches.sort_by(f64::total_cmp);
    let pitch = pitches.get(pitches.len() / 2).copied().unwrap_or(0.125);
    let mut frames = Vec::with_capacity(nf);
    let mut offsets = Vec::new();
    for f in 0..nf {
        let mut runs = Vec::new();
        let mut cur: Vec<P3> = Vec::new();
        let mut gap = 0;
        for j in 0..rows {
            let p = grid.point(f, j);
            if p.iter().all(|v| v.is_finite()) {
                cur.push(p);
                gap = 0;
            } else if !cur.is_empty() {
                gap += 1;
                if gap > MAX_GAP_ROWS {
                    let run = std::mem::take(&mut cur);
                    if run.len() >= MIN_RUN_ROWS {
                        runs.push(make_run(run, pitch));
                    }
                }
            }
        }
        if cur.len() >= MIN_RUN_ROWS {
            runs.push(make_run(cur, pitch));
        }
        runs.sort_by(|a, b| a.lo.total_cmp(&b.lo));
        let n: usize = runs.iter().map(|r| r.pts.len()).sum();
        let x = if n > 0 {
            let x = runs.iter().flat_map(|r| &r.pts).map(|p| p[0]).sum::<f64>() / n as f64;
            offsets.push(x - grid.frames[f].x_mm);
            x
        } else {
            f64::NAN
        };
        frames.push(Frame { x, runs });
    }
    offsets.sort_by(f64::total_cmp);
    let offset = offsets[offsets.len() / 2];
    for (f, fr) in frames.iter_mut().enumerate() {
        if fr.x.is_nan() {
            fr.x = grid.frames[f].x_mm + offset;
        }
    }
    frames.sort_by(|a, b| a.x.total_cmp(&b.x));
    // Frames at the same x (a stalled slider) add nothing: keep the first.
    frames.dedup_by(|b, a| b.x - a.x < 1e-6);
    envelope_ends(&mut frames);
    Ok(frames)
}

/// Half-length (mm along x) of the neighbourhood whose run ends form the envelope.
const ENVELOPE_HALF_MM: f64 = 8.0;
/// Largest outward move of a run end by the envelope (mm).
const ENVELOPE_MAX_MM: f64 = 0.6;

/// Where the sole curves up into the side of the foot, the camera's ray becomes tangent to it
/// (the profile folds in the image) and no row beyond the fold sees the line; the last row
/// that does lies a random fraction of a row short of the fold, which near the fold is a
/// long way in y (up to ~0.3 mm). The y of a return is precise (the row fixes it, the
/// height hardly moves it), so along a side the ends of the same run in neighbouring frames
/// are the fold minus a random shortfall, and their outer envelope is the fold: fit a
/// cubic in x to the last returns over +-8 mm and move the end out to the fit plus the
/// second largest outward residual (one stray point cannot set it). Only where the side runs
/// along x (|dy/dx| < 1); ends of the heel, the toes and the ball front keep the half-pitch
/// margin.
fn envelope_ends(frames: &mut [Frame]) {
    let nf = frames.len();
    // Unique one-to-one links to the next frame's run.
    let mut next: Vec<Vec<Option<usize>>> = Vec::with_capacity(nf);
    let mut prev: Vec<Vec<Option<usize>>> =
        frames.iter().map(|f| vec![None; f.runs.len()]).collect();
    for k in 0..nf {
        let mut links = vec![None; frames[k].runs.len()];
        if k + 1 < nf {
            for (i, r) in frames[k].runs.iter().enumerate() {
                if let Some(p) = unique_partner(r, &frames[k].runs, &frames[k + 1].runs) {
                    let j = frames[k + 1]
                        .runs
                        .iter()
                        .position(|q| std::ptr::eq(q, p))
                        .expect("partner is in the next frame");
                    links[i] = Some(j);
                    prev[k + 1][j] = Some(i);
                }
            }
        }
        next.push(links);
    }
    let raw: Vec<Vec<(f64, f64)>> = frames
        .iter()
        .map(|f| {
            f.runs
                .iter()
                .map(|r| (r.pts[0][1], r.pts[r.pts.len() - 1][1]))
                .collect()
        })
        .collect();
    // Outward position of an end: y at the high end, -y at the low end.
    let out = |kk: usize, ii: usize, is_lo: bool| -> f64 {
        let r: (f64, f64) = raw[kk][ii];
        if is_lo {
            -r.0
        } else {
            r.1
        }
    };
    let mut new_ends = Vec::new();
    for k in 0..nf {
        let xk = frames[k].x;
        for i in 0..frames[k].runs.len() {
            for is_lo in [false, true] {
                // The same end in the neighbouring frames, while it runs along x: where it
                // turns steep (the end of a toe or of the ball) no polynomial follows it.
                let (mut ds, mut vs) = (vec![0.0], vec![out(k, i, is_lo)]);
                for dir in [-1i64, 1] {
                    let (mut kk, mut ii) = (k, i);
                    loop {
                        let link = if dir < 0 { prev[kk][ii] } else { next[kk][ii] };
                        let Some(n) = link else { break };
                        let (k2, i2) = ((kk as i64 + dir) as usize, n);
                        let dx = (frames[k2].x - frames[kk].x).abs();
                        let step = (out(k2, i2, is_lo) - out(kk, ii, is_lo)).abs();
                        if (frames[k2].x - xk).abs() > ENVELOPE_HALF_MM || step > dx {
                            break;
                        }
                        (kk, ii) = (k2, i2);
                        ds.push(frames[kk].x - xk);
                        vs.push(out(kk, ii, is_lo));
                    }
                }
                if ds.len() < 7 {
                    continue;
                }
                let Some((c, off)) = envelope(&ds, &vs) else {
                    continue;
                };
                let end = c[0] + off;
                new_ends.push((k, i, is_lo, if is_lo { -end } else { end }));
            }
        }
    }
    for (k, i, is_lo, e) in new_ends {
        let r = &mut frames[k].runs[i];
        if is_lo {
            r.lo = r.lo.min(e).max(r.pts[0][1] - ENVELOPE_MAX_MM);
        } else {
            r.hi = r.hi.max(e).min(r.pts[r.pts.len() - 1][1] + ENVELOPE_MAX_MM);
        }
    }
}

/// Outer envelope of outward positions `v` sampled at offsets `d`: the cubic fit's
/// coefficients and the offset to add to it (the second largest residual); None where the
/// side is steep (|slope| >= 1).
fn envelope(d: &[f64], v: &[f64]) -> Option<(nalgebra::Vector4<f64>, f64)> {
    use nalgebra::{Matrix4, Vector4};
    let mut ata = Matrix4::zeros();
    let mut atb = Vector4::zeros();
    for (&x, &y) in d.iter().zip(v) {
        let row = Vector4::new(1.0, x, x * x, x * x * x);
        ata += row * row.transpose();
        atb += row * y;
    }
    let c = ata.lu().solve(&atb)?;
    if c[1].abs() >= 1.0 {
        return None;
    }
    let mut res: Vec<f64> = d
        .iter()
        .zip(v)
        .map(|(&x, &y)| y - (c[0] + x * (c[1] + x * (c[2] + x * c[3]))))
        .collect();
    res.sort_by(|a, b| b.total_cmp(a));
    Some((c, res[1].max(0.0)))
}

fn make_run(mut pts: Vec<P3>, pitch: f64) -> Run {
    pts.sort_by(|a, b| a[1].total_cmp(&b[1]));
    let n = pts.len();
    let (lo_pitch, hi_pitch) = if n >= 2 {
        (pts[1][1] - pts[0][1], pts[n - 1][1] - pts[n - 2][1])
    } else {
        (pitch, pitch)
    };
    // A bridged gap at an end would overstate the pitch there.
    let (lo_pitch, hi_pitch) = (lo_pitch.min(1.5 * pitch), hi_pitch.min(1.5 * pitch));
    Run {
        lo: pts[0][1] - 0.5 * lo_pitch,
        hi: pts[n - 1][1] + 0.5 * hi_pitch,
        pts,
    }
}

fn overlaps(a: &Run, b: &Run) -> bool {
    a.lo < b.hi && b.lo < a.hi
}

/// The unique partner of `r` in `other`, if r overlaps exactly one run there and that run
/// overlaps only r in r's frame.
fn unique_partner<'a>(r: &Run, own: &[Run], other: &'a [Run]) -> Option<&'a Run> {
    let mut it = other.iter().filter(|o| overlaps(r, o));
    let p = it.next()?;
    if it.next().is_some() || own.iter().filter(|o| overlaps(o, p)).count() != 1 {
        return None;
    }
    Some(p)
}

/// Pieces between frame k and k + 1 of `all`.
fn pieces<'a>(all: &[&'a Frame], k: usize) -> Vec<Piece<'a>> {
    let (fa, fb) = (all[k], all[k + 1]);
    let (na, nb) = (fa.runs.len(), fb.runs.len());
    // Union-find over a's runs (0..na) and b's runs (na..na+nb).
    let mut parent: Vec<usize> = (0..na + nb).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for (ia, ra) in fa.runs.iter().enumerate() {
        for (ib, rb) in fb.runs.iter().enumerate() {
            if overlaps(ra, rb) {
                let (x, y) = (find(&mut parent, ia), find(&mut parent, na + ib));
                parent[x] = y;
            }
        }
    }
    let mut groups: std::collections::BTreeMap<usize, (Vec<usize>, Vec<usize>)> =
        Default::default();
    for i in 0..na + nb {
        let g = find(&mut parent, i);
        let e = groups.entry(g).or_default();
        if i < na {
            e.0.push(i);
        } else {
            e.1.push(i - na);
        }
    }
    let mut out = Vec::new();
    for (_, (ga, gb)) in groups {
        match (ga.as_slice(), gb.as_slice()) {
            ([a], [b]) => out.push(Piece::Pair(&fa.runs[*a], &fb.runs[*b])),
            ([a], []) => {
                let run = &fa.runs[*a];
                let prev = (k > 0)
                    .then(|| unique_partner(run, &fa.runs, &all[k - 1].runs))
                    .flatten();
                out.push(tip(run, fa.x, fb.x, prev.map(|p| (p, all[k - 1].x))));
            }
            ([], [b]) => {
                let run = &fb.runs[*b];
                let next = all
                    .get(k + 2)
                    .and_then(|f| unique_partner(run, &fb.runs, &f.runs).map(|p| (p, f.x)));
                out.push(tip(run, fb.x, fa.x, next));
            }
            _ => out.push(Piece::Nearest(
                ga.iter().map(|&i| &fa.runs[i]).collect(),
                gb.iter().map(|&i| &fb.runs[i]).collect(),
            )),
        }
    }
    out
}

/// A run at `at` that has no partner toward `toward`; `trend` is its partner on the other
/// side (run and x), from which the closing point is extrapolated.
fn tip<'a>(run: &'a Run, at: f64, toward: f64, trend: Option<(&Run, f64)>) -> Piece<'a> {
    let span = toward - at;
    let h2 = run.half().powi(2);
    if let Some((p, xp)) = trend {
        let d = at - xp;
        // Rates per unit x toward `toward`.
        let dh2 = (h2 - p.half().powi(2)) / d;
        let dc = (run.centre() - p.centre()) / d;
        if dh2 * span.signum() < 0.0 {
            let reach = (h2 / -(dh2 * span.signum())).min(span.abs());
            return Piece::Tip {
                run,
                at,
                end: at + reach * span.signum(),
                dc,
                dh2,
            };
        }
    }
    Piece::Tip {
        run,
        at,
        end: at + 0.5 * span,
        dc: 0.0,
        dh2: 0.0,
    }
}

fn fill_piece(map: &mut HeightMap, i: usize, x: f64, w: f64, piece: &Piece) {
    let mut fill = |lo: f64, hi: f64, h: &mut dyn FnMut(f64) -> f64| {
        let j0 = ((lo - map.y0) / map.cell_mm).ceil().max(0.0) as usize;
        let mut j = j0;
        while j < map.ny && map.y(j) <= hi {
            let y = map.y(j);
            map.set(i, j, h(y));
            j += 1;
        }
    };
    match piece {
        Piece::Pair(a, b) => {
            let c = a.centre() + w * (b.centre() - a.centre());
            let h2 = a.half().powi(2) + w * (b.half().powi(2) - a.half().powi(2));
            let half = h2.max(0.0).sqrt();
            let (mut ka, mut kb) = (0, 0);
            fill(c - half, c + half, &mut |y| {
                (1.0 - w) * a.height(y, &mut ka) + w * b.height(y, &mut kb)
            });
        }
        Piece::Tip {
            run,
            at,
            end,
            dc,
            dh2,
        } => {
            let (lo_x, hi_x) = if end > at { (*at, *end) } else { (*end, *at) };
            if x < lo_x || x >= hi_x {
                return;
            }
            let d = x - at;
            let h2 = run.half().powi(2) + dh2 * d;
            if h2 <= 0.0 {
                return;
            }
            let c = run.centre() + dc * d;
            let half = h2.sqrt();
            let mut k = 0;
            fill(c - half, c + half, &mut |y| run.height(y, &mut k));
        }
        Piece::Nearest(ra, rb) => {
            let runs = if w < 0.5 { ra } else { rb };
            for r in runs {
                let mut k = 0;
                fill(r.lo, r.hi, &mut |y| r.height(y, &mut k));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::detect::LinePeak;
    use crate::scandata::{FrameMeta, FramePoints};

    /// Frames every 0.5 mm, rows every 0.125 mm (the default scanner's sampling) of a height
    /// field `h` (None outside), rows and frames offset from the shape by fractions.
    fn grid(h: impl Fn(f64, f64) -> Option<f64>, x: (f64, f64), rows: usize) -> ScanGrid {
        let mut g = ScanGrid::new(rows);
        let n = ((x.1 - x.0) / 0.5) as usize;
        for f in 0..=n {
            let xf = x.0 + 0.5 * f as f64 + 0.13;
            let points = (0..rows)
                .map(|r| {
                    let y = (r as f64 - rows as f64 / 2.0) * 0.125 + 0.037;
                    h(xf, y).map_or(P3::from([f64::NAN; 3]), |z| P3::new(xf, y, z))
                })
                .collect();
            g.push(FramePoints {
                meta: FrameMeta {
                    index: f as u64,
                    seq: f as u64,
                    timestamp: footscan_hal::Timestamp { nanos: 0 },
                    x_mm: xf - 70.0,
                },
                lines: vec![LinePeak::NONE; rows],
                points,
            });
        }
        g
    }

    #[test]
    fn a_stray_row_far_off_the_glass_is_not_a_piece_of_sole() {
        let disc = |x: f64, y: f64| ((x - 40.0).powi(2) + y * y <= 400.0).then_some(1.0);
        let clean = rasterize_grid(&grid(disc, (15.0, 65.0), 400), 0.5).unwrap();
        // The same disc with one stray row in the frame at x = 40, triangulated 1.8 m away.
        let stray = |x: f64, y: f64| {
            if (x - 40.13).abs() < 1e-9 && (y + 24.963).abs() < 1e-6 {
                Some(7397.0)
            } else {
                disc(x, y)
            }
        };
        let g = grid(stray, (15.0, 65.0), 400);
        assert_eq!(
            g.valid_count(),
            grid(disc, (15.0, 65.0), 400).valid_count() + 1
        );
        let map = rasterize_grid(&g, 0.5).unwrap();
        assert_eq!(
            (map.nx, map.ny, map.x0, map.y0),
            (clean.nx, clean.ny, clean.x0, clean.y0)
        );
    }

    #[test]
    fn disc_and_ellipse_are_rasterised_to_their_outline() {
        // A disc (heel-like, r = 30) and a small ellipse (toe-like), apart along x.
        let h = |x: f64, y: f64| -> Option<f64> {
            let d = ((x - 40.0).powi(2) + y * y).sqrt();
            let e = ((x - 90.0) / 12.0).powi(2) + ((y - 5.0) / 7.0).powi(2);
            (d <= 30.0 || e <= 1.0).then_some(0.3 * x / 10.0)
        };
        let g = grid(h, (0.0, 110.0), 640);
        assert!(grid_truncation(&g).is_empty());
        let map = rasterize_grid(&g, 0.1).unwrap();
        let regions = crate::measure::regions(&map);
        assert_eq!(regions.len(), 2);
        let disc = std::f64::consts::PI * 900.0;
        let ell = std::f64::consts::PI * 84.0;
        assert!(
            (regions[0].area_mm2 - disc).abs() / disc < 0.003,
            "{}",
            regions[0].area_mm2
        );
        assert!(
            (regions[1].area_mm2 - ell).abs() / ell < 0.01,
            "{}",
            regions[1].area_mm2
        );
        // Ends along x (between frames) within 0.1 mm.
        let xs = |r: &crate::measure::Region| {
            r.outline
                .iter()
                .map(|p| p[0])
                .fold((f64::MAX, f64::MIN), |a, x| (a.0.min(x), a.1.max(x)))
        };
        let (a, b) = xs(&regions[0]);
        assert!((a - 10.0).abs() < 0.1 && (b - 70.0).abs() < 0.1, "{a} {b}");
        let (a, b) = xs(&regions[1]);
        assert!((a - 78.0).abs() < 0.1 && (b - 102.0).abs() < 0.1, "{a} {b}");
        // Heights interpolated between frames.
        let (i, j) = map.cell_of(40.0, 0.0).unwrap();
        assert!((map.get(i, j) - 1.2).abs() < 1e-9);
    }

    #[test]
    fn cut_off_footprints_are_reported() {
        // Reaches both image rows (|y| > 40 is out of view) and the last frame.
        let h = |x: f64, y: f64| ((x - 70.0).powi(2) + y * y <= 2500.0).then_some(0.0);
        let g = grid(h, (0.0, 80.0), 640);
        let w = grid_truncation(&g);
        assert_eq!(w.len(), 3, "{w:?}");
        assert!(w[0].contains("first image row") && w[0].contains("cut off"));
        assert!(w[1].contains("last image row"));
        assert!(w[2].contains("last frame"));
        assert!(rasterize_grid(&g, 0.0).is_err());
        assert!(rasterize_grid(&ScanGrid::new(4), 0.1).is_err());
    }
}
