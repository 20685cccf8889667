//! A last mesh as an adjustment input ([`prepare_last`]: its bottom found, levelled and
//! measured) and the whole last deformed to the adjusted bottom ([`deform_last`]).

use super::outline;
use super::{AdjustError, Adjustment, HeightMap, LastBottom};
use crate::smoothstep;
use footscan_geom::mesh::{LoadReport, TriMesh, Units};
use footscan_geom::{P2, P3, V2, V3};
use nalgebra::{Matrix3, Rotation3, Vector3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// How a last mesh is read and its bottom found.
#[derive(Clone, Copy, Debug)]
pub struct LastOptions {
    pub units: Units,
    /// Scale the last so its longest side is this long (mm); for unscaled files.
    pub length_mm: Option<f64>,
    /// A triangle faces down when its unit normal's z is below minus this (0.5: 60 deg).
    pub down_cos: f64,
    /// Cell of the bottom's height grid (mm).
    pub cell_mm: f64,
}

impl Default for LastOptions {
    fn default() -> Self {
        LastOptions {
            units: Units::Auto,
            length_mm: None,
            down_cos: 0.5,
            cell_mm: 0.5,
        }
    }
}

/// A last ready for adjustment, in its bottom frame: x heel to toe along the bottom's long
/// axis, the bottom's best-fit plane horizontal and facing down, the lowest bottom point at
/// z = 0, the heel point's x at 0.
#[derive(Clone, Debug)]
pub struct PreparedLast {
    pub path: PathBuf,
    pub mesh: TriMesh,
    pub bottom: LastBottom,
    /// z of the bottom surface, continued beyond its outline over the whole last, for
    /// heights above the bottom.
    pub lowest: HeightMap,
    pub load: Option<LoadReport>,
    pub bottom_triangles: usize,
    /// Tilt of the file's frame to the bottom frame (deg).
    pub levelled_by_deg: f64,
}

/// Reads, validates and scales a last file (errors name it: open or non-manifold, metres
/// given as mm, unscaled without a length), then [`prepare_mesh`].
pub fn prepare_last(path: &Path, opts: &LastOptions) -> Result<PreparedLast, AdjustError> {
    let (mesh, load) = TriMesh::load_solid(path, opts.units, opts.length_mm).map_err(|source| {
        AdjustError::Mesh {
            path: path.to_path_buf(),
            source: Box::new(source),
        }
    })?;
    crate::size::check_last_size(path, &mesh).map_err(|e| AdjustError::Last {
        input: path.display().to_string(),
        why: footscan_util::chain(&e),
    })?;
    let mut p = prepare_mesh(mesh, path, opts)?;
    p.load = Some(load);
    Ok(p)
}

fn down_region(mesh: &TriMesh, down_cos: f64) -> (Vec<usize>, f64) {
    let nt = mesh.triangles.len();
    let normals: Vec<V3> = (0..nt).map(|t| mesh.face_normal(t)).collect();
    let down: Vec<bool> = normals.iter().map(|n| n.z < -down_cos).collect();
    let mut edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if !down[t] {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            edge.entry((a.min(b), a.max(b))).or_default().push(t);
        }
    }
    let mut parent: Vec<usize> = (0..nt).collect();
    fn find(p: &mut [usize], mut i: usize) -> usize {
        while p[i] != i {
            p[i] = p[p[i]];
            i = p[i];
        }
        i
    }
    for ts in edge.values() {
        for w in ts.windows(2) {
            let (a, b) = (find(&mut parent, w[0]), find(&mut parent, w[1]));
            if a != b {
                parent[b] = a;
            }
        }
    }
    let mut area: HashMap<usize, f64> = HashMap::new();
    for (t, &d) in down.iter().enumerate() {
        if d {
            let r = find(&mut parent, t);
            *area.entry(r).or_default() += mesh.face_normal_raw(t).norm() / 2.0;
        }
    }
    let Some((&root, &a)) = area.iter().max_by(|a, b| a.1.total_cmp(b.1)) else {
        return (Vec::new(), 0.0);
    };
    let region = (0..nt)
        .filter(|&t| down[t] && find(&mut parent, t) == root)
        .collect();
    (region, a)
}

/// Area-weighted centroid and covariance of the region's triangle centroids.
fn region_stats(mesh: &TriMesh, region: &[usize]) -> (P3, Matrix3<f64>) {
    let (mut c, mut w) = (Vector3::zeros(), 0.0);
    for &t in region {
        let [a, b, d] = mesh.corners(t);
        let ar = mesh.face_normal_raw(t).norm();
        c += ar * (a.coords + b.coords + d.coords) / 3.0;
        w += ar;
    }
    c /= w;
    let mut m = Matrix3::zeros();
    for &t in region {
        let [a, b, d] = mesh.corners(t);
        let ar = mesh.face_normal_raw(t).norm();
        let q = (a.coords + b.coords + d.coords) / 3.0 - c;
        m += ar * q * q.transpose();
    }
    (P3::from(c), m / w)
}

/// Turns a closed last mesh (mm, z roughly up) into its bottom frame, in place: the largest
/// connected region of triangles facing down (normal z below `-down_cos`) levelled so its
/// best-fit plane is horizontal (twice: the region is found again after levelling), turned
/// so the region's long axis is x with the heel at -x (the heel is the end under the tall
/// back of the last), the region's rearmost point at x = 0, its extent across centred on
/// y = 0 and its lowest point at z = 0. Returns the region (triangle indices) and the tilt
/// of the levelling (deg).
pub fn orient_last(mesh: &mut TriMesh, down_cos: f64) -> Result<(Vec<usize>, f64), String> {
    let mut tilt = 0.0;
    for _ in 0..2 {
        let region = down_region(mesh, down_cos).0;
        if region.is_empty() {
            return Err(format!(
                "no downward-facing triangles (normal z below -{}): is the last upside down?",
                down_cos
            ));
        }
        let (c, cov) = region_stats(mesh, &region);
        let e = cov.symmetric_eigen();
        let k = e.eigenvalues.imin();
        let mut n: Vector3<f64> = e.eigenvectors.column(k).into();
        if n.z > 0.0 {
            n = -n;
        }
        let rot =
            Rotation3::rotation_between(&n, &-Vector3::z()).unwrap_or_else(Rotation3::identity);
        tilt += rot.angle().to_degrees();
        for p in &mut mesh.vertices {
            *p = c + rot * (*p - c);
        }
    }
    let region = down_region(mesh, down_cos).0;
    let (c, cov) = region_stats(mesh, &region);
    let sub2 = cov.fixed_view::<2, 2>(0, 0).into_owned();
    let e = sub2.symmetric_eigen();
    let k = e.eigenvalues.imax();
    let mut ang = e.eigenvectors[(1, k)].atan2(e.eigenvectors[(0, k)]);
    // Heel at -x: the tall back of the last stands over the heel.
    let bb = mesh.bbox();
    let z_top = bb.min.z + 0.7 * (bb.max.z - bb.min.z);
    let (mut sx, mut ns) = (0.0, 0.0);
    let (ca, sa) = (ang.cos(), ang.sin());
    for p in &mesh.vertices {
        if p.z > z_top {
            sx += (p.x - c.x) * ca + (p.y - c.y) * sa;
            ns += 1.0;
        }
    }
    if ns > 0.0 && sx > 0.0 {
        ang += std::f64::consts::PI;
    }
    let rz = Rotation3::from_axis_angle(&Vector3::z_axis(), -ang);
    for p in &mut mesh.vertices {
        *p = c + rz * (*p - c);
    }
    // Heel point at x = 0, bottom centred on y = 0, lowest bottom point at z = 0.
    let mut lo = V3::repeat(f64::INFINITY);
    let mut hi = V3::repeat(f64::NEG_INFINITY);
    for &t in &region {
        for p in mesh.corners(t) {
            lo = lo.inf(&p.coords);
            hi = hi.sup(&p.coords);
        }
    }
    let shift = V3::new(-lo.x, -(lo.y + hi.y) / 2.0, -lo.z);
    mesh.translate(&shift);
    Ok((region, tilt))
}

/// Finds the bottom of a valid closed last mesh (already in mm) and measures it: the
/// largest connected region of downward-facing triangles; the mesh levelled so the region's
/// best-fit plane is horizontal (twice: the region is found again after levelling), turned
/// so the region's long axis is x with the heel at -x (the heel is the end under the tall
/// back of the last), then its outline (the region's boundary, seen from below) and heights
/// (the lowest surface above each cell, by vertical rays).
pub fn prepare_mesh(
    mut mesh: TriMesh,
    path: &Path,
    opts: &LastOptions,
) -> Result<PreparedLast, AdjustError> {
    let input = path.display().to_string();
    let (region, tilt) =
        orient_last(&mut mesh, opts.down_cos).map_err(|why| AdjustError::Last {
            input: input.clone(),
            why,
        })?;

    // Lowest surface under each cell over the whole last, by vertical rays.
    let bvh = footscan_geom::mesh::Bvh::new(&mesh);
    let bb = mesh.bbox();
    let cell = opts.cell_mm;
    let margin = 3.0;
    let (x0, y0) = (bb.min.x - margin, bb.min.y - margin);
    let nx = ((bb.max.x - bb.min.x + 2.0 * margin) / cell).ceil() as usize + 1;
    let ny = ((bb.max.y - bb.min.y + 2.0 * margin) / cell).ceil() as usize + 1;
    let mut lowest = HeightMap::new(x0, y0, cell, nx, ny);
    let z0 = bb.min.z - 5.0;
    let span = bb.max.z - z0 + 5.0;
    let in_region: std::collections::HashSet<usize> = region.iter().copied().collect();
    let mut mask = vec![false; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let o = P3::new(lowest.x(i), lowest.y(j), z0);
            if let Some(h) = bvh.ray_cast(&o, &V3::z(), span) {
                lowest.set(i, j, h.point.z);
                mask[j * nx + i] = in_region.contains(&h.triangle);
            }
        }
    }
    let (bottom, lowest) = bottom_from_below(&input, &lowest, &mask)?;
    Ok(PreparedLast {
        path: path.to_path_buf(),
        mesh,
        bottom,
        lowest,
        load: None,
        bottom_triangles: region.len(),
        levelled_by_deg: tilt,
    })
}

/// A bottom from its heights seen from below: `mask` marks the cells that belong to it (the
/// downward-facing region of a mesh, the gently sloped cells of a scan). The outline is the
/// largest 4-connected piece's extreme cells per column, smoothed (a last bottom is one
/// interval across at every station along its length); the heights are kept inside it. Also
/// returns the heights continued outward over the whole grid, the reference for heights
/// above the bottom (not whatever surface is lowest: the back of the heel overhangs the
/// bottom).
pub fn bottom_from_below(
    source: &str,
    below: &HeightMap,
    mask: &[bool],
) -> Result<(LastBottom, HeightMap), AdjustError> {
    let err = |why: String| AdjustError::Last {
        input: source.to_string(),
        why,
    };
    let (nx, ny, cell) = (below.nx, below.ny, below.cell_mm);
    let piece = largest_piece(mask, nx, ny);
    let (mut lower, mut upper) = (Vec::new(), Vec::new());
    for i in 0..nx {
        let js: Vec<usize> = (0..ny).filter(|&j| piece[j * nx + i]).collect();
        if let (Some(&a), Some(&b)) = (js.first(), js.last()) {
            lower.push(V2::new(below.x(i), below.y(a) - cell / 2.0));
            upper.push(V2::new(below.x(i), below.y(b) + cell / 2.0));
        }
    }
    if lower.len() < 8 {
        return Err(err(format!(
            "the bottom seen from below covers {} grid columns; too small for a last",
            lower.len()
        )));
    }
    // Smoothed as positions from the origin, then points.
    let mut around = lower;
    around.extend(upper.into_iter().rev());
    let pinned = vec![false; around.len()];
    outline::taubin(&mut around, &pinned, 10, 0.5, -0.53);
    let mut outline_pts: Vec<P2> = around.into_iter().map(P2::from).collect();
    outline::make_ccw(&mut outline_pts);
    let inside = outline::inside_mask(&outline_pts, below.x0, below.y0, cell, nx, ny);
    let mut heights = below.clone();
    for (k, z) in heights.z.iter_mut().enumerate() {
        if !inside[k] {
            *z = f64::NAN;
        }
    }
    if heights.valid_count() == 0 {
        return Err(err("the bottom outline covers no grid cell".into()));
    }
    let mut continued = heights.clone();
    continued.fill();
    Ok((
        LastBottom {
            source: source.to_string(),
            outline: outline_pts,
            heights,
        },
        continued,
    ))
}

/// The bottom of a scanned last (heights from below on a grid, NaN where nothing was
/// seen; x heel to toe as a foot stands): the cells whose surface slopes less than a
/// mesh triangle counts as facing down (`down_cos`, as [`LastOptions`]), their largest
/// piece and its outline, as [`bottom_from_below`].
pub fn scanned_bottom(
    source: &str,
    below: &HeightMap,
    down_cos: f64,
) -> Result<LastBottom, AdjustError> {
    let (nx, ny, c) = (below.nx, below.ny, below.cell_mm);
    // |grad z| <= tan(acos(down_cos)) is n.z >= down_cos for the surface's unit normal.
    let max_slope = (1.0 - down_cos * down_cos).max(0.0).sqrt() / down_cos;
    let z = |i: usize, j: usize| below.z[j * nx + i];
    let mut mask = vec![false; nx * ny];
    for j in 1..ny.saturating_sub(1) {
        for i in 1..nx.saturating_sub(1) {
            let (gx, gy) = (
                (z(i + 1, j) - z(i - 1, j)) / (2.0 * c),
                (z(i, j + 1) - z(i, j - 1)) / (2.0 * c),
            );
            // NaN neighbours (the edge of what was seen) leave the cell out.
            mask[j * nx + i] = gx.hypot(gy) <= max_slope;
        }
    }
    Ok(bottom_from_below(source, below, &mask)?.0)
}

/// What [`deform_last`] did.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct DeformReport {
    /// Height over which the change fades to nothing (mm).
    pub fade_mm: f64,
    /// Largest vertex displacement by the non-rigid part (mm).
    pub max_displacement_mm: f64,
    /// Triangles whose normal turned by more than 90 degrees (0 for a sound deformation).
    pub flipped_triangles: usize,
    /// Vertices moved to undo a fold, and the most any of them moved from where the faded
    /// field put it (mm; a bottom vertex's move off the adjusted bottom).
    pub relaxed_vertices: usize,
    pub relaxed_max_mm: f64,
    /// The most a bottom vertex slid along the adjusted bottom to undo a fold (mm, in plan).
    pub slid_max_mm: f64,
    /// The deformed last's bottom vertices inside the adjusted outline against the adjusted
    /// bottom's heights: how many, RMS and largest height difference (mm).
    pub bottom_vertices: usize,
    pub bottom_rms_mm: f64,
    pub bottom_max_mm: f64,
    pub volume_before_mm3: f64,
    pub volume_after_mm3: f64,
}

/// A vertex within this height of the original bottom is a bottom vertex (mm).
const BOTTOM_VERTEX_MM: f64 = 0.25;

/// Cell of the grid the bottom's change is averaged on (mm).
const BLUR_CELL_MM: f64 = 2.0;
/// Half-width of the average per mm above the bottom, its least value, and the height over
/// which the exact change gives way to the average (mm).
const BLUR_PER_MM: f64 = 1.0;
const BLUR_MIN_MM: f64 = 3.0;
const BLUR_RAMP_MM: f64 = 8.0;

/// A vector field on a grid with its summed-area table: box means of any half-width in O(1),
/// continuous in the box's centre and size (the table is interpolated bilinearly).
struct BoxField {
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    /// (nx + 1) x (ny + 1) sums of the cells below and left of each corner.
    sat: Vec<V3>,
}

impl BoxField {
    fn new(over: &HeightMap, cell: f64, f: impl Fn(f64, f64) -> V3) -> BoxField {
        let (x0, y0) = (over.x0, over.y0);
        let nx = ((over.x(over.nx - 1) - x0) / cell).ceil() as usize + 1;
        let ny = ((over.y(over.ny - 1) - y0) / cell).ceil() as usize + 1;
        let mut sat = vec![V3::zeros(); (nx + 1) * (ny + 1)];
        for j in 0..ny {
            let mut row = V3::zeros();
            for i in 0..nx {
                row += f(x0 + (i as f64 + 0.5) * cell, y0 + (j as f64 + 0.5) * cell);
                sat[(j + 1) * (nx + 1) + i + 1] = sat[j * (nx + 1) + i + 1] + row;
            }
        }
        BoxField {
            x0,
            y0,
            cell,
            nx,
            ny,
            sat,
        }
    }

    /// The table at (x, y), bilinear between corners, clamped to the grid.
    fn at(&self, x: f64, y: f64) -> V3 {
        let fx = ((x - self.x0) / self.cell).clamp(0.0, self.nx as f64);
        let fy = ((y - self.y0) / self.cell).clamp(0.0, self.ny as f64);
        let (i, j) = (
            (fx as usize).min(self.nx - 1),
            (fy as usize).min(self.ny - 1),
        );
        let (u, v) = (fx - i as f64, fy - j as f64);
        let w = self.nx + 1;
        let s = |i: usize, j: usize| self.sat[j * w + i];
        s(i, j) * ((1.0 - u) * (1.0 - v))
            + s(i + 1, j) * (u * (1.0 - v))
            + s(i, j + 1) * ((1.0 - u) * v)
            + s(i + 1, j + 1) * (u * v)
    }

    /// Mean over the square of half-width r about (x, y), clipped to the grid.
    fn mean(&self, x: f64, y: f64, r: f64) -> V3 {
        let xa = (x - r).max(self.x0);
        let xb = (x + r).min(self.x0 + self.nx as f64 * self.cell);
        let ya = (y - r).max(self.y0);
        let yb = (y + r).min(self.y0 + self.ny as f64 * self.cell);
        let area = (xb - xa) * (yb - ya) / (self.cell * self.cell);
        if area <= 0.0 {
            return V3::zeros();
        }
        (self.at(xb, yb) - self.at(xa, yb) - self.at(xb, ya) + self.at(xa, ya)) / area
    }
}

/// Smooth fade from 1 at the bottom to 0 at height 1 (quintic, zero slope and curvature at
/// both ends).
fn fade(s: f64) -> f64 {
    let s = s.clamp(0.0, 1.0);
    1.0 - s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)
}

/// The whole last carried into the foot frame and deformed so its bottom is the adjusted
/// bottom (docs/method.md 9.1): every vertex takes the rigid fit; the rest of the change (eps,
/// the thin-plate map and the new heights) is applied exactly on the bottom, box-averaged
/// above it, and fades with the height above the original bottom over `fade_mm` (more when
/// the bottom moves further: at least four times the largest change); folds left are
/// repaired locally with the bottom pinned. The result is checked as a valid closed solid.
pub fn deform_last(
    prep: &PreparedLast,
    adj: &Adjustment,
    fade_mm: f64,
) -> Result<(TriMesh, DeformReport), AdjustError> {
    let mut mesh = prep.mesh.clone();
    let new_bottom = continued_bottom(adj);
    let moves = planned_moves(prep, adj, &new_bottom);
    let fade_len = fade_length(&moves, fade_mm);
    let mut disp: Vec<V3> = moves
        .iter()
        .map(|(_, d, hb)| fade(hb / fade_len) * d)
        .collect();
    let faded = disp.clone();
    let mirrored = adj.to_foot.det() < 0.0;
    let wants = wanted_normals(prep, adj, &moves, &faded, mirrored);
    let pinned = bottom_vertices(prep, &moves);
    let (bad, relaxed) = unfold(prep, &moves, &mut disp, &wants, &pinned, &new_bottom);
    let mut max_d: f64 = 0.0;
    let (mut relax_max, mut slid_max) = (0.0f64, 0.0f64);
    for (i, v) in mesh.vertices.iter_mut().enumerate() {
        *v = moves[i].0 + disp[i];
        max_d = max_d.max(disp[i].norm());
        if pinned[i] {
            // A bottom vertex slides along the adjusted bottom: that is no change of shape,
            // its move off the bottom is.
            let was = moves[i].0 + faded[i];
            let above = |p: &P3| p.z - new_bottom.sample_clamped(p.x, p.y);
            relax_max = relax_max.max((above(v) - above(&was)).abs());
            slid_max = slid_max.max((v.xy() - was.xy()).norm());
        } else {
            relax_max = relax_max.max((disp[i] - faded[i]).norm());
        }
    }
    let (bottom_max, bottom_rms, bottom_n) = bottom_fit(&mesh, &pinned, adj);
    if mirrored {
        mesh.flip();
    }
    let input = prep.path.display().to_string();
    let report = mesh.check().map_err(|defect| AdjustError::Last {
        input: input.clone(),
        why: format!("the deformed last is not a valid solid: {defect}"),
    })?;
    Ok((
        mesh,
        DeformReport {
            fade_mm: fade_len,
            max_displacement_mm: max_d,
            flipped_triangles: bad,
            relaxed_vertices: relaxed,
            relaxed_max_mm: relax_max,
            slid_max_mm: slid_max,
            bottom_vertices: bottom_n,
            bottom_rms_mm: bottom_rms,
            bottom_max_mm: bottom_max,
            volume_before_mm3: prep.mesh.volume(),
            volume_after_mm3: report.volume,
        },
    ))
}

/// The adjusted bottom continued beyond its outline the way the last's own bottom is
/// (`prep.lowest`), so the rim and sides, which fall outside both outlines, change by the
/// difference of two smooth continuations (the adjusted grid's own values out there follow
/// the foot's sides up and then drop, which turned the last's rim over).
fn continued_bottom(adj: &Adjustment) -> HeightMap {
    let mut new_bottom = adj.heights.clone();
    for (z, &inside) in new_bottom.z.iter_mut().zip(&adj.inside) {
        if !inside {
            *z = f64::NAN;
        }
    }
    new_bottom.fill();
    new_bottom
}

/// Each vertex under the rigid fit, its whole change (exact on the bottom, box-averaged
/// above it) and its height above the last's original bottom.
fn planned_moves(
    prep: &PreparedLast,
    adj: &Adjustment,
    new_bottom: &HeightMap,
) -> Vec<(P3, V3, f64)> {
    let change = |x: f64, y: f64| -> V3 {
        let p = P2::new(x, y);
        let q = adj.rigid.apply(p);
        let t = adj.forward.apply(adj.to_foot.apply(p));
        let zb = prep.lowest.sample_clamped(x, y);
        let nb = new_bottom.sample_clamped(t.x, t.y);
        let d = t - q;
        V3::new(d.x, d.y, nb - zb)
    };
    // Above the bottom the change is taken from a box average of the bottom's change whose
    // half-width grows with the height: a wall leaning over the rim, where the plan map
    // stretches most, is moved by a smooth field instead of being folded by the rim's.
    let blurred = BoxField::new(&prep.lowest, BLUR_CELL_MM, change);
    prep.mesh
        .vertices
        .iter()
        .map(|v| {
            let q = adj.rigid.apply(v.xy());
            let hb = v.z - prep.lowest.sample_clamped(v.x, v.y);
            let exact = change(v.x, v.y);
            let s = smoothstep(hb / BLUR_RAMP_MM);
            let d = if s > 0.0 {
                let r = (hb * BLUR_PER_MM).max(BLUR_MIN_MM);
                exact + s * (blurred.mean(v.x, v.y, r) - exact)
            } else {
                exact
            };
            (P3::new(q.x, q.y, v.z), d, hb)
        })
        .collect()
}

/// The fade's length: long enough that the shear the fade makes stays small. Its steepest
/// slope is 15/8 per fade length, so with four times the largest change within reach no
/// slope exceeds 0.47 (twice that folded a steep side wall of a real last).
fn fade_length(moves: &[(P3, V3, f64)], fade_mm: f64) -> f64 {
    let mut fade_len = fade_mm;
    for _ in 0..5 {
        let near = moves
            .iter()
            .filter(|m| m.2 < fade_len)
            .map(|m| m.1.norm())
            .fold(0.0, f64::max);
        fade_len = fade_len.max(4.0 * near);
    }
    fade_len
}

/// The orientations each triangle should keep: its original normal under the rigid fit (a
/// mirrored last's triangles are turned round at the end, which restores the sign), and
/// under the orthogonal map that best carries the whole last's triangle centroids to where
/// the faded field puts them: a last whose heel comes down is pitched as a whole, and a rim
/// triangle turned past the vertical against that is as folded to whoever compares the
/// files, though not against the plan's rigid fit alone.
fn wanted_normals(
    prep: &PreparedLast,
    adj: &Adjustment,
    moves: &[(P3, V3, f64)],
    faded: &[V3],
    mirrored: bool,
) -> [Vec<V3>; 2] {
    let a = adj.rigid.a;
    let sign = |n: V3| if mirrored { -n } else { n };
    let want: Vec<V3> = (0..prep.mesh.triangles.len())
        .map(|t| {
            let n = prep.mesh.face_normal(t);
            sign(V3::new(
                a[0][0] * n.x + a[0][1] * n.y,
                a[1][0] * n.x + a[1][1] * n.y,
                n.z,
            ))
        })
        .collect();
    let whole = best_orthogonal(&prep.mesh, |i| moves[i].0 + faded[i]);
    let want_whole: Vec<V3> = (0..prep.mesh.triangles.len())
        .map(|t| sign(whole * prep.mesh.face_normal(t)))
        .collect();
    [want, want_whole]
}

/// Bottom vertices: on the lowest surface and corners of a triangle facing down. Height
/// alone also took the steep walls' vertices where a wall overhangs its own footprint (a
/// pointed toe's tip, a heel's back).
fn bottom_vertices(prep: &PreparedLast, moves: &[(P3, V3, f64)]) -> Vec<bool> {
    let mut faces_down = vec![false; moves.len()];
    for (t, tri) in prep.mesh.triangles.iter().enumerate() {
        if prep.mesh.face_normal(t).z < -0.5 {
            for &i in tri {
                faces_down[i as usize] = true;
            }
        }
    }
    moves
        .iter()
        .zip(&faces_down)
        .map(|(m, &down)| down && m.2.abs() <= BOTTOM_VERTEX_MM)
        .collect()
}

/// The triangles `disp` folds against either wanted orientation.
fn folded(
    triangles: &[[u32; 3]],
    moves: &[(P3, V3, f64)],
    disp: &[V3],
    wants: &[Vec<V3>; 2],
) -> Vec<usize> {
    (0..triangles.len())
        .filter(|&t| {
            let [i, j, k] = triangles[t].map(|i| i as usize);
            let (pi, pj, pk) = (
                moves[i].0 + disp[i],
                moves[j].0 + disp[j],
                moves[k].0 + disp[k],
            );
            let n = (pj - pi).cross(&(pk - pi));
            n.dot(&wants[0][t]) < 0.0 || n.dot(&wants[1][t]) < 0.0
        })
        .collect()
}

/// Where the faded field still folds a triangle (the rim where the bottom turns up into the
/// side, thin in plan, under a plan map that moves it much; the slivers of a narrow end),
/// the vertices round the fold are untangled: a small optimisation that moves them as
/// little as it can, with bottom vertices sliding on the adjusted bottom so the bottom stays
/// the adjusted one (docs/method.md 9.2.1). Returns the folds left and how many vertices
/// moved.
fn unfold(
    prep: &PreparedLast,
    moves: &[(P3, V3, f64)],
    disp: &mut [V3],
    wants: &[Vec<V3>; 2],
    pinned: &[bool],
    new_bottom: &HeightMap,
) -> (usize, usize) {
    let triangles = &prep.mesh.triangles;
    let bad = folded(triangles, moves, disp, wants);
    if bad.is_empty() {
        return (0, 0);
    }
    let mut nbrs: Vec<Vec<u32>> = vec![Vec::new(); disp.len()];
    for tri in triangles {
        for e in 0..3 {
            let (u, w) = (tri[e], tri[(e + 1) % 3]);
            nbrs[u as usize].push(w);
            nbrs[w as usize].push(u);
        }
    }
    for n in &mut nbrs {
        n.sort_unstable();
        n.dedup();
    }
    let mut pos: Vec<P3> = (0..disp.len()).map(|i| moves[i].0 + disp[i]).collect();
    let area2: Vec<f64> = (0..triangles.len())
        .map(|t| prep.mesh.face_normal_raw(t).norm())
        .collect();
    let off: Vec<f64> = pos
        .iter()
        .map(|p| p.z - new_bottom.sample_clamped(p.x, p.y))
        .collect();
    let task = Untangle {
        triangles,
        wants: [&wants[0], &wants[1]],
        area2: &area2,
        pinned,
        off: &off,
        bottom: new_bottom,
        nbrs: &nbrs,
    };
    let left = task.run(&mut pos, &bad);
    if left.len() >= bad.len() {
        return (bad.len(), 0);
    }
    let mut relaxed = 0;
    for (i, p) in pos.iter().enumerate() {
        let d = p - moves[i].0;
        if (d - disp[i]).norm() > 1e-9 {
            relaxed += 1;
        }
        disp[i] = d;
    }
    (folded(triangles, moves, disp, wants).len(), relaxed)
}

/// The deformed last's bottom against the adjusted bottom: bottom vertices (on the original
/// bottom) that land inside the adjusted outline; the largest and RMS height difference and
/// how many.
fn bottom_fit(mesh: &TriMesh, pinned: &[bool], adj: &Adjustment) -> (f64, f64, usize) {
    let (mut bottom_max, mut bottom_ss, mut bottom_n) = (0.0f64, 0.0, 0usize);
    let h = &adj.heights;
    for (v, &bottom) in mesh.vertices.iter().zip(pinned) {
        if !bottom {
            continue;
        }
        match h.cell_of(v.x, v.y) {
            Some((i, j)) if adj.inside[j * h.nx + i] => {}
            _ => continue,
        }
        let d = v.z - h.sample(v.x, v.y);
        if d.is_finite() {
            bottom_max = bottom_max.max(d.abs());
            bottom_ss += d * d;
            bottom_n += 1;
        }
    }
    (
        bottom_max,
        (bottom_ss / bottom_n.max(1) as f64).sqrt(),
        bottom_n,
    )
}

/// Least cosine between an untangled triangle's normal and its wanted one (84 deg): a
/// margin, so a triangle is not left on edge where two readings of "wanted" differ.
const UNTANGLE_MARGIN: f64 = 0.1;
/// Weights, against the folds' penalty (dimensionless, one per triangle), of bending the
/// deformed surface (an edge's change of displacement over its length, squared) and of
/// leaving where the deformation put a vertex (its move over its edges' mean length,
/// squared): the untangling moves a sliver by its own size, not a fan's centre by
/// millimetres.
const UNTANGLE_BEND: f64 = 0.05;
const UNTANGLE_STAY: f64 = 0.001;
/// Descent steps per region.
const UNTANGLE_ITERATIONS: usize = 1000;

/// Untangling of the folds a deformation left: the vertices round them move to minimise
/// the sum over triangles and wanted normals u of max(0, (margin |n| - n.u) / a)^2 (n the
/// triangle's area normal, a the smaller of its length at the start and on the input), a
/// bending term and a small pull back to where they were (docs/method.md 9.2.1). Bottom
/// vertices slide on the adjusted bottom (their height above it kept), so the bottom stays
/// the adjusted one while a rim made of bottom vertices can turn back. Jacobi-scaled
/// gradient descent with a backtracking step over a region grown ring by ring.
struct Untangle<'a> {
    triangles: &'a [[u32; 3]],
    wants: [&'a [V3]; 2],
    /// Each triangle's doubled area on the input.
    area2: &'a [f64],
    pinned: &'a [bool],
    off: &'a [f64],
    bottom: &'a HeightMap,
    nbrs: &'a [Vec<u32>],
}

impl Untangle<'_> {
    fn folded(&self, pos: &[P3], t: usize) -> bool {
        let [i, j, k] = self.triangles[t].map(|i| pos[i as usize]);
        let n = (j - i).cross(&(k - i));
        self.wants.iter().any(|w| n.dot(&w[t]) < 0.0)
    }

    /// Moves `pos` to undo the folded triangles `bad`; returns the folds left among all.
    fn run(&self, pos: &mut [P3], bad: &[usize]) -> Vec<usize> {
        let nv = pos.len();
        let mut tris_of: Vec<Vec<u32>> = vec![Vec::new(); nv];
        for (t, tri) in self.triangles.iter().enumerate() {
            for &i in tri {
                tris_of[i as usize].push(t as u32);
            }
        }
        let all_bad = |pos: &[P3]| -> Vec<usize> {
            (0..self.triangles.len())
                .filter(|&t| self.folded(pos, t))
                .collect()
        };
        let mut left = bad.to_vec();
        let mut region = vec![false; nv];
        for &t in bad {
            for &i in &self.triangles[t] {
                region[i as usize] = true;
            }
        }
        let mut pinned = self.pinned.to_vec();
        // Rings grown round what is left; last, the corners of a fold made only of bottom
        // vertices (a rim standing on edge) are let off the bottom.
        for (rings, release) in [
            (2usize, false),
            (2, false),
            (4, false),
            (8, false),
            (4, true),
        ] {
            if left.is_empty() {
                break;
            }
            if release {
                for &t in &left {
                    for &i in &self.triangles[t] {
                        pinned[i as usize] = false;
                    }
                }
            }
            for &t in &left {
                for &i in &self.triangles[t] {
                    region[i as usize] = true;
                }
            }
            for _ in 0..rings {
                let grow: Vec<usize> = (0..nv)
                    .filter(|&i| region[i])
                    .flat_map(|i| self.nbrs[i].iter().map(|&n| n as usize))
                    .collect();
                for i in grow {
                    region[i] = true;
                }
            }
            let verts: Vec<usize> = (0..nv).filter(|&i| region[i]).collect();
            let mut tris: Vec<usize> = verts
                .iter()
                .flat_map(|&i| tris_of[i].iter().map(|&t| t as usize))
                .collect();
            tris.sort_unstable();
            tris.dedup();
            let before: Vec<P3> = pos.to_vec();
            self.descend(pos, &verts, &tris, &pinned);
            let now = all_bad(pos);
            if now.len() < left.len() {
                left = now;
            } else {
                pos.copy_from_slice(&before);
            }
        }
        left
    }

    /// The energy over `tris` and the moved `verts` (pull back to `start`).
    fn energy(
        &self,
        pos: &[P3],
        start: &[P3],
        verts: &[usize],
        tris: &[usize],
        scale: &Scale,
    ) -> f64 {
        let mut e = 0.0;
        for &t in tris {
            let [i, j, k] = self.triangles[t].map(|i| pos[i as usize]);
            let n = (j - i).cross(&(k - i));
            let a = scale.a_ref[t];
            for w in self.wants {
                let s = (UNTANGLE_MARGIN * n.norm() - n.dot(&w[t])) / a;
                if s > 0.0 {
                    e += s * s;
                }
            }
        }
        for (k, &v) in verts.iter().enumerate() {
            let d = pos[v] - start[v];
            e += UNTANGLE_STAY * d.norm_squared() * scale.inv_len2[k];
            for (&n, &w) in self.nbrs[v].iter().zip(&scale.edge_w[k]) {
                let n = n as usize;
                // Each edge inside the region counted once, edges to the rest whole.
                if scale.in_region[n] == usize::MAX || n > v {
                    e += UNTANGLE_BEND * w * (d - (pos[n] - start[n])).norm_squared();
                }
            }
        }
        e
    }

    fn descend(&self, pos: &mut [P3], verts: &[usize], tris: &[usize], pinned: &[bool]) {
        let start: Vec<P3> = pos.to_vec();
        let mut in_region = vec![usize::MAX; pos.len()];
        for (k, &v) in verts.iter().enumerate() {
            in_region[v] = k;
        }
        let mut grad = vec![V3::zeros(); verts.len()];
        let mut diag = vec![0.0f64; verts.len()];
        let mut scale = Scale::new(pos, verts, in_region, self.nbrs);
        // Each triangle's penalty is measured against its area normal's length at the start
        // (or on the input, if larger): a flipped triangle keeps a gradient, and a sliver
        // stretched by the deformation is not held to its input's tiny scale.
        scale.a_ref = vec![1.0; self.triangles.len()];
        for &t in tris {
            let [i, j, k] = self.triangles[t].map(|i| pos[i as usize]);
            scale.a_ref[t] = (j - i).cross(&(k - i)).norm().min(self.area2[t]).max(1e-12);
        }
        let in_region = &scale.in_region;
        let mut e = self.energy(pos, &start, verts, tris, &scale);
        let mut step: f64 = 0.0;
        for _ in 0..UNTANGLE_ITERATIONS {
            let mut active = 0usize;
            grad.iter_mut().for_each(|g| *g = V3::zeros());
            for (k, &v) in verts.iter().enumerate() {
                let d = pos[v] - start[v];
                grad[k] += 2.0 * UNTANGLE_STAY * scale.inv_len2[k] * d;
                diag[k] = 2.0 * UNTANGLE_STAY * scale.inv_len2[k];
                for (&n, &w) in self.nbrs[v].iter().zip(&scale.edge_w[k]) {
                    let n = n as usize;
                    let dn = pos[n] - start[n];
                    grad[k] += 2.0 * UNTANGLE_BEND * w * (d - dn);
                    diag[k] += 2.0 * UNTANGLE_BEND * w;
                }
            }
            for &t in tris {
                let [a, b, c] = self.triangles[t].map(|i| i as usize);
                let (pa, pb, pc) = (pos[a], pos[b], pos[c]);
                let n = (pb - pa).cross(&(pc - pa));
                let ar = scale.a_ref[t];
                let nh = n / n.norm().max(1e-12);
                for w in self.wants {
                    let u = w[t];
                    let s = (UNTANGLE_MARGIN * n.norm() - n.dot(&u)) / ar;
                    if s <= 0.0 {
                        continue;
                    }
                    active += 1;
                    // s = (margin |n| - n.u) / ar: ds = -q . dn with q = (u - margin nh) / ar,
                    // and q . dn over a corner's move is the move dotted with q x (the
                    // opposite edge), so d(s^2)/dpa = -2 s q x (pc - pb) and cyclically.
                    let q = (u - UNTANGLE_MARGIN * nh) / ar;
                    for (v, g) in [
                        (a, q.cross(&(pc - pb))),
                        (b, q.cross(&(pa - pc))),
                        (c, q.cross(&(pb - pa))),
                    ] {
                        if in_region[v] != usize::MAX {
                            grad[in_region[v]] += -2.0 * s * g;
                            diag[in_region[v]] += 2.0 * g.norm_squared();
                        }
                    }
                }
            }
            for (k, &v) in verts.iter().enumerate() {
                if pinned[v] {
                    // z follows the bottom: the chain rule through z = bottom(x, y) + off.
                    let (hx, hy) = self.slope(pos[v].x, pos[v].y);
                    let gz = grad[k].z;
                    grad[k] = V3::new(grad[k].x + gz * hx, grad[k].y + gz * hy, 0.0);
                }
            }
            // Each vertex's step scaled by its own curvature (Jacobi): a sliver's corner and
            // a large triangle's move at their own scales.
            let dir: Vec<V3> = grad.iter().zip(&diag).map(|(g, &h)| -g / h).collect();
            // Done once every triangle keeps its margin: what is left is only the pull
            // back, and the region's moves are already as small as the folds allowed.
            if active == 0 {
                break;
            }
            let gmax = dir.iter().map(|g| g.norm()).fold(0.0, f64::max);
            if gmax < 1e-9 {
                break;
            }
            if step == 0.0 {
                step = 1.0;
            }
            step = step.min(0.5 / gmax);
            let g2: f64 = -grad.iter().zip(&dir).map(|(g, d)| g.dot(d)).sum::<f64>();
            let base: Vec<P3> = verts.iter().map(|&v| pos[v]).collect();
            let mut accepted = false;
            for _ in 0..30 {
                for (k, &v) in verts.iter().enumerate() {
                    let mut p = base[k] + step * dir[k];
                    if pinned[v] {
                        p.z = self.bottom.sample_clamped(p.x, p.y) + self.off[v];
                    }
                    pos[v] = p;
                }
                let e2 = self.energy(pos, &start, verts, tris, &scale);
                if e2 <= e - 1e-4 * step * g2 {
                    e = e2;
                    accepted = true;
                    step = (step * 2.0).min(1.0);
                    break;
                }
                step *= 0.5;
            }
            if !accepted {
                for (k, &v) in verts.iter().enumerate() {
                    pos[v] = base[k];
                }
                break;
            }
        }
    }

    /// The adjusted bottom's slope at (x, y) (central differences, 0.05 mm).
    fn slope(&self, x: f64, y: f64) -> (f64, f64) {
        let h = 0.05;
        let f = |x, y| self.bottom.sample_clamped(x, y);
        (
            (f(x + h, y) - f(x - h, y)) / (2.0 * h),
            (f(x, y + h) - f(x, y - h)) / (2.0 * h),
        )
    }
}

/// Per region vertex: its index map, 1 / its edges' mean length squared, and 1 / length
/// squared of each of its edges (in the order of `nbrs`), all at the start of a descent.
struct Scale {
    in_region: Vec<usize>,
    inv_len2: Vec<f64>,
    edge_w: Vec<Vec<f64>>,
    /// Per triangle (of the whole mesh): the length its fold penalty is measured in.
    a_ref: Vec<f64>,
}

impl Scale {
    fn new(pos: &[P3], verts: &[usize], in_region: Vec<usize>, nbrs: &[Vec<u32>]) -> Scale {
        let mut inv_len2 = Vec::with_capacity(verts.len());
        let mut edge_w = Vec::with_capacity(verts.len());
        for &v in verts {
            let lens: Vec<f64> = nbrs[v]
                .iter()
                .map(|&n| (pos[n as usize] - pos[v]).norm().max(1e-3))
                .collect();
            let mean = lens.iter().sum::<f64>() / lens.len().max(1) as f64;
            inv_len2.push(1.0 / (mean * mean).max(1e-6));
            edge_w.push(lens.iter().map(|l| 1.0 / (l * l)).collect());
        }
        Scale {
            in_region,
            inv_len2,
            edge_w,
            a_ref: Vec::new(),
        }
    }
}

/// The orthogonal map (a mirror allowed) that best takes `m`'s triangle centroids onto the
/// centroids of the same triangles with the vertices at `moved` (least squares, Kabsch).
fn best_orthogonal(m: &TriMesh, moved: impl Fn(usize) -> P3) -> Matrix3<f64> {
    let n = m.triangles.len().max(1) as f64;
    let cen = |t: usize, f: &dyn Fn(usize) -> P3| {
        let [a, b, c] = m.triangles[t].map(|i| f(i as usize).coords);
        (a + b + c) / 3.0
    };
    let given = |i: usize| m.vertices[i];
    let nt = m.triangles.len();
    let ca = (0..nt).map(|t| cen(t, &given)).sum::<Vector3<f64>>() / n;
    let cb = (0..nt).map(|t| cen(t, &moved)).sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for t in 0..nt {
        h += (cen(t, &given) - ca) * (cen(t, &moved) - cb).transpose();
    }
    let svd = h.svd(true, true);
    match (svd.u, svd.v_t) {
        (Some(u), Some(vt)) => vt.transpose() * u.transpose(),
        _ => Matrix3::identity(),
    }
}

/// The largest 4-connected set of true cells.
fn largest_piece(mask: &[bool], nx: usize, ny: usize) -> Vec<bool> {
    let mut label = vec![usize::MAX; mask.len()];
    let (mut best, mut best_n, mut next) = (usize::MAX, 0usize, 0usize);
    let mut stack = Vec::new();
    for s in 0..mask.len() {
        if !mask[s] || label[s] != usize::MAX {
            continue;
        }
        let mut n = 0;
        label[s] = next;
        stack.push(s);
        while let Some(k) = stack.pop() {
            n += 1;
            let (i, j) = (k % nx, k / nx);
            let mut visit = |m: usize| {
                if mask[m] && label[m] == usize::MAX {
                    label[m] = next;
                    stack.push(m);
                }
            };
            if i > 0 {
                visit(k - 1);
            }
            if i + 1 < nx {
                visit(k + 1);
            }
            if j > 0 {
                visit(k - nx);
            }
            if j + 1 < ny {
                visit(k + nx);
            }
        }
        if n > best_n {
            (best, best_n) = (next, n);
        }
        next += 1;
    }
    label.iter().map(|&l| l == best).collect()
}
