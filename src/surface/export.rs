//! The model of a scan end to end: grid to network, network to a closed mesh, mesh to files.
//! Shared by the `model.bezier` stage and `footscan model`.

use super::{BezierNetwork, Continuity, Mesh, PointGrid, SurfaceError};
use crate::scandata::ScanGrid;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

type MeshWriter = fn(&std::path::Path, &Mesh) -> std::io::Result<()>;

/// Which mesh files to write, and the cell of the (x, y) grid the mesh is sampled on.
#[derive(Clone, Debug)]
pub struct MeshFiles {
    pub stl: Option<PathBuf>,
    pub ply: Option<PathBuf>,
    pub obj: Option<PathBuf>,
    pub cell_mm: f64,
}

/// What a model run built and wrote.
#[derive(Clone, Debug, Serialize)]
pub struct ModelSummary {
    /// Grid points (frames x rows) and the valid ones.
    pub grid: [usize; 2],
    pub grid_points: usize,
    /// Segment lattice, modelled segments, and segments left out for a missing point.
    pub lattice: [usize; 2],
    pub segments: usize,
    pub skipped: usize,
    pub bytes: usize,
    pub build_ms: f64,
    pub continuity: Continuity,
    /// Height-map cells with a height, and the mesh written from them.
    pub cell_mm: f64,
    pub cells: usize,
    pub vertices: usize,
    pub triangles: usize,
    pub volume_mm3: f64,
    pub files: Vec<PathBuf>,
}

/// Build the network of a scan grid (u = frame, v = row), timing the build.
pub fn build_scan_model(grid: &ScanGrid) -> Result<(BezierNetwork, f64), SurfaceError> {
    let g = PointGrid::from_scan(grid);
    if g.valid_count() == 0 {
        return Err(SurfaceError::Empty);
    }
    let t = Instant::now();
    let net = BezierNetwork::build(&g)?;
    Ok((net, t.elapsed().as_secs_f64() * 1e3))
}

/// Sample `net` on `files.cell_mm`, close it into a solid 2 mm below its lowest point and
/// write the requested files.
pub fn write_model(
    net: &BezierNetwork,
    build_ms: f64,
    files: &MeshFiles,
) -> Result<ModelSummary, SurfaceError> {
    if files.cell_mm.is_nan() || files.cell_mm <= 0.0 {
        return Err(SurfaceError::BadCell(files.cell_mm));
    }
    let map = net.eval_heightmap(files.cell_mm);
    let zmin = map
        .z
        .iter()
        .copied()
        .filter(|z| z.is_finite())
        .fold(f64::INFINITY, f64::min);
    let mesh = Mesh::closed_from_heightmap(&map, zmin.min(0.0) - 2.0);
    let mut written = Vec::new();
    let writers: [(&Option<PathBuf>, MeshWriter); 3] = [
        (&files.stl, crate::io::write_stl),
        (&files.ply, crate::io::write_ply_mesh),
        (&files.obj, crate::io::write_obj),
    ];
    for (path, write) in writers {
        if let Some(p) = path {
            write(p, &mesh).map_err(|source| SurfaceError::Write {
                path: p.clone(),
                source,
            })?;
            written.push(p.clone());
        }
    }
    let (nu, nv) = net.grid_size();
    let (lu, lv) = net.lattice();
    Ok(ModelSummary {
        grid: [nu, nv],
        grid_points: 0,
        lattice: [lu, lv],
        segments: net.segments().len(),
        skipped: net.skipped(),
        bytes: net.bytes(),
        build_ms,
        continuity: net.continuity(8),
        cell_mm: files.cell_mm,
        cells: map.valid_count(),
        vertices: mesh.vertices.len(),
        triangles: mesh.triangles.len(),
        volume_mm3: mesh.signed_volume(),
        files: written,
    })
}

/// [`build_scan_model`] then [`write_model`].
pub fn model_scan(
    grid: &ScanGrid,
    files: &MeshFiles,
) -> Result<(BezierNetwork, ModelSummary), SurfaceError> {
    let (net, ms) = build_scan_model(grid)?;
    let mut s = write_model(&net, ms, files)?;
    s.grid_points = grid.valid_count();
    Ok((net, s))
}

impl ModelSummary {
    /// A few lines for a terminal.
    pub fn text(&self) -> String {
        let mut s = format!(
            "grid {} x {} ({} points): {} of {} x {} segments modelled, {} left out (missing points), \
             {} bytes, built in {:.1} ms\n\
             normal-angle jump across segment edges: max {:.1} deg, mean {:.1} deg over {} edges \
             (first derivatives vanish on every edge: the tangent there comes from second derivatives)\n\
             mesh on {} mm cells: {} cells, {} vertices, {} triangles, closed, volume {:.0} mm^3\n",
            self.grid[0],
            self.grid[1],
            self.grid_points,
            self.segments,
            self.lattice[0],
            self.lattice[1],
            self.skipped,
            self.bytes,
            self.build_ms,
            self.continuity.max_deg,
            self.continuity.mean_deg,
            self.continuity.edges,
            self.cell_mm,
            self.cells,
            self.vertices,
            self.triangles,
            self.volume_mm3
        );
        for f in &self.files {
            s += &format!("wrote {}\n", f.display());
        }
        s
    }
}
