//! The foot model for CAD (issue 18 item 5): one closed solid per foot in the foot's own frame,
//! its walls on the measured sole outline, written as STL (and PLY / OBJ) and as a faceted
//! STEP solid. Shared by the `model.bezier` stage and `footscan model`.
//!
//! - Frame: the measurements' heel point is the origin, x runs along the foot axis (heel
//!   centre to second metatarsal head) toward the toes, y is x turned 90 degrees
//!   counterclockwise seen from above (medial for a right foot, lateral for a left one), z is
//!   up, the glass at z = 0. So x of the toe tip is the foot length.
//! - Outline: the measured body outline (toes excluded) joined to the toe pads by the convex
//!   hull of the toe pads and the body in front of the metatarsal heads (the scanner sees no
//!   sole between the toes and the ball; the hull bridges that gap like a mitten). Behind the
//!   metatarsal heads the outline is the measured one, vertex for vertex.
//! - Heights: those the measurements were taken on (the Bezier model where it has a segment,
//!   else the scan grid, at 0.1 mm), bilinear between cells; the bridged gaps, which no scan
//!   point covers, are filled by the Laplace equation from their borders.
//! - Solid: [`crate::surface::solid`] on cells of `cell_mm` (STL) and `step_cell_mm` (STEP),
//!   bottom 2 mm below the glass. The gaps are filled once, on [`FILL_CELL_MM`], and other
//!   cells sample that fill, so the STL and the STEP agree there.

mod iges;
mod step;

use crate::geom::HeightMap;
use crate::measure::{measure_grid, MeasureError, Measurements, DEFAULT_CELL_MM};
use crate::scandata::ScanGrid;
use crate::surface::solid::{outline_solid, OutlineSolid};
use crate::surface::{build_scan_model, BezierNetwork, Continuity, SurfaceError};
use footscan_geom::mesh::{Format, GlbError, MeshError, TriMesh};
use footscan_geom::polygon::convex_hull;
use footscan_geom::{unit_by_hypot, P2, P3, V2};
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;

pub use iges::{iges_solid, write_iges_solid};
pub use step::{faceted_step, write_faceted_step};

/// Smallest model cell (mm): a whole foot on 0.1 mm cells is 7 million triangles and
/// 0.44 GB while it is built; finer grids would not fit the scanner's memory.
pub const MIN_CELL_MM: f64 = 0.1;
/// Largest cell accepted before the foot is measured; after, a quarter of its ball width.
pub const MAX_CELL_MM: f64 = 50.0;

/// Why a model could not be built or written.
#[derive(Debug, thiserror::Error)]
pub enum CadError {
    #[error("{name} = {value}: the model's cell must be between {lo} and {hi:.2} mm{why}")]
    Cell {
        name: &'static str,
        value: f64,
        lo: f64,
        hi: f64,
        why: String,
    },
    #[error(transparent)]
    Surface(#[from] SurfaceError),
    #[error("measuring the foot for the model's frame and outline")]
    Measure(#[from] MeasureError),
    #[error("writing {}", path.display())]
    Write {
        path: PathBuf,
        source: std::io::Error,
    },
    /// A mesh file (the error names it).
    #[error(transparent)]
    Mesh(#[from] MeshError),
    #[error("writing {}", path.display())]
    Glb { path: PathBuf, source: GlbError },
}

/// Refuse a cell that is not a number, not positive, finer than [`MIN_CELL_MM`] or coarser
/// than a quarter of the foot's ball width (before measuring: [`MAX_CELL_MM`]). `name` is
/// how the caller spells the setting (`--cell-mm`, `cell_mm`).
pub fn check_cell(
    name: &'static str,
    value: f64,
    ball_width_mm: Option<f64>,
) -> Result<(), CadError> {
    let (hi, why) = match ball_width_mm {
        Some(w) if w.is_finite() && w > 0.0 => (
            (w / 4.0).min(MAX_CELL_MM),
            format!(" (at most a quarter of this foot's ball width, {w:.1} mm)"),
        ),
        _ => (MAX_CELL_MM, String::new()),
    };
    if value.is_finite() && value >= MIN_CELL_MM && value <= hi {
        return Ok(());
    }
    let why = if value.is_nan() {
        format!("{why}; it is not a number")
    } else if value < MIN_CELL_MM {
        format!("{why}; finer cells would not fit in memory, and none can be 0 or negative")
    } else if ball_width_mm.is_some() {
        format!("{why}; coarser cells leave too few across the foot to model it")
    } else {
        format!("{why}; coarser cells leave too few across any foot (the limit is a quarter of its ball width)")
    };
    Err(CadError::Cell {
        name,
        value,
        lo: MIN_CELL_MM,
        hi,
        why,
    })
}

/// The foot's frame on the glass: origin (the heel point) and the unit axis, world mm.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct FootFrame {
    pub origin: P2,
    pub x_axis: V2,
}

impl FootFrame {
    pub fn of(m: &Measurements) -> FootFrame {
        FootFrame {
            origin: m.heel_point,
            x_axis: unit_by_hypot(&m.axis_dir),
        }
    }

    /// World (glass) point to foot coordinates.
    pub fn to_foot(&self, p: P2) -> P2 {
        let d = p - self.origin;
        let (c, s) = (self.x_axis.x, self.x_axis.y);
        P2::new(c * d.x + s * d.y, -s * d.x + c * d.y)
    }

    /// Foot coordinates to the world (glass).
    pub fn to_world(&self, q: P2) -> P2 {
        let (c, s) = (self.x_axis.x, self.x_axis.y);
        P2::new(
            self.origin.x + c * q.x - s * q.y,
            self.origin.y + s * q.x + c * q.y,
        )
    }
}

/// The sole outline in foot coordinates (counterclockwise) and what was done to get it.
#[derive(Clone, Debug)]
pub struct SoleOutline {
    pub points: Vec<P2>,
    /// Area the hull added between the toe pads and the body (mm^2).
    pub bridged_mm2: f64,
    pub warnings: Vec<String>,
}

/// The measured body outline joined to the toe pads (see the module doc), foot coordinates.
pub fn sole_outline(m: &Measurements, frame: &FootFrame) -> SoleOutline {
    let mut body: Vec<P2> = m.outline.iter().map(|&p| frame.to_foot(p)).collect();
    if area(&body) < 0.0 {
        body.reverse();
    }
    let toes: Vec<Vec<P2>> = m
        .toe_outlines
        .iter()
        .map(|t| t.iter().map(|&p| frame.to_foot(p)).collect())
        .collect();
    let body_area = area(&body);
    let toe_area: f64 = toes.iter().map(|t| area(t).abs()).sum();
    let mut warnings = Vec::new();
    // The cut: behind both metatarsal heads and every toe pad.
    let mut s_cut = frame.to_foot(m.mt1_head).x.min(frame.to_foot(m.mt5_head).x);
    for t in &toes {
        for p in t {
            s_cut = s_cut.min(p.x);
        }
    }
    s_cut -= 1.0;
    // Step back until the body outline crosses the cut exactly twice.
    for _ in 0..40 {
        if let Some(points) = join_front(&body, &toes, s_cut) {
            let bridged = area(&points) - body_area - toe_area;
            return SoleOutline {
                points,
                bridged_mm2: bridged.max(0.0),
                warnings,
            };
        }
        s_cut -= 2.0;
    }
    warnings.push(format!(
        "the body outline is not a simple band across the forefoot: the model leaves out the \
         {} toe pads",
        toes.len()
    ));
    SoleOutline {
        points: body,
        bridged_mm2: 0.0,
        warnings,
    }
}

/// Body outline behind x = `cut` followed by the convex hull of the body and toes in front of
/// it; None unless the body crosses the cut exactly twice.
fn join_front(body: &[P2], toes: &[Vec<P2>], cut: f64) -> Option<Vec<P2>> {
    let n = body.len();
    // Crossings: (edge index k from body[k] to body[k+1], point, entering the front?).
    let mut cross = Vec::new();
    for k in 0..n {
        let (a, b) = (body[k], body[(k + 1) % n]);
        if (a.x < cut) != (b.x < cut) {
            let f = (cut - a.x) / (b.x - a.x);
            cross.push((k, P2::new(cut, a.y + f * (b.y - a.y)), a.x < cut));
        }
    }
    if cross.len() != 2 || cross[0].2 == cross[1].2 {
        return None;
    }
    let (enter, leave) = if cross[0].2 {
        (cross[0], cross[1])
    } else {
        (cross[1], cross[0])
    };
    // Rear chain: from the leaving crossing through the vertices behind the cut to the
    // entering one (counterclockwise).
    let mut out = vec![leave.1];
    let mut k = (leave.0 + 1) % n;
    while k != (enter.0 + 1) % n {
        out.push(body[k]);
        k = (k + 1) % n;
    }
    out.push(enter.1);
    // Front: hull of the body in front of the cut, the two crossings and the toes.
    let mut pts: Vec<P2> = body.iter().copied().filter(|p| p.x >= cut).collect();
    pts.push(enter.1);
    pts.push(leave.1);
    for t in toes {
        pts.extend(t.iter().copied());
    }
    let hull = convex_hull(&pts).points;
    // Walk the hull counterclockwise from the entering crossing to the leaving one.
    let at = |q: P2| hull.iter().position(|&p| p == q);
    let (s, e) = (at(enter.1)?, at(leave.1)?);
    let h = hull.len();
    let mut k = (s + 1) % h;
    while k != e {
        out.push(hull[k]);
        k = (k + 1) % h;
    }
    Some(out)
}

/// Signed area, positive counterclockwise (mm^2): the shoelace sum on the coordinates as they
/// are (`Polygon::signed_area` takes them relative to the first vertex, which rounds
/// differently).
fn area(p: &[P2]) -> f64 {
    let n = p.len();
    0.5 * (0..n)
        .map(|k| {
            let (a, b) = (p[k], p[(k + 1) % n]);
            a.x * b.y - b.x * a.y
        })
        .sum::<f64>()
}

/// Height at a world point from a measured height map: bilinear between the four cell centres
/// around it when all have a height, else the nearest cell with one within two cells.
pub fn sample_height(map: &HeightMap, x: f64, y: f64) -> Option<f64> {
    let c = map.cell_mm;
    let fx = (x - map.x0) / c;
    let fy = (y - map.y0) / c;
    let (i0, j0) = (fx.floor(), fy.floor());
    if i0 >= 0.0 && j0 >= 0.0 && (i0 as usize + 1) < map.nx && (j0 as usize + 1) < map.ny {
        let (i, j) = (i0 as usize, j0 as usize);
        let z = [
            map.get(i, j),
            map.get(i + 1, j),
            map.get(i, j + 1),
            map.get(i + 1, j + 1),
        ];
        if z.iter().all(|v| v.is_finite()) {
            let (u, v) = (fx - i0, fy - j0);
            return Some(
                (1.0 - v) * ((1.0 - u) * z[0] + u * z[1]) + v * ((1.0 - u) * z[2] + u * z[3]),
            );
        }
    }
    let (ci, cj) = (fx.round() as i64, fy.round() as i64);
    let mut best: Option<(f64, f64)> = None;
    for dj in -2..=2i64 {
        for di in -2..=2i64 {
            let (i, j) = (ci + di, cj + dj);
            if i < 0 || j < 0 || i as usize >= map.nx || j as usize >= map.ny {
                continue;
            }
            let z = map.get(i as usize, j as usize);
            if !z.is_finite() {
                continue;
            }
            let d = (i as f64 - fx).powi(2) + (j as f64 - fy).powi(2);
            if best.is_none_or(|(bd, _)| d < bd) {
                best = Some((d, z));
            }
        }
    }
    best.map(|(_, z)| z)
}

/// Which files to write, and the cells of the STL (and PLY / OBJ) and of the STEP solid.
#[derive(Clone, Debug)]
pub struct ModelFiles {
    pub stl: Option<PathBuf>,
    pub ply: Option<PathBuf>,
    pub obj: Option<PathBuf>,
    pub step: Option<PathBuf>,
    /// The same solid as the STEP file, as an IGES 5.3 B-rep solid (entity 186).
    pub iges: Option<PathBuf>,
    /// glTF binary for the web and Blender: the solid on `glb_cell_mm` cells (node "foot"),
    /// the landmarks (empty nodes) and the length and ball-width lines, in metres.
    pub glb: Option<PathBuf>,
    pub cell_mm: f64,
    pub step_cell_mm: f64,
    /// Cell of the .glb solid (mm): the STL's cell keeps every triangle; a coarser one
    /// (footscand's 1 mm) keeps the file small enough to show at once in a browser.
    pub glb_cell_mm: f64,
}

/// Default cell of the .glb a scan writes for the dashboard's viewer (mm): about a quarter
/// of the 0.5 mm model's triangles, under 3 MB for an adult foot.
pub const DEFAULT_GLB_CELL_MM: f64 = 1.0;

/// Default cell of the STEP solid (mm): a faceted solid with about 10,000 faces for an adult
/// foot; a planar facet of 2 mm departs from a sole of 30 mm radius by 0.02 mm.
pub const DEFAULT_STEP_CELL_MM: f64 = 2.0;

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
    /// The foot frame (world mm on the glass) and the measured length.
    pub frame: FootFrame,
    pub foot_length_mm: f64,
    pub ball_width_mm: f64,
    /// Model extent in the foot frame: x (heel to toe), y, z (bottom to top), mm.
    pub extent_mm: [[f64; 2]; 3],
    /// Outline vertices, the area bridged between toes and body, nodes filled there.
    pub outline_vertices: usize,
    pub bridged_mm2: f64,
    pub filled_nodes: usize,
    pub cell_mm: f64,
    pub vertices: usize,
    pub triangles: usize,
    pub boundary_vertices: usize,
    pub components: usize,
    pub volume_mm3: f64,
    pub base_z_mm: f64,
    /// The STEP solid: cell, faces, volume of its facets.
    pub step_cell_mm: Option<f64>,
    pub step_faces: Option<usize>,
    pub step_volume_mm3: Option<f64>,
    /// The .glb solid: cell and triangles.
    pub glb_cell_mm: Option<f64>,
    pub glb_triangles: Option<usize>,
    /// Measuring plus meshing plus writing (ms), beside `build_ms`.
    pub mesh_ms: f64,
    pub warnings: Vec<String>,
    pub files: Vec<PathBuf>,
}

/// Cell of the solid whose filled heights (the bridged gaps) every other cell samples, so
/// solids on different cells (the STL's, the STEP's) agree there.
pub const FILL_CELL_MM: f64 = 0.5;

/// The solid of a measured foot on `cell_mm` cells, in the foot frame: heights from `map`,
/// else from `fill` (a solid on [`FILL_CELL_MM`]), else the Laplace fill.
pub fn foot_solid(
    map: &HeightMap,
    m: &Measurements,
    outline: &SoleOutline,
    cell_mm: f64,
    base_z: Option<f64>,
    fill: Option<&OutlineSolid>,
) -> Result<OutlineSolid, CadError> {
    let frame = FootFrame::of(m);
    let solid = outline_solid(&outline.points, cell_mm, base_z, |x, y| {
        let w = frame.to_world(P2::new(x, y));
        sample_height(map, w.x, w.y).or_else(|| fill.and_then(|f| f.height_at(x, y)))
    })?;
    Ok(solid)
}

/// The landmarks of `m` in the foot frame, on the glass (z = 0), by the names the viewer
/// and the glTF nodes use.
pub fn foot_landmarks(m: &Measurements, frame: &FootFrame) -> Vec<(&'static str, P3)> {
    let at = |p: P2| {
        let q = frame.to_foot(p);
        P3::new(q.x, q.y, 0.0)
    };
    vec![
        ("heel_point", at(m.heel_point)),
        ("toe_tip", at(m.toe_tip)),
        ("mt1_head", at(m.mt1_head)),
        ("mt5_head", at(m.mt5_head)),
        ("mt2_head", at(m.mt2_head)),
        ("heel_centre", at(m.heel_centre)),
        ("arch_point", at(m.arch_point)),
    ]
}

/// Writes the foot `mesh` (foot frame, mm) with its landmarks and the length (along the
/// axis, from the heel point) and ball-width (first to fifth metatarsal head) lines as a
/// .glb; returns its triangle count.
pub fn write_foot_glb(
    path: &std::path::Path,
    mesh: &TriMesh,
    m: &Measurements,
    frame: &FootFrame,
) -> Result<usize, GlbError> {
    use footscan_geom::mesh::{write_glb_scene, GlbLine, GlbMark, GlbPart, GlbScene};
    let lm = foot_landmarks(m, frame);
    let marks: Vec<GlbMark> = lm.iter().map(|&(name, at)| GlbMark { name, at }).collect();
    let get = |n: &str| lm.iter().find(|(k, _)| *k == n).expect("a landmark").1;
    let length = [P3::origin(), P3::new(m.foot_length_mm, 0.0, 0.0)];
    let ball = [get("mt1_head"), get("mt5_head")];
    write_glb_scene(
        path,
        &GlbScene {
            parts: &[GlbPart {
                name: "foot",
                mesh,
                colour: [0.85, 0.68, 0.58, 1.0],
                vertex_colours: None,
            }],
            marks: &marks,
            lines: &[
                GlbLine {
                    name: "length",
                    points: &length,
                    colour: [0.85, 0.1, 0.1, 1.0],
                },
                GlbLine {
                    name: "ball_width",
                    points: &ball,
                    colour: [0.1, 0.3, 0.9, 1.0],
                },
            ],
        },
    )?;
    Ok(mesh.triangles.len())
}

/// Build the network of `grid`, then [`write_foot_model`].
pub fn model_scan(
    grid: &ScanGrid,
    files: &ModelFiles,
    names: [&'static str; 3],
) -> Result<(BezierNetwork, ModelSummary), CadError> {
    check_cell(names[0], files.cell_mm, None)?;
    let (net, build_ms) = build_scan_model(grid)?;
    let s = write_foot_model(grid, &net, build_ms, files, names)?;
    Ok((net, s))
}

/// Measure the foot of `grid` with its network `net` and write its solid as `files` asks;
/// `names` are how the caller spells the three cells (STL, STEP, glb) in errors.
pub fn write_foot_model(
    grid: &ScanGrid,
    net: &BezierNetwork,
    build_ms: f64,
    files: &ModelFiles,
    names: [&'static str; 3],
) -> Result<ModelSummary, CadError> {
    check_cell(names[0], files.cell_mm, None)?;
    if files.step.is_some() || files.iges.is_some() {
        check_cell(names[1], files.step_cell_mm, None)?;
    }
    if files.glb.is_some() {
        check_cell(names[2], files.glb_cell_mm, None)?;
    }
    let t = Instant::now();
    let (map, m) = measure_grid(grid, Some(net), DEFAULT_CELL_MM)?;
    write_measured_foot_model(grid, net, build_ms, files, names, &map, &m, t)
}

/// [`write_foot_model`] of a foot already measured: `map` and `m` are what
/// [`measure_grid`] gives for `grid` with `net` on [`DEFAULT_CELL_MM`] cells (the scan's
/// `measure.foot` shares them, so the foot is measured once). `t` is when the work began,
/// for `mesh_ms`.
#[allow(clippy::too_many_arguments)]
pub fn write_measured_foot_model(
    grid: &ScanGrid,
    net: &BezierNetwork,
    build_ms: f64,
    files: &ModelFiles,
    names: [&'static str; 3],
    map: &HeightMap,
    m: &Measurements,
    t: Instant,
) -> Result<ModelSummary, CadError> {
    check_cell(names[0], files.cell_mm, Some(m.ball_width_mm))?;
    if files.step.is_some() || files.iges.is_some() {
        check_cell(names[1], files.step_cell_mm, Some(m.ball_width_mm))?;
    }
    if files.glb.is_some() {
        check_cell(names[2], files.glb_cell_mm, Some(m.ball_width_mm))?;
    }
    let frame = FootFrame::of(m);
    let outline = sole_outline(m, &frame);
    let mut warnings: Vec<String> = m
        .warnings
        .iter()
        .map(|w| format!("measurements: {w}"))
        .collect();
    warnings.extend(outline.warnings.iter().cloned());
    let reference = foot_solid(map, m, &outline, FILL_CELL_MM, None, None)?;
    let base = Some(reference.base_z);
    let on = |cell: f64| -> Result<OutlineSolid, CadError> {
        if cell == FILL_CELL_MM {
            Ok(reference.clone())
        } else {
            foot_solid(map, m, &outline, cell, base, Some(&reference))
        }
    };
    let solid = on(files.cell_mm)?;
    let components = solid.components();
    if components != 1 {
        warnings.push(format!(
            "the model falls into {components} pieces on {} mm cells (a part of the outline \
             thinner than a cell): use a finer cell",
            files.cell_mm
        ));
    }
    let mesh = solid.mesh();
    let mut written = Vec::new();
    for (path, format) in [
        (&files.stl, Format::StlBinary),
        (&files.ply, Format::PlyBinary),
        (&files.obj, Format::Obj),
    ] {
        if let Some(p) = path {
            mesh.write(p, format)?;
            written.push(p.clone());
        }
    }
    let (mut step_faces, mut step_volume) = (None, None);
    if files.step.is_some() || files.iges.is_some() {
        let s = on(files.step_cell_mm)?;
        let err = |p: &PathBuf| {
            let path = p.clone();
            move |source| CadError::Write { path, source }
        };
        if let Some(p) = &files.step {
            step_faces = Some(write_faceted_step(p, &s, "footscan foot model").map_err(err(p))?);
            written.push(p.clone());
        }
        if let Some(p) = &files.iges {
            step_faces = Some(write_iges_solid(p, &s, "footscan foot model").map_err(err(p))?);
            written.push(p.clone());
        }
        step_volume = Some(s.mesh().volume());
    }
    let mut glb_triangles = None;
    if let Some(p) = &files.glb {
        let g = on(files.glb_cell_mm)?;
        glb_triangles =
            Some(
                write_foot_glb(p, &g.mesh(), m, &frame).map_err(|source| CadError::Glb {
                    path: p.clone(),
                    source,
                })?,
            );
        written.push(p.clone());
    }
    let mut ext = [[f64::MAX, f64::MIN]; 3];
    for t in &mesh.triangles {
        for &k in t {
            let p = mesh.vertices[k as usize];
            for d in 0..3 {
                ext[d][0] = ext[d][0].min(p[d]);
                ext[d][1] = ext[d][1].max(p[d]);
            }
        }
    }
    let (nu, nv) = net.grid_size();
    let (lu, lv) = net.lattice();
    let summary = ModelSummary {
        grid: [nu, nv],
        grid_points: grid.valid_count(),
        lattice: [lu, lv],
        segments: net.segments().len(),
        skipped: net.skipped(),
        bytes: net.bytes(),
        build_ms,
        continuity: net.continuity(8),
        frame,
        foot_length_mm: m.foot_length_mm,
        ball_width_mm: m.ball_width_mm,
        extent_mm: ext,
        outline_vertices: outline.points.len(),
        bridged_mm2: outline.bridged_mm2,
        filled_nodes: reference.filled_nodes,
        cell_mm: files.cell_mm,
        vertices: mesh.vertices.len(),
        triangles: mesh.triangles.len(),
        boundary_vertices: solid.boundary_len(),
        components,
        volume_mm3: mesh.volume(),
        base_z_mm: solid.base_z,
        step_cell_mm: step_volume.map(|_| files.step_cell_mm),
        step_faces,
        step_volume_mm3: step_volume,
        glb_cell_mm: glb_triangles.map(|_| files.glb_cell_mm),
        glb_triangles,
        mesh_ms: t.elapsed().as_secs_f64() * 1e3,
        warnings,
        files: written,
    };
    Ok(summary)
}

impl ModelSummary {
    /// A few lines for a terminal.
    pub fn text(&self) -> String {
        let e = &self.extent_mm;
        let mut s = format!(
            "grid {} x {} ({} points): {} of {} x {} segments modelled, {} left out (missing points), \
             {} bytes, built in {:.1} ms\n\
             normal-angle jump across segment edges: max {:.1} deg, mean {:.1} deg over {} edges \
             (first derivatives vanish on every edge: the tangent there comes from second derivatives)\n\
             foot frame: heel point ({:.2}, {:.2}) mm on the glass is the origin, x along the axis at \
             {:.2} deg; measured length {:.2} mm, ball width {:.2} mm\n\
             outline: {} vertices, {:.0} mm^2 bridged between toes and ball ({} heights filled)\n\
             solid on {} mm cells: {} vertices, {} triangles, {} boundary vertices, {} piece(s), \
             closed, volume {:.0} mm^3, bottom at z = {:.2} mm\n\
             extent: x {:.2} .. {:.2} (length {:.2}), y {:.2} .. {:.2}, z {:.2} .. {:.2} mm; \
             measured, meshed and written in {:.0} ms\n",
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
            self.frame.origin.x,
            self.frame.origin.y,
            self.frame.x_axis.y.atan2(self.frame.x_axis.x).to_degrees(),
            self.foot_length_mm,
            self.ball_width_mm,
            self.outline_vertices,
            self.bridged_mm2,
            self.filled_nodes,
            self.cell_mm,
            self.vertices,
            self.triangles,
            self.boundary_vertices,
            self.components,
            self.volume_mm3,
            self.base_z_mm,
            e[0][0],
            e[0][1],
            e[0][1] - e[0][0],
            e[1][0],
            e[1][1],
            e[2][0],
            e[2][1],
            self.mesh_ms,
        );
        if let (Some(c), Some(f), Some(v)) =
            (self.step_cell_mm, self.step_faces, self.step_volume_mm3)
        {
            s += &format!(
                "STEP: faceted closed solid on {c} mm cells, {f} faces, volume {v:.0} mm^3 ({:+.3} % of the STL's)\n",
                100.0 * (v / self.volume_mm3 - 1.0)
            );
        }
        if let (Some(c), Some(t)) = (self.glb_cell_mm, self.glb_triangles) {
            s += &format!(
                "glTF: the solid on {c} mm cells, {t} triangles, with landmarks and the length and ball-width lines, in metres\n"
            );
        }
        for w in &self.warnings {
            s += &format!("warning: {w}\n");
        }
        for f in &self.files {
            s += &format!("wrote {}\n", f.display());
        }
        s
    }
}
