//! Any closed triangle mesh standing on the glass, as a scene the renderer can image.
//!
//! The scanner looks up through the glass, so what the laser meets is the mesh's lower
//! envelope. [`MeshSurface::plane_height`] intersects the laser plane's line at a fixed y,
//! `x = x0 + tan_b z`, with every triangle near it and keeps the lowest hit: exact to
//! rounding on the piecewise-planar surface (no iteration). Each triangle is sheared along
//! that line onto z = 0, `(x - tan_b z, y)`, where the line becomes the point `(x0, y)`; the
//! triangle contains it when the three edge functions agree in sign (edges included, with a
//! relative slack of 1e-12 so a point on a shared edge is never lost between neighbours), and
//! the hit's z is the barycentric mix of the corner heights. [`MeshSurface::height`] is the
//! same with a vertical line.
//!
//! Candidate triangles come from a uniform grid over the xy plane: each cell lists the
//! triangles whose xy box overlaps it; a query visits the cells the line's xy shadow (at most
//! `|tan_b| max_height` long) crosses.

use crate::optics::{check_range, SimError};
use crate::render::Surface;
use footscan_geom::mesh::{Axes, IntakeOptions, MeshError, TriMesh, Units};
use footscan_geom::{P2, P3};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A rigid placement of a mesh on the glass: turned about the vertical through its
/// reference point (the rear end of its x extent, at the middle of its y extent; for a
/// parametric last, its heel point), then moved so that point is at (`heel_x_mm`,
/// `axis_y_mm`) and its lowest point at `lift_mm` above the glass.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct Placement {
    /// World x of the reference point (mm).
    pub heel_x_mm: f64,
    /// World y of the reference point (mm).
    pub axis_y_mm: f64,
    /// Rotation about z, counterclockwise seen from above (degrees): [-180, 180].
    pub yaw_deg: f64,
    /// Height of the mesh's lowest point above the glass (mm): [0, 200]; 0 = resting on it.
    pub lift_mm: f64,
}

impl Default for Placement {
    fn default() -> Self {
        Placement {
            heel_x_mm: 110.0,
            axis_y_mm: 0.0,
            yaw_deg: 0.0,
            lift_mm: 0.0,
        }
    }
}

impl Placement {
    pub fn validate(&self) -> Result<(), SimError> {
        check_range("placement.heel_x_mm", self.heel_x_mm, -1e4, 1e4)?;
        check_range("placement.axis_y_mm", self.axis_y_mm, -1e4, 1e4)?;
        check_range("placement.yaw_deg", self.yaw_deg, -180.0, 180.0)?;
        check_range("placement.lift_mm", self.lift_mm, 0.0, 200.0)
    }

    /// The map from the mesh's own frame to the world, given its reference point and lowest
    /// z there: `world = R (p - reference) + (heel_x, axis_y, lift - z_min)`.
    pub fn transform(&self, reference: P2, z_min: f64) -> RigidXy {
        let (s, c) = self.yaw_deg.to_radians().sin_cos();
        RigidXy {
            cos: c,
            sin: s,
            from: P3::new(reference.x, reference.y, z_min),
            to: P3::new(self.heel_x_mm, self.axis_y_mm, self.lift_mm),
        }
    }
}

/// A rotation about z and a translation (see [`Placement::transform`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigidXy {
    pub cos: f64,
    pub sin: f64,
    pub from: P3,
    pub to: P3,
}

impl RigidXy {
    pub fn apply(&self, p: P3) -> P3 {
        let (x, y) = (p.x - self.from.x, p.y - self.from.y);
        P3::new(
            self.to.x + self.cos * x - self.sin * y,
            self.to.y + self.sin * x + self.cos * y,
            self.to.z + p.z - self.from.z,
        )
    }
}

/// How to load a mesh file as a scene (`[sim.mesh]` in a scan config).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields, default)]
pub struct MeshSceneConfig {
    /// STL (binary or ASCII), PLY or OBJ file; a relative path is taken from the working
    /// directory.
    pub path: PathBuf,
    /// "mm", "cm", "m" or "auto". With `axes = "file"`: from the size (under 1 long is
    /// metres, 50 and over millimetres, in between it needs `length_mm`); otherwise from the
    /// heel-to-toe length (a foot or last is 100-360 mm: mm, cm or m, whichever fits).
    pub units: String,
    /// Scale to this length (mm): heel to toe, or with `axes = "file"` the longest side;
    /// overrides `units`.
    pub length_mm: Option<f64>,
    /// How the mesh stands before it is placed: "auto" (the default: up and heel to toe found
    /// from the mesh as for a foot, docs/method.md 10.1, so it stands sole down on the glass,
    /// heel toward -x; inward triangles turned and an open top cut closed), "F,U" (the file
    /// axes running heel to toe and up, e.g. "y,z" or "-y,z"), or "file" (as the file has
    /// it, z up, x heel to toe, as before this option).
    pub axes: String,
    pub placement: Placement,
}

impl Default for MeshSceneConfig {
    fn default() -> Self {
        MeshSceneConfig {
            path: PathBuf::new(),
            units: "auto".into(),
            length_mm: None,
            axes: "auto".into(),
            placement: Placement::default(),
        }
    }
}

/// Errors of building a mesh scene; each names its input.
#[derive(Debug, thiserror::Error)]
pub enum MeshSceneError {
    // The mesh error and the simulator's name their input (the file, the key) themselves.
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error(transparent)]
    Invalid(#[from] SimError),
    #[error("mesh scene: no mesh file given (set path = \"file.stl\" under [sim.mesh])")]
    NoPath,
    #[error("mesh scene {path}: invalid units {units:?}; valid: mm, cm, m, auto")]
    Units { path: PathBuf, units: String },
    #[error("mesh scene {path}: invalid axes {axes:?}: {why}; valid: auto, file, or heel-to-toe and up like \"y,z\" or \"-y,z\"")]
    Axes {
        path: PathBuf,
        axes: String,
        why: footscan_geom::mesh::AxesError,
    },
}

impl MeshSceneConfig {
    /// Reads, validates (closed, 2-manifold, outward), scales and places the mesh.
    pub fn load(&self) -> Result<MeshSurface, MeshSceneError> {
        Ok(MeshSurface::new(&self.load_placed()?)?)
    }

    /// The mesh read, validated, scaled to millimetres and placed in the world.
    pub fn load_placed(&self) -> Result<TriMesh, MeshSceneError> {
        if self.path.as_os_str().is_empty() {
            return Err(MeshSceneError::NoPath);
        }
        let units: Units = self.units.parse().map_err(|_| MeshSceneError::Units {
            path: self.path.clone(),
            units: self.units.clone(),
        })?;
        let retell = |e: MeshError| {
            e.retold(
                "set units = \"m\" (or \"auto\") under [sim.mesh]",
                "set its unit with units = \"mm\", \"cm\" or \"m\", or its length with length_mm = MM, under [sim.mesh]",
            )
        };
        let mesh = if self.axes.trim() == "file" {
            TriMesh::load_solid(&self.path, units, self.length_mm)
                .map_err(retell)?
                .0
        } else {
            let axes: Axes = self.axes.parse().map_err(|why| MeshSceneError::Axes {
                path: self.path.clone(),
                axes: self.axes.clone(),
                why,
            })?;
            let opts = IntakeOptions {
                units,
                length_mm: self.length_mm,
                axes,
            };
            let intake = TriMesh::read_foot(&self.path, &opts).map_err(retell)?;
            for n in &intake.notes {
                tracing::info!("mesh scene {}: {n}", self.path.display());
            }
            intake.mesh
        };
        Ok(place(&mesh, &self.placement)?)
    }
}

/// A triangle's corners.
#[derive(Clone, Copy, Debug)]
struct Tri {
    p: [[f64; 3]; 3],
}

/// A closed triangle mesh on the glass, as a [`Surface`] (see the module documentation).
#[derive(Debug, Clone)]
pub struct MeshSurface {
    tris: Vec<Tri>,
    /// Grid origin and cell size (mm), and its size in cells.
    x0: f64,
    y0: f64,
    cell: f64,
    nx: usize,
    ny: usize,
    /// Triangle indices of cell (ix, iy) are `items[start[iy * nx + ix]..start[.. + 1]]`.
    start: Vec<u32>,
    items: Vec<u32>,
    z_max: f64,
    y_min: f64,
    y_max: f64,
}

impl MeshSurface {
    /// The mesh in world coordinates as given (every z must be >= 0).
    pub fn new(mesh: &TriMesh) -> Result<MeshSurface, SimError> {
        if mesh.triangles.is_empty() {
            return Err(SimError::invalid(
                "mesh",
                "0 triangles",
                "a mesh with triangles",
            ));
        }
        let tris: Vec<Tri> = (0..mesh.triangles.len())
            .map(|t| Tri {
                p: mesh.corners(t).map(|c| [c.x, c.y, c.z]),
            })
            .collect();
        let bb = mesh.bbox();
        let finite = bb.min.iter().chain(bb.max.iter()).all(|v| v.is_finite());
        if !finite || bb.min.z < -1e-9 {
            return Err(SimError::invalid(
                "mesh lowest z",
                bb.min.z,
                "a mesh at or above the glass (z >= 0), finite",
            ));
        }
        let (wx, wy) = (bb.max.x - bb.min.x, bb.max.y - bb.min.y);
        // About two triangles' xy footprint per cell on each surface layer.
        let cell = ((wx * wy / tris.len() as f64).sqrt() * 1.5).clamp(0.25, 50.0);
        let nx = ((wx / cell).floor() as usize + 1).min(4096);
        let ny = ((wy / cell).floor() as usize + 1).min(4096);
        let mut s = MeshSurface {
            tris,
            x0: bb.min.x,
            y0: bb.min.y,
            cell,
            nx,
            ny,
            start: Vec::new(),
            items: Vec::new(),
            z_max: bb.max.z.max(0.0),
            y_min: bb.min.y,
            y_max: bb.max.y,
        };
        s.build_grid();
        Ok(s)
    }

    /// The mesh placed on the glass by `placement`, its reference point the rear end of its x
    /// extent at the middle of its y extent (after the rotation the reference point is where
    /// the placement says).
    pub fn placed(mesh: &TriMesh, placement: &Placement) -> Result<MeshSurface, SimError> {
        MeshSurface::new(&place(mesh, placement)?)
    }

    fn build_grid(&mut self) {
        let ncell = self.nx * self.ny;
        let mut count = vec![0u32; ncell + 1];
        let ranges: Vec<[usize; 4]> = self.tris.iter().map(|t| self.cell_range(t)).collect();
        for r in &ranges {
            for iy in r[2]..=r[3] {
                for ix in r[0]..=r[1] {
                    count[iy * self.nx + ix + 1] += 1;
                }
            }
        }
        for i in 0..ncell {
            count[i + 1] += count[i];
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; count[ncell] as usize];
        for (t, r) in ranges.iter().enumerate() {
            for iy in r[2]..=r[3] {
                for ix in r[0]..=r[1] {
                    let c = iy * self.nx + ix;
                    items[fill[c] as usize] = t as u32;
                    fill[c] += 1;
                }
            }
        }
        self.start = count;
        self.items = items;
    }

    fn cell_range(&self, t: &Tri) -> [usize; 4] {
        let xs = t.p.map(|p| p[0]);
        let ys = t.p.map(|p| p[1]);
        let lo_x = xs.iter().copied().fold(f64::INFINITY, f64::min);
        let hi_x = xs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let lo_y = ys.iter().copied().fold(f64::INFINITY, f64::min);
        let hi_y = ys.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        [self.ix(lo_x), self.ix(hi_x), self.iy(lo_y), self.iy(hi_y)]
    }

    fn ix(&self, x: f64) -> usize {
        (((x - self.x0) / self.cell).floor().max(0.0) as usize).min(self.nx - 1)
    }
    fn iy(&self, y: f64) -> usize {
        (((y - self.y0) / self.cell).floor().max(0.0) as usize).min(self.ny - 1)
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.tris.len()
    }

    /// The lowest z where the line `(x0 + tan_b z, y, z)` meets the mesh.
    pub fn lowest_hit(&self, x0: f64, tan_b: f64, y: f64) -> Option<f64> {
        let y_slack = 1e-9 * (1.0 + y.abs());
        if y < self.y_min - y_slack || y > self.y_max + y_slack {
            return None;
        }
        let xa = x0 + tan_b.min(0.0) * self.z_max;
        let xb = x0 + tan_b.max(0.0) * self.z_max;
        let cell_x = self.cell * 1e-9;
        if xb < self.x0 - cell_x || xa > self.x0 + self.nx as f64 * self.cell + cell_x {
            return None;
        }
        let iy = self.iy(y);
        let (i0, i1) = (self.ix(xa), self.ix(xb));
        let mut best = f64::INFINITY;
        for ix in i0..=i1 {
            let c = iy * self.nx + ix;
            for &t in &self.items[self.start[c] as usize..self.start[c + 1] as usize] {
                if let Some(z) = hit(&self.tris[t as usize], x0, tan_b, y) {
                    best = best.min(z);
                }
            }
        }
        best.is_finite().then_some(best)
    }
}

/// The line `(x0 + tan_b z, y, z)` against one triangle (see the module documentation).
#[inline]
fn hit(t: &Tri, x0: f64, tan_b: f64, y: f64) -> Option<f64> {
    let [a, b, c] = t.p;
    // Quick rejection on y.
    if (a[1] > y && b[1] > y && c[1] > y) || (a[1] < y && b[1] < y && c[1] < y) {
        return None;
    }
    let u = |p: [f64; 3]| [p[0] - tan_b * p[2] - x0, p[1] - y];
    let (pa, pb, pc) = (u(a), u(b), u(c));
    // Edge functions of the origin against each edge: w_a is opposite corner a, etc.
    let wa = pb[0] * pc[1] - pb[1] * pc[0];
    let wb = pc[0] * pa[1] - pc[1] * pa[0];
    let wc = pa[0] * pb[1] - pa[1] * pb[0];
    let area = wa + wb + wc;
    let scale = (pb[0] - pa[0]).abs().max((pb[1] - pa[1]).abs())
        * (pc[0] - pa[0]).abs().max((pc[1] - pa[1]).abs());
    if area.abs() <= 1e-14 * scale || area == 0.0 {
        return None; // edge-on to the line
    }
    let slack = 1e-12 * area.abs();
    let s = area.signum();
    if wa * s < -slack || wb * s < -slack || wc * s < -slack {
        return None;
    }
    let z = (wa * a[2] + wb * b[2] + wc * c[2]) / area;
    Some(z)
}

impl Surface for MeshSurface {
    fn height(&self, x: f64, y: f64) -> Option<f64> {
        self.lowest_hit(x, 0.0, y)
    }
    fn max_height(&self) -> f64 {
        self.z_max
    }
    fn y_bounds(&self) -> (f64, f64) {
        (self.y_min, self.y_max)
    }
    fn plane_height(&self, x0: f64, tan_b: f64, y: f64) -> Option<f64> {
        self.lowest_hit(x0, tan_b, y)
    }
}

/// A copy of `mesh` placed on the glass (see [`Placement`]); the reference point is the rear
/// end of the x extent at the middle of the y extent.
pub fn place(mesh: &TriMesh, placement: &Placement) -> Result<TriMesh, SimError> {
    placement.validate()?;
    let bb = mesh.bbox();
    let reference = P2::new(bb.min.x, 0.5 * (bb.min.y + bb.max.y));
    Ok(place_at(mesh, placement, reference))
}

/// A copy of `mesh` placed with the given reference point (mesh frame).
pub fn place_at(mesh: &TriMesh, placement: &Placement, reference: P2) -> TriMesh {
    let z_min = mesh.bbox().min.z;
    let tf = placement.transform(reference, z_min);
    let mut m = mesh.clone();
    for v in &mut m.vertices {
        *v = tf.apply(*v);
    }
    m
}
