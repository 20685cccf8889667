//! `footscan bench measure`: the foot measurements on a population of simulated feet of every
//! kind against their exact truth, and on the real feet of the data directory (read as they
//! come, seen from below as the simulator's mesh scene sees them) against what holds for feet.

use anyhow::{anyhow, Result};
use footscan::measure::measure_foot;
use footscan_bench::measure::{
    mesh_map, pair_difference, population_rows, PopulationRow, RealRow, TARGET_HEAD_MM,
    TARGET_LENGTH_MM, TARGET_WIDTH_MM,
};
use footscan_geom::mesh::{IntakeOptions, TriMesh};
use serde_json::json;
use std::path::Path;
use std::time::Instant;

/// The real feet of the data directory (relative to it); the dupontgu pair is one person's.
pub const REAL_FEET: [&str; 5] = [
    "feet/find_template/template_mm.stl",
    "feet/find_lowres/find_demo_template.obj",
    "feet/makehuman/makehuman_default_right_foot_cut150mm.stl",
    "feet/dupontgu_my_feet/left_foot.stl",
    "feet/dupontgu_my_feet/right_foot.stl",
];
const PAIR: (usize, usize) = (3, 4);

pub fn run(data: &Path, feet: usize, seed: u64, cell: f64, json: bool) -> Result<()> {
    let t0 = Instant::now();
    let pop = population_rows(feet, seed, cell).map_err(|e| anyhow!(e))?;
    let pop_s = t0.elapsed().as_secs_f64();
    let mut real = Vec::new();
    for rel in REAL_FEET {
        let path = data.join(rel);
        let intake = TriMesh::read_foot(&path, &IntakeOptions::default()).map_err(|e| {
            anyhow!(
                "{e} (give --data DIR holding feet/)",
                e = footscan_util::Chain(&e)
            )
        })?;
        let map = mesh_map(&intake.mesh, cell).map_err(|e| anyhow!("{}: {e}", path.display()))?;
        let t = Instant::now();
        let m = measure_foot(&map)
            .map_err(|e| anyhow!("{}: {e}", path.display(), e = footscan_util::Chain(&e)))?;
        real.push(RealRow::of(rel, &m, t.elapsed().as_secs_f64() * 1e3));
    }
    let (a, b) = (&real[PAIR.0], &real[PAIR.1]);
    let pair = [
        ("length", pair_difference(a.length_mm, b.length_mm)),
        (
            "ball width",
            pair_difference(a.ball_width_mm, b.ball_width_mm),
        ),
        (
            "heel width",
            pair_difference(a.heel_width_mm, b.heel_width_mm),
        ),
    ];
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(&json!({
                "population": pop,
                "real": real,
                "pair": pair.iter().map(|(n, d)| json!({"measure": n, "difference": d}))
                    .collect::<Vec<_>>(),
            }))?
        );
        return Ok(());
    }
    print_population(&pop, pop_s);
    println!(
        "\nreal feet, read as they come and seen from below on {cell} mm cells (heads as a \
         fraction of the length from the heel; feet have them at 0.60-0.80):"
    );
    println!(
        "{:58} {:5} {:>6} {:>6} {:>6} {:>6} {:>5} {:>5} {:>5} {:>5} {:>6}  warnings",
        "foot", "side", "length", "ball", "heel", "mid", "arch", "AI", "MT1", "MT5", "ms"
    );
    for r in &real {
        println!(
            "{:58} {:5} {:6.1} {:6.1} {:6.1} {:6.1} {:5.1} {:5.3} {:5.3} {:5.3} {:6.1}  {}",
            r.name,
            r.side,
            r.length_mm,
            r.ball_width_mm,
            r.heel_width_mm,
            r.midfoot_width_mm,
            r.arch_height_mm,
            r.arch_index,
            r.mt1_frac,
            r.mt5_frac,
            r.ms,
            r.warnings.len()
        );
        for w in &r.warnings {
            println!("    ! {w}");
        }
    }
    println!("\none person's left and right foot (dupontgu), |left - right| / mean (target 2 %):");
    for (n, d) in pair {
        println!("  {n:10} {:5.2} %", 100.0 * d);
    }
    Ok(())
}

fn print_population(rows: &[PopulationRow], secs: f64) {
    println!(
        "simulated population: {} feet of {} kinds, analytic height maps, against the truth \
         (targets: heads {TARGET_HEAD_MM} mm, widths {TARGET_WIDTH_MM} mm, length \
         {TARGET_LENGTH_MM} mm); worst per kind:",
        rows.len(),
        footscan_sim::foot::KINDS.len()
    );
    println!(
        "{:26} {:>3} {:>5} {:>5} {:>5} {:>5} {:>5} {:>6} {:>6} {:>6} {:>6} {:>6} {:>5}",
        "kind",
        "n",
        "MT1",
        "MT5",
        "ball",
        "heel",
        "mid",
        "length",
        "axis",
        "waist",
        "within",
        "warned",
        "ms"
    );
    let worst = |rs: &[&PopulationRow], f: fn(&PopulationRow) -> f64| {
        rs.iter().map(|r| f(r)).fold(0.0, f64::max)
    };
    let line = |name: &str, rs: Vec<&PopulationRow>| {
        println!(
            "{:26} {:3} {:5.2} {:5.2} {:5.2} {:5.2} {:5.2} {:6.2} {:6.2} {:6.1} {:6} {:6} {:5.1}",
            name,
            rs.len(),
            worst(&rs, |r| r.mt1_mm),
            worst(&rs, |r| r.mt5_mm),
            worst(&rs, |r| r.ball_mm),
            worst(&rs, |r| r.heel_mm),
            worst(&rs, |r| r.midfoot_mm),
            worst(&rs, |r| r.length_err_mm),
            worst(&rs, |r| r.axis_deg),
            worst(&rs, |r| r.waist_inner_mm.max(r.waist_outer_mm)),
            rs.iter().filter(|r| r.within_targets()).count(),
            rs.iter().filter(|r| !r.warnings.is_empty()).count(),
            rs.iter().map(|r| r.ms).sum::<f64>() / rs.len().max(1) as f64,
        );
    };
    for kind in footscan_sim::foot::KINDS {
        line(kind, rows.iter().filter(|r| r.kind == kind).collect());
    }
    line("all", rows.iter().collect());
    let silent = rows
        .iter()
        .filter(|r| !r.within_targets() && r.warnings.is_empty())
        .count();
    println!(
        "off a target without a warning: {silent}; {secs:.1} s in all (truth and maps included)"
    );
}
