//! Reading the staircase pass: which step each row sees, where the line on a step ends (at a
//! side of the block or at a riser), and the starting values that the ends give (F from the
//! known width, c_y, the block's pose).
//!
//! The block stands at a slight yaw to the slider axis (a few degrees), like a slanted-edge
//! target: the rows where a side or a riser cuts the line then move from frame to frame, so the
//! whole-row quantisation of an end averages out over the pass, and a riser crosses the line
//! inside a frame (which locates it along x to a small fraction of the slider step).

use super::closed_form::median;
use super::data::InsystemData;
use super::{CalibError, CameraModel};
use nalgebra::{Matrix3, Vector3};

/// A run of consecutive rows of one frame on one step face.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Piece {
    pub frame: usize,
    pub step: usize,
    pub first: usize,
    pub last: usize,
    pub first_end: End,
    pub last_end: End,
}

/// What the rows beyond a piece's end show.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum End {
    /// Nothing: a side of the block, or one of its two end faces.
    Free,
    /// Another step face: the riser to step `other`.
    Neighbour { other: usize },
    /// The image border, a dropout or something unexplained: not used.
    Unknown,
}

/// The block edge that ends a piece, in block coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Edge {
    /// A side, w = 0 or w = W.
    Side { w: f64 },
    /// A riser or an end face, u = const.
    Face { u: f64 },
}

/// One end of one piece, identified.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EndEdge {
    pub piece: usize,
    /// The piece's first row (else its last).
    pub first: bool,
    pub edge: Edge,
}

/// Rows whose height is within this fraction of the smallest step spacing of a step face are
/// assigned to it.
const ASSIGN_FRACTION: f64 = 0.35;
/// Rows searched beyond a piece's end for the neighbouring piece.
const NEIGHBOUR_ROWS: usize = 12;
/// Shortest piece used.
const MIN_PIECE_ROWS: usize = 5;

/// Step index of every row of every frame (None: no line or no step face near its height),
/// from the height `z_of(row, col)` of a starting model.
pub fn assign_steps(
    data: &InsystemData,
    z_of: &dyn Fn(usize, f64) -> f64,
) -> Vec<Vec<Option<usize>>> {
    let hs = &data.staircase.heights_mm;
    let mut spacing = f64::INFINITY;
    for (i, a) in hs.iter().enumerate() {
        for b in &hs[i + 1..] {
            spacing = spacing.min((a - b).abs());
        }
    }
    let tol = if spacing.is_finite() {
        ASSIGN_FRACTION * spacing
    } else {
        2.0
    };
    data.stair
        .iter()
        .map(|f| {
            f.col
                .iter()
                .enumerate()
                .map(|(r, &c)| {
                    if !c.is_finite() {
                        return None;
                    }
                    let z = z_of(r, c);
                    hs.iter()
                        .enumerate()
                        .map(|(j, h)| (j, (z - h).abs()))
                        .filter(|(_, d)| *d < tol)
                        .min_by(|a, b| a.1.total_cmp(&b.1))
                        .map(|(j, _)| j)
                })
                .collect()
        })
        .collect()
}

/// Pieces of every frame with their ends classified.
pub fn pieces(steps: &[Vec<Option<usize>>]) -> Vec<Piece> {
    let mut out = Vec::new();
    for (fi, rows) in steps.iter().enumerate() {
        let n = rows.len();
        let mut r = 0;
        while r < n {
            let Some(j) = rows[r] else {
                r += 1;
                continue;
            };
            let first = r;
            while r + 1 < n && rows[r + 1] == Some(j) {
                r += 1;
            }
            let last = r;
            r += 1;
            if last + 1 - first < MIN_PIECE_ROWS {
                continue;
            }
            let beyond_first = (0..first).rev().take(NEIGHBOUR_ROWS);
            let beyond_last = (last + 1..n).take(NEIGHBOUR_ROWS);
            out.push(Piece {
                frame: fi,
                step: j,
                first,
                last,
                first_end: classify(rows, j, first, beyond_first),
                last_end: classify(rows, j, last, beyond_last),
            });
        }
    }
    out
}

fn classify(
    rows: &[Option<usize>],
    step: usize,
    end: usize,
    mut beyond: impl Iterator<Item = usize>,
) -> End {
    if end <= 1 || end + 2 >= rows.len() {
        return End::Unknown;
    }
    match beyond.find(|&r| rows[r].is_some()) {
        None => End::Free,
        Some(r) => match rows[r] {
            Some(other) if other != step => End::Neighbour { other },
            _ => End::Unknown,
        },
    }
}

/// F from the pieces that run from nothing to nothing (most of them span the block's whole
/// width), under the ideal model with `d_mm` from the closed forms: the median of
/// `rows (D + h) / W`.
pub fn scale(data: &InsystemData, pieces: &[Piece], d_mm: f64) -> Result<f64, CalibError> {
    let w = data.staircase.width_mm;
    let h = &data.staircase.heights_mm;
    let fs: Vec<f64> = pieces
        .iter()
        .filter(|p| p.first_end == End::Free && p.last_end == End::Free)
        .map(|p| (p.last + 1 - p.first) as f64 * (d_mm + h[p.step]) / w)
        .collect();
    if fs.is_empty() {
        return Err(CalibError::NoUsableRows {
            target: "the staircase gauge block".into(),
            detail: "no frame shows a step across the block's whole width (both sides in view): \
                     put the block in the middle of the glass and cover it with the pass"
                .into(),
        });
    }
    Ok(median(&fs))
}

/// The block's pose (x0, y0, yaw in degrees) from the piece ends triangulated with a starting
/// model: a robust straight-line fit of the two sides (shared direction, known width apart),
/// then the risers along them.
pub fn block_pose(
    data: &InsystemData,
    pieces: &[Piece],
    model: &CameraModel,
) -> Result<(f64, f64, f64), CalibError> {
    let tri = model.triangulator();
    let g = &data.staircase;
    let point = |p: &Piece, row: usize| {
        let f = &data.stair[p.frame];
        tri.point(f.x_mm, f.col[row], row as f64)
    };
    let unusable = |detail: &str| CalibError::NoUsableRows {
        target: "the staircase gauge block".into(),
        detail: detail.into(),
    };
    // Free ends: mostly sides (first row: w = 0, last row: w = W), some end faces (outliers).
    let mut side = Vec::new();
    for p in pieces {
        if p.first_end == End::Free {
            side.extend(point(p, p.first).map(|q| (q, 0.0)));
        }
        if p.last_end == End::Free {
            side.extend(point(p, p.last).map(|q| (q, 1.0)));
        }
    }
    if !(side.iter().any(|s| s.1 == 0.0) && side.iter().any(|s| s.1 == 1.0)) {
        return Err(unusable("both sides of the block must be seen"));
    }
    // y = c0 + t x on the w = 0 side, y = c1 + t x on the other; reweighted until the end faces
    // drop out.
    let mut keep = vec![true; side.len()];
    let mut sol = Vector3::zeros();
    for _ in 0..4 {
        let mut ata = Matrix3::zeros();
        let mut atb = Vector3::zeros();
        for ((q, s), _) in side.iter().zip(&keep).filter(|(_, k)| **k) {
            let a = Vector3::new(1.0 - s, *s, q[0]);
            ata += a * a.transpose();
            atb += a * q[1];
        }
        sol = ata
            .lu()
            .solve(&atb)
            .ok_or_else(|| unusable("its sides do not determine a line (too few side ends)"))?;
        let res: Vec<f64> = side
            .iter()
            .map(|(q, s)| q[1] - (sol[0] * (1.0 - s) + sol[1] * s + sol[2] * q[0]))
            .collect();
        let spread = 1.4826 * median(&res.iter().map(|r| r.abs()).collect::<Vec<_>>());
        let tol = (4.0 * spread).max(0.3);
        for (k, r) in keep.iter_mut().zip(&res) {
            *k = r.abs() < tol;
        }
    }
    let (c0, c1, t) = (sol[0], sol[1], sol[2]);
    let yaw = t.atan();
    let (sn, cs) = yaw.sin_cos();
    let width_seen = (c1 - c0) * cs;
    if (width_seen - g.width_mm).abs() > 0.2 * g.width_mm {
        return Err(CalibError::Implausible(format!(
            "the staircase's sides are {width_seen:.1} mm apart but its drawing says {} mm: \
             wrong block or wrong plan",
            g.width_mm
        )));
    }
    // Risers: (x - x0) cos + (y - y0) sin = U with y0 = c0 + t x0.
    let mut x0s = Vec::new();
    for p in pieces {
        for (end, row) in [(p.first_end, p.first), (p.last_end, p.last)] {
            let End::Neighbour { other } = end else {
                continue;
            };
            if !riser_usable(g, p.step, other) {
                continue;
            }
            let u = g.step_start(p.step.max(other));
            if let Some(q) = point(p, row) {
                x0s.push((q[0] * cs + (q[1] - c0) * sn - u) / (cs + t * sn));
            }
        }
    }
    if x0s.is_empty() {
        return Err(unusable(
            "the pass never crossed a riser inside a frame: place the block at a few degrees \
             to the slider axis and cover its whole length",
        ));
    }
    let x0 = median(&x0s);
    Ok((x0, c0 + t * x0, yaw.to_degrees()))
}

/// Identify the block edge at every usable piece end: the end's point, triangulated with the
/// starting model, in block coordinates at the starting pose, must lie within `tol_mm` of the
/// edge its kind allows and of no other edge of the block (ends near a corner are left out).
/// A free end is a side (w = 0 at a first row, w = W at a last row) or, on the first or last
/// step, the block's end face; a neighbour end is the riser between the two steps, used from
/// the lower face only (see [`riser_usable`]).
pub fn identify_ends(
    data: &InsystemData,
    pieces: &[Piece],
    model: &CameraModel,
    pose: (f64, f64, f64),
    tol_mm: f64,
) -> Vec<EndEdge> {
    let tri = model.triangulator();
    let g = &data.staircase;
    let n = g.heights_mm.len();
    let (sn, cs) = pose.2.to_radians().sin_cos();
    // Every edge line of the block: both sides and every u = const line (risers, end faces).
    let mut all = vec![Edge::Side { w: 0.0 }, Edge::Side { w: g.width_mm }];
    all.extend((0..=n).map(|j| Edge::Face { u: g.step_start(j) }));
    let dist = |e: &Edge, u: f64, w: f64| match *e {
        Edge::Side { w: we } => (w - we).abs(),
        Edge::Face { u: ue } => (u - ue).abs(),
    };
    let mut out = Vec::new();
    for (i, p) in pieces.iter().enumerate() {
        let f = &data.stair[p.frame];
        for (end, row, first) in [(p.first_end, p.first, true), (p.last_end, p.last, false)] {
            let mut cands = Vec::new();
            match end {
                End::Free => {
                    cands.push(Edge::Side {
                        w: if first { 0.0 } else { g.width_mm },
                    });
                    if p.step == 0 {
                        cands.push(Edge::Face { u: 0.0 });
                    }
                    if p.step + 1 == n {
                        cands.push(Edge::Face { u: g.length() });
                    }
                }
                End::Neighbour { other } if riser_usable(g, p.step, other) => {
                    cands.push(Edge::Face {
                        u: g.step_start(p.step.max(other)),
                    });
                }
                _ => continue,
            }
            let Some(q) = tri.point(f.x_mm, f.col[row], row as f64) else {
                continue;
            };
            let (dx, dy) = (q[0] - pose.0, q[1] - pose.1);
            let (u, w) = (dx * cs + dy * sn, -dx * sn + dy * cs);
            let near: Vec<&Edge> = all.iter().filter(|e| dist(e, u, w) < tol_mm).collect();
            if let [edge] = near[..] {
                if cands.contains(edge) {
                    out.push(EndEdge {
                        piece: i,
                        first,
                        edge: *edge,
                    });
                }
            }
        }
    }
    out
}

/// A riser end is used from the lower of its two faces only: where the tilted laser plane
/// meets both faces at one y the lower one is what the camera sees, so the lower face's end is
/// always its own edge, while the upper face's end depends on the overlap.
pub fn riser_usable(g: &footscan_targets::StaircaseGeometry, step: usize, other: usize) -> bool {
    step.abs_diff(other) == 1 && g.heights_mm[step] < g.heights_mm[other]
}
