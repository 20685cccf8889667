//! `footscan bench measure`: the foot measurements (docs/method.md section 8) on a population
//! of simulated feet of every kind against their exact truth, and on the real feet of the data
//! directory against themselves (heads where feet have them, a person's left and right foot
//! alike).

use footscan::geom::HeightMap;
use footscan::measure::{compare_with_truth, measure_foot, Measurements};
use footscan_geom::mesh::TriMesh;
use footscan_sim::foot::{population, Foot};
use footscan_sim::mesh_scene::{MeshSurface, Placement};
use footscan_sim::render::Surface;
use serde::Serialize;
use std::time::Instant;

/// The population targets: metatarsal heads (mm), widths (mm), length (mm).
pub const TARGET_HEAD_MM: f64 = 3.0;
pub const TARGET_WIDTH_MM: f64 = 0.5;
pub const TARGET_LENGTH_MM: f64 = 0.3;

/// The analytic foot sampled at cell centres (NaN outside the footprint); `toes` false leaves
/// the toe pads out. The map sees the whole sole up to its vertical edge.
pub fn analytic_map(foot: &Foot, cell: f64, toes: bool) -> HeightMap {
    let t = foot.truth();
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for p in t.outline_body.iter().chain(t.outline_toes.iter().flatten()) {
        for a in 0..2 {
            lo[a] = lo[a].min(p[a] - 3.0);
            hi[a] = hi[a].max(p[a] + 3.0);
        }
    }
    HeightMap::sampled(lo, hi, cell, |x, y| {
        if toes {
            foot.height(x, y)
        } else {
            let f = foot.to_foot(x, y);
            foot.body_height_foot_frame(f.x, f.y)
        }
    })
}

/// One simulated foot measured against its truth.
#[derive(Clone, Debug, Serialize)]
pub struct PopulationRow {
    pub kind: &'static str,
    pub length_mm: f64,
    pub side_correct: bool,
    /// Errors: landmark distances and |measured - truth| (mm), axis (degrees).
    pub mt1_mm: f64,
    pub mt5_mm: f64,
    pub ball_mm: f64,
    pub heel_mm: f64,
    pub midfoot_mm: f64,
    pub length_err_mm: f64,
    pub axis_deg: f64,
    pub waist_inner_mm: f64,
    pub waist_outer_mm: f64,
    pub arch_height_mm: f64,
    pub warnings: Vec<String>,
    pub ms: f64,
}

impl PopulationRow {
    /// Within every target of the population (side, heads, widths, length).
    pub fn within_targets(&self) -> bool {
        self.side_correct
            && self.mt1_mm <= TARGET_HEAD_MM
            && self.mt5_mm <= TARGET_HEAD_MM
            && self.ball_mm.max(self.heel_mm).max(self.midfoot_mm) <= TARGET_WIDTH_MM
            && self.length_err_mm <= TARGET_LENGTH_MM
    }
}

/// `n` feet of [`population`]`(n, seed)` measured on analytic maps of `cell` mm.
pub fn population_rows(n: usize, seed: u64, cell: f64) -> Result<Vec<PopulationRow>, String> {
    population(n, seed)
        .into_iter()
        .enumerate()
        .map(|(i, pf)| {
            let foot = Foot::new(pf.params.clone()).map_err(|e| format!("foot {i}: {e}"))?;
            let map = analytic_map(&foot, cell, true);
            let t0 = Instant::now();
            let m = measure_foot(&map).map_err(|e| format!("foot {i} ({}): {e}", pf.kind))?;
            let ms = t0.elapsed().as_secs_f64() * 1e3;
            let truth = serde_json::to_string(&foot.truth()).expect("truth serialises");
            let c = compare_with_truth(&m, &truth).expect("truth reads back");
            let e = |name: &str| c.row(name).map_or(f64::NAN, |r| r.error.abs());
            Ok(PopulationRow {
                kind: pf.kind,
                length_mm: pf.params.length_mm,
                side_correct: c.side_correct,
                mt1_mm: e("mt1_head"),
                mt5_mm: e("mt5_head"),
                ball_mm: e("ball_width_mm"),
                heel_mm: e("heel_width_mm"),
                midfoot_mm: e("midfoot_width_mm"),
                length_err_mm: e("foot_length_mm"),
                axis_deg: e("axis_angle_deg"),
                waist_inner_mm: e("waist_inner"),
                waist_outer_mm: e("waist_outer"),
                arch_height_mm: e("arch_height_mm"),
                warnings: m.warnings,
                ms,
            })
        })
        .collect()
}

/// What the scanner sees of a foot mesh standing in its frame (mm, heel toward -x, sole on
/// z = 0): its lower envelope on `cell` mm cells, as the simulator's mesh scene renders it.
pub fn mesh_map(mesh: &TriMesh, cell: f64) -> Result<HeightMap, String> {
    let s = MeshSurface::placed(mesh, &Placement::default()).map_err(|e| e.to_string())?;
    let placed =
        footscan_sim::mesh_scene::place(mesh, &Placement::default()).map_err(|e| e.to_string())?;
    let bb = placed.bbox();
    Ok(HeightMap::sampled(
        [bb.min.x - 2.0, bb.min.y - 2.0],
        [bb.max.x + 2.0, bb.max.y + 2.0],
        cell,
        |x, y| s.height(x, y),
    ))
}

/// The figures of one real foot's measurement: where its heads lie along it and its widths.
#[derive(Clone, Debug, Serialize)]
pub struct RealRow {
    pub name: String,
    pub side: String,
    pub length_mm: f64,
    pub ball_width_mm: f64,
    pub heel_width_mm: f64,
    pub midfoot_width_mm: f64,
    pub arch_height_mm: f64,
    pub arch_index: f64,
    /// Distance of each head from the heel point along the axis over the length.
    pub mt1_frac: f64,
    pub mt5_frac: f64,
    pub warnings: Vec<String>,
    pub ms: f64,
}

impl RealRow {
    pub fn of(name: &str, m: &Measurements, ms: f64) -> RealRow {
        let along = |p: footscan_geom::P2| (p - m.heel_point).dot(&m.axis_dir) / m.foot_length_mm;
        RealRow {
            name: name.into(),
            side: format!("{:?}", m.side).to_lowercase(),
            length_mm: m.foot_length_mm,
            ball_width_mm: m.ball_width_mm,
            heel_width_mm: m.heel_width_mm,
            midfoot_width_mm: m.midfoot_width_mm,
            arch_height_mm: m.arch_height_mm,
            arch_index: m.arch_index,
            mt1_frac: along(m.mt1_head),
            mt5_frac: along(m.mt5_head),
            warnings: m.warnings.clone(),
            ms,
        }
    }
}

/// Relative difference of a person's two feet, |a - b| / mean.
pub fn pair_difference(a: f64, b: f64) -> f64 {
    (a - b).abs() / (0.5 * (a + b))
}
