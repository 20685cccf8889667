//! The footprint of a height map: connected regions of valid cells and their outlines.
//!
//! A cell is in the footprint when its height is finite. Regions are 4-connected (cells that
//! touch only at a corner are apart, as toes separated by a one-cell gap should be). A region's
//! outline is traced by marching squares on the cell centres with the boundary halfway between
//! an inside and an outside centre: for a map whose valid cells are those with the centre in
//! the footprint, each outline vertex is within half a cell of the true outline, without bias.

use crate::geom::HeightMap;
use footscan_geom::polygon::Polygon;
use footscan_geom::{P2, V2};

/// One 4-connected region of valid cells.
#[derive(Clone, Debug)]
pub struct Region {
    /// Cell indices into the map's `z` (`HeightMap::index`), ascending.
    pub cells: Vec<usize>,
    /// Area in mm^2.
    pub area_mm2: f64,
    /// Mean cell centre (world mm).
    pub centroid: P2,
    /// Outer outline, counterclockwise, world mm (last vertex not repeated).
    pub outline: Vec<P2>,
}

impl Region {
    /// Its cells as (index, column, row) on a map `nx` cells wide, without a division per
    /// cell (the cells ascend, so the row only grows).
    pub fn cells_ij(&self, nx: usize) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
        let mut j = self.cells.first().map_or(0, |&k| k / nx);
        let mut start = j * nx;
        self.cells.iter().map(move |&k| {
            debug_assert!(k >= start, "cells not ascending");
            while k >= start + nx {
                start += nx;
                j += 1;
            }
            (k, k - start, j)
        })
    }
}

/// The 4-connected regions of the valid cells of `map`, largest first (equal sizes in the
/// order of their first cell), each with its cells in row order and its outline.
///
/// Labelled by runs: the valid cells of each row in runs, a run joined to the runs of the row
/// before that share a column, the joins resolved by union-find. A flood fill from cell to
/// cell took 20 ms on a scan's 2.5 M-cell map, and the results of a scan wait on this (issue
/// 34 item 2).
pub fn regions(map: &HeightMap) -> Vec<Region> {
    let (nx, ny) = (map.nx, map.ny);
    // Runs as (row, first column, one past the last column), in row order.
    let mut runs: Vec<(usize, usize, usize)> = Vec::new();
    let mut parent: Vec<usize> = Vec::new();
    fn root(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    let mut prev = 0..0;
    for j in 0..ny {
        let row = &map.z[j * nx..(j + 1) * nx];
        let start = runs.len();
        let mut q = prev.start;
        let mut i = 0;
        while i < nx {
            if !row[i].is_finite() {
                i += 1;
                continue;
            }
            let a = i;
            while i < nx && row[i].is_finite() {
                i += 1;
            }
            let id = runs.len();
            runs.push((j, a, i));
            parent.push(id);
            // The runs of the row before that share a column with [a, i).
            while q < prev.end && runs[q].2 <= a {
                q += 1;
            }
            let mut r = q;
            while r < prev.end && runs[r].1 < i {
                let (x, y) = (root(&mut parent, r), root(&mut parent, id));
                // The earlier run's root stays the root: a region is named by its first run.
                if x < y {
                    parent[y] = x;
                } else {
                    parent[x] = y;
                }
                r += 1;
            }
        }
        prev = start..runs.len();
    }
    // Regions in the order of their first run (of their first cell, row by row).
    let mut id_of = vec![u32::MAX; runs.len()];
    let mut label = vec![u32::MAX; nx * ny];
    let mut out: Vec<Region> = Vec::new();
    let mut sums: Vec<(f64, f64)> = Vec::new();
    let mut boxes: Vec<[usize; 4]> = Vec::new();
    for (n, &(j, a, b)) in runs.iter().enumerate() {
        let r = root(&mut parent, n);
        if id_of[r] == u32::MAX {
            id_of[r] = out.len() as u32;
            out.push(Region {
                cells: Vec::new(),
                area_mm2: 0.0,
                centroid: P2::origin(),
                outline: Vec::new(),
            });
            sums.push((0.0, 0.0));
            boxes.push([usize::MAX, 0, usize::MAX, 0]);
        }
        let id = id_of[r];
        let g = id as usize;
        let k = j * nx;
        out[g].cells.extend(k + a..k + b);
        label[k + a..k + b].fill(id);
        // Centre sums in the order of the cells, and the bounding box.
        let (sx, sy) = &mut sums[g];
        let y = map.y(j);
        for i in a..b {
            *sx += map.x(i);
            *sy += y;
        }
        let bb = &mut boxes[g];
        *bb = [bb[0].min(a), bb[1].max(b - 1), bb[2].min(j), bb[3].max(j)];
    }
    for (id, ((r, bb), (sx, sy))) in out.iter_mut().zip(&boxes).zip(&sums).enumerate() {
        let n = r.cells.len() as f64;
        r.area_mm2 = n * map.cell_mm * map.cell_mm;
        r.centroid = P2::new(sx / n, sy / n);
        r.outline = outer_outline(map, &label, id as u32, *bb);
    }
    out.sort_by_key(|r| std::cmp::Reverse(r.cells.len()));
    out
}

/// Marching squares over the bounding box of one region (label `id`), padded by one cell;
/// returns the loop of largest area (the outer boundary; holes are clockwise and smaller).
/// `bb` is the region's bounding box in cells: first and last column, first and last row.
fn outer_outline(map: &HeightMap, label: &[u32], id: u32, bb: [usize; 4]) -> Vec<P2> {
    let nx = map.nx;
    let [i0, i1, j0, j1] = bb;
    // Local padded grid: local (a, b) = cell (i0 + a - 1, j0 + b - 1).
    let w = i1 - i0 + 3;
    let h = j1 - j0 + 3;
    let inside = |a: usize, b: usize| -> bool {
        if a == 0 || b == 0 || a >= w - 1 || b >= h - 1 {
            return false;
        }
        label[(j0 + b - 1) * nx + (i0 + a - 1)] == id
    };
    // Crossing points are identified by the edge between two sample points: horizontal edge
    // (a, b)-(a+1, b) is 2 (b w + a), vertical (a, b)-(a, b+1) is 2 (b w + a) + 1.
    let hid = |a: usize, b: usize| 2 * (b * w + a);
    let vid = |a: usize, b: usize| 2 * (b * w + a) + 1;
    let mut next = std::collections::HashMap::new();
    // Two rows of samples, each looked up once.
    let row = |b: usize, r: &mut Vec<bool>| {
        r.clear();
        r.extend((0..w).map(|a| inside(a, b)));
    };
    let (mut lo, mut hi) = (Vec::with_capacity(w), Vec::with_capacity(w));
    row(0, &mut hi);
    for b in 0..h - 1 {
        std::mem::swap(&mut lo, &mut hi);
        row(b + 1, &mut hi);
        for a in 0..w - 1 {
            // Corners counterclockwise (x right, y up): (a,b), (a+1,b), (a+1,b+1), (a,b+1).
            let c = [lo[a], lo[a + 1], hi[a + 1], hi[a]];
            if c.iter().all(|&v| v) || c.iter().all(|&v| !v) {
                continue;
            }
            // Edge k joins corner k to corner k+1.
            let edges = [hid(a, b), vid(a + 1, b), hid(a, b + 1), vid(a, b)];
            for k in 0..4 {
                // An exit edge: inside -> outside going counterclockwise. The segment with
                // the inside on its left runs from it back (clockwise) to the first crossed
                // edge, which cuts off the inside corners between them (saddles stay apart).
                if c[k] && !c[(k + 1) % 4] {
                    let mut e = (k + 3) % 4;
                    while c[e] == c[(e + 1) % 4] {
                        e = (e + 3) % 4;
                    }
                    next.insert(edges[k], edges[e]);
                }
            }
        }
    }
    let point = |e: usize| -> P2 {
        let (k, vertical) = (e / 2, e % 2 == 1);
        let (a, b) = ((k % w) as f64, (k / w) as f64);
        let (a, b) = if vertical { (a, b + 0.5) } else { (a + 0.5, b) };
        P2::new(
            map.x0 + (i0 as f64 + a - 1.0) * map.cell_mm,
            map.y0 + (j0 as f64 + b - 1.0) * map.cell_mm,
        )
    };
    let mut best: Vec<P2> = Vec::new();
    let mut best_area = f64::NEG_INFINITY;
    let mut seen = std::collections::HashSet::new();
    let mut starts: Vec<usize> = next.keys().copied().collect();
    starts.sort_unstable();
    for s in starts {
        if seen.contains(&s) {
            continue;
        }
        let mut ring = Vec::new();
        let mut e = s;
        loop {
            seen.insert(e);
            ring.push(point(e));
            e = next[&e];
            if e == s {
                break;
            }
        }
        let a = signed_area(&ring);
        if a > best_area {
            best_area = a;
            best = ring;
        }
    }
    best
}

// The polygon operations live in the geometry layer (footscan_geom::polygon); these take the
// outlines as the slices the measurements hold.

/// Signed area of a closed polygon (counterclockwise positive).
pub fn signed_area(p: &[P2]) -> f64 {
    Polygon::new(p.to_vec()).signed_area()
}

/// Parameters t where the line `o + t d` crosses the closed polygon `p`.
pub fn line_crossings(p: &[P2], o: P2, d: V2) -> Vec<f64> {
    Polygon::new(p.to_vec()).line_crossings(&o, &d)
}

/// Douglas-Peucker simplification of a closed polygon to `tol` mm.
pub fn simplify(p: &[P2], tol: f64) -> Vec<P2> {
    Polygon::new(p.to_vec()).simplify(tol).points
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc_map(cx: f64, cy: f64, r: f64, cell: f64) -> HeightMap {
        let n = ((2.0 * r + 4.0) / cell) as usize;
        let mut m = HeightMap::new(cx - r - 2.0, cy - r - 2.0, cell, n, n);
        for j in 0..n {
            for i in 0..n {
                if (m.x(i) - cx).powi(2) + (m.y(j) - cy).powi(2) <= r * r {
                    m.set(i, j, 0.0);
                }
            }
        }
        m
    }

    #[test]
    fn disc_outline_is_close_and_counterclockwise() {
        let m = disc_map(3.0, -2.0, 10.0, 0.2);
        let rs = regions(&m);
        assert_eq!(rs.len(), 1);
        let o = &rs[0].outline;
        assert!(signed_area(o) > 0.0);
        for p in o {
            let r = ((p.x - 3.0).powi(2) + (p.y + 2.0).powi(2)).sqrt();
            assert!((r - 10.0).abs() < 0.15, "vertex at radius {r}");
        }
        let area = signed_area(o);
        let truth = std::f64::consts::PI * 100.0;
        assert!((area - truth).abs() / truth < 0.01, "{area} vs {truth}");
        assert!((rs[0].area_mm2 - truth).abs() / truth < 0.01);
        // A line through the centre crosses twice, 20 mm apart.
        let t = line_crossings(o, P2::new(3.0, -2.0), V2::new(0.6, 0.8));
        assert_eq!(t.len(), 2);
        assert!(((t[0] - t[1]).abs() - 20.0).abs() < 0.2, "{t:?}");
        let s = simplify(o, 0.05);
        assert!(
            s.len() < o.len() / 2 && s.len() > 20,
            "{} of {}",
            s.len(),
            o.len()
        );
    }

    #[test]
    fn diagonal_cells_are_apart_and_holes_ignored() {
        let mut m = HeightMap::new(0.0, 0.0, 1.0, 12, 12);
        for (i, j) in [(1, 1), (2, 2)] {
            m.set(i, j, 0.0);
        }
        // A ring with a hole.
        for j in 5..10 {
            for i in 5..10 {
                if !(i == 7 && j == 7) {
                    m.set(i, j, 1.0);
                }
            }
        }
        let rs = regions(&m);
        assert_eq!(rs.len(), 3);
        assert_eq!(rs[0].cells.len(), 24);
        assert!((signed_area(&rs[0].outline) - 24.5).abs() < 1e-9);
        assert!((signed_area(&rs[1].outline) - 0.5).abs() < 1e-9);
        assert!((rs[0].centroid.x - 7.0).abs() < 1e-9);
    }
}
