//! What a fill hands over: seam and fairness figures (the join's seam measure, so the two
//! methods compare on one scale), the surfaces as IGES and STEP, a closed STL, JSON and
//! pictures (zebra stripes of the join region, views, and the slices with b).

use super::{fair, surface, Filled, Piece};
use crate::draw::{Canvas, View, BLACK, BLUE, GREEN, GREY, RED, WHITE};
use crate::join::seam::{self, Deviation, SeamMetrics};
use crate::join::tessellation::Tessellation;
use crate::join::zebra;
use crate::join::{reference, JoinError};
use footscan_geom::export::{iges, step, Header};
use footscan_geom::mesh::{Format, TriMesh};
use footscan_geom::P3;
use image::Rgb;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Seam, fairness and fit figures of a filled last.
#[derive(Debug, Clone, Serialize)]
pub struct Quality {
    /// Back part / fill and fill / toe part.
    pub back_seam: SeamMetrics,
    pub toe_seam: SeamMetrics,
    /// Integral over the fill of the squared curvature variation along the principal
    /// directions (1/mm^2), and of the squared principal curvatures (dimensionless).
    pub fill_variation: f64,
    pub fill_energy: f64,
    /// Kept parts against the meshes they came from.
    pub back_deviation: Deviation,
    pub toe_deviation: Deviation,
    /// The kept parts' ends at the seams against the original lasts there, the join's
    /// figure ([`crate::join::reference`]).
    pub back_original: SeamMetrics,
    pub toe_original: SeamMetrics,
}

/// Measure a fill (seams with `samples` points each); fails only where the original lasts
/// cannot be cut for the reference near the planes.
pub fn quality(f: &Filled, samples: usize) -> Result<Quality, JoinError> {
    let [back_original, toe_original] = reference::seams_against_originals(
        (&f.back, &f.toe),
        (&f.back_mesh, &f.toe_mesh),
        (&f.back_plane, &f.toe_plane),
        samples,
    )?;
    let (fill_variation, fill_energy) = fair::surface_fairness(&f.fill, 96, 24);
    Ok(Quality {
        back_seam: seam::seam(&f.back, 1.0, &f.fill, 0.0, samples),
        toe_seam: seam::seam(&f.fill, 1.0, &f.toe, 0.0, samples),
        fill_variation,
        fill_energy,
        back_deviation: seam::deviation(&f.back, &f.back_mesh, 240, 120),
        toe_deviation: seam::deviation(&f.toe, &f.toe_mesh, 240, 80),
        back_original,
        toe_original,
    })
}

/// The filled last as one closed mesh (back part 0, fill 1, toe part 2).
pub fn tessellate(f: &Filled, nu: usize, step_mm: f64) -> Tessellation {
    surface::tessellate(
        &[&f.back, &f.fill, &f.toe],
        (f.heel_end, f.toe_end),
        nu,
        step_mm,
    )
}

/// Paths written by [`write`].
#[derive(Debug, Clone, Serialize)]
pub struct Written {
    pub iges: PathBuf,
    pub step: PathBuf,
    pub stl: PathBuf,
    pub json: PathBuf,
    pub zebra: PathBuf,
    pub views: PathBuf,
    pub slices: PathBuf,
}

impl Written {
    pub fn files(&self) -> Vec<PathBuf> {
        vec![
            self.iges.clone(),
            self.step.clone(),
            self.stl.clone(),
            self.json.clone(),
            self.zebra.clone(),
            self.views.clone(),
            self.slices.clone(),
        ]
    }
}

#[derive(Serialize)]
struct Report<'a> {
    method: &'static str,
    blend: &'a str,
    gap_mm: f64,
    step_mm: f64,
    slices_in_fill: usize,
    points_per_slice: usize,
    morph_shift: usize,
    points_by_curve_extension: usize,
    /// Per fill slice: its position across the gap, where b was read, b.
    weights: &'a [[f64; 3]],
    fair: &'a Option<super::FairReport>,
    quality: &'a Quality,
    timings_ms: super::Timings,
    back_plane: [f64; 6],
    toe_plane: [f64; 6],
    stl: String,
}

fn io(e: impl std::fmt::Display, path: &Path) -> std::io::Error {
    std::io::Error::other(format!("{}: {e}", path.display()))
}

/// Write `dir/NAME.igs`, `.step`, `.stl`, `.json`, `NAME_zebra.png`, `NAME_views.png` and
/// `NAME_slices.png`.
pub fn write(f: &Filled, q: &Quality, dir: &Path, name: &str) -> std::io::Result<Written> {
    let path = |ext: &str| dir.join(format!("{name}{ext}"));
    let w = Written {
        iges: path(".igs"),
        step: path(".step"),
        stl: path(".stl"),
        json: path(".json"),
        zebra: path("_zebra.png"),
        views: path("_views.png"),
        slices: path("_slices.png"),
    };
    write_to(f, q, dir, w)
}

/// Write the files under the Gordon join's names (joined.igs, joined.step, joined.stl,
/// seams.json, zebra.png, views.png, and slices.png), so `footscan last join` leaves the
/// same files whichever method it ran.
pub fn write_as_join(f: &Filled, q: &Quality, dir: &Path) -> std::io::Result<Written> {
    let w = Written {
        iges: dir.join("joined.igs"),
        step: dir.join("joined.step"),
        stl: dir.join("joined.stl"),
        json: dir.join("seams.json"),
        zebra: dir.join("zebra.png"),
        views: dir.join("views.png"),
        slices: dir.join("slices.png"),
    };
    write_to(f, q, dir, w)
}

fn write_to(f: &Filled, q: &Quality, dir: &Path, w: Written) -> std::io::Result<Written> {
    std::fs::create_dir_all(dir)?;
    let surfs = [f.back.clone(), f.fill.clone(), f.toe.clone()];
    let header = Header::new(&format!("footscan blend fill ({})", f.blend));
    iges::write(&w.iges, &[], &surfs, &header).map_err(|e| io(e, &w.iges))?;
    step::write(&w.step, &[], &surfs, &header).map_err(|e| io(e, &w.step))?;
    let t = tessellate(f, 160, 1.0);
    let mesh = TriMesh::new(t.vertices.clone(), t.triangles.clone());
    let stl = match mesh.check() {
        Ok(r) => format!("closed, volume {:.0} mm3", r.volume),
        Err(d) => format!("not closed: {d}"),
    };
    mesh.write(&w.stl, Format::StlBinary)
        .map_err(|e| io(e, &w.stl))?;
    let plane6 = |p: &footscan_geom::plane::Plane| {
        [
            p.origin.x, p.origin.y, p.origin.z, p.normal.x, p.normal.y, p.normal.z,
        ]
    };
    let report = Report {
        method: "blend",
        blend: &f.blend,
        gap_mm: f.gap_mm,
        step_mm: f.step_mm,
        slices_in_fill: f.slices.iter().filter(|s| s.piece == Piece::Fill).count(),
        points_per_slice: f.u.len(),
        morph_shift: f.morph_shift,
        points_by_curve_extension: f.by_curve,
        weights: &f.weights,
        fair: &f.fair,
        quality: q,
        timings_ms: f.timings,
        back_plane: plane6(&f.back_plane),
        toe_plane: plane6(&f.toe_plane),
        stl,
    };
    let json = serde_json::to_string_pretty(&report).map_err(|e| io(e, &w.json))?;
    crate::draw::write_atomic(&w.json, json.as_bytes())?;
    let seams: Vec<Vec<P3>> = [(&f.back, 1.0), (&f.toe, 0.0)]
        .iter()
        .map(|(s, v)| (0..=200).map(|i| s.point(i as f64 / 200.0, *v)).collect())
        .collect();
    let (x0, x1) = (
        f.back_plane.origin.x - 30.0,
        f.back_plane.origin.x + f.gap_mm + 30.0,
    );
    let caption = format!(
        "blend fill ({}): gap {:.1} mm, back seam normal jump {:.3} deg, toe seam {:.3} deg",
        f.blend, f.gap_mm, q.back_seam.normal_max_deg, q.toe_seam.normal_max_deg
    );
    zebra::zebra_png(&w.zebra, &t, (x0, x1), &seams, &caption)?;
    zebra::views_png(&w.views, &t, &seams, &caption)?;
    slices_png(&w.slices, f)?;
    Ok(w)
}

const MAGENTA: Rgb<u8> = Rgb([200, 0, 200]);

/// Top and side views of the slices near the gap (kept parts green, fill magenta, as the
/// gap-filling paper draws them) and the blending function b(t) used.
pub fn slices_png(path: &Path, f: &Filled) -> std::io::Result<()> {
    let (w, h) = (1100u32, 980u32);
    let mut c = Canvas::new(w, h, WHITE);
    let near: Vec<_> = f
        .slices
        .iter()
        .filter(|s| s.z > -20.0 && s.z < f.gap_mm + 20.0)
        .collect();
    for (panel, (ax, label)) in [(1usize, "top view (x, y)"), (2, "side view (x, z)")]
        .iter()
        .enumerate()
    {
        let coords = |p: &P3| (p.x, if *ax == 1 { p.y } else { p.z });
        let mut bnd = [
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        for s in &near {
            for p in &s.points {
                let (x, y) = coords(p);
                bnd = [bnd[0].min(x), bnd[1].max(x), bnd[2].min(y), bnd[3].max(y)];
            }
        }
        let top = 30.0 + panel as f64 * 330.0;
        let view = View::fit(bnd, 60.0, top + 300.0, w as f64 - 120.0, 290.0);
        for s in &near {
            let col = if s.piece == Piece::Fill {
                MAGENTA
            } else {
                GREEN
            };
            for p in s.points.iter().step_by(2) {
                c.dot(&view, coords(p), 1, col);
            }
        }
        c.text(
            20,
            top as i64 - 14,
            &format!("{label}: kept slices green, fill magenta"),
            BLACK,
            1,
        );
    }
    // b(t).
    let view = View::fit([0.0, 1.0, 0.0, 1.0], 100.0, 950.0, 400.0, 240.0);
    c.line(&view, (0.0, 0.0), (1.0, 0.0), GREY, 1);
    c.line(&view, (0.0, 0.0), (0.0, 1.0), GREY, 1);
    let pts: Vec<(f64, f64)> = f.weights.iter().map(|w| (w[0], w[2])).collect();
    for w2 in pts.windows(2) {
        c.line(&view, w2[0], w2[1], BLUE, 2);
    }
    for p in &pts {
        c.dot(&view, *p, 3, RED);
    }
    c.text(
        100,
        700,
        &format!(
            "b(t) of the '{}' blend: morph weight across the gap (t = 0 back, 1 toe)",
            f.blend
        ),
        BLACK,
        1,
    );
    c.text(80, 704 + 6, "1", BLACK, 1);
    c.text(80, 946, "0", BLACK, 1);
    c.save_png(path)
}
