//! Everything an insole run writes, all or nothing: insole.stl, insole.3mf, insole.step,
//! thickness.png, top.png, side.png and insole.json.

use crate::design::{design_in, Design, Marks, Plantar, ShoeBottom};
use crate::measure::{measure_back, Measured};
use crate::params::Params;
use crate::picture;
use crate::InsoleError;
use footscan::cad::faceted_step;
use footscan::cad::FootFrame;
use footscan_geom::mesh::TriMesh;
use footscan_geom::P2;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub const STL: &str = "insole.stl";
pub const THREEMF: &str = "insole.3mf";
pub const STEP: &str = "insole.step";
pub const JSON: &str = "insole.json";
pub const THICKNESS_PNG: &str = "thickness.png";
pub const TOP_PNG: &str = "top.png";
pub const SIDE_PNG: &str = "side.png";

/// insole.json.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    pub scan: String,
    pub side: String,
    /// The frame of every file: the scan's foot frame (origin the heel point, x along the
    /// axis at the given direction on the glass, z up from the insole's bottom), mm.
    pub frame: FootFrame,
    pub foot_length_mm: f64,
    pub landmarks: Marks,
    /// The parameters as applied.
    pub params: Params,
    /// The scanned arch height (laid flat) and the insole's (mm); the pad's apex as placed.
    pub scanned_arch_mm: f64,
    pub arch_target_mm: f64,
    pub pad_apex_mm: P2,
    /// How far the midfoot stood off the glass (0: the foot bore weight).
    pub midfoot_off_glass_mm: f64,
    pub outline_vertices: usize,
    /// How sharply the outline turns: the most over any 2 mm of it behind the metatarsal
    /// heads (deg/mm; a 10 mm radius is 5.7; in front, a shoe bottom adjusted to the foot
    /// has the toes' lobes) and in all (deg; 360 for a convex outline).
    pub outline_max_turn_deg_per_mm: f64,
    /// Where that most is (foot frame, mm).
    pub outline_max_turn_at: P2,
    pub outline_total_turn_deg: f64,
    /// Where the outline came from: "footprint + margin" or the shoe bottom's last.
    pub outline_from: String,
    /// The shoe's bottom curve the insole is bent onto (absent: its bottom is flat).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spring: Option<crate::design::Spring>,
    /// Each parameter measured back on insole.stl's mesh.
    pub measured: Measured,
    pub mesh: MeshFacts,
    pub step_faces: usize,
    pub step_cell_mm: f64,
    pub threemf_bytes: usize,
    /// Designing and meshing the insole (ms), and measuring and writing (ms).
    pub design_ms: f64,
    pub write_ms: f64,
    pub warnings: Vec<String>,
    pub files: Vec<String>,
}

#[derive(Clone, Debug, Serialize)]
pub struct MeshFacts {
    pub cell_mm: f64,
    pub vertices: usize,
    pub triangles: usize,
    pub closed: bool,
    pub components: usize,
    pub volume_mm3: f64,
    pub extent_mm: [[f64; 2]; 3],
}

/// What a run wrote.
#[derive(Debug)]
pub struct Written {
    pub report: Report,
    pub dir: PathBuf,
    pub mesh: TriMesh,
    pub design: Design,
}

/// Designs the insole for `p`, measures it back and writes every file into `out` (a
/// directory, replaced whole or left as it was).
pub fn write_insole(p: &Plantar, params: &Params, out: &Path) -> Result<Written, InsoleError> {
    write_insole_in(p, params, None, out)
}

/// [`write_insole`] with the outline of a shoe's bottom when given.
pub fn write_insole_in(
    p: &Plantar,
    params: &Params,
    shoe: Option<&ShoeBottom>,
    out: &Path,
) -> Result<Written, InsoleError> {
    let t0 = Instant::now();
    let d = design_in(p, params, shoe)?;
    let solid = d.bent_solid(params.mesh_cell_mm)?;
    let mesh = solid.mesh();
    let closed = mesh.check_closed();
    if let Err(e) = &closed {
        return Err(InsoleError::Solid(format!("the mesh is not closed: {e}")));
    }
    let components = solid.components();
    if components != 1 {
        return Err(InsoleError::Solid(format!(
            "the insole falls into {components} pieces on {} mm cells (a part of the outline \
             thinner than a cell): use a finer mesh_cell_mm",
            params.mesh_cell_mm
        )));
    }
    let step_solid = if params.step_cell_mm == params.mesh_cell_mm {
        solid.clone()
    } else {
        d.bent_solid(params.step_cell_mm)?
    };
    let design_ms = t0.elapsed().as_secs_f64() * 1e3;
    let t1 = Instant::now();
    // Measured and drawn in the insole's own frame (the shoe's bottom curve taken off).
    let local = d.unbent(&mesh);
    let measured = measure_back(&d, p, &local);
    let (step_text, step_faces) = faceted_step(&step_solid, "footscan insole");
    let threemf = crate::threemf::to_3mf(&mesh, "footscan insole");
    let bb = mesh.bbox();
    let heads_x = d.marks.mt1_head.x.min(d.marks.mt5_head.x);
    let turning = crate::design::outline_turning_behind(&d.outline, 2.0, heads_x);
    let mut report = Report {
        scan: p.source.clone(),
        side: format!("{:?}", d.side).to_lowercase(),
        frame: d.frame,
        foot_length_mm: d.foot_length_mm,
        landmarks: d.marks,
        params: params.clone(),
        scanned_arch_mm: d.scanned_arch_mm,
        arch_target_mm: d.arch_target_mm,
        pad_apex_mm: d.pad_apex,
        midfoot_off_glass_mm: d.bottom_rise_mm,
        outline_vertices: d.outline.len(),
        outline_max_turn_deg_per_mm: turning.max,
        outline_max_turn_at: turning.at,
        outline_total_turn_deg: turning.total,
        outline_from: match shoe {
            Some(s) => format!("shoe bottom: {}", s.source),
            None => format!("footprint + {} mm margin", params.margin_mm),
        },
        spring: d.spring.clone(),
        measured,
        mesh: MeshFacts {
            cell_mm: params.mesh_cell_mm,
            vertices: mesh.vertices.len(),
            triangles: mesh.triangles.len(),
            closed: closed.is_ok(),
            components,
            volume_mm3: mesh.volume(),
            extent_mm: [
                [bb.min.x, bb.max.x],
                [bb.min.y, bb.max.y],
                [bb.min.z, bb.max.z],
            ],
        },
        step_faces,
        step_cell_mm: params.step_cell_mm,
        threemf_bytes: threemf.len(),
        design_ms,
        write_ms: 0.0,
        warnings: d.warnings.clone(),
        files: [STL, THREEMF, STEP, JSON, THICKNESS_PNG, TOP_PNG, SIDE_PNG]
            .iter()
            .map(|n| out.join(n).display().to_string())
            .collect(),
    };
    for c in report.measured.checks.iter().filter(|c| !c.ok) {
        report.warnings.push(format!(
            "{} measured {:.3} {} on the mesh, asked {:.3} (bound {})",
            c.name, c.measured, c.unit, c.asked, c.bound
        ));
    }
    let pictures = [
        (THICKNESS_PNG, picture::thickness_map(&d, &local)),
        (TOP_PNG, picture::top_picture(&d, &local)),
        (SIDE_PNG, picture::side_picture(&d, &mesh)),
    ];
    report.write_ms = t1.elapsed().as_secs_f64() * 1e3;
    footscan_last::outdir::write_dir_atomic(out, |tmp| {
        std::fs::create_dir_all(tmp).map_err(|e| (tmp.to_path_buf(), e.to_string()))?;
        let put = |name: &str, bytes: &[u8]| {
            let path = tmp.join(name);
            std::fs::write(&path, bytes).map_err(|e| (out.join(name), e.to_string()))
        };
        put(STL, &mesh.to_stl_binary())?;
        put(THREEMF, &threemf)?;
        put(STEP, step_text.as_bytes())?;
        for (name, cv) in &pictures {
            cv.save_png(&tmp.join(name))
                .map_err(|e| (out.join(name), e.to_string()))?;
        }
        put(
            JSON,
            &serde_json::to_vec_pretty(&report).expect("the report serialises"),
        )?;
        Ok(())
    })
    .map_err(|(path, why)| InsoleError::Write { path, why })?;
    Ok(Written {
        report,
        dir: out.to_path_buf(),
        mesh,
        design: d,
    })
}

impl Report {
    /// A few lines for a terminal.
    pub fn text(&self) -> String {
        let m = &self.measured;
        let mut s = format!(
            "{} foot, length {:.1} mm: insole on {} mm cells, {} triangles, closed, one piece, \
             volume {:.0} mm^3; STEP {} faces on {} mm cells; 3MF {} bytes\n\
             scanned arch {:.2} mm, insole arch {:.2} mm{}\n",
            self.side,
            self.foot_length_mm,
            self.mesh.cell_mm,
            self.mesh.triangles,
            self.mesh.volume_mm3,
            self.step_faces,
            self.step_cell_mm,
            self.threemf_bytes,
            self.scanned_arch_mm,
            self.arch_target_mm,
            if self.midfoot_off_glass_mm > 0.0 {
                format!(
                    "; midfoot {:.1} mm off the glass, laid flat",
                    self.midfoot_off_glass_mm
                )
            } else {
                String::new()
            }
        );
        s += "measured back on the mesh:\n";
        for c in &m.checks {
            s += &format!(
                "  {:<28} asked {:>8.3} measured {:>8.3} {:<3} error {:+.3} (bound {}) {}\n",
                c.name,
                c.asked,
                c.measured,
                c.unit,
                c.error,
                c.bound,
                if c.ok { "ok" } else { "OUT" }
            );
        }
        s += &format!(
            "  thinnest shell {:.3} mm at ({:.1}, {:.1}) (at least {:.3})\n  top vs scanned \
             sole over the weight-bearing area: {} points, max {:.3} mm at ({:.1}, {:.1}), RMS \
             {:.3} mm (bound {})\n",
            m.min_thickness_mm,
            m.min_thickness_at.x,
            m.min_thickness_at.y,
            m.min_thickness_bound_mm,
            m.contact_points,
            m.contact_max_mm,
            m.contact_max_at.x,
            m.contact_max_at.y,
            m.contact_rms_mm,
            crate::measure::CONTACT_BOUND_MM
        );
        s += &format!(
            "designed and meshed in {:.0} ms, measured and drawn in {:.0} ms\n",
            self.design_ms, self.write_ms
        );
        for w in &self.warnings {
            s += &format!("warning: {w}\n");
        }
        for f in &self.files {
            s += &format!("wrote {f}\n");
        }
        s
    }
}
