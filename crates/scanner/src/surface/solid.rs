//! A closed solid over a simple polygon: the top surface sampled on a regular triangulation of
//! the polygon's interior whose boundary vertices lie on the polygon, vertical walls from the
//! polygon down to a flat bottom at `base_z`.
//!
//! The interior is cut by a square grid of `cell_mm` (marching squares on the exact polygon):
//! grid nodes inside the polygon are vertices; where the polygon crosses a grid edge its exact
//! crossing point is a vertex, shared by the two cells of that edge. Each cell's inside part
//! (the square cut by the polygon) is fanned into triangles; in a cell whose two opposite
//! corners alone are inside, the cell centre decides whether they are joined. The top's
//! boundary is then a chain of chords between crossing points, each within
//! cell^2 / (8 R) of a polygon of curvature radius R (0.003 mm for R = 10 mm and 0.5 mm
//! cells). Heights come from a sampler; nodes where it has none (e.g. bridged gaps) are filled
//! by the discrete Laplace equation from the nodes around them (a membrane: no new extremum),
//! and a crossing point without one takes its edge's inside node.
//!
//! The solid is watertight by construction (every edge in exactly two triangles, once in
//! each direction, outward normals); [`TriMesh::check_closed`] checks it.

use super::SurfaceError;
use footscan_geom::mesh::TriMesh;
use footscan_geom::{P2, P3};

/// A crossing closer than this fraction of a cell to a grid node is moved to this distance,
/// so no triangle degenerates (0.005 mm on 0.5 mm cells).
const MIN_FRACTION: f64 = 0.01;
/// The bottom's height when none is given: 2 mm below the glass (lower only when a height
/// is below -1 mm: then 1 mm under it).
pub const DEFAULT_BASE_Z: f64 = -2.0;
/// Grid nodes above this count are refused (memory: about 60 bytes per node).
pub const MAX_NODES: usize = 40_000_000;

/// The solid over a polygon: vertices are (top, bottom) pairs, bottom = top + 1.
#[derive(Clone, Debug, Default)]
pub struct OutlineSolid {
    pub vertices: Vec<P3>,
    /// Top triangles, counterclockwise seen from above (top vertex indices, even).
    pub top: Vec<[u32; 3]>,
    /// Boundary loops of the top, counterclockwise seen from above (top vertex indices).
    pub loops: Vec<Vec<u32>>,
    pub base_z: f64,
    /// Grid nodes inside the polygon, and those whose height came from the Laplace fill.
    pub inside_nodes: usize,
    pub filled_nodes: usize,
    /// Largest change of the last fill sweep (mm): how far the fill is from converged.
    pub fill_residual_mm: f64,
    /// The node grid: origin, cell, size, and each node's top vertex (u32::MAX outside).
    grid: NodeGrid,
}

#[derive(Clone, Debug, Default)]
struct NodeGrid {
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    node_v: Vec<u32>,
}

/// Builds the solid over the simple polygon `outline` (either orientation; at least three
/// vertices) on cells of `cell_mm`, heights from `height` (None where it has none), bottom at
/// `base_z` if given, else at [`DEFAULT_BASE_Z`] (or 1 mm under the lowest height if lower).
pub fn outline_solid(
    outline: &[P2],
    cell_mm: f64,
    base_z: Option<f64>,
    height: impl Fn(f64, f64) -> Option<f64>,
) -> Result<OutlineSolid, SurfaceError> {
    if !(cell_mm.is_finite() && cell_mm > 0.0) {
        return Err(SurfaceError::BadCell(cell_mm));
    }
    let mut poly: Vec<P2> = outline.to_vec();
    if poly.len() > 1 && poly[0] == poly[poly.len() - 1] {
        poly.pop();
    }
    if poly.len() < 3 || poly.iter().any(|p| !(p.x.is_finite() && p.y.is_finite())) {
        return Err(SurfaceError::Empty);
    }
    if signed_area(&poly) < 0.0 {
        poly.reverse();
    }
    let c = cell_mm;
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in &poly {
        x0 = x0.min(p.x);
        x1 = x1.max(p.x);
        y0 = y0.min(p.y);
        y1 = y1.max(p.y);
    }
    // One empty node column/row beyond the polygon on every side.
    let gx0 = (x0 / c).floor() * c - c;
    let gy0 = (y0 / c).floor() * c - c;
    let nx = ((x1 - gx0) / c).ceil() as usize + 2;
    let ny = ((y1 - gy0) / c).ceil() as usize + 2;
    if nx.saturating_mul(ny) > MAX_NODES {
        return Err(SurfaceError::TooManyCells {
            cell_mm,
            nx,
            ny,
            max: MAX_NODES,
        });
    }
    let gx = |i: usize| gx0 + i as f64 * c;
    let gy = |j: usize| gy0 + j as f64 * c;

    // Crossings of the polygon with every node row (y = gy(j)) and column (x = gx(i)),
    // half-open in the other coordinate so a vertex on a line counts once.
    let mut rows: Vec<Vec<f64>> = vec![Vec::new(); ny];
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); nx];
    let n = poly.len();
    for k in 0..n {
        let (p, q) = (poly[k], poly[(k + 1) % n]);
        for (lines, lo0, a, b, along, across) in [
            (&mut rows, gy0, p, q, 1usize, 0usize),
            (&mut cols, gx0, p, q, 0, 1),
        ] {
            let (ya, yb) = (a[along], b[along]);
            if ya == yb {
                continue;
            }
            let (lo, hi) = (ya.min(yb), ya.max(yb));
            // Lines t with lo <= t < hi: (t <= y) differs at the two ends.
            let j0 = ((lo - lo0) / c).ceil().max(0.0) as usize;
            let mut j = j0;
            while j < lines.len() {
                let t = lo0 + j as f64 * c;
                if t >= hi {
                    break;
                }
                if t >= lo {
                    let f = (t - ya) / (yb - ya);
                    lines[j].push(a[across] + f * (b[across] - a[across]));
                }
                j += 1;
            }
        }
    }
    for l in rows.iter_mut().chain(cols.iter_mut()) {
        l.sort_by(f64::total_cmp);
    }
    // Node (i, j) is inside when an odd number of row crossings lie left of it.
    let mut inside = vec![false; nx * ny];
    for j in 0..ny {
        let r = &rows[j];
        let mut k = 0;
        for i in 0..nx {
            let x = gx(i);
            while k < r.len() && r[k] < x {
                k += 1;
            }
            inside[j * nx + i] = k % 2 == 1;
        }
    }
    let inn = |i: usize, j: usize| inside[j * nx + i];

    let mut s = OutlineSolid::default();
    let mut zs: Vec<f64> = Vec::new(); // top height per top vertex (NaN: none yet)
    let mut node_v = vec![u32::MAX; nx * ny];
    let push = |s: &mut OutlineSolid, x: f64, y: f64| -> u32 {
        let v = s.vertices.len() as u32;
        s.vertices.push(P3::new(x, y, f64::NAN));
        s.vertices.push(P3::new(x, y, f64::NAN));
        v
    };
    for j in 0..ny {
        for i in 0..nx {
            if inn(i, j) {
                node_v[j * nx + i] = push(&mut s, gx(i), gy(j));
                s.inside_nodes += 1;
            }
        }
    }
    // Crossing vertices on horizontal edges (i, j)-(i+1, j) and vertical (i, j)-(i, j+1),
    // with the node whose height they fall back to.
    let mut h_v = vec![u32::MAX; nx * ny];
    let mut v_v = vec![u32::MAX; nx * ny];
    let mut fallback: Vec<(u32, u32)> = Vec::new();
    let pick = |list: &[f64], a: f64, b: f64| -> f64 {
        let lo = list.partition_point(|&t| t < a);
        let hi = list.partition_point(|&t| t <= b);
        let t = if hi > lo {
            list[(lo + hi - 1) / 2]
        } else {
            0.5 * (a + b)
        };
        let m = MIN_FRACTION * (b - a);
        t.clamp(a + m, b - m)
    };
    for j in 0..ny {
        for i in 0..nx {
            if i + 1 < nx && inn(i, j) != inn(i + 1, j) {
                let x = pick(&rows[j], gx(i), gx(i + 1));
                let v = push(&mut s, x, gy(j));
                h_v[j * nx + i] = v;
                let node = if inn(i, j) { (i, j) } else { (i + 1, j) };
                fallback.push((v, node_v[node.1 * nx + node.0]));
            }
            if j + 1 < ny && inn(i, j) != inn(i, j + 1) {
                let y = pick(&cols[i], gy(j), gy(j + 1));
                let v = push(&mut s, gx(i), y);
                v_v[j * nx + i] = v;
                let node = if inn(i, j) { (i, j) } else { (i, j + 1) };
                fallback.push((v, node_v[node.1 * nx + node.0]));
            }
        }
    }

    // Cells: the inside part of each, fanned; chords (crossing to crossing) are the boundary.
    let mut next = std::collections::HashMap::new();
    for j in 0..ny - 1 {
        for i in 0..nx - 1 {
            let corners = [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)];
            let ins = corners.map(|(a, b)| inn(a, b));
            let count = ins.iter().filter(|&&b| b).count();
            if count == 0 {
                continue;
            }
            let cv = corners.map(|(a, b)| node_v[b * nx + a]);
            // Crossings on the edges corner k -> k+1 (bottom, right, top, left).
            let ev = [
                h_v[j * nx + i],
                v_v[j * nx + i + 1],
                h_v[(j + 1) * nx + i],
                v_v[j * nx + i],
            ];
            // Walk counterclockwise: (vertex, is_crossing).
            let mut walk: Vec<(u32, bool)> = Vec::with_capacity(8);
            for k in 0..4 {
                if ins[k] {
                    walk.push((cv[k], false));
                }
                if ins[k] != ins[(k + 1) % 4] {
                    walk.push((ev[k], true));
                }
            }
            let saddle = count == 2 && ins[0] == ins[2];
            let pieces: Vec<Vec<(u32, bool)>> =
                if saddle && !point_in_polygon(&poly, P2::new(gx(i) + 0.5 * c, gy(j) + 0.5 * c)) {
                    // Two separate corners: split the hexagon after each corner's crossings.
                    let w = &walk;
                    if ins[0] {
                        // [c0, e0, e1, c2, e2, e3]
                        vec![vec![w[0], w[1], w[5]], vec![w[2], w[3], w[4]]]
                    } else {
                        // [e0, c1, e1, e2, c3, e3]
                        vec![vec![w[0], w[1], w[2]], vec![w[3], w[4], w[5]]]
                    }
                } else {
                    vec![walk]
                };
            for piece in pieces {
                let m = piece.len();
                for k in 1..m - 1 {
                    s.top.push([piece[0].0, piece[k].0, piece[k + 1].0]);
                }
                for k in 0..m {
                    let (a, b) = (piece[k], piece[(k + 1) % m]);
                    if a.1 && b.1 {
                        next.insert(a.0, b.0);
                    }
                }
            }
        }
    }

    // Heights: the sampler, then the Laplace fill of nodes without one, then crossings.
    zs.resize(s.vertices.len() / 2, f64::NAN);
    for (k, z) in zs.iter_mut().enumerate() {
        let p = s.vertices[2 * k];
        if let Some(h) = height(p.x, p.y).filter(|h| h.is_finite()) {
            *z = h;
        }
    }
    let (filled, residual) = laplace_fill(&node_v, &inside, nx, ny, &mut zs)?;
    s.grid = NodeGrid {
        x0: gx0,
        y0: gy0,
        cell: c,
        nx,
        ny,
        node_v,
    };
    s.filled_nodes = filled;
    s.fill_residual_mm = residual;
    for &(v, node) in &fallback {
        let (kv, kn) = (v as usize / 2, node as usize / 2);
        if !zs[kv].is_finite() {
            zs[kv] = zs[kn];
        }
    }
    let zmin = zs.iter().copied().fold(0.0f64, f64::min);
    s.base_z = base_z.unwrap_or((zmin - 1.0).min(DEFAULT_BASE_Z));
    for (k, z) in zs.iter().enumerate() {
        s.vertices[2 * k].z = *z;
        s.vertices[2 * k + 1].z = s.base_z;
    }

    // Boundary loops from the chords.
    let mut starts: Vec<u32> = next.keys().copied().collect();
    starts.sort_unstable();
    let mut seen = std::collections::HashSet::new();
    for st in starts {
        if seen.contains(&st) {
            continue;
        }
        let mut lp = vec![st];
        seen.insert(st);
        let mut v = next[&st];
        while v != st {
            if !seen.insert(v) {
                return Err(SurfaceError::Topology(format!(
                    "boundary vertex {v} reached twice"
                )));
            }
            lp.push(v);
            v = *next.get(&v).ok_or_else(|| {
                SurfaceError::Topology(format!("boundary chain open at vertex {v}"))
            })?;
        }
        s.loops.push(lp);
    }
    if s.top.is_empty() {
        return Err(SurfaceError::Empty);
    }
    Ok(s)
}

impl OutlineSolid {
    /// The closed triangle mesh: top, walls (two triangles per boundary chord), bottom (the
    /// top's triangulation at `base_z`, reversed).
    pub fn mesh(&self) -> TriMesh {
        let mut m = TriMesh::new(
            self.vertices.clone(),
            Vec::with_capacity(2 * self.top.len() + 2 * self.boundary_len()),
        );
        for &[a, b, c] in &self.top {
            m.triangles.push([a, b, c]);
            m.triangles.push([a + 1, c + 1, b + 1]);
        }
        for lp in &self.loops {
            for k in 0..lp.len() {
                let (a, b) = (lp[k], lp[(k + 1) % lp.len()]);
                m.triangles.push([a, a + 1, b + 1]);
                m.triangles.push([a, b + 1, b]);
            }
        }
        m
    }

    /// Top height at (x, y) from the grid nodes: bilinear in the node cell when its four
    /// corners are inside, else the nearest inside corner; None away from every inside node.
    pub fn height_at(&self, x: f64, y: f64) -> Option<f64> {
        let g = &self.grid;
        if g.node_v.is_empty() {
            return None;
        }
        let fx = (x - g.x0) / g.cell;
        let fy = (y - g.y0) / g.cell;
        let (i0, j0) = (fx.floor(), fy.floor());
        if i0 < 0.0 || j0 < 0.0 || i0 as usize + 1 >= g.nx || j0 as usize + 1 >= g.ny {
            return None;
        }
        let (i, j) = (i0 as usize, j0 as usize);
        let (u, v) = (fx - i0, fy - j0);
        let corners = [
            (i, j, (1.0 - u) * (1.0 - v)),
            (i + 1, j, u * (1.0 - v)),
            (i, j + 1, (1.0 - u) * v),
            (i + 1, j + 1, u * v),
        ];
        let z = |a: usize, b: usize| {
            let k = g.node_v[b * g.nx + a];
            (k != u32::MAX).then(|| self.vertices[k as usize].z)
        };
        if corners.iter().all(|&(a, b, _)| z(a, b).is_some()) {
            return Some(corners.iter().map(|&(a, b, w)| w * z(a, b).unwrap()).sum());
        }
        corners
            .iter()
            .filter_map(|&(a, b, w)| z(a, b).map(|h| (w, h)))
            .max_by(|p, q| p.0.total_cmp(&q.0))
            .map(|(_, h)| h)
    }

    /// Boundary chords over all loops.
    pub fn boundary_len(&self) -> usize {
        self.loops.iter().map(Vec::len).sum()
    }

    /// Area of the top seen from above (mm^2).
    pub fn area_mm2(&self) -> f64 {
        self.top
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|k| self.vertices[k as usize]);
                0.5 * ((b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y))
            })
            .sum()
    }

    /// Connected pieces of the top (triangles sharing a vertex belong together).
    pub fn components(&self) -> usize {
        let n = self.vertices.len() / 2;
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn find(p: &mut [u32], mut x: u32) -> u32 {
            while p[x as usize] != x {
                p[x as usize] = p[p[x as usize] as usize];
                x = p[x as usize];
            }
            x
        }
        let mut used = vec![false; n];
        for t in &self.top {
            let [a, b, c] = t.map(|k| k / 2);
            for k in [a, b, c] {
                used[k as usize] = true;
            }
            for (x, y) in [(a, b), (b, c)] {
                let (rx, ry) = (find(&mut parent, x), find(&mut parent, y));
                if rx != ry {
                    parent[rx as usize] = ry;
                }
            }
        }
        (0..n as u32)
            .filter(|&k| used[k as usize] && find(&mut parent, k) == k)
            .count()
    }
}

/// Gauss-Seidel with over-relaxation on the inside nodes without a height, each the mean of
/// its inside neighbours (outside neighbours left out: zero slope across the boundary).
/// Unknowns start from the mean of their known neighbours, spread outward by rings.
fn laplace_fill(
    node_v: &[u32],
    inside: &[bool],
    nx: usize,
    ny: usize,
    zs: &mut [f64],
) -> Result<(usize, f64), SurfaceError> {
    let z_of = |zs: &[f64], k: usize| zs[node_v[k] as usize / 2];
    let unknown: Vec<usize> = (0..nx * ny)
        .filter(|&k| inside[k] && !z_of(zs, k).is_finite())
        .collect();
    if unknown.is_empty() {
        return Ok((0, 0.0));
    }
    let neighbours = |k: usize| {
        let (i, j) = (k % nx, k / nx);
        let mut out = [usize::MAX; 4];
        if i > 0 {
            out[0] = k - 1;
        }
        if i + 1 < nx {
            out[1] = k + 1;
        }
        if j > 0 {
            out[2] = k - nx;
        }
        if j + 1 < ny {
            out[3] = k + nx;
        }
        out.map(|n| {
            if n != usize::MAX && inside[n] {
                n
            } else {
                usize::MAX
            }
        })
    };
    // Initial values by rings from the known nodes.
    let mut todo = unknown.clone();
    while !todo.is_empty() {
        let mut set = Vec::new();
        let mut rest = Vec::new();
        for &k in &todo {
            let (mut sum, mut cnt) = (0.0, 0);
            for n in neighbours(k) {
                if n != usize::MAX && z_of(zs, n).is_finite() {
                    sum += z_of(zs, n);
                    cnt += 1;
                }
            }
            if cnt > 0 {
                set.push((k, sum / cnt as f64));
            } else {
                rest.push(k);
            }
        }
        if set.is_empty() {
            // A piece with no height anywhere: the mean of all known heights.
            let known: Vec<f64> = (0..nx * ny)
                .filter(|&k| inside[k] && z_of(zs, k).is_finite())
                .map(|k| z_of(zs, k))
                .collect();
            if known.is_empty() {
                return Err(SurfaceError::Empty);
            }
            let mean = known.iter().sum::<f64>() / known.len() as f64;
            for &k in &rest {
                zs[node_v[k] as usize / 2] = mean;
            }
            break;
        }
        for (k, z) in set {
            zs[node_v[k] as usize / 2] = z;
        }
        todo = rest;
    }
    let omega = 1.85;
    let mut residual = f64::INFINITY;
    for _ in 0..5000 {
        residual = 0.0f64;
        for &k in &unknown {
            let (mut sum, mut cnt) = (0.0, 0);
            for n in neighbours(k) {
                if n != usize::MAX {
                    sum += z_of(zs, n);
                    cnt += 1;
                }
            }
            if cnt == 0 {
                continue;
            }
            let v = node_v[k] as usize / 2;
            let d = sum / cnt as f64 - zs[v];
            zs[v] += omega * d;
            residual = residual.max(d.abs());
        }
        if residual < 1e-5 {
            break;
        }
    }
    Ok((unknown.len(), residual))
}

/// Twice the signed area of a closed polygon, positive when counterclockwise.
fn signed_area(p: &[P2]) -> f64 {
    let n = p.len();
    (0..n)
        .map(|k| {
            let (a, b) = (p[k], p[(k + 1) % n]);
            a.x * b.y - b.x * a.y
        })
        .sum()
}

/// Even-odd test, with the row rule of the grid (crossings strictly left of the point).
fn point_in_polygon(p: &[P2], q: P2) -> bool {
    let n = p.len();
    let mut odd = false;
    for k in 0..n {
        let (a, b) = (p[k], p[(k + 1) % n]);
        if (a.y <= q.y) != (b.y <= q.y) {
            let x = a.x + (q.y - a.y) / (b.y - a.y) * (b.x - a.x);
            if x < q.x {
                odd = !odd;
            }
        }
    }
    odd
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(r: f64, n: usize, cx: f64, cy: f64) -> Vec<P2> {
        (0..n)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / n as f64;
                P2::new(cx + r * t.cos(), cy + r * t.sin())
            })
            .collect()
    }

    #[test]
    fn disc_solid_is_watertight_reaches_the_outline_and_has_the_volume() {
        let poly = circle(20.0, 720, 3.3, -1.7);
        let s = outline_solid(&poly, 0.5, Some(-2.0), |_, _| Some(3.0)).unwrap();
        let m = s.mesh();
        m.check_closed().unwrap();
        assert_eq!(s.loops.len(), 1);
        assert_eq!(s.components(), 1);
        // Polygon area (inscribed 720-gon) times the 5 mm height, to the chord error.
        let area = 0.5 * signed_area(&poly);
        let v = m.volume();
        assert!(
            (v - 5.0 * area).abs() < 5.0 * area * 2e-4,
            "{v} vs {}",
            5.0 * area
        );
        let xmax = m.vertices.iter().map(|p| p[0]).fold(f64::MIN, f64::max);
        assert!((xmax - 23.3).abs() < 0.01, "{xmax}");
        // Every boundary vertex lies on the circle.
        for lp in &s.loops {
            for &k in lp {
                let p = m.vertices[k as usize];
                let r = (p[0] - 3.3).hypot(p[1] + 1.7);
                assert!((r - 20.0).abs() < 0.01, "{r}");
            }
        }
    }

    #[test]
    fn gaps_in_the_heights_are_filled_between_their_neighbours() {
        // Heights known only left of x = 5 (z = 1) and right of x = 15 (z = 3): the fill
        // in between lies between them, rising left to right.
        let poly = [[0.0, 0.0], [20.0, 0.0], [20.0, 4.0], [0.0, 4.0]].map(P2::from);
        let s = outline_solid(&poly, 0.5, None, |x, _| {
            if x < 5.0 {
                Some(1.0)
            } else if x > 15.0 {
                Some(3.0)
            } else {
                None
            }
        })
        .unwrap();
        s.mesh().check_closed().unwrap();
        assert!(s.filled_nodes > 0);
        assert!(s.fill_residual_mm < 1e-4);
        let mid = s
            .vertices
            .iter()
            .step_by(2)
            .find(|p| (p[0] - 10.0).abs() < 0.3 && (p[1] - 2.0).abs() < 0.3)
            .unwrap();
        assert!((mid[2] - 2.0).abs() < 0.1, "{mid:?}");
        assert_eq!(s.base_z, -2.0);
    }

    #[test]
    fn a_neck_thinner_than_a_cell_leaves_the_mesh_watertight() {
        // Two squares joined by a 0.3 mm neck between node rows (0.5 mm cells): the grid
        // cannot see the neck, so the top falls into two pieces, each closed.
        let poly = [
            [0.0, 0.0],
            [10.0, 0.0],
            [10.0, 4.6],
            [20.0, 4.6],
            [20.0, 0.0],
            [30.0, 0.0],
            [30.0, 10.0],
            [20.0, 10.0],
            [20.0, 4.9],
            [10.0, 4.9],
            [10.0, 10.0],
            [0.0, 10.0],
        ]
        .map(P2::from);
        let s = outline_solid(&poly, 0.5, None, |_, _| Some(1.0)).unwrap();
        s.mesh().check_closed().unwrap();
        assert_eq!(s.components(), 2);
        // A neck across a node row is kept: one piece.
        let mut wide = poly;
        wide[2].y = 4.85;
        wide[3].y = 4.85;
        wide[8].y = 5.15;
        wide[9].y = 5.15;
        let s = outline_solid(&wide, 0.5, None, |_, _| Some(1.0)).unwrap();
        s.mesh().check_closed().unwrap();
        assert_eq!(s.components(), 1);
    }
}
