//! What an adjustment writes: the bottom surface (IGES, STEP), the deformed last (STL), the
//! deviation heat map (PNG) and a report (JSON), all or nothing.

use super::last::{DeformReport, PreparedLast};
use super::surface::BottomSurface;
use super::{AdjustError, Adjustment, Deviation, HeightMap, LandmarkPair};
use crate::draw::{self, Canvas, View, BLACK, BLUE, GREEN, GREY, WHITE};
use footscan_geom::export::{iges, step, Header};
use footscan_geom::mesh::{Format, TriMesh};
use footscan_geom::{P2, V2};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// File names inside the output directory.
pub const BOTTOM_IGES: &str = "bottom.igs";
pub const BOTTOM_STEP: &str = "bottom.step";
pub const LAST_STL: &str = "last_adjusted.stl";
/// The adjusted last as glTF binary, for the web and Blender (issue 35).
pub const LAST_GLB: &str = "last_adjusted.glb";
pub const HEATMAP_PNG: &str = "deviation.png";
pub const REPORT_JSON: &str = "adjust.json";

/// The figures of one adjustment, as written to adjust.json.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub foot: String,
    pub last: String,
    pub eps: f64,
    pub zeta: f64,
    pub eps_at: P2,
    pub zeta_at: P2,
    pub mirrored: bool,
    pub rotation_deg: f64,
    pub shift_mm: V2,
    pub before: Deviation,
    pub after: Deviation,
    pub landmarks: Vec<LandmarkPair>,
    pub correspondences: usize,
    pub surface_fit_rms_mm: f64,
    pub surface_fit_max_mm: f64,
    pub surface_control_points: [usize; 2],
    pub deform: Option<DeformReport>,
    pub notes: Vec<String>,
}

impl Report {
    pub fn new(
        foot: &str,
        last: &str,
        adj: &Adjustment,
        surf: &BottomSurface,
        deform: Option<DeformReport>,
    ) -> Report {
        let mut notes = adj.notes.clone();
        notes.extend(surf.notes.iter().cloned());
        Report {
            foot: foot.into(),
            last: last.into(),
            eps: adj.eps,
            zeta: adj.zeta,
            eps_at: adj.eps_at,
            zeta_at: adj.zeta_at,
            mirrored: adj.mirrored,
            rotation_deg: adj.rotation_deg,
            shift_mm: adj.shift,
            before: adj.before,
            after: adj.after,
            landmarks: adj.landmarks.clone(),
            correspondences: adj.correspondences,
            surface_fit_rms_mm: surf.rms_mm,
            surface_fit_max_mm: surf.max_mm,
            surface_control_points: [surf.surface.nu, surf.surface.nv],
            deform,
            notes,
        }
    }
}

fn panel(
    c: &mut Canvas,
    view: &View,
    map: &HeightMap,
    range: f64,
    outlines: [(&[P2], draw::Colour); 2],
    marks: &[(P2, draw::Colour)],
    area: (i64, i64, i64, i64),
) {
    let (x0, y0, w, h) = area;
    for r in y0..y0 + h {
        for col in x0..x0 + w {
            let (x, y) = view.world(col as f64, r as f64);
            if let Some((i, j)) = map.cell_of(x, y) {
                let d = map.get(i, j);
                if d.is_finite() {
                    c.put(col, r, draw::diverging(d, range));
                }
            }
        }
    }
    for (o, colour) in outlines {
        let pts: Vec<(f64, f64)> = o.iter().map(|p| (p.x, p.y)).collect();
        c.polyline(view, &pts, true, colour, 2);
    }
    for (p, colour) in marks {
        c.dot(view, (p.x, p.y), 4, *colour);
    }
}

/// The heat map: deviation (bottom minus foot, mm) before (rigid fit only) and after, each
/// with its own colour bar; foot outline black, bottom outline blue, foot landmarks black,
/// the bottom's green.
pub fn heatmap(adj: &Adjustment, title: &str) -> Canvas {
    let (w, h) = (1500u32, 760u32);
    let mut c = Canvas::new(w, h, WHITE);
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in adj
        .foot_outline
        .iter()
        .chain(&adj.outline)
        .chain(&adj.bottom_outline_before)
    {
        for d in 0..2 {
            lo[d] = lo[d].min(p[d]);
            hi[d] = hi[d].max(p[d]);
        }
    }
    let bounds = [lo[0] - 3.0, hi[0] + 3.0, lo[1] - 3.0, hi[1] + 3.0];
    let range = |m: &HeightMap, floor: f64| {
        let mut v: Vec<f64> =
            m.z.iter()
                .filter(|z| z.is_finite())
                .map(|z| z.abs())
                .collect();
        v.sort_by(f64::total_cmp);
        let p = v
            .get((v.len() as f64 * 0.98) as usize)
            .copied()
            .unwrap_or(1.0);
        // A round number at or above the 98th percentile.
        let nice = [0.25, 0.5, 1.0, 2.0, 3.0, 5.0, 10.0, 20.0, 30.0, 50.0, 100.0];
        nice.iter()
            .copied()
            .find(|&n| n >= p.max(floor))
            .unwrap_or(100.0)
    };
    c.text(20, 12, title, BLACK, 2);
    for (k, (name, map, dev, bottom, floor)) in [
        (
            "before (rigid fit)",
            &adj.before_map,
            &adj.before,
            &adj.bottom_outline_before,
            1.0,
        ),
        (
            "after adjustment",
            &adj.after_map,
            &adj.after,
            &adj.outline,
            0.25,
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let (px, py, pw, ph) = (20 + k as i64 * 740, 90i64, 600i64, 600i64);
        let view = View::fit(bounds, px as f64, (py + ph) as f64, pw as f64, ph as f64);
        let r = range(map, floor);
        let marks: Vec<(P2, draw::Colour)> = adj
            .landmarks
            .iter()
            .flat_map(|l| {
                [
                    (l.foot, BLACK),
                    (if k == 0 { l.before } else { l.after }, GREEN),
                ]
            })
            .collect();
        panel(
            &mut c,
            &view,
            map,
            r,
            [(&adj.foot_outline, BLACK), (bottom, BLUE)],
            &marks,
            (px, py, pw, ph),
        );
        c.text(px, 50, name, BLACK, 2);
        let line = format!(
            "height RMS {:.2} max {:.2} mm, >0.5 mm {:.1} %, uncovered {:.1} %",
            dev.height_rms_mm,
            dev.height_max_mm,
            100.0 * dev.share_beyond_0_5,
            100.0 * dev.uncovered_share
        );
        c.text(px, 700, &line, BLACK, 1);
        let line2 = format!(
            "outline RMS {:.2} max {:.2} mm, landmarks max {:.2} mm",
            dev.outline_rms_mm, dev.outline_max_mm, dev.landmark_max_mm
        );
        c.text(px, 714, &line2, BLACK, 1);
        c.colour_bar(
            px + pw + 15,
            py + 40,
            18,
            ph - 80,
            &|v| draw::diverging(v, r),
            -r,
            r,
            5,
            "mm",
        );
    }
    c.text(
        20,
        736,
        &format!(
            "bottom minus foot; black: foot outline and landmarks, blue: bottom outline, green: bottom landmarks; eps {:.4}, zeta {:.4}",
            adj.eps, adj.zeta
        ),
        GREY,
        1,
    );
    c
}

/// Everything written by [`write_outputs`].
#[derive(Clone, Debug)]
pub struct Written {
    pub dir: PathBuf,
    pub files: Vec<PathBuf>,
}

/// The files of one adjustment written into the existing directory `dir`; errors name
/// `named_dir`'s file (the directory the user asked for).
fn write_files(
    dir: &Path,
    named_dir: &Path,
    adj: &Adjustment,
    surf: &BottomSurface,
    last: Option<(&PreparedLast, &TriMesh)>,
    report: &Report,
) -> Result<(), AdjustError> {
    let io = |name: &str, e: &dyn std::fmt::Display| AdjustError::Output {
        path: named_dir.join(name),
        why: e.to_string(),
    };
    let header = Header::new("footscan adjusted last bottom");
    let curves: Vec<_> = surf.outline.iter().cloned().collect();
    let surfaces = [surf.surface.clone()];
    iges::write(&dir.join(BOTTOM_IGES), &curves, &surfaces, &header)
        .map_err(|e| io(BOTTOM_IGES, &e))?;
    step::write(&dir.join(BOTTOM_STEP), &curves, &surfaces, &header)
        .map_err(|e| io(BOTTOM_STEP, &e))?;
    if let Some((_, mesh)) = last {
        mesh.write(dir.join(LAST_STL), Format::StlBinary)
            .map_err(|e| io(LAST_STL, &e))?;
        let part = footscan_geom::mesh::GlbPart {
            name: "last",
            mesh,
            colour: [0.7, 0.7, 0.75, 1.0],
            vertex_colours: None,
        };
        footscan_geom::mesh::write_glb(dir.join(LAST_GLB), &[part])
            .map_err(|e| io(LAST_GLB, &e))?;
    }
    let title = format!("{}  on  {}", report.last, report.foot);
    heatmap(adj, &title)
        .save_png(&dir.join(HEATMAP_PNG))
        .map_err(|e| io(HEATMAP_PNG, &e))?;
    let json = serde_json::to_vec_pretty(report).map_err(|e| io(REPORT_JSON, &e))?;
    draw::write_atomic(&dir.join(REPORT_JSON), &json).map_err(|e| io(REPORT_JSON, &e))?;
    Ok(())
}

/// An output error naming the file or directory.
fn io(path: &Path, e: &dyn std::fmt::Display) -> AdjustError {
    AdjustError::Output {
        path: path.to_path_buf(),
        why: e.to_string(),
    }
}

/// `path` as a new empty directory (a leftover of a killed run removed first).
fn fresh_dir(path: PathBuf) -> Result<PathBuf, AdjustError> {
    let _ = std::fs::remove_dir_all(&path);
    std::fs::create_dir_all(&path).map_err(|e| io(&path, &e))?;
    Ok(path)
}

/// The names [`write_files`] writes.
fn names(with_last: bool) -> Vec<&'static str> {
    let mut n = vec![BOTTOM_IGES, BOTTOM_STEP];
    if with_last {
        n.extend([LAST_STL, LAST_GLB]);
    }
    n.extend([HEATMAP_PNG, REPORT_JSON]);
    n
}

/// Writes the outputs beside other files in the existing directory `dir` (a scan directory):
/// into a temporary directory inside it, then each file renamed into place, so a reader sees
/// every file whole; on an error the files already moved are removed again and nothing is
/// left behind.
pub fn write_into(
    dir: &Path,
    adj: &Adjustment,
    surf: &BottomSurface,
    last: Option<(&PreparedLast, &TriMesh)>,
    report: &Report,
) -> Result<Written, AdjustError> {
    let tmp = fresh_dir(dir.join(format!(".last-adjust.tmp{}", std::process::id())))?;
    let mut moved = Vec::new();
    let result = write_files(&tmp, dir, adj, surf, last, report).and_then(|()| {
        for n in names(last.is_some()) {
            std::fs::rename(tmp.join(n), dir.join(n)).map_err(|e| io(&dir.join(n), &e))?;
            moved.push(dir.join(n));
        }
        Ok(())
    });
    let _ = std::fs::remove_dir_all(&tmp);
    if let Err(e) = result {
        for f in &moved {
            let _ = std::fs::remove_file(f);
        }
        return Err(e);
    }
    Ok(Written {
        dir: dir.to_path_buf(),
        files: moved,
    })
}

/// Writes the outputs into `out` all or nothing: into a temporary directory beside it, then
/// renamed into place (an existing `out` is replaced only once everything is written). On
/// an error nothing is left behind.
pub fn write_outputs(
    out: &Path,
    adj: &Adjustment,
    surf: &BottomSurface,
    last: Option<(&PreparedLast, &TriMesh)>,
    report: &Report,
) -> Result<Written, AdjustError> {
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = out
        .file_name()
        .ok_or_else(|| io(out, &"not a directory path"))?
        .to_string_lossy()
        .to_string();
    let tmp = fresh_dir(parent.join(format!(".{name}.tmp{}", std::process::id())))?;
    let result = write_files(&tmp, out, adj, surf, last, report).and_then(|()| {
        // Replace `out` only now.
        let old = parent.join(format!(".{name}.old{}", std::process::id()));
        let had = out.exists();
        if had {
            std::fs::rename(out, &old).map_err(|e| io(out, &e))?;
        }
        if let Err(e) = std::fs::rename(&tmp, out) {
            if had {
                let _ = std::fs::rename(&old, out);
            }
            return Err(io(out, &e));
        }
        if had {
            let _ = std::fs::remove_dir_all(&old);
        }
        Ok(())
    });
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result?;
    Ok(Written {
        dir: out.to_path_buf(),
        files: names(last.is_some()).iter().map(|n| out.join(n)).collect(),
    })
}
